"""The demo pair (examples/prism_a_small_job.json, after scripts/demo.sh has
simulated its data and calibrated its material) measured from Python and by
`xgauge measure`: result.json the same to the bit apart from seconds.
Minutes on two cores, so only with XGAUGE_DEMO_PAIR=1 (and the demo's files
present): `XGAUGE_DEMO_PAIR=1 ctest -R python.pytest`."""

import json
import os

import pytest

import xgauge
from conftest import SOURCE_DIR
from test_measure import TIMING, without

JOB = SOURCE_DIR / "examples" / "prism_a_small_job.json"
NEEDS = [SOURCE_DIR / "data" / "prism_a_small" / "t03.tif",
         SOURCE_DIR / "out" / "calibration_wedge_small" / "material.json"]


@pytest.mark.skipif(os.environ.get("XGAUGE_DEMO_PAIR") != "1" or
                    not all(p.exists() for p in NEEDS),
                    reason="XGAUGE_DEMO_PAIR=1 and scripts/demo.sh's data and material")
def test_demo_pair_equals_the_clis_result(tmp_path, cli):
    cli("measure", JOB, "-o", tmp_path / "cli", "--no-report", "-q")
    summary = xgauge.measure(JOB)
    cli_result = json.loads((tmp_path / "cli" / "result.json").read_text())
    assert without(summary.result, TIMING) == without(cli_result, TIMING)
