"""Exact ray casting through solids and their CSG combinations.

Every ray starts at one point o (the focal spot, expressed in each solid's
own frame) and runs along a unit direction D, so t is the distance in mm.
Each solid reports, per ray, *events*: the parameters t where the ray
crosses its boundary and a step s of a counter (+1 in, -1 out, 0 for an
empty slot).  A solid's points along the ray are those where its counter is
> 0 ("count" solids) or odd ("parity" solids: the solid of revolution,
written as an exclusive-or of solid cone frustums).  A CSG tree merges the
events of all its solids, sorts them along the ray and keeps the segments
its boolean operations accept; the path length is the total length of the
kept segments.  No surface is ever tessellated:

- box and convex slabs: the slab method;
- cylinder: the quadratic of the circle, numerically stable roots;
- extrusion of a polygon (with holes): the 2-D crossings of the projected
  line with the polygon's edges, with every vertex classified once per ray
  by the sign of one cross product (a vertex exactly on the line counts as
  on its negative side), so that the number of crossings is always even and
  a ray through a vertex is neither lost nor doubled;
- solid of revolution: an exclusive-or of solid cone frustums, one per
  profile edge that is not perpendicular to the axis (the crossing-number
  rule along the radius), each intersected exactly (quadratic + slab);
- closed triangle mesh: per ray, every vertex is projected once onto the
  plane perpendicular to the ray, each undirected edge's orientation test is
  evaluated once and shared by its two triangles, and exact zeros are broken
  by a fixed symbolic perturbation of the ray.  A ray through an edge or a
  vertex is therefore counted by exactly one of the triangles that meet
  there (watertight), which the signed crossing count needs.

Accuracy: double precision throughout; the closed-form tests in
tests/test_geometry.py agree to 1e-9 mm.
"""

import numpy as np

INF = np.inf
BIG = 1e12


def _weights(n, seed):
    """Deterministic pseudo-random weights in [1, 2) that identify faces in
    the ray signatures (sums of the weights of the faces a ray crosses)."""
    k = np.arange(1, n + 1, dtype=float)
    return 1.0 + np.mod(k * 0.6180339887498949 + seed * 0.7548776662466927, 1.0)


