"""A lamp's far field from the command line and the Python client, against a real service process (issue 22):
`lumenlink sensor` (a far_field body), `lumenlink simulate` (writes <sensor>.csv and <sensor>.ies), `lumenlink export
--format ies|ldt`, `Client.export`; the files read back through `tracer.photometry.files` to the simulated table and
flux (within 0.5 %); bad usage exits 2 saying what to do."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from service_process import running_service  # noqa: E402

from lumenlink import Client  # noqa: E402
from lumenlink.cli import app  # noqa: E402
from tracer.photometry.files import parse_photometry  # noqa: E402

IES = ROOT / "lumenlink" / "data" / "rab_dled6r8y_7.ies"
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("far-field-service")) as url:
        yield url


def cli(service: str, *args: str):
    return CliRunner().invoke(app, list(args), env={"LUMENLINK_SERVER": service})


def test_far_field_from_the_command_line(service, tmp_path) -> None:
    with Client(service) as ll:
        info = ll.scene("downlight", create=True)
        ll.add_light(info, ies=IES, at=(0.0, 0.0, 0.0))
    r = cli(service, "sensor", "--scene", "downlight", "--name", "lamp", "--body",
            '{"type": "far_field", "nc": 24, "ngamma": 37}')
    assert r.exit_code == 0, r.output
    # before any simulation there is nothing to export
    r = cli(service, "export", "--scene", "downlight", "--sensor", "lamp", "--out", str(tmp_path / "x.ies"))
    assert r.exit_code == 2 and "simulate" in r.output
    r = cli(service, "simulate", "--scene", "downlight", "--sensor", "lamp", "--out", str(tmp_path / "run"),
            "--max-photons", "400000")
    assert r.exit_code == 0, r.output
    assert "lm leaving" in r.output
    assert (tmp_path / "run" / "lamp.csv").read_text().startswith("i,j,c_deg,gamma_deg,cd,stderr_cd\n")
    written = (tmp_path / "run" / "lamp.ies").read_text()
    with Client(service) as ll:
        # the same query again answers the same numbers (same seed, same revision)
        result = ll.simulate("downlight", "lamp", max_photons=400_000)
        [res] = result.values()
        text_ldt = ll.export("downlight", "lamp", "ldt", out=tmp_path / "py.ldt")
    cd = np.array(res["candela"])
    for fmt in ("ies", "ldt"):
        out = tmp_path / f"lamp.{fmt}"
        r = cli(service, "export", "--scene", "downlight", "--sensor", "lamp", "--format", fmt, "--out", str(out))
        assert r.exit_code == 0, r.output
        ph = parse_photometry(fmt, out.read_text())
        np.testing.assert_allclose(ph.candela[:24].T, cd, rtol=0, atol=1e-5 * cd.max())   # 6 digits
        assert ph.total_flux() == pytest.approx(res["flux_lm"], rel=0.005)
    assert parse_photometry("ies", written).total_flux() == pytest.approx(res["flux_lm"], rel=0.005)
    assert (tmp_path / "py.ldt").read_bytes().decode() == text_ldt   # EULUMDAT lines end in CRLF
    # the lamp file's own flux comes back: the scene is the lamp alone
    assert res["flux_lm"] == pytest.approx(parse_photometry("ies", IES.read_text()).total_flux(), rel=0.01)


def test_export_bad_usage(service, tmp_path) -> None:
    with Client(service) as ll:
        info = ll.scene("bad-export", create=True)
        ll.add_light(info, {"type": "point", "position": [0.0, 0.0, 1.0], "intensity_cd": 10.0})
        ll.add_sensor(info, Client.grid((-1, -1, 0), (2, 0, 0), (0, 2, 0), 2, 2, name="floor"))
    r = cli(service, "export", "--scene", "bad-export", "--sensor", "floor", "--out", str(tmp_path / "f.ies"))
    assert r.exit_code == 2 and "far_field" in r.output
    r = cli(service, "export", "--scene", "bad-export", "--sensor", "floor", "--format", "csv", "--out",
            str(tmp_path / "f.csv"))
    assert r.exit_code == 2 and "ies" in r.output and "ldt" in r.output
    r = cli(service, "export", "--scene", "bad-export", "--sensor", "flor", "--out", str(tmp_path / "f.ies"))
    assert r.exit_code == 2 and "did you mean" in r.output
    r = cli(service, "export", "--scene", "bad-export", "--sensor", "floor", "--out", str(tmp_path))
    assert r.exit_code == 2 and "directory" in r.output
