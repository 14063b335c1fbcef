"""A part (CSG tree of exact solids) placed in the world by a pose, and the
path length of rays from the focal spot through it."""

import numpy as np

from .partmodel import Node, rotation_matrix

CHUNK_ELEMENTS = 1 << 21  # rays x events per chunk: keeps memory near 0.5 GB


class Scene:
    """root: a partmodel.Node tree; pose: x_world = R x_part + t."""

    def __init__(self, root, R=None, t=None):
        self.root = root
        self.R = np.eye(3) if R is None else np.asarray(R, float)
        self.t = np.zeros(3) if t is None else np.asarray(t, float)
        self.leaves = []  # (solid, M, c): x_world = M x_local + c
        self._collect(root, self.R, self.t)
        self.n_events = sum(s.n_events for s, _, _ in self.leaves)
        self.simple = len(self.leaves) == 1 and self.leaves[0][0].mode == "count" and root.op == "leaf"

    @staticmethod
    def from_pose(root, rotation_deg=(0, 0, 0), translation_mm=(0, 0, 0)):
        return Scene(root, rotation_matrix(*rotation_deg), np.asarray(translation_mm, float))

    def _collect(self, node, M, c):
        # node placement: x_parent = R_n x_child + t_n ; parent -> world: M, c
        M2 = M @ node.R
        c2 = M @ node.t + c
        if node.op == "leaf":
            node._leaf_index = len(self.leaves)
            self.leaves.append((node.solid, M2, c2))
        else:
            for ch in node.children:
                self._collect(ch, M2, c2)

    def bbox_corners_world(self):
        pts = []
        for solid, M, c in self.leaves:
            lo, hi = solid.bbox()
            for m in range(8):
                p = np.array([hi[a] if (m >> a) & 1 else lo[a] for a in range(3)])
                pts.append(M @ p + c)
        return np.array(pts)

    def _membership(self, node, inside):
        if node.op == "leaf":
            return inside[node._leaf_index]
        kids = [self._membership(ch, inside) for ch in node.children]
        if node.op == "union":
            out = kids[0].copy()
            for k in kids[1:]:
                out |= k
            return out
        if node.op == "intersection":
            out = kids[0].copy()
            for k in kids[1:]:
                out &= k
            return out
        out = kids[0].copy()  # difference
        for k in kids[1:]:
            out &= ~k
        return out

    def trace(self, S, D):
        """Path lengths (mm) along unit directions D (N, 3) from the world point
        S, and a per-ray signature (equal for rays that cross the same faces)."""
        D = np.asarray(D, float)
        N = len(D)
        path = np.zeros(N)
        sig = np.zeros(N)
        step = max(256, CHUNK_ELEMENTS // max(1, self.n_events * 3))
        for a in range(0, N, step):
            b = min(N, a + step)
            path[a:b], sig[a:b] = self._trace_chunk(S, D[a:b])
        return path, sig

    def _trace_chunk(self, S, D):
        ev = []
        sig = np.zeros(len(D))
        for n, (solid, M, c) in enumerate(self.leaves):
            o = M.T @ (np.asarray(S, float) - c)
            Dl = D @ M
            t, s, g = solid.events(o, Dl)
            np.clip(t, -1e12, np.inf, out=t)
            ev.append((t, s))
            sig += g * (1.0 + 0.37 * n)
        if self.simple:
            t, s = ev[0]
            st = np.where(s != 0, s * np.where(np.isfinite(t), t, 0.0), 0.0)
            return -st.sum(axis=1), sig
        T = np.concatenate([e[0] for e in ev], axis=1)
        Sg = np.concatenate([e[1] for e in ev], axis=1)
        col = np.concatenate([np.full(e[0].shape[1], n) for n, e in enumerate(ev)])
        order = np.argsort(T, axis=1, kind="stable")
        Ts = np.take_along_axis(T, order, axis=1)
        Ss = np.take_along_axis(Sg, order, axis=1).astype(np.int32)
        Ls = col[order]
        inside = []
        for n, (solid, _, _) in enumerate(self.leaves):
            cnt = np.cumsum(np.where(Ls == n, Ss, 0), axis=1)
            inside.append(cnt > 0 if solid.mode == "count" else (cnt & 1) == 1)
        keep = self._membership(self.root, inside)
        fin = np.isfinite(Ts)
        last = np.max(np.where(fin, Ts, -np.inf), axis=1)
        last = np.where(np.isfinite(last), last, 0.0)
        Tf = np.where(fin, Ts, last[:, None])
        seg = np.diff(Tf, axis=1)
        return (seg * keep[:, :-1]).sum(axis=1), sig
