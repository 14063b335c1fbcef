"""Measured parts: physical specimens (closed forms of their imperfections),
the rotated shot's pose, the stated inputs' spread, and a tiny session's
datasets, jobs and verify jobs."""

import copy
import json
import math
import os

import numpy as np
import pytest

from lab2 import grid, measured, physical, stated
from lab2.partmodel import rotation_matrix
from lab2.scene import Scene
from lab2.session import Machine, Session

BRACKET = physical.model("bracket").nominal
SHAFT = physical.model("shaft").nominal
ZERO_BRACKET = {"fillet_radius_mm": 0.0, "holes": {}}
ZERO_SHAFT = {"small_section_offset_mm": [0.0, 0.0, 0.0], "cross_hole_offset_z_mm": 0.0}


def trace_one(root, S, D):
    p, _ = Scene(root).trace(np.asarray(S, float), np.atleast_2d(np.asarray(D, float)))
    return float(p[0])


def test_fillet_chord_and_area():
    r = 1.2
    T, W = BRACKET["thickness"], BRACKET["width"]
    _, root = physical.physical_part("bracket", BRACKET, {"fillet_radius_mm": r, "holes": {}})
    zs = T + (np.arange(400) + 0.5) / 400 * r
    chords = np.array([trace_one(root, [-50.0, W / 2, z], [1, 0, 0]) for z in zs]) - T
    exact = r - np.sqrt(r * r - (T + r - zs) ** 2)
    assert np.abs(chords - exact).max() < 1e-9
    area = chords.sum() * r / 400  # midpoint rule
    assert area == pytest.approx(physical.fillet_area(r), rel=2e-4)
    # above the fillet the upright alone
    assert trace_one(root, [-50.0, W / 2, T + r + 0.01], [1, 0, 0]) == pytest.approx(T, abs=1e-9)


@pytest.mark.parametrize("kind,dims,zero", [("bracket", BRACKET, ZERO_BRACKET), ("shaft", SHAFT, ZERO_SHAFT)])
def test_physical_without_imperfections_is_the_model(kind, dims, zero):
    _, phys = physical.physical_part(kind, dims, zero)
    model = physical.model(kind).build(dims)
    rng = np.random.default_rng(5)
    R = rotation_matrix(*rng.uniform(-60, 60, 3))
    t = np.array([3.0, -4.0, 400.0])
    S = np.array([0.0, 0.0, 1000.0])
    bb = Scene(model, R, t).bbox_corners_world()
    P = bb.min(0) + rng.uniform(0, 1, (3000, 3)) * (bb.max(0) - bb.min(0))
    D = P - S
    D /= np.linalg.norm(D, axis=1)[:, None]
    a, _ = Scene(phys, R, t).trace(S, D)
    b, _ = Scene(model, R, t).trace(S, D)
    assert (b > 0).sum() > 1000
    assert np.abs(a - b).max() < 1e-9


def test_tilted_hole_is_straight_through():
    R = rotation_matrix(0.35, -0.4, 0.0)
    imp = {"fillet_radius_mm": 0.0, "holes": {"base_hole_1": {"rotate_deg": [0.35, -0.4, 0.0]}}}
    _, root = physical.physical_part("bracket", BRACKET, imp)
    d, T, W, c = BRACKET["hole_diameter"], BRACKET["thickness"], BRACKET["width"], BRACKET["hole_position"]
    ax = R[:, 2]
    centre = np.array([c, W / 2, T / 2])
    perp = np.cross(ax, [0.0, 1.0, 0.0])
    perp /= np.linalg.norm(perp)
    for off, want in ((0.0, 0.0), (d / 2 - 0.01, 0.0), (d / 2 + 0.01, T / ax[2])):
        assert trace_one(root, centre + off * perp - 30 * ax, ax) == pytest.approx(want, abs=1e-9)
    # along the nominal axis, near the hole's wall, the tilt shows
    off = d / 2 - 0.005
    p = trace_one(root, centre + np.array([off, 0, -30.0]), [0, 0, 1])
    assert p > 0.0


def test_eccentric_small_section():
    ex, ez = 0.04, -0.03
    _, root = physical.physical_part("shaft", SHAFT, {**ZERO_SHAFT, "small_section_offset_mm": [ex, 0.0, ez]})
    r2, y = SHAFT["small_diameter"] / 2, SHAFT["large_length"] + 10.0
    for x in (ex, ex + 3.0, ex - r2 + 0.002):
        assert trace_one(root, [x, y, -50.0], [0, 0, 1]) == pytest.approx(2 * math.sqrt(r2 * r2 - (x - ex) ** 2), abs=1e-9)
    for z in (ez + 1.0, ez - 5.0):
        assert trace_one(root, [-50.0, y, z], [1, 0, 0]) == pytest.approx(2 * math.sqrt(r2 * r2 - (z - ez) ** 2), abs=1e-9)


