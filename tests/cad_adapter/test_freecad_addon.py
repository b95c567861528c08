"""The FreeCAD add-on's parts that need no FreeCAD (issue 56): the light's arithmetic (`lumenlink_freecad.light`
is standard library only), the add-on's install and an export file that is not one."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from cad_adapter.errors import CadImportError
from cad_adapter.freecad import MOD, install_addon

sys.path.insert(0, str(MOD))
from lumenlink_freecad import light  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def test_a_face_is_the_area_weighted_mean_of_its_triangles_with_its_standard_error() -> None:
    lux, err, area = [100.0, 300.0, 50.0, 7.0], [10.0, 20.0, 5.0, 1.0], [1.0, 3.0, 2.0, 1.0]
    faces = [0, 0, 2, 2]
    got = light.face_values(lux, err, area, faces)
    assert got[1] is None                                  # face 1 has no triangle
    assert got[0][0] == pytest.approx((100 + 900) / 4) and got[0][1] == pytest.approx(math.hypot(10, 60) / 4)
    assert got[2][0] == pytest.approx((100 + 7) / 3) and got[2][1] == pytest.approx(math.hypot(10, 1) / 3)
    with pytest.raises(ValueError, match="push the document again"):
        light.face_values(lux, err, area, faces[:3])       # a result of another mesh


def test_the_colour_scale_runs_from_the_smallest_face_to_the_largest() -> None:
    assert light.colour(0, 0, 10) == pytest.approx(light.VIRIDIS[0])
    assert light.colour(10, 0, 10) == pytest.approx(light.VIRIDIS[-1])
    assert light.colour(99, 0, 10) == pytest.approx(light.VIRIDIS[-1])   # clipped
    assert light.colour(5, 5, 5) == pytest.approx(light.VIRIDIS[0])      # a uniform result: one colour
    html = light.legend_html({"low": 0.0, "high": 1000.0, "stderr": 12.0, "faces": 6, "skipped": 0}, "top")
    assert "1,000 lx" in html and "± 12 lx" in html and "6 faces" in html


def test_install_links_the_add_on_and_leaves_a_folder_of_its_own_alone(tmp_path) -> None:
    link, _ = install_addon(tmp_path / "Mod")
    assert link.is_symlink() and link.resolve() == MOD.resolve() and (link / "InitGui.py").exists()
    again, _ = install_addon(tmp_path / "Mod")             # installing twice replaces our link
    assert again == link and link.is_symlink()
    other = tmp_path / "Other" / "LumenLink"
    other.mkdir(parents=True)
    with pytest.raises(CadImportError, match="not LumenLink's link"):
        install_addon(tmp_path / "Other")
    assert other.is_dir() and not other.is_symlink()


@pytest.mark.parametrize("text, why", [("not json", "not a LumenLink FreeCAD export"),
                                       (json.dumps([1, 2]), "not a LumenLink FreeCAD export"),
                                       (json.dumps({"format": "other"}), "format 'other'"),
                                       (json.dumps({"format": "lumenlink-freecad-1", "nodes": []}), "not a valid")])
def test_an_export_file_that_is_not_one_is_refused_saying_why(tmp_path, text, why) -> None:
    bad = tmp_path / "lamp.lumenlink-freecad.json"
    bad.write_text(text)
    r = subprocess.run([sys.executable, "-m", "lumenlink.cli", "push", str(bad), "--scene", "s", "--server",
                        "http://127.0.0.1:9"], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 2 and why in r.stderr, r.stderr   # read before any call to the (absent) service
