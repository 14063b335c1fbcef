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
  mid-plate are the model's).  With the "strong" defect profile
  (``defect_profile``): a fillet of 1 to 1.5 mm, tilts of 0.5 to 1 deg and
  a chamfer of 0.3 to 0.6 mm on the upright's outer top edge.
- ``shaft`` (Part 6, parts/stepped_shaft.json): dimensions off Shaft A by
  up to 0.3 mm (diameters 0.1 mm); the small section eccentric (its axis
  offset by 0.01 to 0.05 mm in a random direction), the cross hole off the
  axis (its axis passing 0 to 0.05 mm from it, along z) and tilted by up to
  0.6 deg ("strong": offset 0.05 to 0.1 mm, tilt 0.5 to 1 deg; "none": the
  bracket and the shaft without imperfections).
- ``screw`` (examples/screw/screw.json, a part given by its CAD file):
  lab2 reads only the file's dimensions (and constraints), never its
  "step" shape.  Dimensions off nominal by up to 0.15 mm (slot_width,
  shank_offset), 0.3 mm (slot_depth, length) and 0.1 mm (shank_diameter);
  no imperfection: the true solid is the CAD shape at those values, made
  outside lab2 by OpenCASCADE's own operations (the program screw_solid:
  environment variable XGAUGE_SCREW_SOLID, else build/bench/screw_solid),
  written as a closed STL (physical_screw.stl, chord tolerance 0.0005 mm)
  into the specimen's folder and rendered as a mesh (its facets, exact;
  the facets of one smooth face share a signature, so the pixel integral
  treats them as one face).
