"""A result of the light transport as the JSON the routes answer with (numbers checked finite, NaN as null)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def finite_list(a: Any) -> list:
    arr = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(arr)):
        # The transport guarantees finite tallies; a NaN here is a bug, never an answer to send.
        raise RuntimeError("the light transport returned a non-finite value")
    return arr.tolist()


def _budget_entry(v: Any) -> Any:
    """An `error_budget` entry: lx per value, or a cost (the estimate's seconds, its levels)."""
    if np.ndim(v):
        return finite_list(v)
    return int(v) if isinstance(v, int | np.integer) else float(v)


def result_payload(result: Any, revision: int) -> dict[str, Any]:
    """An `IlluminanceResult` or `GridResult` as the JSON the routes answer with."""
    return {
        "lux": finite_list(result.lux),
        "stderr": finite_list(result.stderr),
        "photons": int(result.photons),
        "seconds": float(result.seconds),
        "effects": sorted(str(e) for e in result.effects),
        **({"effect_reasons": dict(result.effect_reasons)} if getattr(result, "effect_reasons", None) else {}),
        "revision": int(revision),
        "estimator": str(result.estimator),
        "stop_reason": str(result.stop_reason),
        "compile_seconds": float(getattr(result, "compile_seconds", 0.0)),
        "cost": getattr(result, "cost", None),
        "backend": getattr(result, "backend", None),
        "device": device_name(getattr(result, "backend", None)),
        **({"error_budget": {name: _budget_entry(v) for name, v in result.error_budget.items()}}
           if getattr(result, "error_budget", None) else {}),
        **({"physics_left_out": {name: {**e, "difference": finite_list(e["difference"]),
                                        "stderr": finite_list(e["stderr"])}
                                 for name, e in result.physics_left_out.items()}}
           if getattr(result, "physics_left_out", None) else {}),
        **spectral_payload(result),
        **stokes_payload(result),
        **table_warnings(result),
    }


def table_warnings(result: Any) -> dict[str, Any]:
    """``{"warnings": [...]}`` where photons met a grating where its table ran out (`tracer.elements.diffraction`:
    a wavelength or angle outside it, an order cut off between its points): never a silent answer."""
    n = int((getattr(result, "counters", None) or {}).get("grating_outside_table", 0))
    if n <= 0:
        return {}
    return {"warnings": [f"{n} photon(s) met a grating where its table of orders ran out (a wavelength or an angle "
                         f"outside the table, or an order cut off between its points): the nearest table point was "
                         f"used there; prepare the grating over the scene's wavelengths and angles"]}


def device_name(backend: dict | None) -> str | None:
    """Where the photon batches ran (`tracer.backends.device_of`): "cpu:2 threads", ... on N dask workers."""
    if backend is None:
        return None
    from tracer.backends import device_of

    return device_of(backend)


def spectral_payload(result: Any) -> dict[str, Any]:
    """The observed spectrum of a result, if any: bands, W/m²/nm ± error, and chromaticity (null where dark)."""
    if getattr(result, "spectral_irradiance", None) is None:
        return {}
    xy = np.asarray(result.cie_xy, float)
    return {"nm": finite_list(result.nm), "spectral_irradiance": finite_list(result.spectral_irradiance),
            "spectral_stderr": finite_list(result.spectral_stderr),
            "cie_xy": nan_to_null(xy.tolist())}


def stokes_payload(result: Any) -> dict[str, Any]:
    """The observed polarization of a result, if any: Stokes (lx) ± error and the degree of polarization (null
    where dark)."""
    if getattr(result, "stokes", None) is None:
        return {}
    return {"stokes": finite_list(result.stokes), "stokes_stderr": finite_list(result.stokes_stderr),
            "dop": nan_to_null(np.asarray(result.dop, float).tolist())}


def nan_to_null(x: Any) -> Any:
    """Nested lists of floats with NaN (nothing arrived, no colour) as JSON null."""
    if isinstance(x, list):
        return [nan_to_null(v) for v in x]
    return x if math.isfinite(x) else None