def _slab(o, d, lo, hi):
    """Entry and exit parameters of the slab lo <= o + t d <= hi."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tn = np.minimum(t1, t2)
    tf = np.maximum(t1, t2)
    zero = d == 0
    if np.any(zero):
        inside = (o >= lo) & (o <= hi)
        tn = np.where(zero, -INF if inside else INF, tn)
        tf = np.where(zero, INF if inside else -INF, tf)
    return tn, tf


class Solid:
    mode = "count"
    n_events = 2

    def bbox(self):
        raise NotImplementedError

    def events(self, o, D):
        raise NotImplementedError


def _interval_events(tn, tf, valid):
    t = np.stack([np.where(valid, tn, INF), np.where(valid, tf, INF)], axis=1)
    s = np.stack([valid.astype(np.int8), -valid.astype(np.int8)], axis=1)
    return t, s


class Box(Solid):
    def __init__(self, lo, hi):
        self.lo = np.asarray(lo, float)
        self.hi = np.asarray(hi, float)
        self.w = _weights(6, 1)

    def bbox(self):
        return self.lo.copy(), self.hi.copy()

    def events(self, o, D):
        tn = np.full(len(D), -INF)
        tf = np.full(len(D), INF)
        fin = np.zeros(len(D))
        fout = np.zeros(len(D))
        for a in range(3):
            n, f = _slab(o[a], D[:, a], self.lo[a], self.hi[a])
            side = (D[:, a] < 0).astype(int)
            better = n > tn
            fin = np.where(better, self.w[2 * a + side], fin)
            tn = np.maximum(tn, n)
            worse = f < tf
            fout = np.where(worse, self.w[2 * a + 1 - side], fout)
            tf = np.minimum(tf, f)
        valid = tn < tf
        t, s = _interval_events(tn, tf, valid)
        sig = np.where(valid, fin + 0.5 * fout, 0.0)
        return t, s, sig


class Cylinder(Solid):
    """Solid circular cylinder: axis k through the origin, radius r, a0 <= a <= a1."""

    def __init__(self, k, r, a0, a1):
        self.k = k
        self.r = float(r)
        self.a0, self.a1 = float(a0), float(a1)
        self.p, self.q = [i for i in range(3) if i != k]
        self.w = _weights(3, 2)

    def bbox(self):
        lo = np.full(3, -self.r)
        hi = np.full(3, self.r)
        lo[self.k], hi[self.k] = self.a0, self.a1
        return lo, hi

    def side_interval(self, o, D):
        p, q = self.p, self.q
        A = D[:, p] ** 2 + D[:, q] ** 2
        B = 2.0 * (o[p] * D[:, p] + o[q] * D[:, q])
        C = o[p] ** 2 + o[q] ** 2 - self.r ** 2
        return quadratic_le0(A, B, np.full(len(D), C))

    def events(self, o, D):
        tn, tf = self.side_interval(o, D)
        sn, sf = _slab(o[self.k], D[:, self.k], self.a0, self.a1)
        cap_in = sn > tn
        cap_out = sf < tf
        tn = np.maximum(tn, sn)
        tf = np.minimum(tf, sf)
        valid = tn < tf
        t, s = _interval_events(tn, tf, valid)
        sig = np.where(valid, np.where(cap_in, self.w[1], self.w[0]) + 0.5 * np.where(cap_out, self.w[2], self.w[0]), 0.0)
        return t, s, sig


def quadratic_le0(a, b, c):
    """The interval of t where a t^2 + b t + c <= 0, for a >= 0 (convex case).

    Returns (tn, tf); empty intervals come back with tn >= tf.  a == 0 is
    solved as the linear case; a tiny a is fine with the stable roots (the
    far root then lies far outside any part)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    c = np.asarray(c, float)
    tn = np.full(a.shape, INF)
    tf = np.full(a.shape, -INF)
    disc = b * b - 4.0 * a * c
    quad = a > 0
    ok = quad & (disc > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(ok, disc, 0.0))
        qq = -0.5 * (b + np.where(b >= 0, sq, -sq))
        r1 = qq / a
        r2 = c / qq
    tn = np.where(ok, np.minimum(r1, r2), tn)
    tf = np.where(ok, np.maximum(r1, r2), tf)
    lin = ~quad
    if np.any(lin):
        with np.errstate(divide="ignore", invalid="ignore"):
            root = -c / b
        tn = np.where(lin & (b > 0), -INF, tn)
        tf = np.where(lin & (b > 0), root, tf)
        tn = np.where(lin & (b < 0), root, tn)
        tf = np.where(lin & (b < 0), INF, tf)
        allt = lin & (b == 0) & (c <= 0)
        tn = np.where(allt, -INF, tn)
        tf = np.where(allt, INF, tf)
    return tn, tf