def test_draws_are_valid_and_in_range():
    for kind in physical.KINDS:
        pm = physical.model(kind)
        for s in range(30):
            rng = np.random.default_rng([s, 7])
            d = physical.draw_dimensions(kind, rng)
            assert not pm.check(d)
            imp = physical.draw_imperfections(kind, rng)
            if kind == "bracket":
                assert 0.5 <= imp["fillet_radius_mm"] <= 1.5
                assert all(0 <= h["tilt_deg"] <= 0.6 + 1e-9 for h in imp["holes"].values())
            if kind == "shaft":
                e = np.hypot(*imp["small_section_offset_mm"][::2])
                assert 0.01 - 1e-6 <= e <= 0.05 + 1e-6 and imp["cross_hole_tilt_deg"] <= 0.6 + 1e-9
            if kind != "screw":  # the screw's solid needs the external builder: tests/test_screw.py
                physical.physical_part(kind, d, imp)  # builds (the prism's mesh is checked closed)
            start, bounds = measured.start_bounds(pm, d)
            assert not pm.check(start)
            for k, v in d.items():
                assert bounds[k][0] <= v <= bounds[k][1]
                assert start[k] * 2 == round(start[k] * 2) or k == "thin_end"


@pytest.mark.parametrize("name,rel", [("caliper", None), ("lag", 0.1), ("weight", 0.05), ("sigma", 0.1), ("cmm", None)])
def test_stated_inputs_errors_match_their_u(name, rel):
    rng = np.random.default_rng(2024)
    z = []
    for _ in range(4000):
        if name == "caliper":
            v = stated.caliper({"a": 20.0, "b": 0.2}, rng)
            z += [(v["a"] - 20.0) / stated.CALIPER_U_MM, (v["b"] - 0.2) / stated.CALIPER_U_MM]
        elif name == "lag":
            v = stated.lag(0.004, rng)
            assert v["u"] == pytest.approx(rel * 0.004)
            z.append((v["value"] - 0.004) / v["u"])
        elif name in ("weight", "sigma"):
            v = stated.halo(0.139, 50.0, rng)
            if name == "weight":
                assert v["weight_uncertainty"] == pytest.approx(rel * 0.139)
                z.append((v["weight"] - 0.139) / v["weight_uncertainty"])
            else:
                assert v["sigma_uncertainty_mm"] == pytest.approx(rel * 50.0)
                z.append((v["sigma_mm"] - 50.0) / v["sigma_uncertainty_mm"])
        else:
            c, u = stated.certificate({"a": 10.0}, rng)
            assert 0.001 <= u <= 0.003
            z.append((c["a"]["value"] - 10.0) / u)
    z = np.array(z)
    # 4000+ draws: mean within 4 standard errors, the spread within 5 % (rounding of the stated values included)
    assert abs(z.mean()) < 4 / math.sqrt(len(z))
    assert 0.95 < z.std() < 1.05
    assert 0.93 < np.mean(np.abs(z) < 2) / 0.9545 < 1.03


# ----------------------------------------------------------------------
TINY = copy.deepcopy(grid.machine("m06"))
TINY.update(id="tinyp", seed=7, description="tiny parts test machine")
TINY["geometry"] = {"sdd_mm": 1000.0, "columns": 200, "rows": 216, "pitch_mm": [1.0, 1.0],
                    "principal_point_px": [99.4, 110.1]}
TINY["wedge"] = {"fill": 0.55}
TINY["frames"] = {"darks": 2, "flats": 2}
TINY["prism"]["magnification"] = 1.6


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    d = tmp_path_factory.mktemp("parts")
    s = Session(Machine(copy.deepcopy(TINY)), str(d / "tinyp"), parts=["bracket"], masters=3, log=lambda *a: None)
    truth = s.run()
    return str(d / "tinyp"), truth, s


