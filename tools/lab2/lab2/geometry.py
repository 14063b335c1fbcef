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


class Mesh(Solid):
    """A closed, outward-oriented triangle mesh (counter-clockwise seen from
    outside), intersected watertight (see the module's description)."""

    def __init__(self, V, T):
        self.V = np.asarray(V, float)
        self.T = np.asarray(T, np.int64)
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
        # coplanar triangles share a signature weight
        area2 = np.linalg.norm(self.N, axis=1)
        nn = self.N / np.where(area2 > 0, area2, 1.0)[:, None]
        off = np.einsum("ij,ij->i", nn, A)
        groups = {}
        gid = np.zeros(len(self.T), np.int64)
        for f in range(len(self.T)):
            g = tuple(np.round(np.append(nn[f], off[f] * 1e-3), 9))
            gid[f] = groups.setdefault(g, len(groups))
        self.w = _weights(len(groups), 5)[gid]
        self.n_events = len(self.T)

    def bbox(self):
        return self.V.min(axis=0), self.V.max(axis=0)

    def events(self, o, D):
        N = len(D)
        m = np.argmin(np.abs(D), axis=1)
        e = np.zeros_like(D)
        e[np.arange(N), m] = 1.0
        u = np.cross(D, e)
        u /= np.linalg.norm(u, axis=1)[:, None]
        w = np.cross(D, u)
        Vr = self.V - o
        keep = self._cull(Vr, D)
        te, ts = self.tri_edge[keep], self.tri_sign[keep]
        used, te = np.unique(te, return_inverse=True)
        te = te.reshape(-1, 3)
        X = Vr @ u.T  # (nv, N): every vertex projected once per ray
        Y = Vr @ w.T
        i, j = self.E[used, 0], self.E[used, 1]
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
        tt = np.full((N, self.n_events), INF)
        ss = np.zeros((N, self.n_events), np.int8)
        k = len(t)
        tt[:, :k] = t.T
        ss[:, :k] = s.T
        return tt, ss, sig

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
