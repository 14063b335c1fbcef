"""`lab2.py shots`: a part at given poses on an existing machine folder."""

import copy
import json
import os

import numpy as np
import pytest

from lab2 import cli, grid, physical, tiffio
from lab2.session import Machine, Session

TINY = copy.deepcopy(grid.machine("m01"))
TINY.update(id="tiny_shots", seed=7, description="tiny machine for the shots command")
TINY["geometry"] = {"sdd_mm": 1000.0, "columns": 200, "rows": 216, "pitch_mm": [1.0, 1.0],
                    "principal_point_px": [100.0, 108.0]}
TINY["frames"] = {"darks": 2, "flats": 2}

# the bracket's bounding-box centre at magnification 1.6, square to the beam, then moved 10 mm along x
POSES = [{"name": "a", "pose": {"rotation_deg": [0.0, 0.0, 0.0], "translation_mm": [-30.0, -12.5, 360.0]}},
         {"name": "b", "pose": {"rotation_deg": [0.0, 0.0, 0.0], "translation_mm": [-20.0, -12.5, 360.0]}}]


@pytest.fixture(scope="module")
def machine_dir(tmp_path_factory):
    d = str(tmp_path_factory.mktemp("m") / "tiny_shots")
    s = Session(Machine(copy.deepcopy(TINY)), d, log=lambda *a: None)
    os.makedirs(d)
    with open(os.path.join(d, "lab2_machine.json"), "w") as f:
        json.dump(TINY, f)
    s.dark_flat()  # dark.tif, flat.tif: all the shots command needs besides lab2_machine.json
    return d


def shoot(machine_dir, tmp, name, seed, specimen="draw"):
    p = os.path.join(str(tmp), "poses.json")
    with open(p, "w") as f:
        json.dump(POSES, f)
    out = os.path.join(str(tmp), name)
    assert cli.main(["shots", machine_dir, "--part", "bracket", "--poses", p, "-o", out, "--seed", str(seed),
                     "--specimen", specimen]) == 0
    return out


def test_shots(machine_dir, tmp_path):
    out = shoot(machine_dir, tmp_path, "s1", 11)
    t = json.load(open(os.path.join(out, "truth.json")))
    info = json.load(open(os.path.join(out, "lab2_shots.json")))
    assert [s["name"] for s in t["shots"]] == ["a", "b"] and t["seed"] == 11
    for s, p in zip(t["shots"], POSES):
        assert np.allclose(s["pose"]["rotation_deg"], p["pose"]["rotation_deg"], atol=1e-9)
        assert np.allclose(s["pose"]["translation_mm"], p["pose"]["translation_mm"], atol=1e-9)
    # the drawn specimen: lab2's usual drift, valid, imperfections recorded; it is the truth
    pm = physical.model("bracket")
    assert not pm.check(info["dimensions"]) and info["dimensions"] != pm.nominal
    assert t["part"]["dimensions"] == info["dimensions"]
    assert 0.5 <= info["imperfections"]["fillet_radius_mm"] <= 1.5
    assert os.path.isfile(os.path.join(out, "physical_part.json"))
    # exposure order: a after a rest, b with a's lag
    assert [(r["name"], r["previous"]) for r in info["exposure_order"]] == [("a", None), ("b", "a")]
    for f in ("a.tif", "b.tif", "dark.tif", "flat.tif", "normalized/a.tif"):
        assert os.path.isfile(os.path.join(out, f)), f
    raw = tiffio.read(os.path.join(out, "a.tif"))
    assert raw.dtype == np.uint16 and raw.shape == (216, 200)
    n = tiffio.read(os.path.join(out, "normalized", "a.tif"))
    x, y, w, h = t["white_region"]
    assert abs(n[y:y + h, x:x + w].mean() - 1.0) < 1e-6
    # the base plate (4 mm of aluminium) seen face-on between the upright and the first hole (part (8, 18)):
    # darker than the open beam, not opaque
    M = 1000.0 / (1000.0 - 362.0)
    u, v = int(100 + (-30.0 + 8.0) * M), int(108 - (-12.5 + 18.0) * M)
    assert 0.3 < n[v, u] < 0.95
    # the same seed gives the same files; another seed other noise (and another specimen)
    out2 = shoot(machine_dir, tmp_path, "s2", 11)
    assert np.array_equal(tiffio.read(os.path.join(out2, "b.tif")), tiffio.read(os.path.join(out, "b.tif")))
    out3 = shoot(machine_dir, tmp_path, "s3", 12, specimen="nominal")
    assert not np.array_equal(tiffio.read(os.path.join(out3, "a.tif")), raw)
    assert json.load(open(os.path.join(out3, "truth.json")))["part"]["dimensions"] == pm.nominal


def test_bad_poses(machine_dir, tmp_path):
    p = os.path.join(str(tmp_path), "poses.json")
    with open(p, "w") as f:
        json.dump([{"name": "a", "pose": {"rotation_deg": [0, 0]}}], f)
    assert cli.main(["shots", machine_dir, "--part", "bracket", "--poses", p, "-o", str(tmp_path / "x"),
                     "--seed", "1"]) == 1
    assert not os.path.exists(str(tmp_path / "x"))
