"""measure(): the same job measured by `xgauge measure` and from Python
gives the same result.json, every number to the bit; a job given as a dict
measures the same; progress reaches a Python callback."""

import json

import numpy as np
import pytest

import xgauge
from conftest import CUBOID, MACHINE, MATERIAL, ROTATION_DEG, TRANSLATION_MM, run_beside_python


def make_job(folder):
    """A radiograph of the cuboid (20 x 30 x 10 mm, noise 0.002) and a job
    measuring its side size_x from it, the pose unknown (tests/cli_test.cpp's
    MeasureJob with the other sides known: one radiograph does not tell all
    three sides from the distance to the source)."""
    (folder / "machine.json").write_text(json.dumps(MACHINE))
    (folder / "material.json").write_text(json.dumps(MATERIAL))
    image = xgauge.render(CUBOID, {"size_x": 20.0, "size_y": 30.0, "size_z": 10.0},
                          (ROTATION_DEG, TRANSLATION_MM), MACHINE, MATERIAL, samples=3).image
    noise = np.random.default_rng(7).normal(0.0, 0.002, image.shape)
    xgauge.write_tiff(folder / "a.tif", (image + noise).astype(np.float32))
    job = {"part": str(CUBOID), "machine": "machine.json", "material": "material.json",
           "dimensions": {"free": ["size_x"]},
           "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 16, 16]}],
           "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                           "centre_mm": [[-10, 10], [-10, 10], [390, 410]]}}
    (folder / "job.json").write_text(json.dumps(job))
    return job


def without(value, keys):
    """`value` with every object member named in `keys` left out, at any depth."""
    if isinstance(value, dict):
        return {k: without(v, keys) for k, v in value.items() if k not in keys}
    if isinstance(value, list):
        return [without(v, keys) for v in value]
    return value


TIMING = {"seconds"}  # wall-clock times: the only members two runs may differ in


@pytest.fixture(scope="module")
def measured(tmp_path_factory, cli):
    folder = tmp_path_factory.mktemp("measure")
    job = make_job(folder)
    cli("measure", folder / "job.json", "-o", folder / "cli", "--no-report", "-q")
    messages = []
    summary = xgauge.measure(folder / "job.json",
                             progress=lambda level, text: messages.append((level, text)))
    return {"folder": folder, "job": job, "summary": summary, "messages": messages,
            "cli": json.loads((folder / "cli" / "result.json").read_text())}


def test_result_json_equals_the_clis_to_the_bit(measured):
    summary, cli = measured["summary"], measured["cli"]
    ours = json.loads(summary.to_json())
    assert without(ours, TIMING) == without(cli, TIMING)  # floats compare exactly
    assert summary.status == "measured"
    assert summary.values["size_x"] == pytest.approx(20.0, abs=0.02)
    assert summary.values["size_y"] == 30.0 and not summary.dimensions["size_y"]["free"]
    assert summary.theta.dtype == np.float64 and summary.theta.ndim == 1
    (simulated,) = summary.simulated
    assert simulated.shape == (128, 128) and not simulated.flags.writeable


def test_outputs_written_from_python_are_the_clis(measured, tmp_path):
    measured["summary"].write_outputs(tmp_path / "out", report=False)
    for name in ("simulated_a.tif", "difference_a.tif"):
        assert np.array_equal(xgauge.read_tiff(tmp_path / "out" / name),
                              xgauge.read_tiff(measured["folder"] / "cli" / name))
    written = json.loads((tmp_path / "out" / "result.json").read_text())
    assert written == json.loads(measured["summary"].to_json())


def test_a_job_given_as_a_dict_measures_the_same(measured):
    summary = xgauge.measure(measured["job"], base_dir=measured["folder"])
    # The inputs' SHA-256 is keyed by file: the dict has none of its own.
    keys = TIMING | {"inputs_sha256"}
    assert without(summary.result, keys) == without(measured["summary"].result, keys)


def test_the_gil_is_released_while_measuring(measured):
    summary, seconds, counted = run_beside_python(
        lambda: xgauge.measure(measured["folder"] / "job.json"))
    assert summary.values == measured["summary"].values
    assert counted > 10, f"{counted} counts in {seconds:.2f} s"


def test_progress_reaches_the_callback(measured):
    levels = {level for level, _ in measured["messages"]}
    assert "info" in levels and len(measured["messages"]) >= 3


def test_a_callback_that_raises_stops_nothing_but_its_error_is_raised(measured):
    def fail(level, text):
        raise RuntimeError("from the callback")
    with pytest.raises(RuntimeError, match="from the callback"):
        xgauge.measure(measured["folder"] / "job.json", progress=fail)


def test_a_bad_job_raises_with_the_key(measured):
    bad = dict(measured["job"], shedule="default")
    with pytest.raises(xgauge.Error, match="shedule"):
        xgauge.measure(bad, base_dir=measured["folder"])
