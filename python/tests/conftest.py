"""Fixtures of the Python module's tests: the source tree, the CLI built
beside the module, and a small scene (a 128 x 128 detector, a one-term
material, the cuboid part) that renders in milliseconds."""

import json
import os
import pathlib
import shutil
import subprocess
import threading
import time

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("XGAUGE_SOURCE_DIR",
                                         pathlib.Path(__file__).resolve().parents[2]))

MACHINE = {"source_detector_distance_mm": 1000,
           "detector": {"columns": 128, "rows": 128, "pixel_pitch_mm": [0.5, 0.5]}}
MATERIAL = {"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.05}]}
CUBOID = SOURCE_DIR / "parts" / "cuboid.json"
# The cuboid turned a little, 400 mm from the detector (tests/cli_test.cpp's).
ROTATION_DEG = (1.0, -2.0, 0.5)
TRANSLATION_MM = (1.0, -2.0, 400.0)


@pytest.fixture
def scene(tmp_path):
    """The scene's machine and material written as files in tmp_path."""
    machine = tmp_path / "machine.json"
    machine.write_text(json.dumps(MACHINE))
    material = tmp_path / "material.json"
    material.write_text(json.dumps(MATERIAL))
    return {"machine": machine, "material": material, "part": CUBOID, "folder": tmp_path}


@pytest.fixture(scope="session")
def cli():
    """Runs the xgauge executable (XGAUGE_EXECUTABLE, as CTest sets it)."""
    exe = os.environ.get("XGAUGE_EXECUTABLE") or shutil.which("xgauge")
    if not exe:
        pytest.skip("no xgauge executable (set XGAUGE_EXECUTABLE)")

    def run(*args):
        result = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        assert result.returncode == 0, result.stdout + result.stderr
        return result
    return run


def run_beside_python(call):
    """Runs call() while a pure-Python thread counts; returns (call's
    result, seconds it took, how many times the thread counted while it ran,
    leaving out 30 ms at either end). The thread counts only while the GIL
    is free: a call that holds it throughout leaves the count at 0."""
    stamps, stop = [], threading.Event()

    def spin():
        while not stop.is_set():
            stamps.append(time.perf_counter())
            for _ in range(1000):
                pass

    thread = threading.Thread(target=spin)
    thread.start()
    try:
        time.sleep(0.05)
        start = time.perf_counter()
        result = call()
        end = time.perf_counter()
    finally:
        stop.set()
        thread.join()
    return result, end - start, sum(start + 0.03 < t < end - 0.03 for t in stamps)
