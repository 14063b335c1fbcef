"""Projection geometry and the pixel integral.

A pixel's value is the mean over its whole area (fill factor 1) of the
quantity a point sample sees: the transmission T(L) of its ray (or the path
L itself when asked).  The integral is taken in two ways:

- smooth pixels (the same faces crossed by this pixel's centre ray and its
  eight neighbours', and no strong curvature of the path): the centre value
  plus the second-order term of the midpoint rule, f + (f_uu + f_vv) / 24,
  with the second differences of the neighbouring centres (exact for any
  quadratic variation over the pixel);
- every other pixel (silhouettes, edges, walls seen edge-on, the steep rim
  of a cylinder; two pixels around the places where three or more
  signatures meet, where edges end): the mean of a Fibonacci lattice of
  n points (default 233).  Each row and column of an n x n grid holds one
  lattice point, so an edge along a detector axis is placed to 1/(2n)
  pixel, and oblique edges to about (log n)/n.
"""

import numpy as np
from scipy import ndimage

from .geometry import fibonacci_lattice


class Geometry:
    """Cone-beam projection geometry of docs/conventions.md."""

    def __init__(self, sdd, columns, rows, pitch_u, pitch_v, cx=None, cy=None):
        self.sdd = float(sdd)
        self.columns, self.rows = int(columns), int(rows)
        self.pitch_u, self.pitch_v = float(pitch_u), float(pitch_v)
        self.cx = columns / 2.0 if cx is None else float(cx)
        self.cy = rows / 2.0 if cy is None else float(cy)

    @property
    def source(self):
        return np.array([0.0, 0.0, self.sdd])

    def world_xy(self, pu, pv):
        return (np.asarray(pu) - self.cx) * self.pitch_u, (self.cy - np.asarray(pv)) * self.pitch_v

    def directions(self, pu, pv):
        x, y = self.world_xy(pu, pv)
        D = np.stack([x, y, np.full(np.shape(x), -self.sdd)], axis=-1).reshape(-1, 3)
        return D / np.linalg.norm(D, axis=1)[:, None]

    def project(self, P):
        P = np.atleast_2d(P)
        m = self.sdd / (self.sdd - P[:, 2])
        return self.cx + P[:, 0] * m / self.pitch_u, self.cy - P[:, 1] * m / self.pitch_v

    def machine_json(self, description=""):
        return {
            "description": description,
            "source_detector_distance_mm": self.sdd,
            "detector": {"columns": self.columns, "rows": self.rows,
                         "pixel_pitch_mm": [self.pitch_u, self.pitch_v],
                         "principal_point_px": [self.cx, self.cy]},
        }


def shadow_region(scene, geom, margin=3):
    P = scene.bbox_corners_world()
    if np.any(P[:, 2] >= geom.sdd) or np.any(P[:, 2] < 0):
        raise ValueError("the part must lie between the detector (z = 0) and the source")
    pu, pv = geom.project(P)
    u0 = int(np.floor(pu.min())) - margin
    u1 = int(np.ceil(pu.max())) + margin
    v0 = int(np.floor(pv.min())) - margin
    v1 = int(np.ceil(pv.max())) + margin
    u0, v0 = max(u0, 0), max(v0, 0)
    u1, v1 = min(u1, geom.columns), min(v1, geom.rows)
    return u0, u1, v0, v1


def render(scene, geom, fn=None, lattice=233, curvature_tol_mm=0.02, stats=None):
    """The pixel-area mean of fn(path) (path itself when fn is None) over
    the whole detector, as float64 (rows, columns)."""
    f = (lambda L: L) if fn is None else fn
    background = float(np.asarray(f(np.zeros(1)))[0])
    img = np.full((geom.rows, geom.columns), background)
    u0, u1, v0, v1 = shadow_region(scene, geom)
    if u1 <= u0 or v1 <= v0:
        return img
    h, w = v1 - v0, u1 - u0
    vv, uu = np.mgrid[v0:v1, u0:u1]
    S = geom.source
    order = _tile_order(vv.ravel(), uu.ravel())
    L = np.empty(h * w)
    sig = np.empty(h * w)
    L[order], sig[order] = scene.trace(S, geom.directions(uu.ravel()[order] + 0.5, vv.ravel()[order] + 0.5))
    L = L.reshape(h, w)
    sig = sig.reshape(h, w)
    flag = np.zeros((h, w), bool)
    other = np.full((h, w), np.nan)  # a second signature seen in the 3 x 3 neighbourhood
    junction = np.zeros((h, w), bool)  # three or more: edges meet (vertices, corners)
    pad = np.pad(sig, 1, mode="edge")
    for dv in (-1, 0, 1):
        for du in (-1, 0, 1):
            if dv or du:
                nb = pad[1 + dv : 1 + dv + h, 1 + du : 1 + du + w]
                diff = nb != sig
                flag |= diff
                junction |= diff & ~np.isnan(other) & (nb != other)
                other = np.where(diff & np.isnan(other), nb, other)
    Lp = np.pad(L, 1, mode="edge")
    d2u = Lp[1:-1, :-2] - 2 * L + Lp[1:-1, 2:]
    d2v = Lp[:-2, 1:-1] - 2 * L + Lp[2:, 1:-1]
    curved = (np.abs(d2u) > curvature_tol_mm) | (np.abs(d2v) > curvature_tol_mm)
    # An edge (a straight line) that crosses a pixel always separates its
    # centre from one of its 8 neighbours' centres, so those two are refined;
    # around junctions (where an edge ends) and steep curvature the band is
    # widened by a pixel.
    grow = ndimage.binary_dilation(junction | curved, structure=np.ones((3, 3), bool), iterations=2)
    flag |= curved | grow
    # pixels on the panel's border have no neighbour on one side: no midpoint correction there
    flag[0, :] |= v0 == 0
    flag[-1, :] |= v1 == geom.rows
    flag[:, 0] |= u0 == 0
    flag[:, -1] |= u1 == geom.columns
    F = f(L)
    Fp = np.pad(F, 1, mode="edge")
    corr = (Fp[1:-1, :-2] - 2 * F + Fp[1:-1, 2:] + Fp[:-2, 1:-1] - 2 * F + Fp[2:, 1:-1]) / 24.0
    out = F + corr
    fv, fu = np.nonzero(flag)
    o = _tile_order(fv, fu)
    fv, fu = fv[o], fu[o]
    if len(fv):
        lat = fibonacci_lattice(lattice)
        step = max(1, (1 << 18) // lattice)
        vals = np.empty(len(fv))
        for a in range(0, len(fv), step):
            b = min(len(fv), a + step)
            pu = (u0 + fu[a:b])[:, None] + lat[None, :, 0]
            pv = (v0 + fv[a:b])[:, None] + lat[None, :, 1]
            Ls, _ = scene.trace(S, geom.directions(pu, pv))
            vals[a:b] = f(Ls).reshape(b - a, lattice).mean(axis=1)
        out[fv, fu] = vals
    img[v0:v1, u0:u1] = out
    if stats is not None:
        stats.update(region=[u0, v0, w, h], refined_pixels=int(len(fv)), lattice=lattice,
                     max_centre_path_mm=float(L.max()))
    return img


def _tile_order(v, u, tile=32):
    """Pixels sorted tile by tile, so that each chunk of rays is compact on
    the detector (the mesh's culling then drops most triangles)."""
    return np.lexsort((u, v, u // tile, v // tile))
