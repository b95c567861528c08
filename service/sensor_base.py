"""The service's side of a sensor kind, what every kind shares: `SensorKind`, the defaults of its contract
(`service.sensor_kinds` states it), and the bases of its answer.

Every sensor's answer holds the run (photons, seconds, stop rule, effects, where it ran, what tighter errors would
cost) and the scene it describes (`SensorAnswer`); a kind's own answer adds its values to it (`LuxAnswer` for the
kinds that answer illuminance) beside its class (``ANSWER``), and the wire's answer is the union of them, told apart
by ``type`` (`service.sensor_kinds.SensorPublic`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from service.simulation_wire import ErrorBudget, PhysicsLeftOut, RunAnswer


class SensorAnswer(RunAnswer):
    """The fields of every sensor's answer (its run's, `RunAnswer`, and these); a kind's model adds its ``type`` and
    its values."""

    sensor: str = Field(description="The sensor's id.")
    stderr: list[Any] = Field(description="Standard error of each value, in the unit of the kind's values.")
    elements: list[dict[str, Any]] | None = Field(None, description=(
        "The optical elements with an inside the scene carries (assignment `id`, `element`, `node`, `model`: "
        "`bsdf`, its tabulated BSDF, with `model_error`: per side (`air`, `solid`) the worst probe beam's "
        "`deviation` of the transmitted share from the exact model's, table − exact, a share of the flux meeting "
        "the element, with its `stderr`, where (`theta_deg`, `phi_deg`) and what was measured; or "
        "`exact`, its micro-geometry traced); absent where it carries none."))
    warnings: list[str] | None = Field(None, description="The sensor or lights far outside the model (world metres); "
                                       "photons that met a grating where its table of orders ran out.")


class LuxAnswer(SensorAnswer):
    """A sensor that answers illuminance (lx), with what a query may observe beside it."""

    lux: list[Any] = Field(description="Illuminance, lx, as the kind lays its values out.")
    min_lux: float = Field(description="The smallest value, lx.")
    mean_lux: float = Field(description="The mean value, lx.")
    max_lux: float = Field(description="The largest value, lx.")
    nm: list[float] | None = Field(None, description="With observe spectrum: centres of the 5 nm bands, nm.")
    spectral_irradiance: list[Any] | None = Field(None, description="With observe spectrum: W/m²/nm per band, "
                                                                    "per cell.")
    spectral_stderr: list[Any] | None = Field(None, description="Standard error of each band, W/m²/nm.")
    cie_xy: list[Any] | None = Field(None, description="With observe spectrum: CIE 1931 (x, y) per cell "
                                                       "(dimensionless); null where no light arrived.")
    error_budget: ErrorBudget | None = Field(None, description="The tessellation's share of the error, lx.")
    physics_left_out: dict[str, PhysicsLeftOut] | None = Field(
        None, description="Where the query asked: per effect, what turning it on would change, lx.")
    stokes: list[Any] | None = Field(None, description="With observe stokes: [S0, S1, S2, S3] per cell, lx.")
    stokes_stderr: list[Any] | None = Field(None, description="Standard error of each Stokes component, lx.")
    dop: list[Any] | None = Field(None, description="With observe stokes: degree of polarization per cell, "
                                                    "a fraction; null where none arrived.")


class SensorKind:
    """What a kind's class inherits where it has nothing of its own to say about its kept results
    (`service.results`): its values are illuminance, one flat row of them, at no known place."""

    #: the quantity its values are: ``"lux"``, ``"luminance"`` (cd/m²) or ``"candela"``
    QUANTITY = "lux"
    #: two of its kept results are drawn as a change (``difference.png``: a grid's cells in place)
    DIFFERENCE_MAP = False
    #: a pack (`service.pack`) can be driven by its figure: a grid of cells over the lit face
    PACKS = False

    @staticmethod
    def sized(sensor: dict, limits: Any) -> None:
        """Refuse (413) what its body alone makes too large for `limits`, before the scene is read."""

    @staticmethod
    def refusal(sensor: dict, limits: Any) -> tuple[str, int] | None:
        """Why no simulate of this service could answer a sensor of this body, and the limit it is beyond (said when
        it is made: 422, nothing stored); None where it can be answered."""
        return None

    @staticmethod
    def centre(sensor: dict) -> np.ndarray | None:
        """The sensor's centre, world metres (for the "far outside the model" warnings); None where it has none."""
        return None if sensor.get("center") is None else np.asarray(sensor["center"], float)

    @staticmethod
    def kept(sensor: dict) -> dict[str, Any]:
        """The sensor's fields kept beside its result (JSON), besides the answer's own."""
        return {}

    @staticmethod
    def layout(meta: dict) -> tuple[int, int] | None:
        """(rows, columns) of a kept result's values; None: one flat row."""
        return None

    @staticmethod
    def centres(meta: dict, shape: tuple[int, int]) -> np.ndarray:
        """World centre (m) of each of the (rows, columns) values; NaN where unknown."""
        return np.full((*shape, 3), np.nan)

    @staticmethod
    def size(meta: dict, values: int) -> str:
        """The sensor's size in words, for a refusal to compare two results."""
        return f"a {meta.get('type')} sensor of {values} values"

    @staticmethod
    def change(before: np.ndarray, after: np.ndarray, se_before: np.ndarray, se_after: np.ndarray,
               meta: dict) -> dict[str, Any] | None:
        """A summary of ``after - before`` of its own (a grid's, with places); None: the counts of cells that
        changed beyond noise."""
        return None


def count_refusal(sensor: dict, a: str, b: str, what: str, limits: Any) -> tuple[str, int] | None:
    """`SensorKind.refusal` of a sensor of ``sensor[a] × sensor[b]`` values (`what`: cells, bins) beyond
    ``max_points``."""
    n = int(sensor[a]) * int(sensor[b])
    if n <= limits.max_points:
        return None
    return (f"a {sensor.get('type')} sensor of {a} × {b} = {sensor[a]} × {sensor[b]} = {n} {what}: this service "
            f"answers at most {limits.max_points} points per query (its max_points setting, LUMENLINK_MAX_POINTS); "
            f"ask for at most {limits.max_points} {what}", limits.max_points)
