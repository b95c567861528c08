"""What the surface and element contract tests share: every registered kind of `tracer.optics.surfaces.dispatch.KINDS`
(surfaces and thin elements register in one list), specs made from the kind's own field metadata, and a
white-furnace driver that calls the very switch the transport kernel calls (`dispatch.scatter`) N times.

A photon arrives at a flat quad (front side +z, no vertex normals) along one direction; each draw has its own
random stream (`path_key(seed, 0, i)`), so every photon is independent and a mean has the standard error
std/√N. The closed forms (`LOBES`) are the kinds' own docstrings, written out independently here:
which outgoing directions a kind promises (mirror, straight on, refracted by Snell's law, cosine-distributed on
the near or far side) and with which probability. A kind without an entry gets the generic promises only.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from tests.tracer.transport_scenes import quad, scene_of
from tracer.jit import njit
from tracer.optics.elements.base import parse_axis
from tracer.optics.polarization import N_POL, ON, S1, S3, E
from tracer.optics.surfaces import dispatch
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    DIFFUSE,
    GLOSSY,
    SPECULAR,
    STACK_FULL,
    TRANSMITS,
    MaterialError,
    spec_from_body,
)
from tracer.optics.surfaces.measured_brdf import parse_table
from tracer.optics.surfaces.mirror import parse_metal
from tracer.rng import path_key

K = 4.0            # tolerance: K standard errors of the estimate
N = 20_000         # photons per (spec, direction, polarization state)
DIR_TOL = 1e-9     # an outgoing direction "is" the mirror / straight / refracted one within this
NG = np.array([0.0, 0.0, 1.0])   # the quad's geometric normal (front side)

# A sample value for a required (or optional) field validated by a parse function, keyed by that function: a new
# kind with a field parsed by a new function fails `specs_of` until it is given one here.
PARSE_SAMPLES = {parse_axis: [0.6, 0.8, 0.0], parse_metal: [0.96, 6.69],   # an axis; aluminium's n − ik at 550 nm
                 parse_table: {"theta_i_deg": [0, 40, 80], "theta_o_deg": [0, 30, 60, 90], "dphi_deg": [0, 90, 180],
                               "brdf": [[[0.2, 0.1]] * 3, [[0.1, 0.2]] * 3, [[0.0, 0.3]] * 3]}}   # a measured BRDF
FRACTIONS = (0.15, 0.4, 1.0)   # where in a number field's range its sample values lie (1.0: its top, a white furnace)


def kinds_in(package: str):
    """The registered kind modules whose module lives in `package` (in registry order)."""
    return [m for m in dispatch.KINDS if m.__name__.startswith(package + ".")]


def _number(meta, x: float) -> float:
    lo, hi = meta["lo"], meta["hi"]
    if hi - lo > 1e3:        # a coefficient in 1/m up to 1e9, a ratio up to 1e15: a modest value
        hi = lo + 10.0
    return lo + x * (hi - lo)


def specs_of(module) -> list:
    """Valid specs of a kind made from its `Spec` fields' metadata: at each fraction of FRACTIONS, (1) the required
    fields, (2) with every optional number field besides, (3) with every optional parsed field (PARSE_SAMPLES).
    Bodies that the kind's `check()` rejects are left out; duplicates once."""
    fields = dataclasses.fields(module.Spec)
    out = []
    for x in FRACTIONS:
        required, numbers, parsed = {}, {}, {}
        for f in fields:
            meta = f.metadata
            if "parse" in meta:
                if f.default is dataclasses.MISSING and meta["parse"] not in PARSE_SAMPLES:
                    raise AssertionError(f"{module.NAME}.{f.name}: add a sample value for {meta['parse'].__name__} "
                                         f"to PARSE_SAMPLES")
                if meta["parse"] in PARSE_SAMPLES:
                    (required if f.default is dataclasses.MISSING else parsed)[f.name] = PARSE_SAMPLES[meta["parse"]]
            else:
                (required if f.default is dataclasses.MISSING else numbers)[f.name] = _number(meta, x)
        for body in (required, {**required, **numbers}, {**required, **parsed}):
            try:
                spec = spec_from_body(module.Spec, module.NAME, {"type": module.NAME, **body}, "contract")
            except MaterialError:
                continue
            if spec not in out:
                out.append(spec)
    assert out, f"no valid spec of {module.NAME!r} could be made from its fields' metadata"
    return out


