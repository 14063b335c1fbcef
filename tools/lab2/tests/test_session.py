"""A whole (tiny) machine session: files, truth keys, determinism."""

import copy
import filecmp
import json
import os

import numpy as np
import pytest

from lab2 import grid, tiffio
from lab2.session import Machine, Session

TINY = copy.deepcopy(grid.machine("m01"))
TINY.update(id="tiny", seed=42, description="tiny test machine")
TINY["geometry"] = {"sdd_mm": 1000.0, "columns": 240, "rows": 256, "pitch_mm": [0.7, 0.7],
                    "principal_point_px": [118.2, 131.7]}
TINY["wedge"] = {"fill": 0.65}
TINY["frames"] = {"darks": 2, "flats": 2}
TINY["prism"]["magnification"] = 1.6
TINY["detector"]["halo"] = {"shape": "two_gauss", "weight": 0.12, "sigma1_mm": 20.0, "sigma2_mm": 50.0,
                            "fraction2": 0.3}
TINY["detector"]["dead_fraction"] = 2e-4
TINY["detector"]["hot_fraction"] = 1e-4


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = []
    for k in range(2):
        d = tmp_path_factory.mktemp(f"run{k}")
        Session(Machine(copy.deepcopy(TINY)), str(d / "tiny"), imperfections=True, log=lambda *a: None).run()
        out.append(str(d / "tiny"))
    return out


def test_layout_and_truth(runs):
    root = runs[0]
    for f in ["machine.json", "lab2_machine.json", "lab2_truth.json", "dark.tif", "flat.tif",
              "darks/dark_000.tif", "flats/flat_001.tif",
              "characterisation/edge.tif", "characterisation/disc.tif", "characterisation/crosstalk.tif",
              "characterisation/lag_bright.tif", "characterisation/lag_dark_after_bright.tif",
              "characterisation/corrected/edge.tif",
              "wedge/truth.json", "wedge/calibration.tif", "wedge/dark.tif", "wedge/flat.tif",
              "wedge/normalized/calibration.tif", "wedge/calibrate_wedge.json",
              "prism/truth.json", "prism/t00.tif", "prism/t01.tif", "prism/t02.tif", "prism/normalized/t01.tif",
              "prism/job.json", "prism/job_true_material.json", "prism/material_true.json", "prism/study.json",
              "prism/physical_part.json"]:
        assert os.path.isfile(os.path.join(root, f)), f
    t = json.load(open(os.path.join(root, "prism", "truth.json")))
    assert set(t) == {"recipe", "description", "seed", "machine", "beam", "material", "detector", "part",
                      "white_region", "dark", "flat", "dead_pixels", "transmission", "shots"}
    assert [s["name"] for s in t["shots"]] == ["t00", "t01", "t02"]
    assert t["shots"][1]["pattern"] == "translated" and t["shots"][1]["distance_mm"] == 10.0
    M = np.array(t["shots"][0]["pose"]["matrix"]).reshape(4, 4)
    assert np.allclose(M[:3, :3] @ M[:3, :3].T, np.eye(3), atol=1e-12)
    raw = tiffio.read(os.path.join(root, "prism", "t00.tif"))
    assert raw.dtype == np.uint16 and raw.shape == (256, 240)
    x, y, w, h = t["white_region"]
    n = tiffio.read(os.path.join(root, "prism", "normalized", "t00.tif"))
    assert n[y:y + h, x:x + w].mean() == pytest.approx(1.0, abs=1e-6)
    lt = json.load(open(os.path.join(root, "lab2_truth.json")))
    assert lt["detector"]["halo"]["shape"] == "two_gauss"
    assert lt["prism"]["imperfections"]["chamfers_mm"]["P0"] > 0
    order = [f["frame"] for f in lt["exposure_order"]]
    assert order.index("t01") == order.index("t00") + 1
    assert [f["previous"] for f in lt["exposure_order"] if f["frame"] == "t01"] == ["t00"]
    # the lag frame after an open frame holds the lag fraction of its signal
    c = tiffio.read(os.path.join(root, "characterisation", "corrected", "lag_dark_after_bright.tif"))
    assert np.median(c) == pytest.approx(lt["detector"]["lag_fraction"], rel=0.1)


def test_same_seed_same_files(runs):
    a, b = runs
    for f in ["prism/t00.tif", "prism/t02.tif", "wedge/calibration.tif", "flat.tif", "dark.tif",
              "characterisation/edge.tif", "prism/truth.json", "wedge/truth.json", "prism/physical_part.json"]:
        fa, fb = os.path.join(a, f), os.path.join(b, f)
        if f.endswith(".json"):
            ja, jb = json.load(open(fa)), json.load(open(fb))
            ja.pop("recipe", None), jb.pop("recipe", None)
            assert ja == jb, f
        else:
            assert filecmp.cmp(fa, fb, shallow=False), f
