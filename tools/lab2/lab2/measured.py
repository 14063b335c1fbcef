"""Measured parts (prism, wedge block, bracket, stepped shaft, screw) as a lab
would shoot them: per part a production specimen with a translated pair
(t00, t01 = t00 + 10 mm along a nearly horizontal axis) and a rotated shot
r00 (the part turned in place, where t00 was, by 0 to 90 deg about a stage
axis tilted 2 to 10 deg from the world's y), and a master specimen of the
same type shot n times (sets) the same way, each set a new placement at the
same magnification.  Jobs carry the run's stated inputs (stated.py)."""

import math
import os
import zlib

import numpy as np

from . import physical, stated
from .partmodel import euler_from_matrix, rotation_matrix
from .render import render
from .scene import Scene

STEP_MM = 10.0


def axis_angle_matrix(axis, deg):
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    th = math.radians(deg)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K


def _wrap(x):
    return (np.asarray(x, float) + 180.0) % 360.0 - 180.0


def euler_near(R, ref):
    """Euler angles (R = Rz Ry Rx, degrees) of R on the branch, and within
    the turn, nearest to ref."""
    e = np.array(euler_from_matrix(R))
    alt = np.array([e[0] + 180.0, 180.0 - e[1], e[2] + 180.0])
    best = None
    for c in (e, alt):
        c = np.asarray(ref) + _wrap(c - np.asarray(ref))
        if best is None or np.abs(c - ref).sum() < np.abs(best - ref).sum():
            best = c
    return [float(v) for v in best]


def base_rotation(kind, rng):
    """How a lab puts the part down (Euler degrees)."""
    s = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    if kind == "prism":
        return [rng.uniform(-2, 2), rng.uniform(-15, 15), rng.uniform(-2, 2)]
    if kind == "wedge":
        return [rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-3, 3)]
    if kind == "bracket":  # looking roughly along its y (the L and the fillet in profile), tilted so the holes open
        return [90.0 + s() * rng.uniform(15, 25), s() * rng.uniform(15, 25), rng.uniform(-10, 10)]
    if kind == "shaft":  # axis along world y, turned about it so the cross hole is oblique
        return [rng.uniform(-3, 3), s() * rng.uniform(20, 40), rng.uniform(-10, 10)]
    if kind == "screw":
        # Laid on its side: rx = -90 takes the screw's axis (part -z, head to tip) to world -y (head up in the
        # image, the axis across the beam), the slot's walls (normal part y) face the beam; turning it about
        # its axis (world y) by 35 to 55 deg either way puts the beam at 35 to 55 deg from the slot's walls and
        # its run (part x): the slot seen obliquely (walls, floor and their ends make edges), part x (the
        # shank_offset) with a component sin 35..55 deg across the beam; the slot's floor and the tip's face
        # (normal to the axis) stay along the beam within the tilt.
        return [-90.0 + rng.uniform(-2, 2), s() * rng.uniform(35, 55), rng.uniform(-10, 10)]
    raise ValueError(kind)


def stage_axis(rng):
    tilt, ph = math.radians(rng.uniform(2.0, 10.0)), rng.uniform(0, 2 * math.pi)
    return np.array([math.sin(tilt) * math.cos(ph), math.cos(tilt), math.sin(tilt) * math.sin(ph)])


