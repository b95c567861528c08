"""``lumenlink uniformity`` and ``lumenlink conoscope``: luminance read by meters, as a display is judged (issues 37,
53). Built on `lumenlink.Client`; exit codes as `lumenlink.commands`: 2 bad usage, 3 the service unreachable, 1 the
rest."""

from __future__ import annotations

import json
from typing import Annotated, Any

import typer
from rich.console import Console

from lumenlink.client import Client, LumenLinkError
from lumenlink.commands import DIRECTION, EXIT_OK, _pm, _run, vec3
from lumenlink.options import DEFAULT_SERVER, JsonOut, SceneOpt, Seed, Server


def uniformity(
    scene: SceneOpt,
    direction: Annotated[str, typer.Option(help="The way the meters look, X,Y,Z (e.g. 0,0,-1: down).")],
    nine_points: Annotated[tuple[str, str, str] | None, typer.Option(
        metavar="ORIGIN U V", help="The 9-point figure of the rectangle ORIGIN + s*U + t*V (each X,Y,Z, m).")] = None,
    thirteen_points: Annotated[tuple[str, str, str] | None, typer.Option(
        metavar="ORIGIN U V", help="The 13-point (SPWG) figure of that rectangle, --inset in from its edges.")] = None,
    inset: Annotated[float, typer.Option(help="With --thirteen-points: the outer points' inset, m.")] = 0.01,
    point: Annotated[list[str] | None, typer.Option(help="A point a meter looks at, X,Y,Z (m); repeat it.")] = None,
    distance: Annotated[float | None, typer.Option(help="How far each meter stands back from its point, m "
                                                        "(default 0.5).")] = None,
    aperture: Annotated[float | None, typer.Option(help="Each meter's acceptance angle, degrees (default 1).")] = None,
    target: Annotated[float | None, typer.Option(help="Stop at this relative error (0.01 = 1 %).")] = None,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Path budget (all meters).")] = None,
    seed: Seed = 0,
    server: Server = DEFAULT_SERVER,
    json_out: JsonOut = False,
) -> int:
    """Luminance uniformity over a grid of meters: each reading (CSV on stdout) and min/max, min/mean ± error."""
    def work(console: Console) -> int:
        if sum((nine_points is not None, thirteen_points is not None, bool(point))) != 1:
            raise LumenLinkError("give --nine-points ORIGIN U V, --thirteen-points ORIGIN U V or one or more --point "
                                 "X,Y,Z", usage=True)
        d = vec3(direction, "--direction", DIRECTION)
        kwargs: dict[str, Any] = {}
        if nine_points is not None:
            kwargs["nine_points"] = [vec3(t, "--nine-points") for t in nine_points]
        elif thirteen_points is not None:
            o, u, v = (vec3(t, "--thirteen-points") for t in thirteen_points)
            kwargs["thirteen_points"] = {"origin": o, "u": u, "v": v, "inset": inset}
        else:
            kwargs["points"] = [vec3(t, "--point") for t in point or []]
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


def conoscope(
    scene: SceneOpt,
    point: Annotated[str, typer.Option(help="The point of the lit face, X,Y,Z (m).")],
    normal: Annotated[str, typer.Option(help="The face's normal there, X,Y,Z (the viewing angles' axis).")],
    theta_max: Annotated[float | None, typer.Option(help="Largest polar angle, degrees (<= 85; default 80).")] = None,
    rings: Annotated[int | None, typer.Option(help="Polar angles from the normal to --theta-max.")] = None,
    azimuths: Annotated[int | None, typer.Option(help="Meters per ring.")] = None,
    distance: Annotated[float | None, typer.Option(help="How far each meter stands back, m.")] = None,
    aperture: Annotated[float | None, typer.Option(help="Each meter's acceptance angle, degrees.")] = None,
    target: Annotated[float | None, typer.Option(help="Stop at this relative error (0.01 = 1 %).")] = None,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Path budget (all meters).")] = None,
    seed: Seed = 0,
    png: Annotated[str | None, typer.Option(help="Also write the polar plot to this PNG file.")] = None,
    server: Server = DEFAULT_SERVER,
    json_out: JsonOut = False,
) -> int:
    """A conoscopic view: the luminance one point of a lit face shows against viewing angle (CSV on stdout)."""
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
        f, spread = out["flatness"], out.get("half_angle_deg")
        half = ("—" if spread is None else f"{_pm(spread, out['half_angle_stderr'])}°"
                if out.get("half_angle_within_view") else f"≥ {spread:g}°")
        console.print(f"on axis {_pm(out['on_axis'], out['on_axis_stderr'])} cd/m²; half-luminance angle {half}; "
                      "min/max "
                      f"{_pm(f['min_max'], f['min_max_stderr'])}, min/mean {_pm(f['min_mean'], f['min_mean_stderr'])}; "
                      f"{out['photons']:,} paths in {out['seconds']:.2f} s" + (f"; plot: {png}" if png else ""))
        return EXIT_OK
    return _run(work)


def ugr(
    scene: SceneOpt,
    sensor: Annotated[str, typer.Option(help="The camera (id or name): the observer at its position, looking along "
                                             "its line of sight.")],
    background: Annotated[float | None, typer.Option(help="Background luminance L_b, cd/m² (CIE 117: E_ind/π); "
                                                          "default: the image's non-source pixels.")] = None,
    threshold: Annotated[float | None, typer.Option(help="Pixels at least this bright (cd/m²) above the line of "
                                                         "sight are luminaires; default 5 × the image's mean.")] = None,
    simulate_first: Annotated[bool, typer.Option("--simulate/--latest", help="Simulate the camera first (default), "
                                                 "or rate its latest image.")] = True,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget of the camera, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Path budget of the camera.")] = None,
    seed: Seed = 0,
    server: Server = DEFAULT_SERVER,
    json_out: JsonOut = False,
) -> int:
    """The unified glare rating (CIE 117) a camera's observer sees, with its error bar."""
    def work(console: Console) -> int:
        with Client(server) as ll:
            info = ll.scene(scene)
            if simulate_first:
                ll.simulate(info, sensor, max_seconds=max_seconds, max_photons=max_photons, seed=seed)
            out = ll.ugr(info, sensor, background=background, threshold=threshold)
        if json_out:
            print(json.dumps(out))
            return EXIT_OK
        bg = _pm(out["background"], out["background_stderr"])
        print(f"UGR {out['ugr']:.2f} ± {out['stderr']:.2f}  (background {bg} cd/m², {out['source_pixels']} source "
              f"pixels ≥ {out['threshold']:.4g} cd/m², revision {out['revision']})")
        return EXIT_OK
    return _run(work)
