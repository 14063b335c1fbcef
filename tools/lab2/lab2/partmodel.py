"""Part models as docs/formats.md ("Part model", "Solids combined and holes
cut (CSG)") describes them, read into exact primitives.

A part file's shape becomes a tree of CSG nodes whose leaves are exact
solids in their own frame (box, cylinder, extrusion of a polygon with holes,
solid of revolution, closed triangle mesh, STL mesh) and a placement
x_parent = R x_local + t per node (rotation first, then translation; a
node's placement applied after those of the nodes inside it).

Deliberate difference from the part files: a ``revolution``'s and a
``cylinder``'s ``segments`` are ignored.  The part file uses them to say how
finely xgauge's mesh approximates the true circle; the physical part is
round, so the lab renders the exact surface of revolution.
"""

import json
import math
import os
import struct

import numpy as np

from . import expr
from . import geometry as G

AXES = {"x": 0, "y": 1, "z": 2}


def rotation_matrix(rx, ry, rz):
    """R = Rz(rz) Ry(ry) Rx(rx), angles in degrees (docs/conventions.md)."""
    a, b, c = (math.radians(v) for v in (rx, ry, rz))
    Rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    Ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    Rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def euler_from_matrix(R):
    """Inverse of rotation_matrix with ry in [-90, 90] degrees."""
    ry = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    if abs(math.cos(ry)) > 1e-12:
        rx = math.atan2(R[2, 1], R[2, 2])
        rz = math.atan2(R[1, 0], R[0, 0])
    else:  # gimbal lock: put everything into rx
        rz = 0.0
        rx = math.atan2(-R[1, 2], R[1, 1])
    return [math.degrees(rx), math.degrees(ry), math.degrees(rz)]


class PartError(ValueError):
    pass


class Node:
    """A CSG node: op in {'leaf', 'union', 'difference', 'intersection'}."""

    def __init__(self, op, children=(), solid=None, R=None, t=None, path=""):
        self.op = op
        self.children = list(children)
        self.solid = solid
        self.R = np.eye(3) if R is None else R
        self.t = np.zeros(3) if t is None else t
        self.path = path

    def leaves(self):
        if self.op == "leaf":
            return [self]
        out = []
        for c in self.children:
            out.extend(c.leaves())
        return out


class PartModel:
    def __init__(self, path):
        self.path = os.path.abspath(path)
        with open(self.path) as f:
            self.doc = json.load(f)
        d = self.doc
        if "description" not in d:
            raise PartError(f"{path}: a part model needs a description")
        self.dimensions = [x["name"] for x in d.get("dimensions", [])]
        self.nominal = {x["name"]: float(x["nominal"]) for x in d.get("dimensions", [])}
        self.bounds = {x["name"]: (float(x["min"]), float(x["max"])) for x in d.get("dimensions", [])}
        self.units = {x["name"]: x.get("unit", "mm") for x in d.get("dimensions", [])}
        self.constants = {c["name"]: float(c["value"]) for c in d.get("constants", [])}

    def environment(self, values=None):
        env = dict(self.nominal)
        for k, v in (values or {}).items():
            if k not in env:
                raise PartError(f"{self.path}: {k!r} is not a dimension of the part")
            env[k] = float(v)
        env.update(self.constants)
        for item in self.doc.get("derived", []):
            env[item["name"]] = expr.evaluate(item["expr"], env)
        return env

    def check(self, values=None):
        env = self.environment(values)
        bad = []
        for c in self.doc.get("constraints", []):
            if not expr.evaluate(c["expr"], env) > 0:
                bad.append(c["message"])
        return bad

    def build(self, values=None, check=True):
        """The shape at these dimension values, as a tree of exact solids."""
        if check:
            bad = self.check(values)
            if bad:
                raise PartError(f"{self.path}: invalid dimensions: " + "; ".join(bad))
        env = self.environment(values)
        return build_shape(self.doc["shape"], env, os.path.dirname(self.path), "/shape")


def _ev(v, env):
    return expr.evaluate(v, env)


def _vec(v, env, n=3):
    if not isinstance(v, list) or len(v) != n:
        raise PartError(f"expected a list of {n} expressions, got {v!r}")
    return np.array([_ev(x, env) for x in v], dtype=float)


def build_shape(s, env, folder, path):
    kind = s.get("type")
    R = np.eye(3)
    t = np.zeros(3)
    if "rotate" in s:
        R = rotation_matrix(*_vec(s["rotate"], env))
    if "translate" in s:
        t = _vec(s["translate"], env)
    if kind in ("union", "difference", "intersection"):
        kids = [build_shape(c, env, folder, f"{path}/solids/{i}") for i, c in enumerate(s["solids"])]
        if not kids:
            raise PartError(f"{path}: {kind} needs at least one solid")
        return Node(kind, kids, R=R, t=t, path=path)
    if kind == "box":
        lo, hi = _vec(s["min"], env), _vec(s["max"], env)
        solid = G.Box(np.minimum(lo, hi), np.maximum(lo, hi))
    elif kind == "cylinder":
        k = AXES[s["axis"]]
        a0, a1 = _ev(s["from"], env), _ev(s["to"], env)
        solid = G.Cylinder(k, 0.5 * _ev(s["diameter"], env), min(a0, a1), max(a0, a1))
    elif kind == "extrusion":
        i, j = AXES[s["plane"][0]], AXES[s["plane"][1]]
        k = AXES[s["axis"]]
        if len({i, j, k}) != 3:
            raise PartError(f"{path}: plane and axis must be three different axes")
        loops = [np.array([[_ev(a, env), _ev(b, env)] for a, b in s["profile"]])]
        for h in s.get("holes", []):
            loops.append(np.array([[_ev(a, env), _ev(b, env)] for a, b in h]))
        a0, a1 = _ev(s["from"], env), _ev(s["to"], env)
        solid = G.Extrusion((i, j), k, loops, min(a0, a1), max(a0, a1))
    elif kind == "revolution":
        k = AXES[s["axis"]]
        prof = np.array([[_ev(r, env), _ev(a, env)] for r, a in s["profile"]])
        solid = G.Revolution(k, prof)
    elif kind == "mesh":
        V = np.array([[_ev(c, env) for c in v] for v in s["vertices"]], dtype=float)
        T = np.array(s["triangles"], dtype=np.int64)
        solid = G.Mesh(V, T)
    elif kind == "stl":
        V, T = read_stl(os.path.join(folder, s["file"]))
        solid = G.Mesh(V, T)
    else:
        raise PartError(f"{path}: unknown shape type {kind!r}")
    return Node("leaf", solid=solid, R=R, t=t, path=path)


def read_stl(path):
    """Binary or ASCII STL; vertices with bit-identical coordinates merged."""
    with open(path, "rb") as f:
        data = f.read()
    tris = None
    if len(data) >= 84:
        n = struct.unpack("<I", data[80:84])[0]
        if 84 + 50 * n == len(data):
            rec = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
            tris = rec["v"].astype(float)
    if tris is None:
        vals = []
        for line in data.decode("ascii", "replace").splitlines():
            p = line.split()
            if p and p[0] == "vertex":
                vals.append([float(x) for x in p[1:4]])
        tris = np.array(vals, dtype=float).reshape(-1, 3, 3)
    flat = tris.reshape(-1, 3)
    V, inv = np.unique(flat, axis=0, return_inverse=True)
    return V, inv.reshape(-1, 3)
