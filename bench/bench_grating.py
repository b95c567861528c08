"""Gratings (issue 52): what a grating on a face costs a query, and what preparing one costs.

1. A query through a grating against the same query through the plain face, in turn in one process (one thread, CPU
   time, `bench.bench_spectral._interleaved`): a 20 x 20 x 2 mm glass plate lit by a collimated 550 nm beam, a 5 x 5
   grid under it, 10^6 photons (the issue's query). The grating (a 1 um lamellar glass relief, 9 wavelengths x 9
   polar angles x 2 azimuths, lit from both sides) on the plate's top face; the plain plate traced in the same photon
   state (spectral and, by physics, polarized: a glass plate already calls for it), and white beside it. The grating
   diffracts light into orders that the plate traps by total internal reflection, so its photons also travel
   further: the ratio is the whole query's, as a user pays it.
2. Preparation: seconds and table bytes (in memory and as the stored .npz) of a lamellar glass grating, a wire grid
   and a moth-eye relief, each solved lit from both sides.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from bench.bench_spectral import _interleaved, _ratios

PLATE = 0.02, 0.002            # m: side, thickness
LAMELLAR = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 1.0, "depth_um": 0.3,
            "ridge": None, "substrate_ior": 1.5, "wavelengths_nm": [450, 650], "wavelength_count": 9,
            "angles": {"polar_deg": [0, 10, 20, 30, 40, 50, 60, 70, 80]}, "orders": 8}
BODIES = {
    "lamellar glass, 1 um": LAMELLAR,
    "wire grid, Al 140 nm": {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 0.14,
                             "depth_um": 0.15, "ridge": {"ior": [0.958, 6.69]}, "substrate_ior": 1.5,
                             "wavelengths_nm": [450, 650], "wavelength_count": 9, "orders": 10},
    "moth-eye cones, 250 nm": {"type": "grating", "profile": {"shape": "moth_eye", "fill": 1.0}, "period_um": 0.25,
                               "depth_um": 0.3, "substrate_ior": 1.5, "wavelengths_nm": [450, 650],
                               "wavelength_count": 5, "angles": {"polar_deg": [0, 20, 40, 60]}, "orders": 2,
                               "layers": 6},
}


def _plate(table=None):
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s = Scene()
    part = s.add_instance(s.add_geometry(*box((0.0, 0.0, 0.0), (PLATE[0], PLATE[0], PLATE[1]))), np.eye(4))
    if table is not None:
        s.set_element(part, table, facing=[0, 0, 1])
    s.commit()
    light = {"type": "collimated", "origin": [0.01, 0.01, 0.01], "direction": [0.0, 0.0, -1.0], "radius": 0.004,
             "illuminance_lx": 1000.0, "spectrum": {"type": "monochromatic", "nm": 550}}
    return Simulation(s, {part: {"type": "dielectric", "ior": 1.5}}, [light])


def query_cost(rounds: int, photons: int) -> dict:
    from tracer.elements import grating

    table = grating.prepare(LAMELLAR)
    plain, grated = _plate(), _plate(table)
    state = [e for e in grated.effects if e in ("spectral", "polarization")]
    below = ([0.0, 0.0, -0.001], [PLATE[0], 0.0, 0.0], [0.0, PLATE[0], 0.0], 5, 5)
    q = dict(max_photons=photons, estimator="forward", seed=1)
    compile_s = {}
    for name, sim, force in (("plain, white", plain, []), ("plain", plain, state), ("grating", grated, [])):
        t0 = time.perf_counter()
        sim.grid(*below, max_photons=1000, estimator="forward", force_effects=force)
        compile_s[name] = time.perf_counter() - t0
    times = _interleaved({"plain, white": lambda: plain.grid(*below, **q),
                          "plain": lambda: plain.grid(*below, force_effects=state, **q),
                          "grating": lambda: grated.grid(*below, **q)}, rounds)
    last = grated.grid(*below, **q)
    return {"photons": photons, "rounds": rounds, "photon_state": state, "effects": grated.effects,
            "seconds": {n: statistics.median(t) for n, t in times.items()}, "ratio_to_plain": _ratios(times, "plain"),
            "first_call_seconds": compile_s, "outside_table": int(last.counters["grating_outside_table"])}


def preparation(quick: bool) -> dict:
    from tracer.elements import grating

    out = {}
    for name, body in BODIES.items():
        if quick and name != "lamellar glass, 1 um":
            continue
        t0 = time.perf_counter()
        table = grating.prepare(body)
        seconds = time.perf_counter() - t0
        canon = grating.check(body)
        points = grating.table_points(canon)
        out[name] = {"seconds": seconds, "estimate_seconds": grating.cost(canon), "points": points,
                     "orders_kept": len(table.orders), "harmonics": grating.harmonics(canon),
                     "bytes": table.nbytes, "npz_bytes": len(table.to_bytes())}
    return out


def run(quick: bool = False) -> dict:
    import numba

    numba.set_num_threads(1)
    cost = query_cost(3 if not quick else 1, 1_000_000 if not quick else 100_000)
    prep = preparation(quick)
    r = cost["ratio_to_plain"]
    lines = [f"### A query through a grating ({cost['photons']:,} photons, one thread, medians of {cost['rounds']} "
             f"interleaved runs)", "",
             "`lumenlink bench --only grating` (a glass plate, a collimated 550 nm beam, "
             "a 5 x 5 grid under it; photon state of both: " + ", ".join(cost["photon_state"]) + ")", "",
             "| face | CPU s | × plain | first call s (compile) |", "| --- | --- | --- | --- |"]
    for n, s in cost["seconds"].items():
        lines.append(f"| {n} | {s:.2f} | {r[n]:.2f} | {cost['first_call_seconds'][n]:.1f} |")
    lines += ["", f"Target: grating ≤ 1.5 × plain. Photons that met the grating where its table ran out (polar angles "
              f"past 80° inside the plate): {cost['outside_table']:,} of {cost['photons']:,}.", "",
              "### Preparation (inkstone RCWA, both polarizations, lit from both sides)", "",
              "| grating | table points | harmonics | orders kept | s | estimate s | bytes | .npz bytes |",
              "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for n, p in prep.items():
        lines.append(f"| {n} | {p['points']} × 2 sides | {p['harmonics']} | {p['orders_kept']} | "
                     f"{p['seconds']:.1f} | {p['estimate_seconds']:.1f} | {p['bytes']:,} | {p['npz_bytes']:,} |")
    return {"query": cost, "preparation": prep, "markdown": "\n".join(lines)}