def is_solid(module) -> bool:
    """A kind with an inside (a `medium`): its geometric normal is outward, a photon arriving from behind is in it."""
    return hasattr(module, "inside")


def directions():
    """Unit arrival directions (θ from the normal: 0°, 45°, 80°), toward the front side and toward the back."""
    out = []
    for theta in (0.0, 45.0, 80.0):
        t, phi = math.radians(theta), 0.7
        s = np.array([math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t)])
        out += [("front", theta, -s), ("back", theta, s)]
    return out


# polarization states of the arriving photon: (name, ON, s1, s2, s3); the closed forms are for the first two
STATES = (("white", 0.0, 0.0, 0.0, 0.0), ("unpolarized", 1.0, 0.0, 0.0, 0.0), ("linear", 1.0, 1.0, 0.0, 0.0),
          ("circular", 1.0, 0.0, 0.0, 1.0))


# --------------------------------------------------------------------------------------------------- the driver


@njit(cache=True)
def _run(scatter, sa, M, inst, d, ng, med0, depth0, lam, pol0, n, seed, out, med_out):
    """n photons through `scatter` (the dispatch switch or a kind's own function): out[i] = (status, d', f, depth',
    dim'), med_out[i] = med after the call."""
    med = med0.copy()
    pol = pol0.copy()
    for i in range(n):
        med[:] = med0
        pol[:] = pol0
        key = path_key(seed, 0, i)
        st, dx, dy, dz, f, depth, dim = scatter(sa, M, inst, 0, 0.25, 0.25, d[0], d[1], d[2], ng[0], ng[1], ng[2],
                                                med, depth0, key, 5, lam, pol)
        out[i, 0] = st
        out[i, 1] = dx
        out[i, 2] = dy
        out[i, 3] = dz
        out[i, 4] = f
        out[i, 5] = depth
        out[i, 6] = dim
        med_out[i] = med


_SCENE = []


def quad_scene():
    """(SceneArrays, instance id) of one committed quad, front side +z, built once."""
    if not _SCENE:
        scene, (inst,) = scene_of(quad((-1.0, -1.0, 0.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0)))
        _SCENE.append((scene.arrays(), inst))
    return _SCENE[0]


class Case:
    """One kind with one spec on the quad, lit along d from one side in one polarization state."""

    def __init__(self, module, spec, side, theta, d, state):
        self.module, self.spec, self.side, self.theta, self.d, self.state = module, spec, side, theta, d, state
        self.sa, self.inst = quad_scene()
        self.M = dispatch.bind(self.sa, dispatch.pack_materials({self.inst: spec}, None, [self.inst], set()))
        self.inside = is_solid(module) and side == "back"
        self.med0 = np.full(4, -7, np.int64)
        self.depth0 = 0
        if self.inside:
            self.med0[0], self.depth0 = self.inst, 1
        _, on, s1, s2, s3 = state
        self.pol0 = np.zeros(N_POL)
        self.pol0[ON], self.pol0[S1], self.pol0[S1 + 1], self.pol0[S3] = on, s1, s2, s3
        e = np.cross(d, [0.3, 0.9, 0.1])          # the frame axis, across d
        self.pol0[E:E + 3] = e / np.linalg.norm(e)
        self.f_arr = NG if d @ NG < 0 else -NG   # the normal on the arrival side

    def run(self, scatter=dispatch.scatter, n=N, seed=11):
        out = np.zeros((n, 7))
        med = np.zeros((n, len(self.med0)), np.int64)
        _run(scatter, self.sa, self.M, self.inst, self.d, NG, self.med0, self.depth0, 0.0, self.pol0, n, seed, out,
             med)
        return out, med

    def __repr__(self):
        return f"{self.module.NAME} {self.spec} from the {self.side} at {self.theta:g}° ({self.state[0]})"