def test_rotated_pose_is_the_stage_rotation(session):
    root, truth, s = session
    run = measured.PartRun(s, "shaft")
    rng = np.random.default_rng(11)
    for _ in range(20):
        base = measured.base_rotation("shaft", rng)
        pl = run.placement(SHAFT, 500.0, base, rng)
        (_, R0, t0), (_, R1, t1), (_, R2, t2) = pl["poses"]
        Q = R2 @ R0.T
        ang = math.degrees(math.acos((np.trace(Q) - 1) / 2))
        assert ang == pytest.approx(pl["angle_deg"], abs=1e-7)
        w, V = np.linalg.eig(Q)
        ax = np.real(V[:, np.argmin(np.abs(w - 1))])
        assert abs(abs(ax @ pl["stage_axis"]) - 1) < 1e-9
        tilt = math.degrees(math.acos(abs(pl["stage_axis"][1])))
        assert 2 - 1e-9 <= tilt <= 10 + 1e-9
        # turned in place: the bounding-box centre stays where t00 had it; t01 is 10 mm along the axis
        c = pl["cpart"]
        assert np.allclose(R2 @ c + t2, R0 @ c + t0, atol=1e-9)
        assert np.allclose(R1, R0) and np.linalg.norm(t1 - t0) == pytest.approx(measured.STEP_MM, abs=1e-12)
        e = measured.euler_near(R2, base)
        assert np.allclose(rotation_matrix(*e), R2, atol=1e-9)


def test_parts_datasets_and_jobs(session):
    root, truth, s = session
    prod = os.path.join(root, "measured", "bracket")
    t = json.load(open(os.path.join(prod, "truth.json")))
    assert [(x["name"], x["pattern"]) for x in t["shots"]] == [("t00", "free"), ("t01", "translated"), ("r00", "rotated")]
    r00 = t["shots"][2]
    M0 = np.array(t["shots"][0]["pose"]["matrix"]).reshape(4, 4)
    M2 = np.array(r00["pose"]["matrix"]).reshape(4, 4)
    rec = truth["measured"]["bracket"]
    ang = math.degrees(math.acos((np.trace(M2[:3, :3] @ M0[:3, :3].T) - 1) / 2))
    assert ang == pytest.approx(rec["production"]["rotation_angle_deg"], abs=1e-6)
    assert r00["nominal_angle_deg"] == pytest.approx(ang, abs=0.05)
    assert t["part"]["dimensions"] == rec["dimensions"]
    phys = json.load(open(os.path.join(prod, "physical_part.json")))
    assert phys["shape"]["type"] == "difference"
    ms = json.load(open(os.path.join(root, "machine_stated.json")))
    st = truth["stated_inputs"]
    assert ms["detector"]["lag_fraction"] == st["lag_fraction"]["value"]
    assert ms["uncertainty"]["lag_fraction"] == st["lag_fraction"]["u"]
    cw = json.load(open(os.path.join(root, "wedge", "calibrate_wedge.json")))
    assert cw["wedge"]["dimensions"] == st["caliper"]["values"] and cw["wedge"]["dimension_uncertainty_mm"] == 0.01
    exposed = [f["frame"] for f in truth["exposure_order"]]
    for sub in ("bracket", "bracket_master/set0", "bracket_master/set2"):
        i = exposed.index(f"{sub}/t00")
        assert exposed[i + 1:i + 3] == [f"{sub}/t01", f"{sub}/r00"]
        folder = os.path.join(root, "measured", sub)
        ts = json.load(open(os.path.join(folder, "truth.json")))
        for nm, n in (("pair", 2), ("pair_rotated", 3)):
            job = json.load(open(os.path.join(folder, f"job_{nm}.json")))
            assert [r["name"] for r in job["radiographs"]] == ["t00", "t01", "r00"][:n]
            assert job["machine"].endswith("machine_stated.json")
            assert os.path.isfile(os.path.join(folder, job["machine"]))
            assert job["scatter"]["weight"] == st["halo"]["weight"]
            for k, v in ts["part"]["dimensions"].items():
                lo, hi = job["dimensions"]["bounds"][k]
                assert lo <= job["dimensions"]["start"][k] <= hi and lo <= v <= hi
                assert job["dimensions"]["start"][k] * 2 == round(job["dimensions"]["start"][k] * 2)
            pb = job["pose_bounds"]
            e0 = None
            for shot in ts["shots"][:n]:
                if shot["pattern"] == "translated":
                    continue
                M = np.array(shot["pose"]["matrix"]).reshape(4, 4)
                e = measured.euler_near(M[:3, :3], shot["pose"]["rotation_deg"] if e0 is None else e0)
                e0 = e0 or e
                assert all(lo <= v <= hi for v, (lo, hi) in zip(e, pb["rotation_deg"])), (sub, nm, e, pb)
            job_t = json.load(open(os.path.join(folder, f"job_{nm}_true_material.json")))
            assert os.path.isfile(os.path.join(folder, job_t["material"]))
    for nm in ("pair", "pair_rotated"):
        v = json.load(open(os.path.join(root, "measured", "bracket_master", f"verify_{nm}.json")))
        assert len(v["measurements"]) == 3
        cert = v["master"]["certificate"]
        assert set(cert) == set(rec["master"]["dimensions"])
        for j in v["measurements"]:
            job = json.load(open(os.path.join(root, "measured", "bracket_master", j)))
            assert job["part"] == rec["model"]
        pv = json.load(open(os.path.join(prod, f"job_{nm}_verified.json")))
        assert pv["verification"] == f"../bracket_master/verification_{nm}/verification.json"