"""

import json
import math
import os
import shutil
import subprocess
import tempfile

from . import expr, imperfect
from . import geometry as G
from .partmodel import Node, PartError, PartModel, build_shape, read_stl, rotation_matrix

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
PARTS = os.path.join(REPO, "parts")
MODEL_FILES = {"prism": "prism_jaw.json", "wedge": "wedge_block.json", "bracket": "bracket.json",
               "shaft": "stepped_shaft.json", "screw": os.path.join(REPO, "examples", "screw", "screw.json")}
KINDS = tuple(MODEL_FILES)
# The screw's true solids: OpenCASCADE's builder (bench/screw_solid.cpp), outside lab2.
SCREW_SOLID_ENV = "XGAUGE_SCREW_SOLID"
SCREW_SOLID_DEFAULT = os.path.join(REPO, "build", "bench", "screw_solid")
SCREW_STL = "physical_screw.stl"
SCREW_CHORD_MM = 0.0005  # the builder's chord tolerance (BRepMesh linear deflection)
SCREW_SMOOTH_DEG = 10.0  # facets whose normals differ by less are one smooth face in the ray signatures
SCREW_SPREAD_MM = {"slot_width": 0.15, "slot_depth": 0.3, "shank_diameter": 0.1, "length": 0.3,
                   "shank_offset": 0.15}
_SCREW_CACHE = {}  # dims -> (Mesh, command) of STLs built in this process
PRISM_A = {"width": 20.977, "groove_center": 10.438, "thickness": 13.020, "groove_depth": 6.923,
           "groove_left": 6.848, "groove_right": 6.963, "slot_width": 4.104, "slot_depth": 3.951}
PRISM_B = {"width": 20.951, "groove_center": 10.462, "thickness": 10.048, "groove_depth": 5.204,
           "groove_left": 5.101, "groove_right": 5.219, "slot_width": 3.052, "slot_depth": 2.903}


def model(kind):
    if kind == "screw":
        return DimensionsModel(MODEL_FILES[kind], solid=screw_solid)
    return PartModel(os.path.join(PARTS, MODEL_FILES[kind]))


class DimensionsModel:
    """A part file read for its dimensions only (name, nominal, min, max,
    unit; constants, derived values and constraints if present), for parts
    whose shape lab2 does not read (a "step" shape: the CAD file is
    xgauge's business).  What PartRun and start_bounds need: path, nominal,
    bounds, check(values) (the broken bounds and constraints, empty when
    valid, as PartModel.check), valid(values), and build(values), the
    true solid from `solid(values)`."""

    def __init__(self, path, solid=None):
        self.path = os.path.abspath(path)
        with open(self.path) as f:
            d = json.load(f)
        if "description" not in d:
            raise PartError(f"{path}: a part model needs a description")
        dims = d.get("dimensions", [])
        self.dimensions = [x["name"] for x in dims]
        self.nominal = {x["name"]: float(x["nominal"]) for x in dims}
        self.bounds = {x["name"]: (float(x["min"]), float(x["max"])) for x in dims}
        self.units = {x["name"]: x.get("unit", "mm") for x in dims}
        self.constants = {c["name"]: float(c["value"]) for c in d.get("constants", [])}
        self.derived = [(x["name"], x["expr"]) for x in d.get("derived", [])]
        self.constraints = [(c["expr"], c.get("message", c["expr"])) for c in d.get("constraints", [])]
        self.shape_type = (d.get("shape") or {}).get("type")  # recorded, never read
        self._solid = solid

    def environment(self, values=None):
        env = dict(self.nominal)
        for k, v in (values or {}).items():
            if k not in env:
                raise PartError(f"{self.path}: {k!r} is not a dimension of the part")
            env[k] = float(v)
        env.update(self.constants)
        for name, e in self.derived:
            env[name] = expr.evaluate(e, env)
        return env

    def check(self, values=None):
        env = self.environment(values)
        bad = [f"{k} = {env[k]} outside [{lo}, {hi}]" for k, (lo, hi) in self.bounds.items()
               if not lo <= env[k] <= hi]
        bad += [msg for e, msg in self.constraints if not expr.evaluate(e, env) > 0]
        return bad

    def valid(self, values=None):
        return not self.check(values)

    def build(self, values=None, check=True):
        if check:
            bad = self.check(values)
            if bad:
                raise PartError(f"{self.path}: invalid dimensions: " + "; ".join(bad))
        if self._solid is None:
            raise PartError(f"{self.path}: lab2 does not build this part's shape ({self.shape_type!r})")
        dims = dict(self.nominal)
        dims.update({k: float(v) for k, v in (values or {}).items()})
        return self._solid(dims)


class ScrewBuilderError(RuntimeError):
    pass


def screw_builder():
    """The path of OpenCASCADE's screw builder (environment variable
    XGAUGE_SCREW_SOLID, else build/bench/screw_solid); a clear error where
    it is missing."""
    env = os.environ.get(SCREW_SOLID_ENV)
    exe = env if env else SCREW_SOLID_DEFAULT
    if os.path.isfile(exe) and os.access(exe, os.X_OK):
        return os.path.abspath(exe)
    where = (f"{SCREW_SOLID_ENV}={env!r} names no executable file" if env else
             f"{SCREW_SOLID_ENV} is not set and {SCREW_SOLID_DEFAULT} does not exist (or is not executable)")
    raise ScrewBuilderError(
        f"the screw's true solids are made by OpenCASCADE's builder screw_solid (bench/screw_solid.cpp), outside "
        f"lab2: {where}. Build it (cmake target screw_solid, {SCREW_SOLID_DEFAULT}) or set {SCREW_SOLID_ENV} to its "
        "path.")


def _screw_key(d):
    return tuple((k, round(float(d[k]), 9)) for k in sorted(d))


def screw_command(d, exe=None):
    """The builder's command line for dimensions d (the STL written as
    physical_screw.stl in the working folder)."""
    cmd = [exe or screw_builder()]
    for k in model_dimension_names("screw"):
        cmd += ["--set", f"{k}={float(d[k])!r}"]
    return cmd + ["--chord-tolerance-mm", repr(SCREW_CHORD_MM), "--stl", SCREW_STL]


def model_dimension_names(kind):
    with open(MODEL_FILES[kind]) as f:
        return [x["name"] for x in json.load(f)["dimensions"]]


def build_screw(d, folder):
    """Runs the builder in `folder` (it writes physical_screw.stl there);
    returns (Mesh, command)."""
    cmd = screw_command(d)
    os.makedirs(folder, exist_ok=True)
    stl = os.path.join(folder, SCREW_STL)
    if os.path.exists(stl):
        os.remove(stl)
    r = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    if r.returncode != 0 or not os.path.isfile(stl):
        raise ScrewBuilderError(f"the screw builder failed (exit {r.returncode}) in {folder}: {' '.join(cmd)}\n"
                                f"{r.stderr.strip()}")
    mesh = screw_mesh(stl)
    _SCREW_CACHE[_screw_key(d)] = (mesh, cmd)
    return mesh, cmd


def screw_mesh(stl):
    """The builder's STL as a lab2 mesh, checked closed and outward."""
    V, T = read_stl(stl)
    mesh = G.Mesh(V, T, smooth_deg=SCREW_SMOOTH_DEG)
    vol = imperfect.signed_volume(V, T)
    if mesh.open_edges or not vol > 0:
        raise ScrewBuilderError(f"{stl}: the builder's STL is not a closed outward mesh (open edges "
                                f"{mesh.open_edges}, volume {vol:.3f} mm^3)")
    return mesh


