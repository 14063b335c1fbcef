"""Measured parts as physical specimens: true dimensions drawn off nominal and
imperfections the part models lack, drawn per run.

Every physical part is written as a part-model file whose shape holds
numbers only (exact CSG of boxes and cylinders, or the prism's closed mesh),
so the file that is rendered is the file in the dataset
(``physical_part.json``); the truth's dimensions stay the model's.

- ``prism`` (Part 1, parts/prism_jaw.json): Prism A or B moved by up to
  0.1 mm per dimension; chamfers on the convex edges and a taper of the
  width (``imperfect.py``), a closed mesh.
- ``wedge`` (Part 2, parts/wedge_block.json): every dimension off nominal
  (walls and pocket edges by up to 0.3 mm, the thickness by up to 0.2 mm,
  the thin end 0.25 to 0.6 mm); no imperfection beyond that, rendered from
  the model itself at the true values.
- ``bracket`` (Part 5, parts/bracket.json): dimensions off Bracket A by up
  to 0.3 mm (diameters 0.1 mm); an inner fillet of radius r (0.5 to 1.5 mm)
  along the inner corner (x = T, z = T, along y: the material
  r^2 (1 - pi/4) per unit length that a bent or milled bracket keeps there);
  each of the three holes drilled off its axis by a tilt of up to 0.6 deg
  about its centre at mid-plate (the diameter and the position at
  mid-plate are the model's).
- ``shaft`` (Part 6, parts/stepped_shaft.json): dimensions off Shaft A by
  up to 0.3 mm (diameters 0.1 mm); the small section eccentric (its axis
  offset by 0.01 to 0.05 mm in a random direction), the cross hole off the
  axis (its axis passing 0 to 0.05 mm from it, along z) and tilted by up to
  0.6 deg.
"""

import math
import os


from . import imperfect
from .partmodel import PartModel, build_shape, rotation_matrix

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
PARTS = os.path.join(REPO, "parts")
MODEL_FILES = {"prism": "prism_jaw.json", "wedge": "wedge_block.json", "bracket": "bracket.json",
               "shaft": "stepped_shaft.json"}
KINDS = tuple(MODEL_FILES)
PRISM_A = {"width": 20.977, "groove_center": 10.438, "thickness": 13.020, "groove_depth": 6.923,
           "groove_left": 6.848, "groove_right": 6.963, "slot_width": 4.104, "slot_depth": 3.951}
PRISM_B = {"width": 20.951, "groove_center": 10.462, "thickness": 10.048, "groove_depth": 5.204,
           "groove_left": 5.101, "groove_right": 5.219, "slot_width": 3.052, "slot_depth": 2.903}


def model(kind):
    return PartModel(os.path.join(PARTS, MODEL_FILES[kind]))


def draw_dimensions(kind, rng, prism="A"):
    """True dimensions of one specimen, off nominal, within the model's
    bounds and constraints."""
    pm = model(kind)
    base = dict(pm.nominal)
    if kind == "prism":
        base = dict(PRISM_A if prism == "A" else PRISM_B)
    for _ in range(200):
        d = {}
        for k, v in base.items():
            if kind == "prism":
                s = 0.1
            elif kind == "wedge":
                s = 0.2 if k == "thickness" else 0.3
            else:
                s = 0.1 if "diameter" in k else 0.3
            d[k] = round(v + rng.uniform(-s, s), 4)
        if kind == "wedge":
            d["thin_end"] = round(rng.uniform(0.25, 0.6), 4)
        if all(pm.bounds[k][0] < v < pm.bounds[k][1] for k, v in d.items()) and not pm.check(d):
            return d
    raise ValueError(f"no valid {kind} dimensions drawn")


def _tilt(rng, max_deg, axis):
    """A rotation (Euler degrees, R = Rz Ry Rx) tilting `axis` ('x' or 'z')
    by up to max_deg in a random direction, and the tilt it makes."""
    th, ph = rng.uniform(0.0, max_deg), rng.uniform(0.0, 2 * math.pi)
    a, b = th * math.cos(ph), th * math.sin(ph)
    e = [round(a, 5), round(b, 5), 0.0] if axis == "z" else [0.0, round(a, 5), round(b, 5)]
    R = rotation_matrix(*e)
    k = 2 if axis == "z" else 0
    ang = math.degrees(math.acos(min(1.0, abs(R[k, k]))))
    return e, ang