def test_several_master_specimens_each_drawn_on_its_own(tmp_path):
    """--master-specimens: each master specimen has its own dimensions,
    imperfections and certificate, and the verification job lists them as
    "masters", each with its own shot sets' jobs."""
    root = str(tmp_path / "tinym")
    s = Session(Machine(copy.deepcopy(TINY)), root, parts=["prism"], masters=1, master_specimens=2,
                log=lambda *a: None)
    rec = s.run()["measured"]["prism"]["master"]
    first, second = rec["specimens"]
    assert first["folders"] == ["set0"] and second["folders"] == ["m1set0"]
    assert first["dimensions"] != second["dimensions"]
    assert rec["dimensions"] == first["dimensions"]
    mroot = os.path.join(root, "measured", "prism_master")
    for nm in ("pair", "pair_rotated"):
        v = json.load(open(os.path.join(mroot, f"verify_{nm}.json")))
        assert "master" not in v and "measurements" not in v
        assert [m["measurements"] for m in v["masters"]] == [[f"set0/job_{nm}.json"], [f"m1set0/job_{nm}.json"]]
        assert [m["certificate"] for m in v["masters"]] == [first["certificate"], second["certificate"]]
        for m in v["masters"]:
            job = os.path.join(mroot, m["measurements"][0])
            assert os.path.isfile(job)
            t = json.load(open(os.path.join(os.path.dirname(job), "truth.json")))
            spec = first if m is v["masters"][0] else second
            assert t["part"]["dimensions"] == spec["dimensions"]


def test_upright_chamfer_chord():
    """A ray along y at (x, z) on the upright's outer top corner meets no
    material where x + (H - z) < c, the whole width W elsewhere."""
    c = 0.5
    H, W = BRACKET["height"], BRACKET["width"]
    _, root = physical.physical_part("bracket", BRACKET, {**ZERO_BRACKET, "upright_chamfer_mm": c})
    _, plain = physical.physical_part("bracket", BRACKET, ZERO_BRACKET)
    for x, z in ((0.1, H - 0.1), (0.2, H - 0.25), (0.3, H - 0.1), (0.05, H - 0.6), (0.26, H - 0.26)):
        cut = x + (H - z) < c
        assert trace_one(root, [x, -50.0, z], [0, 1, 0]) == pytest.approx(0.0 if cut else W, abs=1e-9)
        assert trace_one(plain, [x, -50.0, z], [0, 1, 0]) == pytest.approx(W, abs=1e-9)


@pytest.mark.parametrize("profile", physical.DEFECT_PROFILES)
def test_defect_profiles_draw_their_ranges(profile, monkeypatch):
    monkeypatch.setattr(physical, "defect_profile", profile)
    rng = np.random.default_rng(11)
    for _ in range(50):
        b, s = physical.draw_imperfections("bracket", rng), physical.draw_imperfections("shaft", rng)
        if profile == "none":
            assert b == {} and s == {}
            continue
        lo_r, lo_t, hi_t, lo_e, hi_e = (1.0, 0.5, 1.0, 0.05, 0.1) if profile == "strong" else (0.5, 0.0, 0.6, 0.01, 0.05)
        assert lo_r <= b["fillet_radius_mm"] <= 1.5
        assert all(lo_t - 1e-4 <= h["tilt_deg"] <= hi_t + 1e-4 for h in b["holes"].values())
        assert ("upright_chamfer_mm" in b) == (profile == "strong")
        e = math.hypot(*s["small_section_offset_mm"])
        assert lo_e - 1e-4 <= e <= hi_e + 1e-4
        assert lo_t - 1e-4 <= s["cross_hole_tilt_deg"] <= hi_t + 1e-4
