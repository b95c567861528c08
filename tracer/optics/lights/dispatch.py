"""The light kinds' registration: the one place that lists them and switches on a kind id.

A kind's id is its position in `KINDS`. Adding a kind: its module (see `base`) and its entry at the end of
`KINDS`; `light_connect` is written out from `KINDS` (`tracer.jit.kind_switch`), `sample_emission` reaches every
kind but the point light through a table of addresses (`tracer.jit.kind_table`, `bind`). `sample_emission` is
inlined into the transport kernel, with the point light's `sample`.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types

from tracer.jit import kind_switch, kind_table, njit
from tracer.optics import spectra
from tracer.optics.fields import BodyField
from tracer.optics.lights import area, collimated, goniometric, point, rayfile, spot
from tracer.optics.lights.base import (
    FLUX_W,
    MAX_FLUX_LM,
    P_FLUX,
    LightArrays,
    LightError,
    Packing,
    shadow_rays_reach,
)
from tracer.optics.polarization import PolarizationError, light_polarization
from tracer.optics.spectra import sample_grid

KINDS = (point, spot, collimated, goniometric, area, rayfile)
POINT, SPOT, COLLIMATED, GONIOMETRIC, AREA, RAYFILE = 0, 1, 2, 3, 4, 5
KIND_OF_NAME = {module.NAME: k for k, module in enumerate(KINDS)}
#: each kind's capability flags (`base`: DELTA_POSITION, DELTA_DIRECTION, AREA_EMITTER), indexed by kind id: what the
#: transport asks of a light instead of its kind
LIGHT_FLAGS = np.array([module.FLAGS for module in KINDS], np.int64)


def pack_lights(lights: list[dict], scene=None, sensor_ids: frozenset = frozenset()) -> LightArrays:
    """Validate light bodies and pack them.

    Parameters
    ----------
    lights : list of light bodies (world metres), each with a ``"type"`` in `KIND_OF_NAME`.
    scene : tracer.Scene, needed for area lights (their triangles are read in world space).
    sensor_ids : instance ids that are sensors (an area light cannot be one).

    Raises
    ------
    LightError
        Unknown type or field, missing or out-of-range value, zero total flux, an area light on an
        unknown instance, a goniometric file that does not parse (the parser's message).
    """
    if not isinstance(lights, list | tuple) or not lights:
        raise LightError("lights: at least one light is needed")
    n = len(lights)
    kind = np.zeros(n, np.int32)
    out = Packing(n, scene, sensor_ids)
    mono, efficacy = np.zeros(n), np.zeros(n)
    spd_cdf, spd_f = np.zeros((n, spectra.GRID_N)), np.zeros((n, spectra.GRID_N))
    pol = np.zeros((n, 4))
    for j, body in enumerate(lights):
        where = f"light {j}" + (f" ({body.get('id')})" if isinstance(body, dict) and body.get("id") else "")
        if not isinstance(body, dict):
            raise LightError(f"{where}: expected a light body (dict), got {type(body).__name__}")
        module, spec, s, pol[j] = light_spec(body, where)
        kind[j] = KIND_OF_NAME[module.NAME]
        efficacy[j] = spectra.efficacy(s)
        mono[j] = s.mono_nm
        spd_cdf[j], spd_f[j] = spectra.sampling_table(s)
        module.pack(spec, j, out, where)
        if not out.par[j, P_FLUX] <= MAX_FLUX_LM:
            raise LightError(f"{where}: its luminous flux {out.par[j, P_FLUX]:.3g} lm is beyond {MAX_FLUX_LM:g} lm (or "
                             f"not finite): check the magnitude and the unit of its intensity, flux or illuminance")
    fluxes = out.par[:, P_FLUX]
    total = float(fluxes.sum())
    if not total > 0:
        raise LightError("lights: the total flux is zero: nothing to simulate")
    cdf = np.cumsum(fluxes) / total
    return LightArrays(kind, out.par, cdf, np.array([total]), out.g_off, out.g_n, out.table("g_c", (0,)),
                       out.table("g_gamma", (0,)), out.table("g_cd", (0,)), out.table("g_cell_cdf", (0,)),
                       out.table("tri", (0, 9)), out.table("tri_n", (0, 3)), out.table("tri_cdf", (0,)), out.a_off,
                       out.a_area, np.zeros(1, np.int64), mono, spd_cdf, spd_f, efficacy, pol, np.zeros(1, np.int64),
                       np.zeros(len(KINDS), np.int64))


def body_fields(module) -> dict[str, BodyField]:
    """A light kind's typed body fields (`tracer.optics.fields`) besides `base.COMMON_FIELDS`, the spectrum and the
    polarization: its ``FIELDS``, and ``flux_w`` where it takes a ``flux_lm`` (`_photometric`)."""
    return {**module.FIELDS, **({FLUX_W.name: FLUX_W} if "flux_lm" in module.FIELDS else {})}


def light_spec(body: dict, where: str) -> tuple:
    """One light body validated, as the transport and the service's wire model take it: ``(kind module, its Spec,
    its tabulated spectrum, its packed polarization (4,))``; `LightError` naming the light and the field."""
    t = body.get("type")
    k = KIND_OF_NAME.get(t, -1) if isinstance(t, str) else -1
    if k < 0:
        raise LightError(f"{where}: unknown light type {t!r}; known: {sorted(KIND_OF_NAME)}")
    module = KINDS[k]
    if hasattr(module, "resolve"):   # what a file the body names says where the body is silent (rayfile)
        body = module.resolve(body, where)
    s = light_spectrum(body, where)
    try:
        pol = light_polarization(body.get("polarization"), where)
    except PolarizationError as exc:
        raise LightError(str(exc)) from None
    return module, module.Spec.from_body(_photometric(body, module, spectra.efficacy(s), where), where), s, pol


def light_spectrum(body: dict, where: str) -> spectra.Spectrum:
    """The light's `spectrum` (equal energy where absent), tabulated; `LightError` naming the light if invalid."""
    try:
        return spectra.spectrum(body.get("spectrum"), f"{where}: spectrum")
    except spectra.SpectrumError as exc:
        raise LightError(str(exc)) from None


