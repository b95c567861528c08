"""The contract every light kind keeps, and what the kinds share.

Units: positions and lengths in m, flux in lm, intensity in cd, illuminance in lx, exitance in lm/m².

A kind is one module of this folder (`point`, `spot`, `collimated`, `goniometric`, `area`), listed
once in `dispatch.KINDS` (its kind id is its position there). Each module holds:

- ``NAME``: the body's ``"type"``. ``FIELDS``: the body fields it accepts besides `COMMON_FIELDS` and the spectral
  ones, typed (`tracer.optics.fields`): its ``from_body`` reads their bounds there, and the service makes its wire
  model from them (a kind whose fields include ``flux_lm`` also takes `FLUX_W`, see `dispatch.body_fields`).
- ``EXAMPLE`` (optional): a body the API docs show.
- ``EFFECTS``: the effects (`tracer.effects`) the light needs beyond the baseline: ``()`` for every
  current kind.
- ``FLAGS``: what the light is, as transport asks it (pbrt's light flags; transport never names a kind): a sum of
  `DELTA_POSITION` (it emits from points no ray can hit: point, spot, goniometric; a ray file's exact rays),
  `DELTA_DIRECTION` (each point emits in one direction: a collimated beam, a ray file) and `AREA_EMITTER` (it emits
  from the surfaces of parts, which paths can hit). A shadow ray can reach a light unless it is `DELTA_DIRECTION`
  (`shadow_rays_reach`); such a kind says why not in ``WHY_NOT_CONNECTABLE`` (a sentence naming it, for error
  messages).
- ``Spec``: a frozen dataclass; ``Spec.from_body(body: dict, where: str) -> Spec`` validates a light
  body and raises `LightError` naming the light (`where`) and the field.
- ``pack(spec, j, out: Packing, where: str) -> float``: fills row j of ``out.par`` (the ``P_*``
  columns) and any tables of its kind, and returns the light's flux Φ_j in lm; it raises `LightError`
  for what only the scene can tell (an area light's instances).
- ``sample(L, j, u0, u1, u2, u3, u4)``: emits one photon from light j. Returns ``(ox, oy, oz, dx, dy,
  dz, f, on_surface, nx, ny, nz)``: origin (m), unit direction, the weight factor
  f = I(ω) / (pdf(ω) Φ_j) (1 where the direction is sampled exactly in proportion to the intensity),
  whether the origin lies on a surface (the caller then offsets it along n before tracing) and that
  surface's unit normal (zeros otherwise). A photon carries Φ_total / N × f.
- ``connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)``: next-event estimation at a point x (m) of a
  surface with unit normal n. Returns ``(e, sx, sy, sz, t_max)``: e, the illuminance (lx) at x due to
  light j from one sample (u1, u2, u3 pick the point of an extended light), ignoring occlusion and not
  divided by the probability of picking light j; (sx, sy, sz) the unnormalised shadow-ray direction
  from x to the sampled point of the light, and t_max the shadow ray's parameter bound (1.0 for a
  point-like light, 1 − `SHADOW_SHORTEN` for a point on an emitting surface, so that the surface
  itself does not occlude it). e = 0 where nothing arrives (x behind the light's emitting side, n
  facing away, outside a cone, a light that is not connectable).

The jitted functions are ``@njit(cache=True, _nrt=False)``, plain Python over floats and arrays (no
allocation, no exceptions), so that numba-cuda's ``cuda.jit(device=True)`` can compile the same source.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracer.errors import TracerError
from tracer.jit import njit
from tracer.optics.fields import BodyField, node_field
from tracer.optics.frames import find_in_cdf

N_LPAR = 20
# columns of the parameter row: position or aperture centre, axis, frame (t, b), then scalars
P_POS, P_AXIS, P_T, P_B = 0, 3, 6, 9
P_I0, P_COS_OUT, P_COS_IN, P_R, P_H, P_FLUX, P_SOLID, P_SHAPE = 12, 13, 14, 15, 16, 17, 18, 19

DELTA_POSITION, DELTA_DIRECTION, AREA_EMITTER = 1, 2, 4   # a kind's FLAGS (see above)
SHADOW_SHORTEN = 1e-6  # a shadow ray toward a point on an emitting surface stops this fraction short of it



def shadow_rays_reach(flags: int) -> bool:
    """Whether next-event estimation can reach a light of these `FLAGS` by a shadow ray: not a delta direction."""
    return not flags & DELTA_DIRECTION


COMMON_FIELDS = frozenset({"id", "name", "attached_to", "type"})  # kept by the service, ignored here
SPECTRAL_FIELDS = frozenset({"spectrum", "flux_w", "polarization"})  # any kind's; `dispatch.pack_lights` reads them
# the photometric magnitudes of a light given by its intensity or its flux: beyond 1e15 it is a unit mistake
INTENSITY_CD = BodyField("intensity_cd", "number", "Luminous intensity, cd (isotropic: in every direction of its "
                         "cone).", required=False, lo=0.0, hi=1e15)
FLUX_LM = BodyField("flux_lm", "number", "Luminous flux, lm (instead of intensity_cd).", required=False, lo=0.0,
                    hi=1e15)
FLUX_W = BodyField("flux_w", "number", "Radiant flux, W (instead of a photometric quantity; lm = W × the spectrum's "
                   "efficacy).", required=False, lo=0.0, hi=1e13)
MAX_FLUX_LM = 1e15   # lm: a light beyond this is a unit mistake (the brightest searchlights are ~1e9 lm); the
                     # estimates (sums of squared tallies) stay finite far beyond it


class LightError(TracerError):
    """A light body the transport cannot use; the message names the light and the field."""


class LightArrays(NamedTuple):
    """Every light of a simulation, for the kernels.

    kind (n,) int32: the position of the light's kind in `dispatch.KINDS`; par (n, 20) float64 (see
    the P_* columns); cdf (n,) float64: cumulative selection probability ∝ flux; flux_total: float (lm)
    in a (1,) array.
    Goniometric tables (flat, per light offsets in `g_off` (n, 4): c offset, γ offset, candela
    offset, cell offset; `g_n` (n, 2): nc, ng): g_c (rad), g_gamma (rad), g_cd (cd), g_cell_cdf.
    Area emitters: tri (m, 9) world v0, e1, e2 (m); tri_n (m, 3) unit front normals; tri_cdf (m,)
    cumulative area within each light; `a_off` (n, 2): first triangle, count; `a_area` (n,): m².
    Spectra (`tracer.optics.spectra`): `spectral` (1,) int64, 1 where photons carry a wavelength and
    radiant power (then `cdf` and `flux_total` are by radiant flux, W), 0 where they carry luminous flux
    (lm); `mono` (n,) nm of a line (0 otherwise); `spd_cdf`, `spd_f` (n, GRID_N): each light's
    `spectra.sampling_table`; `efficacy` (n,) lm/W.
    Polarization (`tracer.optics.polarization`): `pol` (n, 4) each light's packed state (`light_polarization`);
    `polarized` (1,) int64, 1 where photons carry a Stokes vector (`polarized_lights`).
    `sample_at` (n_kinds,) int64, the address of each kind's ``sample`` in this process, filled by
    `tracer.optics.lights.dispatch.bind` before a CPU kernel runs (zeros as packed and shipped).
    """

    kind: np.ndarray
    par: np.ndarray
    cdf: np.ndarray
    flux_total: np.ndarray
    g_off: np.ndarray
    g_n: np.ndarray
    g_c: np.ndarray
    g_gamma: np.ndarray
    g_cd: np.ndarray
    g_cell_cdf: np.ndarray
    tri: np.ndarray
    tri_n: np.ndarray
    tri_cdf: np.ndarray
    a_off: np.ndarray
    a_area: np.ndarray
    spectral: np.ndarray
    mono: np.ndarray
    spd_cdf: np.ndarray
    spd_f: np.ndarray
    efficacy: np.ndarray
    pol: np.ndarray
    polarized: np.ndarray
    sample_at: np.ndarray = np.zeros(0, np.int64)


class Packing:
    """The arrays of `LightArrays` while the kinds' `pack` functions fill them, light by light.

    Per-light rows (`par`, `g_off`, `g_n`, `a_off`, `a_area`) are allocated for n lights; the flat
    tables are lists of parts, one per light that has them (`used` gives the length so far).
    `scene` (a tracer.Scene or None) and `sensor_ids` are what area lights read their triangles from.
    """

    TABLES = ("g_c", "g_gamma", "g_cd", "g_cell_cdf", "tri", "tri_n", "tri_cdf")

    def __init__(self, n: int, scene=None, sensor_ids: frozenset = frozenset()):
        self.scene = scene
        self.sensor_ids = sensor_ids
        self.par = np.zeros((n, N_LPAR))
        self.g_off = np.zeros((n, 4), np.int64)
        self.g_n = np.zeros((n, 2), np.int64)
        self.a_off = np.zeros((n, 2), np.int64)
        self.a_area = np.zeros(n)
        self.parts: dict[str, list[np.ndarray]] = {name: [] for name in self.TABLES}

    def used(self, table: str) -> int:
        """Rows appended to flat table `table` so far (the offset of the next light's part)."""
        return sum(len(part) for part in self.parts[table])

    def table(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """Flat table `name`, its parts concatenated (an empty array of `shape` if none)."""
        parts = self.parts[name]
        return np.concatenate(parts) if parts else np.zeros(shape)


# ------------------------------------------------------------------------------------------------- validation


def check_fields(body: dict, where: str, name: str, fields: dict[str, BodyField]) -> None:
    """Reject any field of `body` that a `name` light does not accept (a kind with a node field takes its
    ``instances``)."""
    extra = set(body) - set(fields) - ({"instances"} if node_field(fields) else set()) - COMMON_FIELDS - SPECTRAL_FIELDS
    if extra:
        raise LightError(f"{where}: unknown field(s) {sorted(extra)} for a {name!r} light")


def vector_field(body: dict, key: str, where: str, unit: bool = False) -> np.ndarray:
    """body[key] as a (3,) float64 vector of finite numbers, normalised if `unit`."""
    if key not in body:
        raise LightError(f"{where}: missing {key!r}")
    try:
        v = np.asarray(body[key], dtype=np.float64)
    except (TypeError, ValueError):
        raise LightError(f"{where}: {key!r} must be 3 numbers, got {body[key]!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise LightError(f"{where}: {key!r} must be 3 finite numbers, got {body[key]!r}")
    if unit:
        n = float(np.linalg.norm(v))
        if not n > 0:
            raise LightError(f"{where}: {key!r} must be a non-zero vector")
        v = v / n
    return v


def number_field(body: dict, key: str, where: str, lo: float = 0.0, hi: float = math.inf, lo_open: bool = False,
         default: float | None = None) -> float:
    """body[key] as a finite float in [lo, hi] ((lo, hi] if `lo_open`); `default` where absent or None."""
    if key not in body or body[key] is None:
        if default is None:
            raise LightError(f"{where}: missing {key!r}")
        return default
    v = body[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise LightError(f"{where}: {key!r} must be a finite number, got {v!r}")
    v = float(v)
    if v < lo or v > hi or (lo_open and v == lo):
        raise LightError(f"{where}: {key!r} must be {'>' if lo_open else '>='} {lo:g} and <= {hi:g}, got {v:g}")
    return v


def field_value(body: dict, f: BodyField, where: str, default: float | None = None) -> float:
    """The number field `f` of `body`, within its declared bounds (`number_field`)."""
    return number_field(body, f.name, where, **f.limits(), default=default)


def intensity_and_flux(body: dict, where: str, solid_angle: float) -> tuple[float, float]:
    """(I0 in cd, Φ in lm) from exactly one of `intensity_cd` and `flux_lm`; Φ = I0 × solid_angle (sr)."""
    has_i = body.get("intensity_cd") is not None
    has_f = body.get("flux_lm") is not None
    if has_i == has_f:
        raise LightError(f"{where}: give exactly one of 'intensity_cd' and 'flux_lm'")
    if has_i:
        i0 = field_value(body, INTENSITY_CD, where)
        return i0, i0 * solid_angle
    flux = field_value(body, FLUX_LM, where)
    return flux / solid_angle, flux


# ---------------------------------------------------------------------------------------------------- kernels


@njit(cache=True, _nrt=False, inline="always")
def pick_light(L, u):
    """Index of a light chosen with probability ∝ its flux, and that probability."""
    n = L.cdf.shape[0]
    j = find_in_cdf(L.cdf, 0, n, u)
    p = L.cdf[j] - (L.cdf[j - 1] if j > 0 else 0.0)
    return j, p


@njit(cache=True, _nrt=False)
def in_light_frame(p, a, b, c):
    """The world vector a t + b b + c axis of the light's frame (the P_T, P_B, P_AXIS columns of row p)."""
    return (a * p[P_T] + b * p[P_B] + c * p[P_AXIS],
            a * p[P_T + 1] + b * p[P_B + 1] + c * p[P_AXIS + 1],
            a * p[P_T + 2] + b * p[P_B + 2] + c * p[P_AXIS + 2])


@njit(cache=True, _nrt=False)
def toward_point(p, x, y, z, nx, ny, nz):
    """From x on a surface with unit normal n toward the point p[P_POS:P_POS+3] (m).

    Returns (dx, dy, dz, d2, dist, cos_x): the unnormalised direction, its squared length (m²), its
    length (m) and the cosine at x; cos_x = 0 (and dist = 0) where d2 is not > 0 (the point is x).
    """
    dx, dy, dz = p[P_POS] - x, p[P_POS + 1] - y, p[P_POS + 2] - z
    d2 = dx * dx + dy * dy + dz * dz
    if not (d2 > 0.0):
        return dx, dy, dz, d2, 0.0, 0.0
    dist = math.sqrt(d2)
    return dx, dy, dz, d2, dist, (dx * nx + dy * ny + dz * nz) / dist
