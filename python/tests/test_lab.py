"""simulate() and calibrate() against the CLI: the report tests' small
wedge session (tests/data/report_wedge.json, 256 x 256 pixels) simulated
and calibrated both ways gives the same files."""

import json

import pytest

import xgauge
from conftest import SOURCE_DIR
from test_measure import TIMING, without

DATA = SOURCE_DIR / "tests" / "data"


@pytest.fixture(scope="module")
def wedge(tmp_path_factory, cli):
    folder = tmp_path_factory.mktemp("wedge")
    cli("simulate", DATA / "report_wedge.json", "-o", folder / "cli", "-q")
    report = xgauge.simulate(DATA / "report_wedge.json", folder / "py")
    return {"folder": folder, "report": report}


def test_simulate_writes_the_clis_files(wedge):
    folder = wedge["folder"]
    names = sorted(p.name for p in (folder / "cli").iterdir())
    assert names == sorted(p.name for p in (folder / "py").iterdir())
    assert "calibration.tif" in names and "truth.json" in names
    for name in names:
        cli, py = (folder / "cli" / name), (folder / "py" / name)
        if name.endswith(".json"):
            assert without(json.loads(py.read_text()), TIMING) == \
                without(json.loads(cli.read_text()), TIMING), name
        else:
            assert py.read_bytes() == cli.read_bytes(), name
    assert wedge["report"]["shots"] == 1  # the calibration shot


def test_calibrate_wedge_writes_the_clis_material(wedge, cli):
    folder = wedge["folder"]
    job = {"machine": str(DATA / "report_wedge_machine.json"),
           "radiograph": {"image": "cli/calibration.tif", "dark": "cli/dark.tif",
                          "flat": "cli/flat.tif", "white_region": [5, 5, 13, 13]},
           "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0},
           "scatter": {"weight": 0.139, "sigma_mm": 50.0}}
    (folder / "wedge_job.json").write_text(json.dumps(job))
    truth = folder / "cli" / "truth.json"
    cli("calibrate", "wedge", folder / "wedge_job.json", "-o", folder / "cal_cli",
        "--truth", truth, "--no-report", "-q")
    ours = xgauge.calibrate("wedge", folder / "wedge_job.json", folder / "cal_py",
                            report=False, truth=truth)
    assert (folder / "cal_py" / "material.json").read_bytes() == \
        (folder / "cal_cli" / "material.json").read_bytes()
    cli_calibration = json.loads((folder / "cal_cli" / "calibration.json").read_text())
    assert without(ours["calibration"], TIMING) == without(cli_calibration, TIMING)
    assert ours["material"]["terms"]


def test_a_failed_calibration_leaves_its_diagnostic(wedge):
    folder = wedge["folder"]
    job = {"machine": str(DATA / "report_wedge_machine.json"),
           "radiograph": {"image": "cli/flat.tif", "dark": "cli/dark.tif",
                          "flat": "cli/flat.tif", "white_region": [5, 5, 13, 13]},
           "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0}}
    (folder / "no_wedge_job.json").write_text(json.dumps(job))
    with pytest.raises(xgauge.Error, match="failed at its step"):
        xgauge.calibrate("wedge", folder / "no_wedge_job.json", folder / "no_wedge",
                         report=False)
    assert (folder / "no_wedge" / "failed_calibration.json").exists()
    assert not (folder / "no_wedge" / "material.json").exists()
