"""xgauge.plan: the front door's view plan from Python, and a bad plan
refused with nothing written."""

import json

import pytest

import xgauge
from conftest import CUBOID


def write_plan(tmp_path, **change):
    (tmp_path / "machine.json").write_text(json.dumps(
        {"source_detector_distance_mm": 1000,
         "detector": {"columns": 96, "rows": 96, "pixel_pitch_mm": [0.8, 0.8]}}))
    (tmp_path / "material.json").write_text(json.dumps(
        {"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.05}]}))
    plan = {"job": {"part": str(CUBOID), "machine": "machine.json", "material": "material.json",
                    "tolerances": {"size_x": {"lower": -0.05, "upper": 0.05}},
                    "pose_bounds": {"rotation_deg": [[-5, 5], [-10, 70], [-5, 5]],
                                    "centre_mm": [[-30, 30], [-20, 20], [470, 530]]},
                    "loss": "l2"},
            "exposure": {"open_beam_noise": 0.01},
            "views": {"centre_mm": [-6, 0, 500], "rotations_deg": [[0, 0, 0], [0, 30, 0]],
                      "stage": {"axis": [1, 0, 0], "positions_mm": [0, 12]}},
            "radiographs": 2, "budgeted": 1}
    plan.update(change)
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan))
    return path


def test_plan_ranks_every_pair(tmp_path):
    result = xgauge.plan(write_plan(tmp_path), tmp_path / "out")
    assert result["screened"] == 6
    best = result["ranked"][0]
    assert best["predicted_by"] == "budget"
    u = best["dimensions"]["size_x"]["expanded_uncertainty"]
    assert 0 < u < 0.5
    assert best["score"] == pytest.approx(u / 0.1)
    assert "size_x" in result["table"]
    assert (tmp_path / "out" / "job.json").exists()


def test_a_bad_plan_is_refused(tmp_path):
    with pytest.raises(xgauge.Error, match="no candidate view named 'v09'"):
        xgauge.plan(write_plan(tmp_path, compare=[["v00", "v09"]]), tmp_path / "out")
    assert not (tmp_path / "out").exists()
