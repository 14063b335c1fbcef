"""Imperfections the part models lack, drawn per run: chamfers on the prism
jaw's convex edges and a taper of its width.

The physical jaw is then a closed triangle mesh (all its faces planar):

- chamfers: each convex corner P of the profile (P0, P1, P2, P9: outer
  edges; P3, P8: the V's edges at the front face; P4, P7: the slot's edges
  at the flanks) is replaced by the two points at distance c_P from P along
  its two edges: a 45-degree-like bevel of leg c_P along the whole length;
- taper: the right face (P1-P2, with its chamfer points) is moved along x
  by taper * (y - L/2), so the true width is `width` at mid-length y = L/2
  and changes by `taper` mm per mm along the jaw (the left face, the
  groove and the slot are untouched).  The moved face stays planar, and so
  do the bottom and the front faces it meets.
"""

import numpy as np

from .geometry import Mesh

CONVEX = {"P0": "outer", "P1": "outer", "P2": "outer", "P9": "outer",
          "P3": "groove", "P8": "groove", "P4": "slot", "P7": "slot"}
RIGHT = {"P1", "P2"}


def prism_profile(d):
    W, c, T, g = d["width"], d["groove_center"], d["thickness"], d["groove_depth"]
    al, ar, sw, sd = d["groove_left"], d["groove_right"], d["slot_width"], d["slot_depth"]
    return [("P0", (0.0, 0.0)), ("P1", (W, 0.0)), ("P2", (W, T)), ("P3", (c + ar, T)),
            ("P4", (c + sw / 2, T - g * (1 - sw / (2 * ar)))), ("P5", (c + sw / 2, T - g - sd)),
            ("P6", (c - sw / 2, T - g - sd)), ("P7", (c - sw / 2, T - g * (1 - sw / (2 * al)))),
            ("P8", (c - al, T)), ("P9", (0.0, T))]


def draw(rng, chamfer=True, taper=True):
    """Random imperfections of one run: chamfer legs (mm) and a taper."""
    out = {"chamfers_mm": {}, "taper": 0.0}
    if chamfer:
        for name, kind in CONVEX.items():
            lo, hi = {"outer": (0.05, 0.25), "groove": (0.03, 0.15), "slot": (0.02, 0.08)}[kind]
            out["chamfers_mm"][name] = float(round(rng.uniform(lo, hi), 4))
    if taper:
        out["taper"] = float(round(rng.uniform(-0.003, 0.003), 6))
    return out


def chamfered_profile(d, chamfers):
    prof = prism_profile(d)
    n = len(prof)
    pts, right = [], []
    for k, (name, p) in enumerate(prof):
        p = np.array(p)
        c = chamfers.get(name, 0.0)
        if c <= 0:
            pts.append(p)
            right.append(name in RIGHT)
            continue
        a = np.array(prof[k - 1][1])
        b = np.array(prof[(k + 1) % n][1])
        for q in (a, b):
            if np.linalg.norm(q - p) <= 2 * c:
                raise ValueError(f"chamfer {c} mm at {name} longer than half its edge")
        pts.append(p + c * (a - p) / np.linalg.norm(a - p))
        pts.append(p + c * (b - p) / np.linalg.norm(b - p))
        right += [name in RIGHT] * 2
    return np.array(pts), np.array(right)


def ear_clip(poly):
    """Triangles of a simple counter-clockwise polygon (indices)."""
    idx = list(range(len(poly)))
    tris = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    guard = 0
    while len(idx) > 3 and guard < 10000:
        guard += 1
        for m in range(len(idx)):
            i0, i1, i2 = idx[m - 1], idx[m], idx[(m + 1) % len(idx)]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross(a, b, c) <= 0:
                continue
            ok = True
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0:
                    ok = False
                    break
            if ok:
                tris.append((i0, i1, i2))
                idx.pop(m)
                break
    tris.append(tuple(idx))
    return tris


def physical_prism(d, imperfections, L=40.0):
    """The jaw as a closed mesh (part frame of docs/conventions.md)."""
    prof, right = chamfered_profile(d, imperfections.get("chamfers_mm", {}))
    tau = imperfections.get("taper", 0.0)
    n = len(prof)
    V = []
    for y in (0.0, L):
        shift = tau * (y - L / 2)
        for (x, z), r in zip(prof, right):
            V.append((x + (shift if r else 0.0), y, z))
    V = np.array(V)
    T = []
    for a, b, c in ear_clip(prof):  # counter-clockwise in (x, z): normal -y, the y = 0 cap
        T.append((a, b, c))
        T.append((n + a, n + c, n + b))
    for k in range(n):
        j = (k + 1) % n
        T.append((k, n + j, j))
        T.append((k, n + k, n + j))
    T = np.array(T)
    mesh = Mesh(V, T)
    vol = signed_volume(V, T)
    if mesh.open_edges or vol <= 0:
        raise ValueError(f"the physical prism mesh is not closed and outward (open edges {mesh.open_edges}, volume {vol})")
    return V, T


def signed_volume(V, T):
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def part_json(V, T, dims, imperfections, source_model):
    return {
        "description": ("lab2's physical prism jaw with imperfections the model lacks (chamfers "
                        f"{imperfections.get('chamfers_mm')}, taper {imperfections.get('taper')} mm/mm of the right face "
                        "about y = L/2), as a fixed mesh in the frame of " + source_model + "; for the record and "
                        "for rendering, not for fitting"),
        "dimensions": [{"name": k, "nominal": v, "min": v - 1.0, "max": v + 1.0, "unit": "mm"} for k, v in dims.items()],
        "shape": {"type": "mesh", "vertices": [[float(x) for x in v] for v in V],
                  "triangles": [[int(i) for i in t] for t in T]},
    }