def screw_solid(d):
    """The true screw at dimensions d as a lab2 tree (one mesh leaf): the
    STL built for these values in this process, else built now in a
    temporary folder (for the bounding box before the specimen's folder
    exists)."""
    hit = _SCREW_CACHE.get(_screw_key(d))
    if hit is None:
        tmp = tempfile.mkdtemp(prefix="lab2_screw_")
        try:
            hit = build_screw(d, tmp)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return Node("leaf", solid=hit[0], path="/shape")


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
            elif kind == "screw":
                s = SCREW_SPREAD_MM[k]
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


# How strong the bracket's and the shaft's imperfections are drawn
# (`lab2.py suite --defects`): "usual" (lab2's ranges above), "strong" (the
# ranges of xgauge's issue 62: a fillet of 1 to 1.5 mm, holes 0.5 to 1 deg
# off, the small section 0.05 to 0.1 mm eccentric, the cross hole tilted
# 0.5 to 1 deg, and a chamfer of 0.3 to 0.6 mm on the upright's outer top
# edge that the model omits), or "none" (the model at the drawn dimensions).
# The prism's imperfections are not affected.
DEFECT_PROFILES = ("usual", "strong", "none")
defect_profile = "usual"


def _tilt_between(rng, lo, hi, axis):
    """As _tilt, the tilt drawn between lo and hi degrees."""
    th, ph = rng.uniform(lo, hi), rng.uniform(0.0, 2 * math.pi)
    a, b = th * math.cos(ph), th * math.sin(ph)
    e = [round(a, 5), round(b, 5), 0.0] if axis == "z" else [0.0, round(a, 5), round(b, 5)]
    R = rotation_matrix(*e)
    k = 2 if axis == "z" else 0
    return e, math.degrees(math.acos(min(1.0, abs(R[k, k]))))


