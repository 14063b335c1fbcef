"""The screw, a measured part given by its CAD file: its model read for the
dimensions only, its draws, the external OpenCASCADE builder's call (a fake
builder here: a box, so no C++ build is needed), the missing builder's
error, the large-mesh tracer and a tiny session with the screw."""

import copy
import json
import math
import os
import sys

import numpy as np
import pytest

from lab2 import cli, grid, measured, physical
from lab2 import geometry as G
from lab2 import partmodel
from lab2.partmodel import Node, rotation_matrix
from lab2.scene import Scene
from lab2.session import Machine, Session

SCREW_JSON = os.path.join(physical.REPO, "examples", "screw", "screw.json")

# A stand-in for screw_solid: a box x in [0, shank_diameter], y in [0, slot_width], z in [7.936 - length, 7.936],
# written as a closed outward binary STL; every call's argv appended to calls.jsonl next to the script.
FAKE = r'''#!{python}
import json, os, struct, sys
vals = {{"slot_width": 2.5, "slot_depth": 5.0, "shank_diameter": 10.0, "length": 42.5, "shank_offset": 0.0}}
a, stl, i = sys.argv[1:], None, 0
while i < len(a):
    if a[i] == "--set":
        k, v = a[i + 1].split("=")
        vals[k] = float(v)
    elif a[i] == "--stl":
        stl = a[i + 1]
    i += 2
with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "calls.jsonl"), "a") as f:
    f.write(json.dumps({{"argv": sys.argv, "cwd": os.getcwd()}}) + "\n")
lo, hi = [0.0, 0.0, 7.936 - vals["length"]], [vals["shank_diameter"], vals["slot_width"], 7.936]
P = [[(hi if (m >> k) & 1 else lo)[k] for k in range(3)] for m in range(8)]
tris = []
for p, q, r, s in [(0, 2, 6, 4), (1, 5, 7, 3), (0, 4, 5, 1), (2, 3, 7, 6), (0, 1, 3, 2), (4, 6, 7, 5)]:
    tris += [(p, r, q), (p, s, r)]
with open(stl, "wb") as f:
    f.write(bytes(80) + struct.pack("<I", len(tris)))
    for t in tris:
        f.write(struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *P[v]) for v in t) + bytes(2))
'''


@pytest.fixture
def fake_builder(tmp_path, monkeypatch):
    d = tmp_path / "builder"
    d.mkdir()
    exe = d / "fake_screw_solid"
    exe.write_text(FAKE.format(python=sys.executable))
    exe.chmod(0o755)
    monkeypatch.setenv(physical.SCREW_SOLID_ENV, str(exe))
    monkeypatch.setattr(physical, "_SCREW_CACHE", {})

    def calls():
        p = d / "calls.jsonl"
        return [json.loads(x) for x in p.read_text().splitlines()] if p.exists() else []
    return str(exe), calls