def cases(modules, states=STATES):
    for m in modules:
        for spec in specs_of(m):
            for side, theta, d in directions():
                for state in states:
                    yield Case(m, spec, side, theta, d, state)


# ------------------------------------------------------------------------------------------------ closed forms


def fresnel(cos_i: float, n1: float, n2: float) -> float:
    """Unpolarized Fresnel reflectance (Rs + Rp)/2, 1 under total internal reflection (Hecht, Optics, 4.4)."""
    sin_t2 = (n1 / n2) ** 2 * (1.0 - cos_i * cos_i)
    if sin_t2 >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t2)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return 0.5 * (rs * rs + rp * rp)


def _s1_blind(case) -> bool:
    """Whether the photon's state reads as unpolarized to an interface (`interface_power` reads s1 only)."""
    return case.state[0] in ("white", "unpolarized", "circular")


def _mirror(spec, case):
    if spec.metal is None:   # a perfect reflector's matrix scaled by R: R for every state
        return [("mirror", float(spec.reflectance))]
    if spec.coating is None and case.theta == 0.0 and _s1_blind(case):   # a metal at normal incidence, in air
        n, k = spec.metal
        return [("mirror", ((n - 1) ** 2 + k * k) / ((n + 1) ** 2 + k * k))]
    return None


def _dielectric(spec, case):
    if spec.coating is not None or spec.alpha or not _s1_blind(case):   # rough: test_rough_dielectric
        return None
    n = float(spec.ior)
    n1, n2 = (n, 1.0) if case.inside else (1.0, n)
    r = fresnel(math.cos(math.radians(case.theta)), n1, n2)
    return [("mirror", r), ("refract", 1.0 - r)]


def _polarizer(spec, case):
    """Unpolarized (or circular) light passes (k1 + k2)/2; linear light at ψ to the axis k1 cos²ψ + k2 sin²ψ (Malus),
    the axis taken onto the sheet, then across the photon's direction (the module's thin-sheet model)."""
    k1 = spec.transmittance
    k2 = 0.0 if spec.extinction_ratio is None else k1 / spec.extinction_ratio
    if _s1_blind(case):
        return [("straight", 0.5 * (k1 + k2))]
    a = np.array(spec.axis) - (np.array(spec.axis) @ NG) * NG
    a = a - (a @ case.d) * case.d
    cos_psi = (case.pol0[E:E + 3] @ a) / np.linalg.norm(a)   # the photon's field lies along its frame axis (s1 = 1)
    return [("straight", k1 * cos_psi ** 2 + k2 * (1.0 - cos_psi ** 2))]


# name -> (spec, case) -> [(lobe, probability)] or None where the kind states no closed form for that spec
LOBES = {
    "black": lambda spec, case: [],
    "lambertian": lambda spec, case: [("cosine near", float(spec.reflectance))],
    "mirror": _mirror,
    "mix": lambda spec, case: [("cosine near", spec.diffuse), ("mirror", spec.specular)],
    "dielectric": _dielectric,
    "diffuser": lambda spec, case: [("cosine near", float(spec.reflectance)),
                                    ("cosine far", float(spec.transmittance))],
    "polarizer": _polarizer,
    "retarder": lambda spec, case: [("straight", spec.transmittance)],
}


def exact_direction(lobe: str, case: Case, spec) -> np.ndarray | None:
    """The one direction of an exact lobe (None for a diffuse one, or where Snell's law has no solution)."""
    d, f = case.d, case.f_arr
    if lobe == "straight":
        return d
    if lobe == "mirror":
        return d - 2.0 * (d @ f) * f
    if lobe == "refract":
        n = float(spec.ior)
        eta = n if case.inside else 1.0 / n
        cos_i = -(d @ f)
        sin_t2 = eta * eta * (1.0 - cos_i * cos_i)
        if sin_t2 >= 1.0:
            return None
        t = eta * d + (eta * cos_i - math.sqrt(1.0 - sin_t2)) * f
        return t / np.linalg.norm(t)
    return None


def mean_and_error(x: np.ndarray) -> tuple[float, float]:
    return float(x.mean()), float(x.std(ddof=1) / math.sqrt(len(x)))


