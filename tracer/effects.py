"""The effect set of a scene, derived here and only here, and the photon state it calls for.

| effect | called for by |
| --- | --- |
| `lambertian` | always (diffuse reflection is the baseline; a `diffuser` needs nothing more) |
| `specular` | a `mirror` material, or a `mix` with specular > 0 |
| `fresnel` | a `dielectric`, smooth or rough (Fresnel interfaces, refraction, total internal reflection) |
| `absorption` | a `dielectric` whose medium has absorption_per_m > 0 |
| `scattering` | a `dielectric` whose medium has scattering_per_m > 0 |
| `spectral` | any value that depends on the wavelength (below), or a query that observes the spectrum |
| `dispersion` | a `dielectric` whose `ior` is a Sellmeier formula or a table |
| `coating` | a `dielectric` with thin films |
| `fluorescence` | a `dielectric` whose medium fluoresces |
| `mie` | a `dielectric` whose medium holds `particles` (Mie scattering, `tracer.optics.mie`) |
| `diffraction` | a grating on a part's face (`tracer.elements.diffraction`: its orders vary with the wavelength) |
| `polarization` | a `polarizer`, `retarder`, polarized light or a query observing Stokes (required); and by physics |
|  | wherever a path can meet two polarizing interactions that could move the answer beyond its error bar |
|  | (`polarization_call` below; a query may then force it off) |

Each kind declares its effects (`effects(spec)` in its module, `tracer/optics/`; a dielectric adds its medium's,
`tracer/optics/media/`); this module gathers them. The effects above change no compiled code: they are branches on
data (a photon meets a mirror only where there is one), which the transport benchmark measured to cost nothing
where unused. What a photon *carries* does change the kernel (Mitsuba's variants): `photon_state(effects)` names it,
and `tracer.transport.forward.forward_kernel(state)` is the one factory of kernels. Every effect listed today
up to `scattering` needs only a weight, the state ``"white"``; `spectral` (implied by `dispersion`, `coating`
`fluorescence`, `mie` and `diffraction`) needs a wavelength, the state ``"spectral"``; `polarization` needs a
Stokes vector and its frame (`tracer.optics.polarization`), the state ``"polarized"`` (``"polarized-spectral"``
with both). A light's spectrum alone does not call for a wavelength: in a grey scene the luminous answer is exact
without it.
`with_forced` turns effects on in a scene that does not need them (the answer must not change), and off where the
physics estimate took them (`OPTIONAL`) and the query asks (`force_effects_off`).

Polarization by physics (docs/DESIGN.md "Physics, and only what a scene calls for"). Unpolarized light meeting one
interface comes out with the right power whether s and p are kept apart or averaged; only a second polarizing
interaction on the same path can turn the first one's polarization into a different power. For two interfaces of
diattenuations D₁ = (Ts − Tp)/(Ts + Tp) (or the same for reflection) and D₂, the polarized answer is the averaged one
times 1 + D₁ D₂ cos 2φ (φ the angle between their planes of incidence): the relative error of leaving polarization
out is at most D₁ D₂. Each kind declares, from its spec, how many polarizing interactions a path can meet at one of
its surfaces and their largest diattenuation over all angles (`polarizing(spec)` in its module): a dielectric solid
(smooth or rough: each facet is a Fresnel interface) 2 (entered and left), diattenuation 1
(its reflection at Brewster's angle is pure s); a metal mirror 1, its own
maximum from the Fresnel formulas of n − ik (aluminium [0.96, 6.69]: 0.139 at 81.7°); a coated mirror 1, bounded
by 1; particles in a medium 2 (Mie scattering polarizes, bounded by 1). Lambertian, perfect mirrors and
Henyey–Greenstein media add nothing (they depolarize or act alike on s and p). With each surface counted once per
instance that carries it, the bound is the product of the two largest diattenuations, and polarization is on where
it exceeds `POLARIZATION_FLOOR` (0.2 %, the tightest relative error an answer's cost is quoted for). Geometry is
looked at once, where it can add a passage: a reflector that is neither planar nor a closed convex solid (a curved
dish, a V groove, a faceted reflector in one mesh) can send a path back onto itself, so its one instance counts as
two interactions (`surface_shape`, `met_twice`); a plane cannot, nor a convex body lit from outside. The rest is
what the materials allow, the cheap and conservative reading of "could exceed"; a query may force polarization on,
and `physics_left_out` measures the difference.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

import numpy as np

from tracer.errors import TracerError
from tracer.optics.surfaces.dispatch import effects_of, material_spec, module_of, polarizing_of

EFFECTS = ("lambertian", "specular", "fresnel", "absorption", "scattering", "spectral", "dispersion", "coating",
           "fluorescence", "mie", "diffraction", "polarization")
BASELINE = "lambertian"   # diffuse reflection: every scene has it, and it costs nothing
NEEDS_WAVELENGTH = ("dispersion", "coating", "fluorescence", "mie", "diffraction")
GRATING = "grating element"   # how the reasons name a grating (`explain_effects`), beside materials' kinds
PHOTON_STATES = ("white", "spectral", "polarized", "polarized-spectral")
OPTIONAL = ("polarization",)    # effects the physics estimate may take, and a query may therefore force off
POLARIZATION_FLOOR = 0.002      # relative error below which leaving polarization out cannot show (module docstring)


class EffectError(TracerError):
    """An unknown effect name."""


def canonical(effects: Iterable[str]) -> list[str]:
    """The effects in `EFFECTS` order; unknown names raise `EffectError`."""
    s = set(effects)
    unknown = sorted(s - set(EFFECTS))
    if unknown:
        raise EffectError(f"unknown effect(s) {unknown}; known: {list(EFFECTS)}")
    return [e for e in EFFECTS if e in s]


def derive_effects(materials: Iterable, lights: Iterable[dict] = (), counts: Mapping | None = None) -> list[str]:
    """The effect set of a scene from its materials (bodies or specs), as their kinds declare it, its light
    bodies (a polarized light calls for `polarization`), and polarization by physics (`explain_effects`).

    Raises `tracer.optics.surfaces.base.MaterialError` for an invalid material body.
    """
    return explain_effects(materials, lights, counts)[0]


def surface_shape(vertices, triangles, rel_tol: float = 1e-6) -> str:
    """What a mesh's shape allows a light path: ``"planar"`` (its vertices (n, 3) lie in one plane), ``"convex"``
    (its triangles (m, 3) close one convex solid: every edge shared by two triangles, one connected piece, and at
    every edge each triangle's far corner behind the other's plane, within `rel_tol` of the mesh's size; a closed
    connected surface convex at every edge bounds a convex body), or ``"other"``. Light leaving a plane never comes
    back to it, nor light leaving a convex body from outside; a dish, a groove, a faceted reflector in one mesh or an
    open curved sheet can send a path back onto itself (`met_twice`)."""
    v = np.asarray(vertices, np.float64).reshape(-1, 3)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    if len(v) < 4:
        return "planar"
    spread = np.linalg.svd(np.cov(v, rowvar=False), compute_uv=False)   # variances along the principal axes
    size = float(np.sqrt(spread[0])) or 1.0
    if np.sqrt(spread[-1]) <= 1e-3 * rel_tol * size:
        return "planar"
    rows = np.ascontiguousarray(v).view(np.dtype((np.void, 24))).ravel()
    points, welded = np.unique(rows, return_inverse=True)   # faces meshed apart share their edges' points
    v, t = points.view(np.float64).reshape(-1, 3), welded.reshape(-1)[t]
    a, b = t.reshape(-1), t[:, [1, 2, 0]].reshape(-1)               # half-edge 3k + j: corner j to j + 1
    far = t[:, [2, 0, 1]].reshape(-1)                               # the triangle's corner across that edge
    key = np.minimum(a, b) * np.int64(len(v)) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    if len(t) < 4 or len(order) % 2 or np.any(key[order[0::2]] != key[order[1::2]]) \
            or np.any(key[order[2::2]] == key[order[1:-1:2]]):
        return "other"                                                   # open, or not a manifold
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    if connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(len(v), len(v))), directed=False)[0] != 1:
        return "other"                                                   # bodies apart can light one another
    normal = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    h1, h2 = order[0::2], order[1::2]                                # the two half-edges of each edge
    ahead = np.concatenate([np.einsum("ij,ij->i", normal[h1 // 3], v[far[h2]] - v[a[h1]]),
                            np.einsum("ij,ij->i", normal[h2 // 3], v[far[h1]] - v[a[h2]])])
    tol = rel_tol * size
    return "convex" if np.all(ahead <= tol) or np.all(ahead >= -tol) else "other"   # either winding


def met_twice(scene, spec_of: Mapping, counts: Mapping, lights: Iterable[dict] = ()) -> set:
    """The specs (of `spec_of`: {instance id: spec or None} of a committed `tracer.Scene`) that polarize on one
    surface per passage, are carried by one surface only (`counts`), and that one path may meet twice: its mesh is
    neither planar nor convex (`surface_shape`), or convex with a light inside its box (`lights`: bodies, a
    ``position`` or ``origin`` point, or emitting ``instances``), as in a closed metal box lit from within. Only
    those specs are looked at, so a scene of many instances pays for a handful of meshes."""
    lights = list(lights)
    points = [np.asarray(b[k], np.float64) for b in lights for k in ("position", "origin") if k in b]
    emitters = [int(j) for b in lights for j in b.get("instances", ())]
    out = set()
    for i, spec in spec_of.items():
        if spec is None or spec in out or int(counts.get(spec, 1)) > 1 or polarizing_of(spec)[0] != 1:
            continue
        gid = scene.instance_geometry(i)
        if gid not in _SHAPES:   # a geometry id names its content: the answer holds for good
            if len(_SHAPES) >= 4096:
                _SHAPES.clear()
            _SHAPES[gid] = surface_shape(*scene.geometry_arrays(gid)[:2])
        lo, hi = scene.instance_bounds(i)
        lit_inside = any(np.all(p >= lo) and np.all(p <= hi) for p in points) or any(
            np.all(scene.instance_bounds(j)[0] <= hi) and np.all(scene.instance_bounds(j)[1] >= lo) for j in emitters)
        if _SHAPES[gid] == "other" or (_SHAPES[gid] == "convex" and lit_inside):
            out.add(spec)
    return out


_SHAPES: dict[str, str] = {}   # `surface_shape` per geometry id (3 s for a 1.3M-triangle mesh, 5 ms for 5k)


def explain_effects(materials: Iterable, lights: Iterable[dict] = (), counts: Mapping | None = None,
                    twice: Iterable = (), gratings: Iterable[float] = ()) -> tuple[list[str], dict[str, str]]:
    """The effect set of a scene and, for every effect in `EFFECTS`, why it is on or off (a sentence that starts
    with ``"on: "`` or ``"off: "``).

    materials : bodies or specs, one per surface that carries it (an instance, or a node), or distinct ones with
        `counts` {spec: surfaces that carry it} beside (missing: 1 each).
    twice : specs carried by a surface that one path may meet twice (`met_twice`): its one interaction counts
        twice in `polarization_call`.
    gratings : the largest diattenuation of each grating on a part's face (`tracer.elements.diffraction`), one per
        face: it calls for `diffraction`, and is one polarizing interaction in `polarization_call`.
    """
    specs = [material_spec(m) for m in materials]
    if counts is None:
        counts = Counter(specs)
    lights = list(lights)
    gratings = [float(d) for d in gratings]
    by_effect: dict[str, list[str]] = {}
    for spec in dict.fromkeys(specs):
        for e in effects_of([spec]) - {BASELINE}:
            by_effect.setdefault(e, []).append(module_of(spec).NAME)
    if gratings:
        for e in ("diffraction", "spectral"):
            by_effect.setdefault(e, []).append(GRATING)
    polarized_lights = [i for i, b in enumerate(lights) if isinstance(b, dict) and b.get("polarization")]
    reasons: dict[str, str] = {}
    on = {BASELINE}
    reasons[BASELINE] = "on: diffuse reflection is the baseline of every scene (it costs nothing)"
    for e in EFFECTS[1:]:
        kinds = sorted(set(by_effect.get(e, [])))
        if e == "polarization":
            continue
        if kinds:
            on.add(e)
            reasons[e] = f"on: called for by {_kinds(kinds)}"
        else:
            reasons[e] = "off: " + ("nothing in the scene's materials depends on the wavelength" if e == "spectral"
                                    else "no material of the scene calls for it")
    required = sorted(set(by_effect.get("polarization", [])))
    if required or polarized_lights:
        on.add("polarization")
        what = [_kinds(required)] if required else []
        what += [f"polarized light(s) {polarized_lights}"] if polarized_lights else []
        reasons["polarization"] = f"on: required by {' and '.join(what)} (cannot be forced off)"
    else:
        call, why = polarization_call(specs, counts, twice, gratings)
        if call:
            on.add("polarization")
        reasons["polarization"] = ("on: " if call else "off: ") + why
    return canonical(on), reasons


def _kinds(names: list[str]) -> str:
    return ", ".join(f"a {n}" if n == GRATING else f"a {n!r} material" for n in names)


def polarization_call(specs: Iterable, counts: Mapping | None = None, twice: Iterable = (),
                      gratings: Iterable[float] = ()) -> tuple[bool, str]:
    """Whether the scene's materials call for polarization by physics (the module docstring), and why: the two
    largest diattenuations a path can meet in a row, their product (the bound on the relative error of leaving
    polarization out) against `POLARIZATION_FLOOR`. `twice`: specs on a surface one path may meet twice;
    `gratings`: the largest diattenuation of each face carrying a grating (a diattenuator met once per passage)."""
    specs = list(specs)
    counts = Counter(specs) if counts is None else counts
    twice = set(twice)
    found: list[tuple[float, str]] = [(d, GRATING) for d in sorted(map(float, gratings), reverse=True)[:2] if d > 0]
    again: list[str] = []   # kinds counted twice: their one surface can be met twice
    for spec in dict.fromkeys(specs):
        per, d = polarizing_of(spec)
        if per <= 0 or d <= 0.0:
            continue
        n = per * max(int(counts.get(spec, 1)), 1)
        name = module_of(spec).NAME
        if spec in twice and n < 2:
            n = 2
            again.append(name)
        found += [(float(d), name)] * min(n, 2)
    found.sort(key=lambda x: -x[0])
    if not found:
        return False, ("no material polarizes (diffuse, perfect mirrors and Henyey-Greenstein media act alike on s "
                       "and p or depolarize)")
    if len(found) < 2:
        return False, (f"a path meets at most one polarizing interaction (one {found[0][1]!r} surface, largest "
                       f"diattenuation {found[0][0]:.3g}): one interface alone gives unpolarized light its right power")
    bound = found[0][0] * found[1][0]
    twice_why = "".join(f"; a {n!r} surface can be met twice: it is not a plane nor a convex body lit from outside"
                        for n in again)
    pair = f"a {found[0][1]!r} then a {found[1][1]!r} interaction (diattenuations up to {found[0][0]:.3g} and " \
           f"{found[1][0]:.3g}{twice_why})"
    if bound > POLARIZATION_FLOOR:
        return True, (f"a path can meet {pair}: leaving polarization out could move the answer by up to "
                      f"{100 * bound:.3g} %, above the {100 * POLARIZATION_FLOOR:g} % any answer resolves "
                      f"(force_effects_off may leave it out)")
    return False, (f"a path can meet {pair}, but leaving polarization out moves the answer by at most "
                   f"{100 * bound:.3g} %, below the {100 * POLARIZATION_FLOOR:g} % any answer resolves")


def with_forced(effects: list[str], force: tuple[str, ...] | list[str] | str,
                off: tuple[str, ...] | list[str] = ()) -> list[str]:
    """`effects` plus the forced ones, less those forced `off`, in canonical order; unknown names raise
    `EffectError` (the caller checks that `off` names only what may be left out: `check_off`)."""
    if isinstance(force, str):
        force = (force,)
    out = set(effects) | set(force)
    if out & set(NEEDS_WAVELENGTH):
        out.add("spectral")
    canonical(off)
    return canonical(out - set(off))


def check_off(off, force, reasons: Mapping[str, str]) -> tuple[str, ...]:
    """A query's `force_effects_off`, checked against the scene's `reasons` (`explain_effects`): a list of distinct
    `OPTIONAL` effects that are not also forced on and that nothing in the scene requires; `EffectError` naming
    the field otherwise."""
    if off is None:
        return ()
    if isinstance(off, str) or not isinstance(off, list | tuple):
        raise EffectError(f"force_effects_off must be a list of effects {list(OPTIONAL)}, got {off!r}")
    try:
        canonical(off)
    except EffectError as exc:
        raise EffectError(f"force_effects_off: {exc}") from None
    if len(set(off)) != len(off):
        raise EffectError(f"force_effects_off lists each effect once, got {list(off)}")
    bad = [e for e in off if e not in OPTIONAL]
    if bad:
        raise EffectError(f"force_effects_off: {bad} cannot be forced off (only {list(OPTIONAL)}, which the scene "
                          f"takes by its physics estimate: the others act wherever a material calls for them)")
    both = sorted(set(off) & set((force,) if isinstance(force, str) else force or ()))
    if both:
        raise EffectError(f"force_effects_off: {both} also forced on (force_effects, or an observable needing it)")
    for e in off:
        if reasons.get(e, "").startswith("on: required"):
            raise EffectError(f"force_effects_off: {e!r} cannot be left out here: {reasons[e][4:]}")
    return tuple(off)


def query_reasons(reasons: Mapping[str, str], effects: list[str], force, off) -> dict[str, str]:
    """The scene's `reasons` as one query ran them: an effect it forced on or off says so."""
    out = dict(reasons)
    force = (force,) if isinstance(force, str) else tuple(force or ())
    for e in EFFECTS:
        if e in effects and not out.get(e, "").startswith("on"):
            out[e] = ("on: forced on by the query" if e in force else "on: needed by a forced effect") \
                + f" ({out.get(e, '')})"
        elif e not in effects and out.get(e, "").startswith("on"):
            out[e] = f"off: forced off by the query (force_effects_off); the scene would take it: {out[e][4:]}"
    return out


def photon_state(effects: list[str]) -> str:
    """What a photon must carry for this effect set (`PHOTON_STATES`): a weight (``"white"``), and a wavelength
    (``"spectral"``), a Stokes vector (``"polarized"``) or both (``"polarized-spectral"``)."""
    e = set(canonical(effects))
    if "polarization" in e:
        return "polarized-spectral" if "spectral" in e else "polarized"
    return "spectral" if "spectral" in e else "white"
