"""What the client and the command line make of each sensor kind's answer: its CSV, the files written beside it,
its summary line. One class per kind of answer and one registry (`OUTPUTS`, by the answer's ``type``, as the
service's `SensorPublic` tells them apart); a kind without a class of its own answers lux at points and is written as
`Lux`. The only place in lumenlink that tells sensor kinds apart."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any


def _num(x: Any) -> str:
    return "" if x is None else f"{float(x):.9g}"


def _flatten(x: Any) -> Iterable[Any]:
    if isinstance(x, list):
        for y in x:
            yield from _flatten(y)
    else:
        yield x


def _run(result: dict[str, Any], what: str) -> str:
    """``N photons in S s (stop reason), revision R``."""
    return (f"{result['photons']:,} {what} in {result['seconds']:.2f} s ({result['stop_reason']}), revision "
            f"{result['revision']}")


class Lux:
    """Illuminance at points (a disk's one value, a surface's triangles): one CSV row per value, at no known place."""

    #: the lux reports apply (uniformity where `UNIFORMITY`, the tessellation's error)
    LUX = True
    #: min/max and min/mean mean something over its values (a layout of points, not triangles of any size)
    UNIFORMITY = False
    #: the service draws a difference of two of its results (``difference.png``)
    DIFFERENCE_MAP = False

    @staticmethod
    def size(body: dict[str, Any]) -> str:
        """Its size in words, after its type (" 4 x 3 cells"); empty where it has none to say."""
        return ""

    @staticmethod
    def csv(result: dict[str, Any]) -> str:
        lines = ["i,j,x_m,y_m,z_m,lux,stderr_lux"]
        for k, (a, b) in enumerate(zip(_flatten(result["lux"]), _flatten(result["stderr"]), strict=False)):
            lines.append(f"{k},0,,,,{_num(a)},{_num(b)}")
        return "\n".join(lines) + "\n"

    @staticmethod
    def files(ll: Any, info: dict, sensor_id: str, stem: str, out_dir: Path, warn: Any) -> list[Path]:
        """The files beside its CSV in `out_dir` (written here through the client `ll`); `warn(text)` says what
        could not be written."""
        return []

    @staticmethod
    def summary(result: dict[str, Any]) -> str:
        return (f"lux min {result['min_lux']:.4g}, mean {result['mean_lux']:.4g}, max {result['max_lux']:.4g}; "
                + _run(result, "photons"))


class Points(Lux):
    """Illuminance at listed points."""

    UNIFORMITY = True


class Grid(Lux):
    """A grid: nv rows of nu cells, each row of the CSV at its cell's centre (world metres), and its map."""

    UNIFORMITY = True
    DIFFERENCE_MAP = True

    @staticmethod
    def size(body: dict[str, Any]) -> str:
        return f" {body['nu']} x {body['nv']} cells"

    @staticmethod
    def csv(result: dict[str, Any]) -> str:
        if result.get("origin") is None:
            return Lux.csv(result)
        lines = ["i,j,x_m,y_m,z_m,lux,stderr_lux"]
        lux, err, o, u, v = result["lux"], result["stderr"], result["origin"], result["u"], result["v"]
        nu, nv = int(result["nu"]), int(result["nv"])
        for j in range(nv):
            for i in range(nu):
                s, t = (i + 0.5) / nu, (j + 0.5) / nv
                c = [o[k] + s * u[k] + t * v[k] for k in range(3)]
                lines.append(f"{i},{j},{c[0]:.9g},{c[1]:.9g},{c[2]:.9g},{_num(lux[j][i])},{_num(err[j][i])}")
        return "\n".join(lines) + "\n"

    @staticmethod
    def files(ll: Any, info: dict, sensor_id: str, stem: str, out_dir: Path, warn: Any) -> list[Path]:
        from lumenlink.errors import LumenLinkError

        try:
            png = ll.map_png(info, sensor_id)
        except LumenLinkError as exc:
            warn(f"no map for sensor {stem}: {exc}")
            return []
        (out_dir / f"{stem}.png").write_bytes(png)
        return [out_dir / f"{stem}.png"]