def binned_uniform(values: np.ndarray, bins: int, what: str) -> None:
    """`values` uniform on [0, 1): each of `bins` equal bins holds n/bins within K binomial standard errors."""
    n = len(values)
    counts = np.histogram(values, bins=bins, range=(0.0, 1.0))[0]
    p = 1.0 / bins
    sigma = math.sqrt(n * p * (1 - p))
    worst = np.max(np.abs(counts - n * p)) / sigma
    assert worst <= K, f"{what}: a bin is {worst:.1f} binomial sigma off uniform ({counts.tolist()})"


def check_lobes(case: Case, out: np.ndarray, med: np.ndarray) -> list[tuple[str, float, float, float]]:
    """Classify every continuing photon into the kind's stated lobes; every photon must fall in one. Returns
    (lobe, expected probability, measured mean weight, its standard error) for each lobe, and checks the shape of
    the cosine lobes (cos²θ and the azimuth uniform: density cosθ/π)."""
    spec = case.spec
    lobes = LOBES[case.module.NAME](spec, case)
    alive = out[:, 0] == CONTINUES
    d_out = out[:, 1:4]
    cos_out = d_out @ case.f_arr
    assigned = np.full(len(out), -1)
    order = sorted(range(len(lobes)), key=lambda k: lobes[k][0].startswith("cosine"))   # exact directions first
    for k in order:
        lobe = lobes[k][0]
        free = alive & (assigned < 0)
        exact = exact_direction(lobe, case, spec)
        if exact is not None:
            hit = free & (np.linalg.norm(d_out - exact, axis=1) < DIR_TOL)
        elif lobe == "cosine near":
            hit = free & (cos_out > 0)
        elif lobe == "cosine far":
            hit = free & (cos_out < 0)
        else:
            hit = np.zeros(len(out), bool)
        assigned[hit] = k
    stray = alive & (assigned < 0)
    assert not stray.any(), (f"{case}: {int(stray.sum())} photons leave along a direction the kind does not state "
                             f"(lobes {lobes}), e.g. {d_out[stray][:3].tolist()}")
    t = np.cross(case.f_arr, [0.37, 0.11, 0.92])   # any frame about the normal, for the azimuth
    t /= np.linalg.norm(t)
    b = np.cross(case.f_arr, t)
    results = []
    for k, (lobe, p) in enumerate(lobes):
        w = np.where(assigned == k, out[:, 4], 0.0)
        mean, err = mean_and_error(w)
        err = max(err, math.sqrt(p * (1 - p) / len(w)))   # where no photon (or every one) took it: p's own error
        results.append((lobe, p, mean, err))
        if lobe.startswith("cosine") and (assigned == k).sum() >= 2000:
            dd = d_out[assigned == k]
            c = np.abs(dd @ case.f_arr)
            binned_uniform(c * c, 10, f"{case}: cos²θ of the {lobe} lobe")
            phi = (np.arctan2(dd @ b, dd @ t) / (2 * math.pi)) % 1.0
            binned_uniform(phi, 8, f"{case}: azimuth of the {lobe} lobe")
    return results


# ---------------------------------------------------------------------------------------------------- the checks


