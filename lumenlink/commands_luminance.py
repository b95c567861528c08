"""``lumenlink uniformity`` and ``lumenlink conoscope``: luminance read by meters, as a display is judged (issues 37,
53). Built on `lumenlink.Client`; exit codes as `lumenlink.commands`: 2 bad usage, 3 the service unreachable, 1 the
rest."""

from __future__ import annotations

import json
from typing import Any

from rich.console import Console

from lumenlink.client import Client, LumenLinkError
from lumenlink.commands import DIRECTION, EXIT_OK, _pm, _run, vec3


def uniformity(scene: str, server: str, direction: str, nine_points: tuple[str, str, str] | None = None,
               points: list[str] | None = None, distance: float | None = None, aperture: float | None = None,
               target: float | None = None, max_seconds: float | None = None, max_photons: int | None = None,
               seed: int = 0, json_out: bool = False) -> int:
    """Luminance meters at points (or the 9-point figure of a rectangle): each reading and the uniformity, with
    error bars."""
    def work(console: Console) -> int:
        if (nine_points is None) == (not points):
            raise LumenLinkError("give --nine-points ORIGIN U V or one or more --point X,Y,Z", usage=True)
        d = vec3(direction, "--direction", DIRECTION)
        kwargs: dict[str, Any] = {}
        if nine_points is not None:
            kwargs["nine_points"] = [vec3(t, "--nine-points") for t in nine_points]
        else:
            kwargs["points"] = [vec3(t, "--point") for t in points or []]
        with Client(server) as ll:
            info = ll.scene(scene)
            out = ll.uniformity(info, direction=d, distance=distance, aperture_deg=aperture, target=target,
                                max_seconds=max_seconds, max_photons=max_photons, seed=seed, **kwargs)
        if json_out:
            print(json.dumps(out))
            return EXIT_OK
        print("point,x_m,y_m,z_m,cd_m2,stderr_cd_m2")
        for k, (p, v, e) in enumerate(zip(out["points"], out["luminance"], out["stderr"], strict=True)):
            print(f"{k},{p[0]:.9g},{p[1]:.9g},{p[2]:.9g},{v!r},{e!r}")
        u = out["uniformity"]
        console.print(f"{out['figure']}: min {u['min']:.4g}, mean {u['mean']:.4g}, max {u['max']:.4g} cd/m²; "
                      f"min/max {_pm(u['min_max'], u['min_max_stderr'])}, min/mean "
                      f"{_pm(u['min_mean'], u['min_mean_stderr'])}; {out['photons']:,} paths in "
                      f"{out['seconds']:.2f} s")
        return EXIT_OK
    return _run(work)


def conoscope(scene: str, server: str, point: str, normal: str, theta_max: float | None = None,
              rings: int | None = None, azimuths: int | None = None, distance: float | None = None,
              aperture: float | None = None, target: float | None = None, max_seconds: float | None = None,
              max_photons: int | None = None, seed: int = 0, png: str | None = None, json_out: bool = False) -> int:
    """The luminance a point of a lit face shows against viewing angle (`Client.conoscope`): one CSV row per meter
    (ring, azimuth, polar and azimuth angles, cd/m², its error) and the on-axis value and flatness; ``png``: also its
    polar plot there."""
    def work(console: Console) -> int:
        kwargs: dict[str, Any] = dict(theta_max_deg=theta_max, rings=rings, azimuths=azimuths, distance=distance,
                                      aperture_deg=aperture, target=target, max_seconds=max_seconds,
                                      max_photons=max_photons, seed=seed)
        p, n = vec3(point, "--point"), vec3(normal, "--normal", DIRECTION)
        with Client(server) as ll:
            info = ll.scene(scene)
            out = ll.conoscope(info, p, n, **kwargs)
            if png:
                image = ll.conoscope(info, p, n, png=True, **kwargs)
                try:
                    with open(png, "wb") as fh:
                        fh.write(image)   # type: ignore[arg-type]  (png=True answers bytes)
                except OSError as exc:
                    raise LumenLinkError(f"cannot write {png}: {exc}", usage=True) from exc
        assert isinstance(out, dict)
        if json_out:
            print(json.dumps(out))
            return EXIT_OK
        print("ring,azimuth,theta_deg,phi_deg,cd_m2,stderr_cd_m2")
        for i, theta in enumerate(out["theta_deg"]):
            for j, phi in enumerate(out["phi_deg"]):
                print(f"{i},{j},{theta:.6g},{phi:.6g},{out['luminance'][i][j]!r},{out['stderr'][i][j]!r}")
        f = out["flatness"]
        console.print(f"on axis {_pm(out['on_axis'], out['on_axis_stderr'])} cd/m²; min/max "
                      f"{_pm(f['min_max'], f['min_max_stderr'])}, min/mean {_pm(f['min_mean'], f['min_mean_stderr'])}; "
                      f"{out['photons']:,} paths in {out['seconds']:.2f} s" + (f"; plot: {png}" if png else ""))
        return EXIT_OK
    return _run(work)