class Extrusion(Solid):
    """A polygon (outer loop plus holes, any winding) in the plane (i, j),
    extruded along axis k from a0 to a1 (even-odd rule across loops)."""

    def __init__(self, plane, k, loops, a0, a1):
        self.i, self.j = plane
        self.k = k
        self.a0, self.a1 = float(a0), float(a1)
        pts, edges = [], []
        base = 0
        for loop in loops:
            loop = np.asarray(loop, float)
            n = len(loop)
            if n < 3:
                raise ValueError("a profile needs at least 3 points")
            pts.append(loop)
            edges.extend((base + m, base + (m + 1) % n) for m in range(n))
            base += n
        self.P = np.concatenate(pts)
        self.E = np.array(edges)
        self.n_events = 2 * (len(self.E) // 2)
        self.w = _weights(len(self.E) + 2, 3)

    def bbox(self):
        lo, hi = np.zeros(3), np.zeros(3)
        lo[self.i], hi[self.i] = self.P[:, 0].min(), self.P[:, 0].max()
        lo[self.j], hi[self.j] = self.P[:, 1].min(), self.P[:, 1].max()
        lo[self.k], hi[self.k] = self.a0, self.a1
        return lo, hi

    def contains2d(self, x, y):
        """Even-odd point-in-polygon test of 2-D points (same vertex rule)."""
        inside = np.zeros(np.shape(x), bool)
        for a, b in self.E:
            (xa, ya), (xb, yb) = self.P[a], self.P[b]
            crosses = (ya > y) != (yb > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                xc = xa + (y - ya) * (xb - xa) / (yb - ya)
            inside ^= crosses & (x < xc)
        return inside

    def events(self, o, D):
        N = len(D)
        dx, dy = D[:, self.i], D[:, self.j]
        Px = self.P[:, 0] - o[self.i]
        Py = self.P[:, 1] - o[self.j]
        s = dx[:, None] * Py[None, :] - dy[:, None] * Px[None, :]
        pos = s > 0
        a, b = self.E[:, 0], self.E[:, 1]
        cross = pos[:, a] != pos[:, b]
        sa, sb = s[:, a], s[:, b]
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.where(cross, sa / (sa - sb), 0.0)
        X = Px[a] + lam * (Px[b] - Px[a])
        Y = Py[a] + lam * (Py[b] - Py[a])
        n2 = dx * dx + dy * dy
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (X * dx[:, None] + Y * dy[:, None]) / n2[:, None]
        t = np.where(cross, t, INF)
        sig = (cross * self.w[: len(self.E)]).sum(axis=1)
        t.sort(axis=1)
        m = len(self.E) // 2
        tin, tout = t[:, 0 : 2 * m : 2], t[:, 1 : 2 * m : 2]
        # A ray (almost) along the extrusion axis: its 2-D trace is a point.
        along = n2 <= 1e-24
        if np.any(along):
            inside = self.contains2d(np.array(o[self.i]), np.array(o[self.j]))
            tin = np.where(along[:, None], INF, tin)
            tout = np.where(along[:, None], INF, tout)
            if inside:
                tin[along, 0] = -INF
                tout[along, 0] = INF
        sn, sf = _slab(o[self.k], D[:, self.k], self.a0, self.a1)
        ci = sn[:, None] > tin
        co = sf[:, None] < tout
        tin = np.maximum(tin, sn[:, None])
        tout = np.minimum(tout, sf[:, None])
        valid = tin < tout
        sig = sig + ((ci & valid) * self.w[-2]).sum(axis=1) + ((co & valid) * self.w[-1]).sum(axis=1)
        tt = np.empty((N, 2 * m))
        ss = np.zeros((N, 2 * m), np.int8)
        tt[:, 0::2] = np.where(valid, tin, INF)
        tt[:, 1::2] = np.where(valid, tout, INF)
        ss[:, 0::2] = valid
        ss[:, 1::2] = -valid.astype(np.int8)
        return tt, ss, sig


class Revolution(Solid):
    """Solid of revolution about axis k of a profile [[radius, axial], ...]:
    the points whose (distance from the axis, axial coordinate) lie inside
    the profile polygon.  Written as the exclusive-or of the solid frustums
    {a between the edge's ends, r <= the edge's radius at a}, one per profile
    edge that is not perpendicular to the axis; a ray's counter is the
    number of frustums it is inside, and the solid is where it is odd."""

    mode = "parity"

    def __init__(self, k, profile):
        self.k = k
        prof = np.asarray(profile, float)
        if np.any(prof[:, 0] < 0):
            raise ValueError("a revolution's profile needs radius >= 0")
        self.p, self.q = [i for i in range(3) if i != k]
        fr = []
        n = len(prof)
        for m in range(n):
            (r0, a0), (r1, a1) = prof[m], prof[(m + 1) % n]
            if a0 == a1 or (r0 == 0 and r1 == 0):
                continue
            if a0 > a1:
                r0, a0, r1, a1 = r1, a1, r0, a0
            fr.append((r0, a0, r1, a1))
        self.F = np.array(fr, float).reshape(-1, 4)
        self.rmax = prof[:, 0].max()
        self.alo, self.ahi = prof[:, 1].min(), prof[:, 1].max()
        self.n_events = 2 * len(self.F)
        self.w = _weights(3 * len(self.F), 4)

    def bbox(self):
        lo = np.full(3, -self.rmax)
        hi = np.full(3, self.rmax)
        lo[self.k], hi[self.k] = self.alo, self.ahi
        return lo, hi

    def events(self, o, D):
        N = len(D)
        p, q, k = self.p, self.q, self.k
        A = (D[:, p] ** 2 + D[:, q] ** 2)[:, None]
        B = (2.0 * (o[p] * D[:, p] + o[q] * D[:, q]))[:, None]
        C = o[p] ** 2 + o[q] ** 2
        r0, a0, r1, a1 = (self.F[:, c][None, :] for c in range(4))
        kk = (r1 - r0) / (a1 - a0)
        Da = D[:, k][:, None]
        alpha = r0 + kk * (o[k] - a0)
        beta = kk * Da
        a2 = A - beta * beta
        b2 = B - 2.0 * alpha * beta
        c2 = C - alpha * alpha
        a2, b2, c2 = np.broadcast_arrays(a2, b2, c2)
        pos = a2 > 0
        neg = a2 < 0
        # convex case (or linear): one interval
        tn, tf = quadratic_le0(np.where(pos, a2, 0.0), b2, c2)
        # concave case: the complement of the roots' interval
        if np.any(neg):
            disc = b2 * b2 - 4.0 * a2 * c2
            okn = neg & (disc > 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                sq = np.sqrt(np.where(okn, disc, 0.0))
                qq = -0.5 * (b2 + np.where(b2 >= 0, sq, -sq))
                ra, rb = qq / a2, c2 / qq
            lo_root = np.minimum(ra, rb)
            hi_root = np.maximum(ra, rb)
            allt = neg & ~(disc > 0)
            tn = np.where(allt, -INF, tn)
            tf = np.where(allt, INF, tf)
            # two pieces (-inf, lo_root] and [hi_root, inf)
            tn = np.where(okn, -INF, tn)
            tf = np.where(okn, lo_root, tf)
            tn2 = np.where(okn, hi_root, INF)
            tf2 = np.where(okn, INF, -INF)
        else:
            tn2 = np.full(tn.shape, INF)
            tf2 = np.full(tn.shape, -INF)
        with np.errstate(divide="ignore", invalid="ignore"):
            s1 = (a0 - o[k]) / Da
            s2 = (a1 - o[k]) / Da
        sn = np.minimum(s1, s2)
        sf = np.maximum(s1, s2)
        zero = Da == 0
        if np.any(zero):
            inside = (o[k] >= a0) & (o[k] <= a1)
            zero, inside = np.broadcast_arrays(zero, inside)
            sn = np.where(zero, np.where(inside, -INF, INF), sn)
            sf = np.where(zero, np.where(inside, INF, -INF), sf)
        l1, h1 = np.maximum(tn, sn), np.minimum(tf, sf)
        l2, h2 = np.maximum(tn2, sn), np.minimum(tf2, sf)
        v1, v2 = l1 < h1, l2 < h2
        lo = np.where(v1, l1, l2)
        hi = np.where(v2, h2, h1)
        lo = np.where(v1 & v2, np.minimum(l1, l2), lo)
        valid = v1 | v2
        capin = valid & (lo == sn)
        capout = valid & (hi == sf)
        nF = len(self.F)
        sig = (valid * self.w[:nF]).sum(1) + (capin * self.w[nF:2 * nF]).sum(1) + (capout * self.w[2 * nF:]).sum(1)
        tt = np.empty((N, 2 * nF))
        ss = np.zeros((N, 2 * nF), np.int8)
        tt[:, 0::2] = np.where(valid, lo, INF)
        tt[:, 1::2] = np.where(valid, hi, INF)
        ss[:, 0::2] = valid
        ss[:, 1::2] = -valid.astype(np.int8)
        return tt, ss, sig


def _ray_frames(D):
    """Per ray two unit vectors u, w perpendicular to it: u = D x e (e the
    axis along which D is smallest), w = D x u; the same numbers as
    numpy.cross gives, written out."""
    N = len(D)
    m = np.argmin(np.abs(D), axis=1)
    d0, d1, d2 = D[:, 0], D[:, 1], D[:, 2]
    z = np.zeros(N)
    # D x e_x = (0, d2, -d1), D x e_y = (-d2, 0, d0), D x e_z = (d1, -d0, 0)
    u = np.stack([np.where(m == 0, z, np.where(m == 1, -d2, d1)),
                  np.where(m == 0, d2, np.where(m == 1, z, -d0)),
                  np.where(m == 0, -d1, np.where(m == 1, d0, z))], axis=1)
    u /= np.linalg.norm(u, axis=1)[:, None]
    w = np.stack([d1 * u[:, 2] - d2 * u[:, 1], d2 * u[:, 0] - d0 * u[:, 2], d0 * u[:, 1] - d1 * u[:, 0]], axis=1)
    return u, w


LARGE_MESH = 2000  # triangles: above this a mesh is culled through a grid and its events packed
SUB_RAYS = 512  # rays per culled batch of a large mesh
SPLIT_WORK = 1 << 15  # (triangles x rays) above which such a batch is halved


class Mesh(Solid):
    """A closed, outward-oriented triangle mesh (counter-clockwise seen from
    outside), intersected watertight (see the module's description).

    smooth_deg: None (default) gives every plane of coplanar triangles its
    own signature weight, so the renderer integrates every pixel a facet
    edge crosses.  A number groups the triangles into smooth faces instead:
    neighbours whose normals differ by less than smooth_deg share a weight,
    so the facets of one tessellated curved face (an STL of a CAD solid)
    count as one face in the ray signatures and the renderer's midpoint rule
    applies across their edges, while the face's real edges are integrated.
    The paths themselves are those of the facets either way.

    Meshes of more than LARGE_MESH triangles are culled through a grid of
    the triangles' central projections from the focal spot (built once per
    focal spot) and report only the crossings each ray has (events packed
    to the largest count in a chunk); the watertight test is the same."""

    def __init__(self, V, T, smooth_deg=None):
        self.V = np.asarray(V, float)
        self.T = np.asarray(T, np.int64)
        self.large = len(self.T) > LARGE_MESH
        if self.large:
            self._edges_vectorized()
        else:
            key = {}
            edges = []
            tri_edge = np.zeros((len(self.T), 3), np.int64)
            tri_sign = np.zeros((len(self.T), 3), np.int64)
            uses = {}
            for f, (a, b, c) in enumerate(self.T):
                for m, (i, j) in enumerate(((a, b), (b, c), (c, a))):
                    u = (min(i, j), max(i, j))
                    if u not in key:
                        key[u] = len(edges)
                        edges.append(u)
                    tri_edge[f, m] = key[u]
                    tri_sign[f, m] = 1 if i < j else -1
                    uses[u] = uses.get(u, 0) + (1 if i < j else -1)
            self.open_edges = sum(1 for v in uses.values() if v != 0)
            self.E = np.array(edges, np.int64)
            self.tri_edge = tri_edge
            self.tri_sign = tri_sign.astype(np.int8)
        A, B, C = (self.V[self.T[:, m]] for m in range(3))
        self.N = np.cross(B - A, C - A)
        self.A = A
        area2 = np.linalg.norm(self.N, axis=1)
        nn = self.N / np.where(area2 > 0, area2, 1.0)[:, None]
        if smooth_deg is not None:
            gid = self._smooth_groups(nn, float(smooth_deg))
            self.w = _weights(int(gid.max()) + 1 if len(gid) else 0, 5)[gid]
        elif self.large:
            key = np.round(np.column_stack([nn, np.einsum("ij,ij->i", nn, A) * 1e-3]), 9)
            _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
            rank = np.empty(len(first), np.int64)
            rank[np.argsort(first)] = np.arange(len(first))
            gid = rank[inv.ravel()]
            self.w = _weights(len(first), 5)[gid]
        else:
            # coplanar triangles share a signature weight
            off = np.einsum("ij,ij->i", nn, A)
            groups = {}
            gid = np.zeros(len(self.T), np.int64)
            for f in range(len(self.T)):
                g = tuple(np.round(np.append(nn[f], off[f] * 1e-3), 9))
                gid[f] = groups.setdefault(g, len(groups))
            self.w = _weights(len(groups), 5)[gid]
        self.n_events = 32 if self.large else len(self.T)
        self._proj = None

    def _edges_vectorized(self):
        T = self.T
        nv = max(len(self.V), 1)
        a = T
        b = T[:, [1, 2, 0]]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        uk, first, inv = np.unique((lo * nv + hi).ravel(), return_index=True, return_inverse=True)
        # edges numbered by first appearance, as the loop does for small meshes
        rank = np.empty(len(uk), np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(uk))
        inv = rank[inv.ravel()]
        E = np.empty((len(uk), 2), np.int64)
        E[rank] = np.column_stack([uk // nv, uk % nv])
        sign = np.where(a < b, 1, -1)
        uses = np.bincount(inv, weights=sign.ravel(), minlength=len(uk))
        self.open_edges = int(np.count_nonzero(uses))
        self.E = E
        self.tri_edge = inv.reshape(-1, 3)
        self.tri_sign = sign.astype(np.int8)

    def _smooth_groups(self, nn, deg):
        """Triangles joined across edges where their normals differ by less
        than deg, numbered by first appearance."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        nt = len(self.T)
        te = self.tri_edge.ravel()
        tri = np.repeat(np.arange(nt), 3)
        order = np.argsort(te, kind="stable")
        te, tri = te[order], tri[order]
        same = te[1:] == te[:-1]
        t1, t2 = tri[:-1][same], tri[1:][same]
        smooth = np.einsum("ij,ij->i", nn[t1], nn[t2]) > np.cos(np.radians(deg))
        g = coo_matrix((np.ones(int(smooth.sum())), (t1[smooth], t2[smooth])), shape=(nt, nt))
        _, lab = connected_components(g, directed=False)
        _, first, inv = np.unique(lab, return_index=True, return_inverse=True)
        rank = np.empty(len(first), np.int64)
        rank[np.argsort(first)] = np.arange(len(first))
        return rank[inv.ravel()]

    def bbox(self):
        return self.V.min(axis=0), self.V.max(axis=0)

    def _crossings(self, o, D, keep, Vr, vsub):
        """The watertight test of rays D against the triangles `keep`:
        (t, s) of shape (n_keep, N) and the rays' signatures.  Vr: vertices
        minus o (all, or those listed by vsub)."""
        u, w = _ray_frames(D)
        te, ts = self.tri_edge[keep], self.tri_sign[keep]
        used, te = np.unique(te, return_inverse=True)
        te = te.reshape(-1, 3)
        i, j = self.E[used, 0], self.E[used, 1]
        if vsub:
            vs, ij = np.unique(np.concatenate([i, j]), return_inverse=True)
            i, j = ij[:len(i)], ij[len(i):]
            Vr = Vr[vs]
        X = Vr @ u.T  # (nv, N): every vertex projected once per ray
        Y = Vr @ w.T
        Xi, Yi, Xj, Yj = X[i], Y[i], X[j], Y[j]
        ef = Xi * Yj - Yi * Xj  # (ne, N), shared by the edge's two triangles
        sgn = np.sign(ef).astype(np.int8)
        zero = ef == 0
        if np.any(zero):
            dy = Yj - Yi
            dx = Xj - Xi
            pert = np.where(dy != 0, -np.sign(dy), np.sign(dx)).astype(np.int8)
            sgn = np.where(zero, pert, sgn)
        tot = (sgn[te[:, 0]] * ts[:, 0:1] + sgn[te[:, 1]] * ts[:, 1:2]
               + sgn[te[:, 2]] * ts[:, 2:3])  # (nt, N): +-3 where the ray is inside the triangle
        den = self.N[keep] @ D.T  # (nt, N)
        hit = (np.abs(tot) == 3) & (den != 0)
        num = np.einsum("ij,ij->i", self.N[keep], self.A[keep] - o)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(hit, num[:, None] / den, INF)
        s = np.where(hit, -(tot // 3), 0).astype(np.int8)
        sig = self.w[keep] @ hit
        return t, s, sig, hit

    def events(self, o, D):
        if self.large:
            return self._events_large(o, D)
        N = len(D)
        Vr = self.V - o
        keep = self._cull(Vr, D)
        t, s, sig, _ = self._crossings(o, D, keep, Vr, False)
        tt = np.full((N, self.n_events), INF)
        ss = np.zeros((N, self.n_events), np.int8)
        k = len(t)
        tt[:, :k] = t.T
        ss[:, :k] = s.T
        return tt, ss, sig

    def _events_large(self, o, D):
        N = len(D)
        P = self._projection(o)
        Vr = P["Vr"] if P is not None else self.V - o
        order = self._compact_order(P, D) if P is not None else None
        pieces = []
        kmax = 0
        todo = [(a, min(N, a + SUB_RAYS), None) for a in range(0, N, SUB_RAYS)][::-1]
        while todo:
            a, b, within = todo.pop()
            Db = D[a:b] if order is None else D[order[a:b]]
            keep = self._candidates(P, Db, within) if P is not None else None
            if keep is None:
                keep = np.nonzero(self._cull(Vr, Db))[0]
            elif order is not None and b - a > 16 and len(keep) * (b - a) > SPLIT_WORK:
                # many triangles over these rays (a dense face seen at a grazing angle): halve the batch
                h = (a + b) // 2
                todo += [(h, b, keep), (a, h, keep)]
                continue
            if len(keep) == 0:
                pieces.append((a, b, None, None, None, np.zeros(b - a)))
                continue
            t, s, sig, hit = self._crossings(o, Db, keep, Vr, True)
            r, k = np.nonzero(hit.T)  # ray-major: each ray's crossings in triangle order
            cnt = np.bincount(r, minlength=b - a)
            pos = np.arange(len(r)) - (np.cumsum(cnt) - cnt)[r]
            kmax = max(kmax, int(cnt.max()) if len(cnt) else 0)
            pieces.append((a, b, r, pos, (t[k, r], s[k, r]), sig))
        tt = np.full((N, kmax), INF)
        ss = np.zeros((N, kmax), np.int8)
        sig = np.zeros(N)
        idx = np.arange(N) if order is None else order
        for a, b, r, pos, ts_, sg in pieces:
            sig[idx[a:b]] = sg
            if r is not None and len(r):
                tt[idx[a + r], pos] = ts_[0]
                ss[idx[a + r], pos] = ts_[1]
        return tt, ss, sig

    @staticmethod
    def _compact_order(P, D):
        """The rays sorted along a Z-order curve of their projections (cells
        of the culling grid), so that each batch of SUB_RAYS rays is compact
        (each ray's result does not depend on its batch)."""
        Dz = D @ P["dc"]
        if np.any(Dz <= 0.5):
            return None
        n = P["n"]
        ia = np.clip(((D @ P["e1"]) / Dz - P["a0"]) // P["ha"], 0, n - 1).astype(np.int64)
        ib = np.clip(((D @ P["e2"]) / Dz - P["b0"]) // P["hb"], 0, n - 1).astype(np.int64)
        key = np.zeros(len(D), np.int64)
        for bit in range(10):
            key |= ((ia >> bit) & 1) << (2 * bit) | ((ib >> bit) & 1) << (2 * bit + 1)
        return np.argsort(key, kind="stable")

    def _projection(self, o):
        """The triangles' central projections from o onto the plane
        perpendicular to the direction of the mesh's centre, binned into a
        grid (cached for the last o); None where o is not clearly outside."""
        key = np.asarray(o, float).tobytes()
        if self._proj is not None and self._proj[0] == key:
            return self._proj[1]
        Vr = self.V - o
        lo, hi = self.bbox()
        dc = 0.5 * (lo + hi) - o
        if not np.linalg.norm(dc) > 0:
            self._proj = (key, None)
            return None
        dc = dc / np.linalg.norm(dc)
        e1 = np.cross(dc, np.eye(3)[np.argmin(np.abs(dc))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(dc, e1)
        z = Vr @ dc
        if np.any(z <= 1e-6 * np.abs(z).max()):
            self._proj = (key, None)
            return None
        a, b = (Vr @ e1) / z, (Vr @ e2) / z
        at, bt = a[self.T], b[self.T]
        amin, amax, bmin, bmax = at.min(1), at.max(1), bt.min(1), bt.max(1)
        eps = 1e-9 * (np.ptp(a) + np.ptp(b) + 1e-12)
        n = int(min(512, max(16, 2 * np.sqrt(len(self.T)))))
        a0, b0 = a.min() - 2 * eps, b.min() - 2 * eps
        ha = (a.max() + 2 * eps - a0) / n
        hb = (b.max() + 2 * eps - b0) / n
        ia0 = np.clip(((amin - eps - a0) // ha).astype(np.int64), 0, n - 1)
        ia1 = np.clip(((amax + eps - a0) // ha).astype(np.int64), 0, n - 1)
        ib0 = np.clip(((bmin - eps - b0) // hb).astype(np.int64), 0, n - 1)
        ib1 = np.clip(((bmax + eps - b0) // hb).astype(np.int64), 0, n - 1)
        na, nb = ia1 - ia0 + 1, ib1 - ib0 + 1
        cnt = na * nb
        tri = np.repeat(np.arange(len(self.T)), cnt)
        k = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        cell = (ia0[tri] + k // nb[tri]) * n + ib0[tri] + k % nb[tri]
        order = np.argsort(cell, kind="stable")
        starts = np.searchsorted(cell[order], np.arange(n * n + 1))
        # each projected triangle's edge lines: f(q) = na qa + nb qb - c0, the triangle on the side sk
        na = -(np.roll(bt, -1, axis=1) - bt)
        nb = np.roll(at, -1, axis=1) - at
        c0 = na * at + nb * bt
        sk = np.sign(na * np.roll(at, -2, axis=1) + nb * np.roll(bt, -2, axis=1) - c0)
        tol = eps * np.hypot(na, nb)
        P = {"Vr": Vr, "dc": dc, "e1": e1, "e2": e2, "eps": eps, "n": n, "a0": a0, "b0": b0, "ha": ha, "hb": hb,
             "tri": tri[order], "starts": starts, "box": (amin, amax, bmin, bmax),
             "lines": (na * sk, nb * sk, c0 * sk, tol)}
        self._proj = (key, P)
        return P

    def _candidates(self, P, D, within=None):
        """The triangles (of `within`, else of the grid's cells) whose
        projection can meet the rays' (conservative: their bounding boxes
        overlap and no edge of the triangle separates them), or None where
        the rays are not all well in front."""
        Dz = D @ P["dc"]
        if np.any(Dz <= 0.5):
            return None
        ra, rb = (D @ P["e1"]) / Dz, (D @ P["e2"]) / Dz
        eps, n = P["eps"], P["n"]
        lo_a, hi_a, lo_b, hi_b = ra.min() - eps, ra.max() + eps, rb.min() - eps, rb.max() + eps
        cl = lambda x: min(max(int(x), 0), n - 1)  # noqa: E731
        i0, i1 = cl((lo_a - P["a0"]) // P["ha"]), cl((hi_a - P["a0"]) // P["ha"])
        j0, j1 = cl((lo_b - P["b0"]) // P["hb"]), cl((hi_b - P["b0"]) // P["hb"])
        if within is None:
            st, tri = P["starts"], P["tri"]
            c = np.unique(np.concatenate([tri[st[i * n + j0]:st[i * n + j1 + 1]] for i in range(i0, i1 + 1)]))
        else:
            c = within
        amin, amax, bmin, bmax = (x[c] for x in P["box"])
        ok = (amax >= lo_a) & (amin <= hi_a) & (bmax >= lo_b) & (bmin <= hi_b)
        c = c[ok]
        # separating axes: a triangle edge's line with the rays' whole rectangle beyond it (by more than
        # eps) on the side away from the triangle (long facets seen at a slant have wide bounding boxes)
        na, nb, c0, tol = (x[c] for x in P["lines"])
        sep = None
        for qa, qb in ((lo_a, lo_b), (hi_a, lo_b), (lo_a, hi_b), (hi_a, hi_b)):
            beyond = na * qa + nb * qb - c0 < -tol
            sep = beyond if sep is None else sep & beyond
        return c[~sep.any(axis=1)]

    def _cull(self, Vr, D):
        """The triangles whose central projection (from the focal spot) can
        contain one of these rays: a conservative bounding-box test in the
        plane perpendicular to the rays' mean direction."""
        keep = np.ones(len(self.T), bool)
        if len(self.T) <= 4 or len(D) < 32:
            return keep
        dc = D.mean(axis=0)
        dc /= np.linalg.norm(dc)
        e1 = np.cross(dc, np.eye(3)[np.argmin(np.abs(dc))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(dc, e1)
        z = Vr @ dc
        Dz = D @ dc
        if np.any(z <= 1e-9 * np.abs(z).max()) or np.any(Dz <= 0.5):
            return keep
        a, b = (Vr @ e1) / z, (Vr @ e2) / z
        ra, rb = (D @ e1) / Dz, (D @ e2) / Dz
        eps = 1e-9 * (np.ptp(a) + np.ptp(b) + 1e-12)
        at, bt = a[self.T], b[self.T]
        keep = ((at.max(1) >= ra.min() - eps) & (at.min(1) <= ra.max() + eps)
                & (bt.max(1) >= rb.min() - eps) & (bt.min(1) <= rb.max() + eps))
        return keep


def fibonacci_lattice(n_points):
    """A rank-1 (Fibonacci) lattice of n points in the unit square, shifted
    by half a cell: every row and every column of an n x n grid holds one
    point, so an edge along either axis is integrated to 1/(2n) of a pixel."""
    fib = [1, 1]
    while fib[-1] < n_points:
        fib.append(fib[-1] + fib[-2])
    if fib[-1] != n_points:
        raise ValueError(f"{n_points} is not a Fibonacci number")
    g = fib[-2]
    k = np.arange(n_points)
    return np.stack([(k + 0.5) / n_points, np.mod(k * g + 0.5, n_points) / n_points], axis=1)