class PartRun:
    def __init__(self, sess, kind, n_master=3, n_specimens=1):
        self.s = sess
        self.m = sess.m
        self.kind = kind
        self.n_master = n_master  # shot sets per master specimen
        self.n_specimens = max(1, int(n_specimens))  # master specimens, each drawn on its own
        self.pm = physical.model(kind)
        self.root_dir = os.path.join(sess.out, "measured")
        self.longest = 0.0

    def rng(self, tag):
        return np.random.default_rng([self.m.seed, zlib.crc32(f"measured/{self.kind}/{tag}".encode())])

    def magnification(self, dims):
        m = self.m
        cfg = m.cfg.get("parts", {}).get(self.kind, {})
        M = float(cfg.get("magnification", m.cfg["prism"]["magnification"]))
        bb = Scene(self.pm.build(dims)).bbox_corners_world()
        diam = float(np.linalg.norm(bb.max(0) - bb.min(0)))
        wmm, hmm = m.panel_mm
        M_fit = 0.9 * min(wmm, hmm) / (diam + STEP_MM)
        M = min(M, M_fit)
        if M < 1.02:
            raise ValueError(f"{self.kind} does not fit on the panel of {m.cfg['id']} (magnification {M_fit:.2f})")
        return round(M, 4)

    # ------------------------------------------------------------------
    def run(self):
        pc = self.m.cfg["prism"].get("dimensions", "A")
        rng = self.rng("specimen")
        dims = physical.draw_dimensions(self.kind, rng, prism=pc if pc in ("A", "B") else "A")
        imp = physical.draw_imperfections(self.kind, rng)
        M = self.magnification(dims)
        z = self.m.geom.sdd * (1 - 1 / M)
        base = base_rotation(self.kind, rng)
        prod = os.path.join(self.root_dir, self.kind)
        mroot = os.path.join(self.root_dir, self.kind + "_master")
        sets = [self.shoot_set(prod, f"{self.kind}", dims, imp, z, base, self.rng("production"), 1)]
        # Master specimens: the first drawn as before several existed (its
        # folders set0, set1, ...), the others each with their own draws
        # (folders m1set0, ...).
        specimens = []
        for j in range(self.n_specimens):
            tag = "master" if j == 0 else f"master{j}"
            rng_m = self.rng(tag)
            dims_m = physical.draw_dimensions(self.kind, rng_m, prism=pc if pc in ("A", "B") else "A")
            imp_m = physical.draw_imperfections(self.kind, rng_m)
            cert, u_cmm = stated.certificate(dims_m, rng_m)
            prefix = "" if j == 0 else f"m{j}"
            folders = [f"{prefix}set{k}" for k in range(self.n_master)]
            for k, f in enumerate(folders):
                sets.append(self.shoot_set(os.path.join(mroot, f), f"{self.kind}_master/{f}", dims_m, imp_m,
                                           z, base, self.rng(f"{tag}_set{k}"), 2))
            specimens.append({"dimensions": dims_m, "imperfections": imp_m, "certificate": cert,
                              "cmm_standard_uncertainty_mm": u_cmm, "folders": folders})
        from .session import fit_material, write_json
        write_json(os.path.join(prod, "material_true.json"), fit_material(self.m.beam, 1.05 * self.longest + 0.5))
        for st in sets:
            self.write_jobs(st)
        names = ["pair", "pair_rotated"]
        if self.n_master:
            for nm in names:
                for mat in ("", "_true_material"):
                    what = (f"a master of the same type: {self.n_master} shot sets, certificate from a CMM "
                            f"(u = {specimens[0]['cmm_standard_uncertainty_mm']} mm)" if self.n_specimens == 1 else
                            f"{self.n_specimens} masters of the same type, each drawn on its own: {self.n_master} "
                            "shot sets each, certificates from a CMM")
                    vjob = {"description": f"lab2 {self.m.cfg['id']}: verification of the {self.kind} jobs "
                                           f"({nm.replace('_', ' + ')}{', true material' if mat else ''}) on {what}; "
                                           f"run: xgauge verify verify_{nm}{mat}.json -o verification_{nm}{mat}"}
                    jobs_of = [[f"{f}/job_{nm}{mat}.json" for f in sp["folders"]] for sp in specimens]
                    if self.n_specimens == 1:
                        vjob.update({"master": {"certificate": specimens[0]["certificate"]},
                                     "measurements": jobs_of[0]})
                    else:
                        vjob["masters"] = [{"certificate": sp["certificate"], "measurements": js}
                                           for sp, js in zip(specimens, jobs_of)]
                    write_json(os.path.join(mroot, f"verify_{nm}{mat}.json"), vjob)
                    job = dict(sets[0]["jobs"][f"job_{nm}{mat}.json"])
                    job["description"] += (f"; verified by ../{self.kind}_master/verification_{nm}{mat}/"
                                           "verification.json (run xgauge verify first)")
                    job["verification"] = f"../{self.kind}_master/verification_{nm}{mat}/verification.json"
                    write_json(os.path.join(prod, f"job_{nm}{mat}_verified.json"), job)
        return {"folder": f"measured/{self.kind}", "model": self.pm.path, "dimensions": dims, "imperfections": imp,
                "magnification_bbox_centre": M, "z_mm": z, "base_rotation_deg": base,
                "production": {k: v for k, v in sets[0].items() if k not in ("jobs", "centre_t00", "e")},
                "master": None if not self.n_master else {
                    "folder": f"measured/{self.kind}_master", "dimensions": specimens[0]["dimensions"],
                    "imperfections": specimens[0]["imperfections"], "certificate": specimens[0]["certificate"],
                    "cmm_standard_uncertainty_mm": specimens[0]["cmm_standard_uncertainty_mm"],
                    "sets": [{k: v for k, v in st.items() if k not in ("jobs", "centre_t00", "e")} for st in sets[1:]],
                    "specimens": specimens,
                    "verify_jobs": [f"measured/{self.kind}_master/verify_{nm}{mat}.json"
                                    for nm in names for mat in ("", "_true_material")]},
                "note": physical.__doc__.strip()}

    # ------------------------------------------------------------------
    def placement(self, dims, z, base, rng):
        """Where the lab puts the part: t00 at a drawn rotation near `base`,
        t01 = t00 moved by STEP_MM along a nearly horizontal axis, r00 turned
        from t00 by a drawn angle (0 to 90 deg) about a drawn stage axis through
        the part's (true) bounding-box centre at t00's position."""
        m, g = self.m, self.m.geom
        rot = [float(b + rng.uniform(-3, 3)) for b in base]
        R0 = rotation_matrix(*rot)
        bb = Scene(self.pm.build(dims)).bbox_corners_world()
        cpart = 0.5 * (bb.min(0) + bb.max(0))
        axis = np.array([1.0, rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03)])
        axis /= np.linalg.norm(axis)
        target = (g.columns * rng.uniform(0.46, 0.54), g.rows * rng.uniform(0.46, 0.54))
        cmid = m.pixel_to_world(target[0], target[1], z)
        c0 = cmid - axis * STEP_MM / 2
        sax = stage_axis(rng)
        angle = float(rng.uniform(0.0, 90.0))
        R2 = axis_angle_matrix(sax, angle) @ R0
        poses = [("t00", R0, c0 - R0 @ cpart), ("t01", R0, c0 + STEP_MM * axis - R0 @ cpart),
                 ("r00", R2, c0 - R2 @ cpart)]
        return {"rotation_deg": rot, "axis": axis, "stage_axis": sax, "angle_deg": angle, "poses": poses,
                "centre": c0, "cpart": cpart, "bbox": bb}

    def shoot_set(self, folder, label, dims, imp, z, base, rng, depth):
        from .session import pose_json, write_json
        s, m, g = self.s, self.m, self.m.geom
        os.makedirs(folder, exist_ok=True)
        doc, root = physical.physical_part(self.kind, dims, imp, folder=folder)
        if doc is not None:
            write_json(os.path.join(folder, "physical_part.json"), doc)
        pl = self.placement(dims, z, base, rng)
        rot, axis, sax, angle, poses = pl["rotation_deg"], pl["axis"], pl["stage_axis"], pl["angle_deg"], pl["poses"]
        R0, R2, c0 = poses[0][1], poses[2][1], pl["centre"]
        bb = pl["bbox"]
        shots, shadow = [], np.zeros((g.rows, g.columns), bool)
        margin = 0.02 * max(g.columns, g.rows)
        for i, (name, R, t) in enumerate(poses):
            sc = Scene(root, R, t)
            pu, pv = g.project(sc.bbox_corners_world())
            if pu.min() < margin or pv.min() < margin or pu.max() > g.columns - margin or pv.max() > g.rows - margin:
                raise ValueError(f"{label} {name} leaves the panel of {m.cfg['id']}")
            st = {}
            T = render(sc, g, fn=m.lut_al, stats=st)
            self.longest = max(self.longest, st.get("max_centre_path_mm", 0.0))
            shadow |= T < 1.0 - 1e-12
            raw = s.expose(f"{label}/{name}", T, rest=(i == 0))
            sh = {"name": name, "file": name + ".tif", "pattern": "free", "pose": pose_json(R, t), "_raw": raw}
            if name == "t01":
                sh.update(pattern="translated", reference="t00", distance_mm=STEP_MM, axis=[float(v) for v in axis])
            if name == "r00":
                sh.update(pattern="rotated", reference="t00", nominal_angle_deg=round(angle, 1))
            shots.append(sh)
        from scipy import ndimage
        shadow = ndimage.binary_dilation(shadow, iterations=max(8, int(0.02 * g.columns)))
        s.part_bbox_pts = bb
        desc = (f"lab2 {m.cfg['id']}: {self.kind} ({'master' if depth == 2 else 'production'} specimen, "
                f"{self.pm.path}) at magnification {m.geom.sdd / (m.geom.sdd - z):.3f}: t00, t01 translated by "
                f"exactly {STEP_MM} mm, r00 turned by {angle:.2f} deg about the stage axis "
                f"{[round(float(v), 5) for v in sax]} through t00's bounding-box centre")
        if imp:
            desc += f"; imperfections the model lacks (physical_part.json): {imp}"
        if self.kind == "screw":
            desc += (f"; the true solid {physical.SCREW_STL} was made by OpenCASCADE's own operations at the true "
                     "dimensions (builder command line in physical_part.json), no imperfection")
        wr = s.write_dataset(folder, self.kind, self.pm.path, dims, shots, shadow, desc, [])
        e0 = [float(v) for v in euler_from_matrix(R0)]
        return {"folder": os.path.relpath(folder, s.out), "depth": depth, "dims": dims, "white_region": wr,
                "base_rotation_deg": [float(b) for b in base], "rotation_deg": rot, "translation_axis": [float(v) for v in axis], "stage_axis": [float(v) for v in sax],
                "rotation_angle_deg": angle, "e": [e0, euler_near(R2, e0)],
                "centre_t00": [float(v) for v in c0],
                "poses": {n: pose_json(R, t) for n, R, t in poses}}

    def write_jobs(self, st):
        from .session import write_json
        s, pm = self.s, self.pm
        folder = os.path.join(s.out, st["folder"])
        up = "../" * st["depth"]
        dims, wr = st["dims"], st["white_region"]
        start, bounds = start_bounds(pm, dims)
        c = st["centre_t00"]
        centre = [[math.floor(v / 10) * 10 - 20, math.floor(v / 10) * 10 + 30] for v in c]
        halo = {k: s.stated["halo"][k] for k in ("weight", "sigma_mm", "weight_uncertainty", "sigma_uncertainty_mm")}
        rads = [{"name": "t00", "image": "t00.tif", "dark": "dark.tif", "flat": "flat.tif", "white_region": wr,
                 "pattern": "free"},
                {"name": "t01", "image": "t01.tif", "dark": "dark.tif", "flat": "flat.tif", "white_region": wr,
                 "pattern": "translated", "reference": "t00", "distance_mm": STEP_MM, "previous": "t00.tif"},
                {"name": "r00", "image": "r00.tif", "dark": "dark.tif", "flat": "flat.tif", "white_region": wr,
                 "pattern": "rotated", "reference": "t00", "previous": "t01.tif"}]
        mat_true = "material_true.json" if st["depth"] == 1 else f"../../{self.kind}/material_true.json"
        jobs = {}
        for nm, n_r in (("pair", 2), ("pair_rotated", 3)):
            es = st["e"][:1] if n_r == 2 else st["e"]
            lo = [5 * math.floor((min(e[i] for e in es) - 8) / 5) for i in range(3)]
            hi = [5 * math.ceil((max(e[i] for e in es) + 8) / 5) for i in range(3)]
            if self.kind == "screw" and n_r == 2:
                # A screw is nearly a solid of revolution: only its slot tells its turn about its axis, and
                # bounds of +-8 deg let a pose search settle about 5 deg off, in a minimum of ten times the
                # loss. The lab's V-block and stop set the screw's orientation (the drawn base rotation,
                # which the lab knows as its fixture's setting) and hold each shot within 3 deg of it
                # (placement()'s jitter): the pair's bounds are the setting +-4 deg.
                lo = [math.floor(st["base_rotation_deg"][i] - 4) for i in range(3)]
                hi = [math.ceil(st["base_rotation_deg"][i] + 4) for i in range(3)]
            for mat, path in (("", f"{up}../calibration/material.json"), ("_true_material", mat_true)):
                job = {"description": (f"lab2 {self.m.cfg['id']}: {self.kind} from t00 and t01 (translated by exactly "
                                       f"{STEP_MM} mm){' and r00 (rotated)' if n_r == 3 else ''}, from values "
                                       "rounded to 0.5 mm with +-1 mm bounds; stated lag (machine_stated.json) and "
                                       "halo (scatter) drawn with their stated u; material "
                                       + ("lab2's true curve (material_true.json)" if mat else
                                          "from the wedge calibration (run from the machine folder: xgauge calibrate "
                                          "wedge wedge/calibrate_wedge.json -o calibration)")),
                       "part": pm.path, "machine": f"{up}../machine_stated.json", "material": path,
                       "dimensions": {"start": start, "bounds": bounds}, "scatter": halo,
                       "radiographs": rads[:n_r],
                       "pose_bounds": {"rotation_deg": [[lo[i], hi[i]] for i in range(3)], "centre_mm": centre},
                       "schedule": "default", "loss": "l1"}
                jobs[f"job_{nm}{mat}.json"] = job
                write_json(os.path.join(folder, f"job_{nm}{mat}.json"), job)
        st["jobs"] = jobs


def start_bounds(pm, dims):
    """Starts rounded to 0.5 mm (to 0.1 mm where 0.5 breaks a constraint),
    bounds start +- 1 mm within the model's."""
    for q in (2.0, 10.0):
        # + 0.0: a value rounding to zero from below (the screw's shank_offset) starts at 0.0, not -0.0
        start = {k: float(np.clip(round(v * q) / q, pm.bounds[k][0], pm.bounds[k][1])) + 0.0 for k, v in dims.items()}
        if not pm.check(start):
            break
    else:
        raise ValueError(f"{pm.path}: no valid rounded start")
    bounds = {k: [max(pm.bounds[k][0], start[k] - 1.0), min(pm.bounds[k][1], start[k] + 1.0)] for k in dims}
    return start, bounds
