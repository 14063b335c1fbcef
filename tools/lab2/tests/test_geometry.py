"""Closed-form paths through exact solids and their CSG combinations."""

import math
import os

import numpy as np
import pytest

from lab2 import expr
from lab2 import geometry as G
from lab2.partmodel import Node, PartModel, rotation_matrix
from lab2.scene import Scene

PARTS = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", "parts"))
S = np.array([0.0, 0.0, 1000.0])


def unit(v):
    v = np.atleast_2d(np.asarray(v, float))
    return v / np.linalg.norm(v, axis=1)[:, None]


@pytest.mark.parametrize("tilt", [0.0, 10.0, 33.3, 60.0, 75.0])
def test_tilted_plate_path_is_t_over_cos(tilt):
    t = 3.7
    plate = Node("leaf", solid=G.Box([-4000, -4000, -t / 2], [4000, 4000, t / 2]))
    R = rotation_matrix(tilt, 0, 0)
    sc = Scene(plate, R, [0.0, 0.0, 500.0])
    rng = np.random.default_rng(1)
    D = unit(np.column_stack([rng.uniform(-0.2, 0.2, 50), rng.uniform(-0.2, 0.2, 50), -np.ones(50)]))
    path, _ = sc.trace(S, D)
    n = R @ np.array([0.0, 0.0, 1.0])
    expected = t / np.abs(D @ n)
    assert np.max(np.abs(path - expected)) < 1e-9


def test_cylinder_chord():
    r = 10.0
    cyl = Node("leaf", solid=G.Cylinder(1, r, -30.0, 30.0))
    sc = Scene(cyl, np.eye(3), [0.0, 0.0, 600.0])
    # rays perpendicular to the axis (y = 0 plane); distance of the line to the axis
    x_det = np.linspace(-30.0, 30.0, 241)
    D = unit(np.column_stack([x_det, np.zeros_like(x_det), -np.full_like(x_det, 1000.0)]))
    path, _ = sc.trace(S, D)
    # distance from the axis point (0, ., 600) to the line through S along D (in the x-z plane)
    v = np.array([0.0, 0.0, 600.0]) - S
    d = np.abs(np.cross(D[:, [0, 2]], v[[0, 2]]))
    chord = 2.0 * np.sqrt(np.clip(r * r - d * d, 0.0, None))
    assert np.max(np.abs(path - chord)) < 1e-9
    assert (path > 0).sum() > 50


def test_cylinder_oblique_to_axis():
    """A ray in a plane containing the axis' perpendicular, tilted along the
    axis: chord / sin(angle to the axis)."""
    r = 5.0
    cyl = Node("leaf", solid=G.Cylinder(1, r, -2000.0, 2000.0))
    sc = Scene(cyl, np.eye(3), [0.0, 0.0, 500.0])
    for d, tilt in [(0.0, 0.2), (2.5, 0.3), (4.9, -0.25)]:
        D = unit([d / 500.0 * 0 + 0.0, tilt, -1.0])
        # shift the cylinder so the ray passes at distance d from its axis
        sc = Scene(cyl, np.eye(3), [d, 0.0, 500.0])
        path, _ = sc.trace(S, D)
        perp = math.hypot(D[0, 0], D[0, 2])
        assert abs(path[0] - 2 * math.sqrt(r * r - d * d) / perp) < 1e-9


def test_plate_with_cylindrical_hole():
    t, r = 4.0, 3.3
    shape = Node("difference", [Node("leaf", solid=G.Box([-20, -20, 0], [20, 20, t])),
                                Node("leaf", solid=G.Cylinder(2, r, -1.0, t + 1.0))])
    sc = Scene(shape, np.eye(3), [0.0, 0.0, 400.0])
    # rays along -z through and beside the hole (the source on the axis: nearly parallel rays)
    x = np.array([0.0, 1.0, 3.2, 3.4, 10.0])
    D = unit(np.column_stack([x / 600.0, np.zeros_like(x), -np.ones_like(x)]))
    path, _ = sc.trace(S, D)
    for xi, p, d in zip(x, path, D):
        # where the ray crosses z = 400 .. 404 it is at radius |x| * (600 - dz)/600
        r_top, r_bot = xi * (600 - 4) / 600, xi
        if r_bot < r and r_top < r:
            assert p == pytest.approx(0.0, abs=1e-12)
        elif r_bot > r and r_top > r:
            assert p == pytest.approx(t / abs(d[2]), abs=1e-9)
    # a ray along x inside the plate: the plate's length minus the hole's chord
    src = np.array([-100.0, 1.5, 402.0])
    p, _ = sc.trace(src, unit([1.0, 0.0, 0.0]))
    assert p[0] == pytest.approx(40.0 - 2 * math.sqrt(r * r - 1.5 ** 2), abs=1e-9)