def test_screw_model_reads_the_dimensions_without_the_step_shape(monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("the screw's shape must not be parsed")
    monkeypatch.setattr(partmodel, "build_shape", refuse)
    monkeypatch.setattr(physical, "build_shape", refuse)
    pm = physical.model("screw")
    doc = json.load(open(SCREW_JSON))
    assert doc["shape"]["type"] == "step" and pm.shape_type == "step"
    assert pm.path == os.path.abspath(SCREW_JSON)
    assert pm.dimensions == [x["name"] for x in doc["dimensions"]]
    assert pm.dimensions == ["slot_width", "slot_depth", "shank_diameter", "length", "shank_offset"]
    for x in doc["dimensions"]:
        assert pm.nominal[x["name"]] == x["nominal"] and pm.bounds[x["name"]] == (x["min"], x["max"])
    assert pm.check(pm.nominal) == [] and pm.valid(pm.nominal)
    assert pm.check({"slot_width": 3.2}) and not pm.valid({"shank_offset": -0.5})
    with pytest.raises(partmodel.PartError):
        pm.check({"head_diameter": 20.0})
    monkeypatch.undo()
    # lab2's own reader does not understand a "step" shape (and is not taught to)
    with pytest.raises(partmodel.PartError, match="unknown shape type 'step'"):
        partmodel.PartModel(SCREW_JSON).build()


def test_screw_draws_within_bounds_and_deterministic():
    pm = physical.model("screw")
    seen = []
    for s in range(300):
        d = physical.draw_dimensions("screw", np.random.default_rng([s, 7]))
        assert d == physical.draw_dimensions("screw", np.random.default_rng([s, 7]))
        assert set(d) == set(pm.nominal) and pm.valid(d)
        assert physical.draw_imperfections("screw", np.random.default_rng(s)) == {}
        for k, v in d.items():
            assert pm.bounds[k][0] < v < pm.bounds[k][1]
            assert abs(v - pm.nominal[k]) <= physical.SCREW_SPREAD_MM[k] + 1e-9
        start, bounds = measured.start_bounds(pm, d)
        assert pm.valid(start)
        assert start["shank_offset"] == 0.0 and math.copysign(1.0, start["shank_offset"]) == 1.0
        for k, v in d.items():
            assert start[k] * 2 == round(start[k] * 2)
            assert bounds[k][0] <= v <= bounds[k][1] and bounds[k][1] - bounds[k][0] <= 2.0
            assert pm.bounds[k][0] <= bounds[k][0] and bounds[k][1] <= pm.bounds[k][1]
        seen.append([d[k] - pm.nominal[k] for k in pm.dimensions])
    seen = np.array(seen)
    spread = np.array([physical.SCREW_SPREAD_MM[k] for k in pm.dimensions])
    assert np.all(seen.max(0) > 0.8 * spread) and np.all(seen.min(0) < -0.8 * spread)


def test_builder_called_with_the_drawn_values_and_its_stl_rendered(fake_builder, tmp_path):
    exe, calls = fake_builder
    d = physical.draw_dimensions("screw", np.random.default_rng(11))
    folder = tmp_path / "spec"
    doc, root = physical.physical_part("screw", d, {}, folder=str(folder))
    (call,) = calls()
    argv = call["argv"]
    assert os.path.realpath(call["cwd"]) == os.path.realpath(folder)
    sets = [argv[i + 1] for i, a in enumerate(argv) if a == "--set"]
    assert sets == [f"{k}={d[k]!r}" for k in physical.model("screw").dimensions]
    assert {s.split("=")[0]: float(s.split("=")[1]) for s in sets} == d
    assert argv[argv.index("--stl") + 1] == physical.SCREW_STL
    assert float(argv[argv.index("--chord-tolerance-mm") + 1]) == physical.SCREW_CHORD_MM
    assert doc["builder"]["command"] == [exe] + argv[1:]
    assert doc["shape"] == {"type": "stl", "file": physical.SCREW_STL}
    assert {x["name"]: x["nominal"] for x in doc["dimensions"]} == d
    assert (folder / physical.SCREW_STL).is_file()
    # the STL is what is rendered: paths through the box are its sides (float32 in the STL)
    f32 = lambda v: float(np.float32(v))  # noqa: E731
    w, sw, L = f32(d["shank_diameter"]), f32(d["slot_width"]), f32(7.936) - f32(7.936 - d["length"])
    sc = Scene(root, rotation_matrix(0, 0, 0), [0.0, 0.0, 0.0])
    p, _ = sc.trace(np.array([-100.0, 1.0, -3.0]), np.array([[1.0, 0.0, 0.0]]))
    assert p[0] == pytest.approx(w, abs=1e-9)
    p, _ = sc.trace(np.array([2.0, -100.0, -3.0]), np.array([[0.0, 1.0, 0.0]]))
    assert p[0] == pytest.approx(sw, abs=1e-9)
    p, _ = sc.trace(np.array([2.0, 1.0, 100.0]), np.array([[0.0, 0.0, -1.0]]))
    assert p[0] == pytest.approx(L, abs=1e-9)
    # a tilted ray through the two large faces: thickness / cos
    th = math.radians(25.0)
    p, _ = sc.trace(np.array([5.0, -100.0 * math.cos(th) + 1.0, 100.0 * math.sin(th) - 10.0]),
                    np.array([[0.0, math.cos(th), -math.sin(th)]]))
    assert p[0] == pytest.approx(sw / math.cos(th), abs=1e-9)
    # the model's solid for the same values is that STL (no second build); another folder: the same files
    assert Scene(physical.model("screw").build(d)).bbox_corners_world().max(0)[0] == pytest.approx(w)
    assert len(calls()) == 1
    doc2, _ = physical.physical_part("screw", d, {}, folder=str(tmp_path / "again"))
    assert doc2 == doc
    assert (tmp_path / "again" / physical.SCREW_STL).read_bytes() == (folder / physical.SCREW_STL).read_bytes()


def test_missing_builder_gives_a_clear_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(physical, "_SCREW_CACHE", {})
    missing = str(tmp_path / "no" / "screw_solid")
    monkeypatch.setenv(physical.SCREW_SOLID_ENV, missing)
    d = physical.model("screw").nominal
    with pytest.raises(physical.ScrewBuilderError) as e:
        physical.physical_part("screw", d, {}, folder=str(tmp_path / "f"))
    assert physical.SCREW_SOLID_ENV in str(e.value) and missing in str(e.value)
    monkeypatch.delenv(physical.SCREW_SOLID_ENV)
    monkeypatch.setattr(physical, "SCREW_SOLID_DEFAULT", missing + "_default")
    with pytest.raises(physical.ScrewBuilderError) as e:
        physical.model("screw").build(d)
    assert physical.SCREW_SOLID_ENV in str(e.value) and missing + "_default" in str(e.value)
    # the command line stops before any frame is made
    assert cli.main(["machine", "m01", "-o", str(tmp_path / "out"), "--parts", "screw"]) == 2
    err = capsys.readouterr().err
    assert physical.SCREW_SOLID_ENV in err and missing + "_default" in err
    assert not (tmp_path / "out").exists()


def test_screw_base_rotation_lays_the_axis_across_the_beam():
    rng = np.random.default_rng(5)
    for _ in range(200):
        R = rotation_matrix(*measured.base_rotation("screw", rng))
        axis, slot_normal, run = R[:, 2], R[:, 1], R[:, 0]  # part z (axis), y (walls' normal), x (slot, offset)
        assert abs(axis[2]) < math.sin(math.radians(2.01))  # across the beam (world z)
        assert axis[1] > 0.98  # head up
        beam_to_walls = math.degrees(math.acos(abs(slot_normal[2])))  # 90 - angle between beam and normal
        assert 35 - 2.1 <= 90 - beam_to_walls <= 55 + 2.1
        assert math.hypot(run[0], run[1]) > math.sin(math.radians(32))  # shank_offset across the beam


def _revolved(profile, nseg):
    prof = np.asarray(profile, float)
    inner = prof[1:-1]
    V = [[0.0, 0.0, prof[0, 1]]]
    for r, z in inner:
        a = 2 * np.pi * np.arange(nseg) / nseg
        V += [[r * math.cos(x), r * math.sin(x), z] for x in a]
    V.append([0.0, 0.0, prof[-1, 1]])
    ring = lambda i, k: 1 + i * nseg + (k % nseg)  # noqa: E731
    last, T = len(V) - 1, []
    for k in range(nseg):
        T.append((0, ring(0, k), ring(0, k + 1)))
        for i in range(len(inner) - 1):
            a, b, c, d = ring(i, k), ring(i, k + 1), ring(i + 1, k), ring(i + 1, k + 1)
            T += [(a, d, b), (a, c, d)]
        T.append((last, ring(len(inner) - 1, k + 1), ring(len(inner) - 1, k)))
    return np.array(V), np.array(T)


def test_large_mesh_tracer_equals_the_small_one(monkeypatch):
    """A revolved mesh of 4,000+ triangles: the grid-culled, packed tracer of
    large meshes gives the same paths and signatures as the plain one, for
    random rays and rays through its vertices and edge midpoints; smooth
    grouping joins the facets of each smooth face."""
    dome = [(r, 5.4 + 2.5 * (1 - (r / 10) ** 2)) for r in np.linspace(1, 10, 6)]
    V, T = _revolved([(0, 7.9)] + dome + [(5, 0.4), (5, -30), (4, -34.6), (0, -34.6)], 200)
    big = G.Mesh(V, T)
    assert big.large and big.open_edges == 0
    from lab2 import imperfect
    assert imperfect.signed_volume(V, T) > 0
    monkeypatch.setattr(G, "LARGE_MESH", 10 ** 9)
    small = G.Mesh(V, T)
    assert not small.large
    assert np.array_equal(small.E, big.E) and np.array_equal(small.w, big.w)
    R, t = rotation_matrix(-88, 40, 5), np.array([1.0, 2.0, 500.0])
    S = np.array([0.0, 0.0, 1000.0])
    sa, sb = Scene(Node("leaf", solid=big), R, t), Scene(Node("leaf", solid=small), R, t)
    rng = np.random.default_rng(1)
    bb = sa.bbox_corners_world()
    Vw = V @ R.T + t
    P = np.concatenate([bb.min(0) + rng.uniform(0, 1, (3000, 3)) * (bb.max(0) - bb.min(0)),
                        Vw[::3], 0.5 * (Vw[big.E[::5, 0]] + Vw[big.E[::5, 1]])])
    P = P[np.lexsort((P[:, 0], np.round(P[:, 1])))]  # roughly compact batches, as the renderer's tiles
    D = P - S
    D /= np.linalg.norm(D, axis=1)[:, None]
    pa, ga = sa.trace(S, D)
    pb, gb = sb.trace(S, D)
    assert (pa > 0).sum() > 1000
    assert np.array_equal(pa, pb) or np.abs(pa - pb).max() < 1e-12
    assert np.abs(ga - gb).max() < 1e-9
    # along the axis (through the centre vertices): the whole length
    c = R @ np.array([0.0, 0.0, -13.0]) + t
    p, _ = sa.trace(S, ((c - S) / np.linalg.norm(c - S))[None])
    assert p[0] > 0
    # smooth faces: dome, countersink, shank, chamfer, tip face -> 5 groups (the dome's rings join)
    sm = G.Mesh(V, T, smooth_deg=10.0)
    assert len(np.unique(sm.w)) == 5


TINY = copy.deepcopy(grid.machine("m06"))
TINY.update(id="tinys", seed=9, description="tiny screw test machine")
TINY["geometry"] = {"sdd_mm": 1000.0, "columns": 200, "rows": 216, "pitch_mm": [1.0, 1.0],
                    "principal_point_px": [99.4, 110.1]}
TINY["wedge"] = {"fill": 0.55}
TINY["frames"] = {"darks": 2, "flats": 2}
TINY["prism"]["magnification"] = 1.6


def test_tiny_session_with_the_screw(fake_builder, tmp_path):
    exe, calls = fake_builder
    root = str(tmp_path / "tinys")
    truth = Session(Machine(copy.deepcopy(TINY)), root, parts=["screw"], masters=1, log=lambda *a: None).run()
    rec = truth["measured"]["screw"]
    assert rec["model"] == os.path.abspath(SCREW_JSON)
    for sub, dims in (("screw", rec["dimensions"]), ("screw_master/set0", rec["master"]["dimensions"])):
        folder = os.path.join(root, "measured", sub)
        t = json.load(open(os.path.join(folder, "truth.json")))
        assert t["part"] == {"model": os.path.abspath(SCREW_JSON), "dimensions": dims}
        phys = json.load(open(os.path.join(folder, "physical_part.json")))
        assert phys["shape"] == {"type": "stl", "file": "physical_screw.stl"}
        assert os.path.isfile(os.path.join(folder, "physical_screw.stl"))
        assert [f"{k}={v!r}" for k, v in dims.items()] == phys["builder"]["command"][2:11:2]
        for nm in ("pair", "pair_rotated"):
            job = json.load(open(os.path.join(folder, f"job_{nm}.json")))
            assert job["part"] == os.path.abspath(SCREW_JSON)
            assert job["dimensions"]["start"]["shank_offset"] == 0.0
            for k, v in dims.items():
                lo, hi = job["dimensions"]["bounds"][k]
                assert lo <= job["dimensions"]["start"][k] <= hi and lo <= v <= hi
    # one build for the bounding box (a temporary folder), then one per shot set's folder
    assert len(calls()) == 3