def draw_imperfections(kind, rng):
    if kind == "prism":
        return imperfect.draw(rng)
    if kind == "wedge":
        return {}
    if kind == "bracket":
        out = {"fillet_radius_mm": round(rng.uniform(0.5, 1.5), 4), "holes": {}}
        for h, ax in (("base_hole_1", "z"), ("base_hole_2", "z"), ("upright_hole", "x")):
            e, ang = _tilt(rng, 0.6, ax)
            out["holes"][h] = {"rotate_deg": e, "tilt_deg": round(ang, 5)}
        return out
    if kind == "shaft":
        e = rng.uniform(0.01, 0.05)
        ph = rng.uniform(0.0, 2 * math.pi)
        te, ang = _tilt(rng, 0.6, "x")
        return {"small_section_offset_mm": [round(e * math.cos(ph), 5), 0.0, round(e * math.sin(ph), 5)],
                "cross_hole_offset_z_mm": round(rng.uniform(-0.05, 0.05), 5),
                "cross_hole_rotate_deg": te, "cross_hole_tilt_deg": round(ang, 5)}
    raise ValueError(kind)


def _cyl(axis, d, a0, a1, translate, rotate=None):
    s = {"type": "cylinder", "axis": axis, "diameter": float(d), "from": float(a0), "to": float(a1),
         "translate": [float(v) for v in translate]}
    if rotate is not None and any(rotate):
        s["rotate"] = [float(v) for v in rotate]
    return s


def _box(lo, hi):
    return {"type": "box", "min": [float(v) for v in lo], "max": [float(v) for v in hi]}


def physical_shape(kind, d, imp):
    """The physical specimen's shape (numbers only) in the model's frame."""
    if kind == "prism":
        V, T = imperfect.physical_prism(d, imp)
        return {"type": "mesh", "vertices": [[float(x) for x in v] for v in V],
                "triangles": [[int(i) for i in t] for t in T]}
    if kind == "bracket":
        L, H, W, T = d["base_length"], d["height"], d["width"], d["thickness"]
        r = imp.get("fillet_radius_mm", 0.0)
        holes = imp.get("holes", {})
        rot = lambda h: holes.get(h, {}).get("rotate_deg")  # noqa: E731
        plates = [_box([0, 0, 0], [L, W, T]), _box([0, 0, 0], [T, W, H])]
        if r > 0:
            plates.append({"type": "difference", "solids": [
                _box([T - 0.5, 0, T - 0.5], [T + r, W, T + r]),
                _cyl("y", 2 * r, -1.0, W + 1.0, [T + r, 0.0, T + r])]})
        c, s, hd = d["hole_position"], d["hole_spacing"], d["hole_diameter"]
        return {"type": "difference", "solids": [
            {"type": "union", "solids": plates},
            _cyl("z", hd, -(T / 2 + 1), T / 2 + 1, [c, W / 2, T / 2], rot("base_hole_1")),
            _cyl("z", hd, -(T / 2 + 1), T / 2 + 1, [c + s, W / 2, T / 2], rot("base_hole_2")),
            _cyl("x", d["upright_hole_diameter"], -(T / 2 + 1), T / 2 + 1, [T / 2, W / 2, d["upright_hole_height"]],
                 rot("upright_hole"))]}
    if kind == "shaft":
        D1, D2, L1, L2 = d["large_diameter"], d["small_diameter"], d["large_length"], d["small_length"]
        off = imp.get("small_section_offset_mm", [0.0, 0.0, 0.0])
        return {"type": "difference", "solids": [
            {"type": "union", "solids": [_cyl("y", D1, 0.0, L1, [0, 0, 0]),
                                         _cyl("y", D2, L1 - 1.0, L1 + L2, off)]},
            _cyl("x", d["cross_hole_diameter"], -D1, D1,
                 [0.0, d["cross_hole_position"], imp.get("cross_hole_offset_z_mm", 0.0)],
                 imp.get("cross_hole_rotate_deg"))]}
    raise ValueError(kind)


def physical_part(kind, d, imp):
    """(part-model document or None, lab2 CSG tree) of the specimen."""
    pm = model(kind)
    if kind == "wedge":
        return None, pm.build(d)
    shape = physical_shape(kind, d, imp)
    doc = {"description": (f"lab2's physical {kind} ({pm.path} at the true dimensions) with imperfections the model "
                           f"lacks: {imp}; numbers only, in the model's frame; for the record and for rendering, "
                           "not for fitting"),
           "dimensions": [{"name": k, "nominal": v, "min": v - 1.0, "max": v + 1.0, "unit": "mm"} for k, v in d.items()],
           "shape": shape}
    return doc, build_shape(shape, {}, PARTS, "/shape")


def fillet_area(r):
    """Cross-section of the bracket's inner fillet (closed form)."""
    return r * r * (1.0 - math.pi / 4.0)