def test_mesh_watertight_through_edges_and_vertices():
    """The cuboid mesh (12 triangles with face diagonals): rays exactly through
    its vertices, edges and face diagonals count each crossing once."""
    pm = PartModel(os.path.join(PARTS, "cuboid.json"))
    mesh = pm.build()
    box = Node("leaf", solid=G.Box([-10, -15, -5], [10, 15, 5]))
    for rot in [(0, 0, 0), (0, 0, 45), (30, 20, 10)]:
        a = Scene.from_pose(mesh, rot, (0, 0, 500))
        b = Scene.from_pose(box, rot, (0, 0, 500))
        corners = a.bbox_corners_world()
        targets = np.concatenate([corners, 0.5 * (corners[:-1] + corners[1:]), [[0, 0, 500.0]]])
        D = unit(targets - S)
        pa, _ = a.trace(S, D)
        pb, _ = b.trace(S, D)
        assert np.max(np.abs(pa - pb)) < 1e-9
    # a ray along the face diagonal of the axis-aligned box's top face
    sc = Scene.from_pose(mesh, (0, 0, 0), (0, 0, 500))
    D = unit([[0.0, 0.0, -1.0]])
    assert sc.trace(S, D)[0][0] == pytest.approx(10.0, abs=1e-12)


def test_extrusion_equals_its_mesh_and_cylinder_equals_revolution():
    from lab2 import imperfect
    d = dict(width=20.977, groove_center=10.438, thickness=13.02, groove_depth=6.923, groove_left=6.848,
             groove_right=6.963, slot_width=4.104, slot_depth=3.951)
    ext = PartModel(os.path.join(PARTS, "prism_jaw.json")).build(d)
    V, T = imperfect.physical_prism(d, {})
    mesh = Node("leaf", solid=G.Mesh(V, T))
    rng = np.random.default_rng(3)
    D = unit(np.column_stack([rng.normal(0, 0.03, 4000), rng.normal(0, 0.03, 4000), -np.ones(4000)]))
    for rot in [(0, 0, 0), (5, 40, -3), (90, 0, 0)]:
        pa, _ = Scene.from_pose(ext, rot, (-10, -20, 600)).trace(S, D)
        pb, _ = Scene.from_pose(mesh, rot, (-10, -20, 600)).trace(S, D)
        assert np.max(np.abs(pa - pb)) < 1e-9
    rev = PartModel(os.path.join(PARTS, "cylinder.json")).build()
    cyl = Node("leaf", solid=G.Cylinder(1, 10.0, -15.0, 15.0))
    for rot in [(0, 0, 0), (20, 10, 70), (90, 0, 0)]:
        pa, _ = Scene.from_pose(rev, rot, (0, 0, 600)).trace(S, D)
        pb, _ = Scene.from_pose(cyl, rot, (0, 0, 600)).trace(S, D)
        assert np.max(np.abs(pa - pb)) < 1e-9


def test_stepped_shaft_and_cone():
    """A revolution with a step and a cone, along the axis and across it."""
    rev = Node("leaf", solid=G.Revolution(2, [[0, 0], [10, 0], [10, 30], [6, 30], [2, 40], [0, 40]]))
    sc = Scene(rev, np.eye(3), [0, 0, 0])
    src = np.array([0.0, 0.0, 100.0])
    for rho in [0.0, 1.0, 5.0, 8.0]:
        p, _ = sc.trace(np.array([rho, 0.0, 100.0]), unit([0, 0, -1.0]))
        # along the axis at radius rho: 30 mm of the large section plus the cone where r(z) > rho
        cone = 10.0 * (6.0 - rho) / 4.0 if rho < 6 else 0.0
        cone = min(max(cone, 0.0), 10.0)
        assert p[0] == pytest.approx(30.0 + cone if rho < 10 else 0.0, abs=1e-9)
    p, _ = sc.trace(np.array([-100.0, 3.0, 15.0]), unit([1.0, 0, 0]))
    assert p[0] == pytest.approx(2 * math.sqrt(100 - 9), abs=1e-9)
    del src


def test_expressions():
    assert expr.evaluate("2 + 3 * 4 ^ 2") == 50.0
    assert expr.evaluate("-2^2") == -4.0
    assert expr.evaluate("2^3^2") == 512.0
    assert expr.evaluate("a > 1 ? a : -a", {"a": -3.0}) == 3.0
    assert expr.evaluate("min(1, 2, -3) + max(4, 5)") == 2.0
    assert expr.evaluate("sind(30) + cosd(60)") == pytest.approx(1.0)
    assert expr.evaluate("atan2d(1, 1)") == pytest.approx(45.0)
    assert expr.evaluate("x == 2 && y != 3 || 0", {"x": 2, "y": 4}) == 1.0
    assert expr.evaluate("pi") == math.pi
    for bad in ["a = 1", "__import__('os')", "x.y", "unknown(1)", "1 +", "(1"]:
        with pytest.raises(expr.ExpressionError):
            expr.evaluate(bad, {"a": 1.0, "x": 1.0})