def draw_imperfections(kind, rng):
    if kind == "prism":
        return imperfect.draw(rng)
    if kind in ("wedge", "screw"):
        return {}
    if defect_profile not in DEFECT_PROFILES:
        raise ValueError(f"defect profile {defect_profile!r}: one of {', '.join(DEFECT_PROFILES)}")
    if defect_profile == "none":
        return {}
    strong = defect_profile == "strong"
    if kind == "bracket":
        out = {"fillet_radius_mm": round(rng.uniform(1.0 if strong else 0.5, 1.5), 4), "holes": {}}
        for h, ax in (("base_hole_1", "z"), ("base_hole_2", "z"), ("upright_hole", "x")):
            e, ang = _tilt_between(rng, 0.5, 1.0, ax) if strong else _tilt(rng, 0.6, ax)
            out["holes"][h] = {"rotate_deg": e, "tilt_deg": round(ang, 5)}
        if strong:
            out["upright_chamfer_mm"] = round(rng.uniform(0.3, 0.6), 4)
        return out
    if kind == "shaft":
        e = rng.uniform(0.05, 0.1) if strong else rng.uniform(0.01, 0.05)
        ph = rng.uniform(0.0, 2 * math.pi)
        te, ang = _tilt_between(rng, 0.5, 1.0, "x") if strong else _tilt(rng, 0.6, "x")
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
        cuts = []
        ch = imp.get("upright_chamfer_mm", 0.0)
        if ch > 0:
            # A square prism turned 45 deg about y on the upright's outer top
            # edge (x = 0, z = H): it removes x + (H - z) <= ch.
            h = ch / math.sqrt(2.0)
            cuts.append({**_box([-h, -1.0, -h], [h, W + 1.0, h]), "rotate": [0.0, 45.0, 0.0],
                         "translate": [0.0, 0.0, float(H)]})
        return {"type": "difference", "solids": [
            {"type": "union", "solids": plates}, *cuts,
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


def physical_part(kind, d, imp, folder=None):
    """(part-model document or None, lab2 CSG tree) of the specimen.  The
    screw's STL is written into `folder` (a temporary one, removed, where
    None)."""
    pm = model(kind)
    if kind == "wedge":
        return None, pm.build(d)
    if kind == "screw":
        return physical_screw(pm, d, folder)
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


def physical_screw(pm, d, folder=None):
    """The screw specimen: the builder run in `folder` (physical_screw.stl),
    the STL rendered as one mesh, and physical_part.json's document (the
    STL and the builder's command line)."""
    bad = pm.check(d)
    if bad:
        raise PartError(f"{pm.path}: invalid dimensions: " + "; ".join(bad))
    if folder is None:
        tmp = tempfile.mkdtemp(prefix="lab2_screw_")
        try:
            mesh, cmd = build_screw(d, tmp)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    else:
        mesh, cmd = build_screw(d, folder)
    lo, hi = mesh.bbox()
    doc = {"description": (f"lab2's physical screw: {pm.path} at the true dimensions, its solid made outside lab2 by "
                           "OpenCASCADE's own operations (screw_solid, bench/screw_solid.cpp) and written as the "
                           f"closed STL {SCREW_STL} (chord tolerance {SCREW_CHORD_MM} mm) in the frame of the part's "
                           "STEP file; lab2 renders that STL (its facets); no imperfection beyond the dimensions; "
                           "for the record and for rendering, not for fitting"),
           "dimensions": [{"name": k, "nominal": float(v), "min": float(v) - 1.0, "max": float(v) + 1.0, "unit": "mm"}
                          for k, v in d.items()],
           "shape": {"type": "stl", "file": SCREW_STL},
           "builder": {"command": cmd, "cwd": "the folder of this file",
                       "environment_variable": SCREW_SOLID_ENV, "chord_tolerance_mm": SCREW_CHORD_MM},
           "mesh": {"triangles": int(len(mesh.T)), "vertices": int(len(mesh.V)),
                    "volume_mm3": round(imperfect.signed_volume(mesh.V, mesh.T), 6),
                    "bbox_mm": [[float(v) for v in lo], [float(v) for v in hi]],
                    "smooth_face_angle_deg": SCREW_SMOOTH_DEG,
                    "note": "facets whose normals differ by less than smooth_face_angle_deg share a ray signature "
                            "(one smooth face for the pixel integral); the paths are the facets' own"}}
    return doc, Node("leaf", solid=mesh, path="/shape")