def check_contract(case: Case, out: np.ndarray, med: np.ndarray) -> None:
    """The promises of `tracer.optics.surfaces.base` that hold for every kind, whatever its physics."""
    st, d_out, f, depth, dim = out[:, 0], out[:, 1:4], out[:, 4], out[:, 5], out[:, 6]
    assert np.isin(st, (ABSORBED, CONTINUES, STACK_FULL)).all(), f"{case}: a status outside the contract"
    assert not (st == STACK_FULL).any(), f"{case}: STACK_FULL with {len(case.med0) - case.depth0} free places"
    alive = st == CONTINUES
    assert np.all(np.isfinite(f)) and np.all(f >= 0), f"{case}: a weight factor that is negative or not finite"
    assert np.all(dim >= 5), f"{case}: dim went back (it must advance past the numbers drawn)"
    # energy: the white furnace, mean carried weight <= 1 within K standard errors
    mean, err = mean_and_error(np.where(alive, f, 0.0))
    assert mean <= 1.0 + K * err, f"{case}: albedo {mean:.5f} ± {err:.5f} > 1"
    # directions: unit, and off the surface on one side
    norm = np.linalg.norm(d_out[alive], axis=1)
    assert np.all(np.abs(norm - 1.0) < 1e-12), f"{case}: outgoing |d| off 1 by {np.max(np.abs(norm - 1.0)):.2e}"
    c = d_out[alive] @ case.f_arr
    assert np.all(c != 0.0), f"{case}: an outgoing direction in the surface's plane"
    far = np.zeros(len(out), bool)
    far[alive] = c < 0
    check_flags(case, d_out, alive, far)
    # the medium stack: only a solid's transmitted photon pushes (entering) or pops (leaving) the solid itself
    same_depth = depth == case.depth0
    same_med = (med == case.med0).all(axis=1)
    if not is_solid(case.module):
        assert same_depth.all() and same_med.all(), f"{case}: a kind without an inside changed the medium stack"
        return
    near = alive & ~far
    assert (same_depth[near] & same_med[near]).all(), f"{case}: a reflected photon changed the medium stack"
    if case.inside:
        assert (depth[far] == 0).all(), f"{case}: a photon leaving the solid did not pop it"
    else:
        assert (depth[far] == 1).all() and (med[far, 0] == case.inst).all(), \
            f"{case}: a photon entering the solid did not push it"


def check_flags(case: Case, d_out: np.ndarray, alive: np.ndarray, far: np.ndarray) -> None:
    """The kind's `FLAGS` say what it may do, and it does nothing else: no photon continues from a kind without
    lobes, none goes through one without `TRANSMITS`; one without a spread lobe (`DIFFUSE`, `GLOSSY`) sends its
    photons along a handful of exact directions (a delta lobe: mirrored, refracted, straight on, back), and one without
    `SPECULAR` never sends two photons along the same direction (within `DIR_TOL`: a spread lobe's draws differ)."""
    flags = dispatch.flags_of(case.spec)
    assert flags == case.M.flags[case.inst], f"{case}: the packed flags are not the kind's"
    assert not (flags == 0 and alive.any()), f"{case}: FLAGS 0 (absorbs everything), but photons continue"
    assert flags & TRANSMITS or not far.any(), f"{case}: photons go through, FLAGS lack TRANSMITS"
    if not alive.any():
        return
    cells, counts = np.unique(np.round(d_out[alive] / DIR_TOL).astype(np.int64), axis=0, return_counts=True)
    if not flags & (DIFFUSE | GLOSSY):
        assert len(cells) <= 4, f"{case}: FLAGS state no spread lobe, but photons leave along {len(cells)} directions"
    if not flags & SPECULAR:
        assert counts.max() == 1, f"{case}: FLAGS lack SPECULAR, but {counts.max()} photons leave along one direction"


def check_closed_form(case: Case, out: np.ndarray, med: np.ndarray) -> str | None:
    """The kind's stated lobes and their probabilities (`LOBES`), each within K standard errors; the reason where
    the kind states none for this spec."""
    rule = LOBES.get(case.module.NAME)
    if rule is None:
        return f"{case.module.NAME}: no closed form written in LOBES"
    if rule(case.spec, case) is None:
        return f"{case}: no closed form for this spec"
    # every continuing photon is in one lobe (`check_lobes`), so the lobes' sum is the albedo
    for lobe, p, mean, err in check_lobes(case, out, med):
        assert abs(mean - p) <= K * err, f"{case}: {lobe} carries {mean:.5f} ± {err:.5f}, stated {p:.5f}"
    return None


def check_dispatch_routes(module) -> None:
    """The switch sends the kind to its own `scatter`: the same photons give bit-identical answers either way."""
    for case in cases([module], STATES[:1]):
        a, ma = case.run(dispatch.scatter, n=300, seed=5)
        b, mb = case.run(module.scatter, n=300, seed=5)
        np.testing.assert_array_equal(a, b, err_msg=f"{case}: dispatch.scatter and {module.NAME}.scatter differ")
        np.testing.assert_array_equal(ma, mb)
