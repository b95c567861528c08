"""`lumenlink pack` against a real service (issue 41): the demo guide's uniform dots packed from the command line,
the scene switched to the result (--switch) and the plot written (--png); then `lumenlink design` on the result.
Tiny photon budgets: the physics is checked in tests/service/test_pack_api.py and test_design_api.py."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import httpx
import pytest
from typer.testing import CliRunner

from lumenlink import Client
from lumenlink.cli import app
from lumenlink.demo import running_service
from lumenlink.guide_demo import DOT, GRID, PITCH, SIZE, _scene

pytestmark = pytest.mark.slow


def test_lumenlink_pack_packs_switches_and_writes_the_plot(tmp_path: Path) -> None:
    data = Path(tempfile.mkdtemp(prefix="lumenlink-pack-cli-"))
    try:
        with running_service(data) as url, Client(url) as ll, httpx.Client(base_url=url, timeout=300) as http:
            body = {"type": "microstructure", "feature": DOT, "relief": "bump",
                    "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                               "fill": [[1.0] * 24], "seed": 1, "pitch_mm": PITCH}}
            eid = ll.add_element(body)["id"]
            sid, _ = _scene(ll, http, "guide-cli")
            aid = ll.put_element(sid, "backlight/guide", eid, facing=[0, 0, -1])["id"]
            sensor = ll.add_sensor(sid, GRID)["id"]
            png = tmp_path / "pack.png"
            out = CliRunner().invoke(app, ["pack", eid, "--scene", "guide-cli", "--assignment", aid, "--sensor",
                                           GRID["name"], "--target", "0.8", "--photons", "50000", "--max-iterations",
                                           "3", "--switch", "--png", str(png), "--server", url])   # by its name
            assert out.exit_code == 0, out.output
            # the progress lines number the iterations as the final table does
            lines = out.output.splitlines()
            shown = {ln.split(":")[0].split()[-1]: ln.split()[4] for ln in lines if ln.strip().startswith("after ")}
            table = {ln.split(":")[0].split()[-1]: ln.split()[3] for ln in lines if ln.startswith("iteration ")}
            assert table and all(table[k] == u for k, u in shown.items()), (shown, table)   # (polled: may be none)
            new = next(line.split()[1].rstrip(":") for line in out.output.splitlines()
                       if line.startswith("element "))
            assert "iteration 0: min_max" in out.output and f"assignment {aid} now carries {new}" in out.output
            assert ll.scene_elements(sid)[0]["body"]["element"] == new and new != eid
            assert png.read_bytes()[:4] == b"\x89PNG"
            assert ll.pack_record(new)["packed_from"] == eid
            # lumenlink design on the packed element: flatter dots let out far less light, so the start stays
            designed = CliRunner().invoke(app, ["design", new, "--scene", "guide-cli", "--assignment", aid,
                                                "--sensor", GRID["name"], "--param", "feature.height_mm=0.03,0.04",
                                                "--objective", "mean", "--photons", "20000", "--server", url])
            assert designed.exit_code == 0, designed.output
            assert "feature.height_mm 0.03: mean" in designed.output and f"element {new} stays" in designed.output
            unread = CliRunner().invoke(app, ["design", new, "--scene", "guide-cli", "--assignment", aid, "--sensor",
                                              GRID["name"], "--param", "feature.height_mm", "--server", url])
            assert unread.exit_code == 2 and "NAME=V1,V2" in unread.output, unread.output
            bad = CliRunner().invoke(app, ["pack", eid, "--scene", "guide-cli", "--assignment", aid, "--sensor",
                                           sensor, "--target", "1.5", "--server", url])   # by its id
            assert bad.exit_code == 2 and "target" in bad.output, bad.output
            typo = CliRunner().invoke(app, ["pack", eid, "--scene", "guide-cli", "--assignment", aid, "--sensor",
                                            "lit face (9 pionts)", "--server", url])
            assert typo.exit_code == 2 and "did you mean 'lit face (9 points)'" in typo.output, typo.output
    finally:
        shutil.rmtree(data, ignore_errors=True)