def _photometric(body: dict, module, efficacy: float, where: str) -> dict:
    """The body with `flux_w` (radiant flux, W) turned into the kind's `flux_lm` = flux_w × K(S)."""
    if body.get("flux_w") is None:
        return body
    if "flux_lm" not in module.FIELDS:
        raise LightError(f"{where}: 'flux_w' is for lights given by their flux (point, spot); a {module.NAME!r} "
                         f"light takes its photometric quantity")
    if body.get("flux_lm") is not None or body.get("intensity_cd") is not None:
        raise LightError(f"{where}: give exactly one of 'intensity_cd', 'flux_lm' and 'flux_w'")
    v = body["flux_w"]
    if isinstance(v, bool) or not isinstance(v, int | float) or not FLUX_W.lo <= v <= FLUX_W.hi:
        raise LightError(f"{where}: 'flux_w' must be a number of watts in [{FLUX_W.lo:g}, {FLUX_W.hi:g}], "
                         f"got {v!r}"[:300])
    return {**{k: x for k, x in body.items() if k != "flux_w"}, "flux_lm": float(v) * efficacy}


def spectral_lights(L: LightArrays) -> LightArrays:
    """The same lights for photons that carry a wavelength: picked by radiant flux Φ_e = Φ_v / K(S),
    with the total in W (see `LightArrays`)."""
    watts = L.par[:, P_FLUX] / L.efficacy
    total = float(watts.sum())
    return L._replace(cdf=np.cumsum(watts) / total, flux_total=np.array([total]), spectral=np.ones(1, np.int64))


def polarized_lights(L: LightArrays) -> LightArrays:
    """The same lights for photons that carry a Stokes vector (`tracer.optics.polarization`)."""
    return L._replace(polarized=np.ones(1, np.int64))


def connectable(L: LightArrays) -> tuple[bool, str]:
    """Whether next-event estimation can sample every light of L, and if not why ("" if it can)."""
    for k in sorted(set(int(k) for k in L.kind)):
        if not shadow_rays_reach(KINDS[k].FLAGS):
            return False, KINDS[k].WHY_NOT_CONNECTABLE
    return True, ""


def flags_of(body: dict) -> int:
    """The capability flags (`LIGHT_FLAGS`) of a validated light body's kind."""
    return KINDS[KIND_OF_NAME[body["type"]]].FLAGS


@njit(cache=True, _nrt=False, inline="always")
def light_flags(L, j):
    """Light j's capability flags (`LIGHT_FLAGS`)."""
    return LIGHT_FLAGS[L.kind[j]]


def _sample_signature(head):
    """The argument types every kind's `sample` is compiled for: the lights' tuple (`head`), j, five uniforms."""
    return (head[0], types.int64, *[types.float64] * 5)


#: what every kind's `sample` returns: (ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz), `base` has the contract
SAMPLE_RETURNS = types.Tuple((*[types.float64] * 7, types.boolean, *[types.float64] * 3))
#: the kinds past the point light, called through `LightArrays.sample_at` (`tracer.jit.kind_table`)
sample_by_address = kind_table("sample_by_address", {k: m.sample for k, m in enumerate(KINDS) if k > POINT},
                               _sample_signature, SAMPLE_RETURNS)
_TABLES: dict = {}


def bind(L: LightArrays) -> LightArrays:
    """`L` with its table of `sample` addresses (`LightArrays.sample_at`) for its types, holding (at least) the kinds
    `L` holds: what a kernel on this process's CPU needs before it runs (`tracer.backends.run_kernel`)."""
    head = (numba.typeof(L),)
    table = _TABLES.setdefault(head, np.zeros(sample_by_address.size, np.int64))
    sample_by_address.bind(table, head, np.unique(L.kind))
    return L._replace(sample_at=table)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def sample_emission(L, j, u0, u1, u2, u3, u4):
    """Emit one photon from light j: (ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz), see `base`. The point
    light's `sample` is compiled in; every other kind is called at its address (`sample_by_address`), so a new
    light kind adds nothing to the kernels' compile."""
    k = L.kind[j]
    if k == POINT:
        return point.sample(L, j, u0, u1, u2, u3, u4)
    if k > POINT and k < len(L.sample_at):
        return sample_by_address(L.sample_at, k, (L, j, u0, u1, u2, u3, u4))
    return 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, False, 0.0, 0.0, 0.0   # an id no kind has: a photon of weight 0


@njit(cache=True, _nrt=False, inline="always")
def emit_wavelength(L, j, u):
    """A photon's wavelength (nm) from light j's spectrum, and its weight factor (`spectra.sampling_table`)."""
    if L.mono[j] > 0.0:
        return L.mono[j], 1.0
    return sample_grid(L.spd_cdf[j], L.spd_f[j], u)


light_connect = kind_switch(
    "light_connect", "L, j, x, y, z, nx, ny, nz, u1, u2, u3", "L.kind[j]", {k: m.connect for k, m in enumerate(KINDS)},
    "(0.0, 0.0, 0.0, 0.0, 0.0)",   # an id no kind has: nothing arrives
    doc="Next-event estimation toward light j from x (m) with unit normal n: (e, sx, sy, sz, t_max), see `base`.",
    cache=True, _nrt=False)