class FarField(Lux):
    """The scene as a lamp: one CSV row per (C, γ) bin in cd, and its IES file."""

    LUX = False

    @staticmethod
    def csv(result: dict[str, Any]) -> str:
        rows = ["i,j,c_deg,gamma_deg,cd,stderr_cd"]
        for j, g in enumerate(result["gamma_deg"]):
            for i, c in enumerate(result["c_deg"]):
                rows.append(f"{i},{j},{c:.9g},{g:.9g},{_num(result['candela'][j][i])},{_num(result['stderr'][j][i])}")
        return "\n".join(rows) + "\n"

    @staticmethod
    def files(ll: Any, info: dict, sensor_id: str, stem: str, out_dir: Path, warn: Any) -> list[Path]:
        ies = out_dir / f"{stem}.ies"
        ll.export(info, sensor_id, "ies", out=ies)
        return [ies]

    @staticmethod
    def summary(result: dict[str, Any]) -> str:
        return (f"far field, {result['flux_lm']:.6g} +- {result['flux_stderr']:.2g} lm leaving, max "
                f"{result['max_cd']:.6g} cd; " + _run(result, "photons"))


class Luminance(Lux):
    """A luminance meter: one CSV row (cd/m²)."""

    LUX = False

    @staticmethod
    def csv(result: dict[str, Any]) -> str:
        values = result["luminance"]
        grid = values if values and isinstance(values[0], list) else [values]
        errs = result["stderr"] if grid is values else [result["stderr"]]
        rows = ["row,col,cd_m2,stderr_cd_m2"]
        rows += [f"{j},{i},{_num(a)},{_num(b)}" for j, (line, line_err) in enumerate(zip(grid, errs, strict=True))
                 for i, (a, b) in enumerate(zip(line, line_err, strict=True))]
        return "\n".join(rows) + "\n"

    @staticmethod
    def summary(result: dict[str, Any]) -> str:
        lum = [float(x) for x in _flatten(result["luminance"])]
        return (f"luminance min {min(lum):.4g}, mean {sum(lum) / len(lum):.4g}, max {max(lum):.4g} cd/m2; "
                + _run(result, "paths"))


class Camera(Luminance):
    """A camera: one CSV row per pixel (row 0 the top), its OpenEXR image, its tone-mapped PNG and its map."""

    @staticmethod
    def files(ll: Any, info: dict, sensor_id: str, stem: str, out_dir: Path, warn: Any) -> list[Path]:
        written = []
        for name, fmt in ((f"{stem}.exr", "exr"), (f"{stem}.png", "png"), (f"{stem}_map.png", "map")):
            (out_dir / name).write_bytes(ll.image(info, sensor_id, fmt))
            written.append(out_dir / name)
        return written


#: the answers with a class of their own, by ``type``; any other is `Lux`
OUTPUTS: dict[str, type[Lux]] = {"points": Points, "grid": Grid, "far_field": FarField, "luminance": Luminance,
                                 "camera": Camera}


def output_of(answer: dict[str, Any]) -> type[Lux]:
    """The output class of a sensor's answer, body or comparison (by its ``type``)."""
    return OUTPUTS.get(str(answer.get("type")), Lux)


def sensor_csv(result: dict[str, Any]) -> str:
    """A sensor result as CSV, one row per value: its indices, its place where known, its value and standard error.

    Grid: ``i`` (along u, 0..nu-1), ``j`` (along v), the cell centre origin + (i+½)/nu·u + (j+½)/nv·v.
    Disk: one row (i = j = 0) with blank coordinates. Far field: ``i,j,c_deg,gamma_deg,cd,stderr_cd``, one row per
    bin (i along C, j along γ). Luminance meter, camera: ``row,col,cd_m2,stderr_cd_m2``, one row per pixel (row 0 the
    top; a meter: one row)."""
    return output_of(result).csv(result)
