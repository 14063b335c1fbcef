"""One machine's session: dark and flat series, characterisation shots, the
wedge calibration shot and the prism jaw's translated series, written in
xgauge's dataset formats (docs/formats.md) with their truth."""

import json
import math
import os
import shutil
import time
import zlib

import numpy as np
from scipy import ndimage

from . import detector as Dt
from . import imperfect
from . import measured
from . import stated
from . import tiffio
from .geometry import Box, Cylinder, Mesh
from .partmodel import Node, PartModel, euler_from_matrix, rotation_matrix
from .render import Geometry, render
from .scene import Scene
from .spectrum import Beam

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
PARTS = os.path.join(REPO, "parts")
PRISM_A = {"width": 20.977, "groove_center": 10.438, "thickness": 13.020, "groove_depth": 6.923,
           "groove_left": 6.848, "groove_right": 6.963, "slot_width": 4.104, "slot_depth": 3.951}
PRISM_B = {"width": 20.951, "groove_center": 10.462, "thickness": 10.048, "groove_depth": 5.204,
           "groove_left": 5.101, "groove_right": 5.219, "slot_width": 3.052, "slot_depth": 2.903}
AL = ("Al", 2.699)
W = ("W", 19.3)


def frame_rng(seed, name):
    """An independent random stream per frame, from the machine's seed and
    the frame's name only: the same seed gives the same files whatever is
    generated before or after."""
    return np.random.default_rng([int(seed), zlib.crc32(name.encode())])


def pose_json(R, t):
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = t
    return {"rotation_deg": [float(v) for v in euler_from_matrix(R)],
            "translation_mm": [float(v) for v in t],
            "matrix": [float(v) for v in M.ravel()]}


def layer_json(layer):
    c, rho, mm = layer
    return {"compound": c, "density_g_cm3": float(rho), "thickness_mm": float(mm)}


def write_json(path, obj):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(obj, f, indent=2)
        f.write("\n")
    os.replace(tmp, path)


def link_or_copy(src, dst):
    if os.path.exists(dst):
        os.remove(dst)
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)


class Machine:
    def __init__(self, cfg):
        self.cfg = cfg
        g = cfg["geometry"]
        cx, cy = g.get("principal_point_px", [None, None])
        self.geom = Geometry(g["sdd_mm"], g["columns"], g["rows"], g["pitch_mm"][0], g["pitch_mm"][1], cx, cy)
        b = cfg["beam"]
        self.beam = Beam(b["tube_kv"], [tuple(x) for x in b["filters"]], tuple(b["detector_window"]),
                         tuple(b["scintillator"]), bin_kev=b.get("bin_kev", 0.5),
                         anode_self_um=b.get("anode_self_um", 4.0))
        self.seed = int(cfg["seed"])
        self.detector = Dt.Detector(self.geom, cfg["detector"], seed=self.seed)
        self.lut_al = self.beam.lut(*AL, max_mm=160.0)

    @property
    def panel_mm(self):
        g = self.geom
        return g.columns * g.pitch_u, g.rows * g.pitch_v

    def pixel_to_world(self, pu, pv, z):
        """The world point at height z whose projection is (pu, pv)."""
        g = self.geom
        x, y = g.world_xy(pu, pv)
        s = (g.sdd - z) / g.sdd
        return np.array([x * s, y * s, z])

    def plate_thickness(self):
        for t in (1.0, 2.0, 3.0, 5.0, 8.0, 10.0, 15.0, 20.0):
            if self.beam.transmission([t], *W)[0] < 2e-5:
                return t
        return 20.0


class Session:
    """Writes one machine folder.  Frames are exposed in the order they are
    generated; each frame lags the previous one unless it follows a rest."""

    def __init__(self, machine, out, imperfections=False, log=print, parts=(), masters=3, master_specimens=1):
        self.m = machine
        self.out = os.path.abspath(out)
        self.imperfect = imperfections
        self.parts = list(parts)
        self.masters = int(masters)
        self.master_specimens = int(master_specimens)
        self.log = log
        self.prev = None
        self.prev_name = None
        self.order = []
        self.timings = {}

    def expose(self, name, T, rest=False):
        d = self.m.detector
        if rest:
            self.prev, self.prev_name = None, None
        raw, sig = d.acquire(frame_rng(self.m.seed, name), T, self.prev)
        self.order.append({"frame": name, "beam": T is not None, "previous": self.prev_name})
        self.prev, self.prev_name = sig, name
        return raw

    # ------------------------------------------------------------------
    def run(self):
        t0 = time.time()
        os.makedirs(self.out, exist_ok=True)
        m = self.m
        cfg = m.cfg
        write_json(os.path.join(self.out, "lab2_machine.json"), cfg)
        write_json(os.path.join(self.out, "machine.json"), m.geom.machine_json(cfg.get("description", "")))
        halo = m.detector.halo.truth()
        self.stated = stated.draw_session(m.seed, float(m.detector.p["lag_fraction"]), float(halo["weight"]),
                                          float(halo["gaussian_equivalent_sigma_mm"]),
                                          PartModel(os.path.join(PARTS, "wedge_block.json")).nominal)
        ms = m.geom.machine_json(cfg.get("description", "") + "; the lab's stated lag fraction (drawn: true plus an "
                                 "error of its stated u, lab2_truth.json stated_inputs)")
        ms["detector"]["lag_fraction"] = self.stated["lag_fraction"]["value"]
        ms["uncertainty"] = {"lag_fraction": self.stated["lag_fraction"]["u"]}
        write_json(os.path.join(self.out, "machine_stated.json"), ms)
        self.dark, self.flat = self.dark_flat()
        self.bad = Dt.bad_pixel_mask(self.dark, self.flat, m.detector.dead | m.detector.hot)
        self.timings["dark_flat_s"] = time.time() - t0
        t = time.time()
        char = self.characterisation()
        self.timings["characterisation_s"] = time.time() - t
        t = time.time()
        wedge = self.wedge()
        self.timings["wedge_s"] = time.time() - t
        t = time.time()
        prism = self.prism()
        self.timings["prism_s"] = time.time() - t
        parts = {}
        for kind in self.parts:
            t = time.time()
            parts[kind] = measured.PartRun(self, kind, self.masters, self.master_specimens).run()
            self.timings[f"measured_{kind}_s"] = time.time() - t
        self.timings["total_s"] = time.time() - t0
        truth = {
            "lab": "lab2 (tools/lab2), independent of xgauge's src/lab",
            "machine_id": cfg["id"], "seed": m.seed,
            "detector": m.detector.truth(),
            "beam": {**m.beam.summary(),
                     "filters": [layer_json(x) for x in m.beam.filters],
                     "detector_window": layer_json(m.beam.detector_window),
                     "scintillator": layer_json(m.beam.scintillator)},
            "part_material": {"compound": AL[0], "density_g_cm3": AL[1]},
            "frames": {"darks": cfg["frames"]["darks"], "flats": cfg["frames"]["flats"],
                       "dark": "dark.tif", "flat": "flat.tif",
                       "note": "dark.tif and flat.tif are the means of darks/ and flats/ (float32 ADU); the flat series "
                               "is exposed without a rest between frames, so each flat frame after the first carries "
                               "the lag of the one before"},
            "exposure_order": self.order,
            "characterisation": char,
            "wedge": wedge,
            "prism": prism,
            "stated_inputs": self.stated,
            "measured": parts,
            "timings_s": self.timings,
            "not_modelled": NOT_MODELLED,
        }
        write_json(os.path.join(self.out, "lab2_truth.json"), truth)
        return truth

    # ------------------------------------------------------------------
    def dark_flat(self):
        n_d, n_f = self.m.cfg["frames"]["darks"], self.m.cfg["frames"]["flats"]
        os.makedirs(os.path.join(self.out, "darks"), exist_ok=True)
        os.makedirs(os.path.join(self.out, "flats"), exist_ok=True)
        acc = np.zeros((self.m.geom.rows, self.m.geom.columns))
        for k in range(n_d):
            raw = self.expose(f"dark_{k:03d}", None, rest=(k == 0))
            tiffio.write_u16(os.path.join(self.out, "darks", f"dark_{k:03d}.tif"), raw)
            acc += raw
        dark = acc / n_d
        acc[:] = 0
        for k in range(n_f):
            raw = self.expose(f"flat_{k:03d}", Dt.OPEN, rest=(k == 0))
            tiffio.write_u16(os.path.join(self.out, "flats", f"flat_{k:03d}.tif"), raw)
            acc += raw
        flat = acc / n_f
        tiffio.write_f32(os.path.join(self.out, "dark.tif"), dark)
        tiffio.write_f32(os.path.join(self.out, "flat.tif"), flat)
        return dark.astype(np.float32).astype(float), flat.astype(np.float32).astype(float)

    def corrected(self, raw):
        return Dt.flat_correct(raw, self.dark, self.flat, self.bad)

    # ------------------------------------------------------------------
    def characterisation(self):
        m = self.m
        g = m.geom
        folder = os.path.join(self.out, "characterisation")
        os.makedirs(os.path.join(folder, "corrected"), exist_ok=True)
        tw = m.plate_thickness()
        lut_w = m.beam.lut(*W, max_mm=3.0 * tw + 1.0, step_mm=1e-3)
        t_plate = float(m.beam.transmission([tw], *W)[0])
        z0 = 0.5
        rng = np.random.default_rng([m.seed, 0xC4A2])
        shots = {}

        def shoot(name, scene, description, extra, previous_rest=True, T=None):
            if T is None:
                st = {}
                T = render(scene, g, fn=lut_w, stats=st)
            raw = self.expose(name, T, rest=previous_rest)
            tiffio.write_u16(os.path.join(folder, name + ".tif"), raw)
            tiffio.write_f32(os.path.join(folder, "corrected", name + ".tif"), self.corrected(raw))
            shots[name] = {"file": f"characterisation/{name}.tif",
                           "corrected": f"characterisation/corrected/{name}.tif",
                           "previous": self.order[-1]["previous"], "description": description, **extra}

        C, R = g.columns, g.rows
        plate = {"material": {"compound": W[0], "density_g_cm3": W[1]}, "thickness_mm": tw,
                 "polychromatic_transmission": t_plate, "bottom_face_height_mm": z0}
        # (b1) a straight edge: a plate covering the left part of the panel, its right edge slanted
        angle = float(rng.choice([-1, 1]) * rng.uniform(2.0, 5.0))
        ue = C * rng.uniform(0.45, 0.55)
        ve = R * 0.5
        edge_c = m.pixel_to_world(ue, ve, z0)
        half_h = 0.42 * R * g.pitch_v
        width = 0.40 * C * g.pitch_u
        root = Node("leaf", solid=Box([-width, -half_h, 0.0], [0.0, half_h, tw]))
        scene = Scene(root, rotation_matrix(0, 0, angle), edge_c)
        shoot("edge", scene, "opaque tungsten plate covering part of the panel (left of a straight edge near the "
              "centre, tilted from the columns by angle_deg); behind it the signal is the halo alone "
              "(plus the plate's transmission)",
              {"plate": {**plate, "box_mm": {"min": [-width, -half_h, 0.0], "max": [0.0, half_h, tw]},
                         "pose": pose_json(rotation_matrix(0, 0, angle), edge_c)},
               "edge": {"angle_deg": angle, "through_px": [float(ue), float(ve)],
                        "note": "the plate's right face (box x = max) is the edge; it projects through through_px "
                                "at its bottom face; the plate lies in the half-plane to the left"}})
        # (b2) a disc
        uc, vc = C * rng.uniform(0.45, 0.55), R * rng.uniform(0.45, 0.55)
        rad = 0.18 * min(C * g.pitch_u, R * g.pitch_v)
        centre = m.pixel_to_world(uc, vc, z0)
        root = Node("leaf", solid=Cylinder(2, rad, 0.0, tw))
        scene = Scene(root, np.eye(3), centre)
        shoot("disc", scene, "opaque tungsten disc near the panel's centre",
              {"plate": {**plate, "disc": {"radius_mm": rad, "axis": "z", "centre_mm": [float(v) for v in centre]}},
               "centre_px": [float(uc), float(vc)]})
        # (d) column crosstalk: a plate over the top-left quadrant
        u1, v1 = C * 0.5 + 0.37, R * 0.5 + 0.41
        u0, v0 = C * 0.05, R * 0.05
        p0 = m.pixel_to_world(u0, v1, z0)
        p1 = m.pixel_to_world(u1, v0, z0)
        root = Node("leaf", solid=Box([p0[0], p0[1], z0], [p1[0], p1[1], z0 + tw]))
        scene = Scene(root)
        shoot("crosstalk", scene, "half-covered frame: an opaque plate over the top-left quadrant, so that the "
              "left columns are partly covered and the right ones not; in the open rows below it every left "
              "column reads lower by about crosstalk x its covered fraction",
              {"plate": {**plate, "box_mm": {"min": [float(p0[0]), float(p0[1]), z0],
                                             "max": [float(p1[0]), float(p1[1]), z0 + tw]}},
               "covered_px": {"u": [float(u0), float(u1)], "v": [float(v0), float(v1)]}})
        # (c) lag: an open frame, then a frame with the beam off right after it
        shoot("lag_bright", None, "open-beam frame after a rest", {}, T=Dt.OPEN)
        raw = self.expose("lag_dark_after_bright", None, rest=False)
        tiffio.write_u16(os.path.join(folder, "lag_dark_after_bright.tif"), raw)
        tiffio.write_f32(os.path.join(folder, "corrected", "lag_dark_after_bright.tif"), self.corrected(raw))
        shots["lag_dark_after_bright"] = {
            "file": "characterisation/lag_dark_after_bright.tif",
            "corrected": "characterisation/corrected/lag_dark_after_bright.tif",
            "previous": "lag_bright",
            "description": "beam off right after lag_bright: raw - dark = lag_fraction x lag_bright's signal (plus "
                           "read noise); its flat-corrected value is about lag_fraction x (lag_bright's signal / the "
                           "flat's)"}
        return {"shots": shots, "plate_thickness_mm": tw, "plate_transmission": t_plate,
                "note": "every characterisation frame is raw 16-bit (ADU); corrected/ holds (raw - dark) / (flat - "
                        "dark) with bad pixels repaired, not divided by any white region"}

    # ------------------------------------------------------------------
    def white_region(self, shadow):
        """An open-beam square far from every shot's shadow and the borders."""
        g = self.m.geom
        R, C = shadow.shape
        border = max(8, int(0.02 * max(R, C)))
        free = ~shadow
        free[:border] = free[-border:] = False
        free[:, :border] = free[:, -border:] = False
        dist = ndimage.distance_transform_cdt(free, metric="chessboard")
        v, u = np.unravel_index(np.argmax(dist), dist.shape)
        half = int(min(dist[v, u] - max(8, 0.01 * max(R, C)), max(R, C) / 16))
        if half < 4:
            raise ValueError("no open-beam region of at least 8 x 8 pixels left for the white region")
        return [int(u - half), int(v - half), int(2 * half + 1), int(2 * half + 1)]

    def write_dataset(self, folder, name, part_model, dims, shots, shadow, description, T_images):
        """truth.json and the shot files of one xgauge dataset."""
        m = self.m
        os.makedirs(os.path.join(folder, "normalized"), exist_ok=True)
        link_or_copy(os.path.join(self.out, "dark.tif"), os.path.join(folder, "dark.tif"))
        link_or_copy(os.path.join(self.out, "flat.tif"), os.path.join(folder, "flat.tif"))
        wr = self.white_region(shadow)
        for s in shots:
            raw = s.pop("_raw")
            tiffio.write_u16(os.path.join(folder, s["file"]), raw)
            norm = Dt.normalize(raw, self.dark, self.flat, wr, self.bad)
            tiffio.write_f32(os.path.join(folder, "normalized", s["file"]), norm)
        b = m.beam
        diag = float(np.linalg.norm(np.ptp(self.part_bbox_pts, axis=0)))
        x = np.round(np.arange(0.0, diag + 0.05, 0.05), 10)
        det = m.detector
        p = det.p
        truth = {
            "recipe": os.path.join(self.out, "lab2_machine.json"),
            "description": description,
            "seed": m.seed,
            "machine": m.geom.machine_json(m.cfg.get("description", "")),
            "beam": {"tube_kv": b.tube_kv, "bin_kev": b.bin_kev,
                     "filters": [layer_json(("W", 19.3, b.anode_self_um * 1e-3))] + [layer_json(f) for f in b.filters],
                     "detector_window": layer_json(b.detector_window),
                     "scintillator": layer_json(b.scintillator)},
            "material": {"compound": AL[0], "density_g_cm3": AL[1]},
            "detector": {"photons_per_open_pixel": det.N0, "photon_noise": True,
                         "adu_per_photon": det.adu_per_quantum, "read_noise_adu": p["read_noise_adu"],
                         "dark_level_adu": p["dark_level_adu"], "dark_pixel_sigma_adu": p["dark_pixel_sigma_adu"],
                         "column_offset_sigma_adu": p["dark_column_sigma_adu"],
                         "gain_pixel_sigma": p["gain_pixel_rms"], "gain_smooth_sigma": p["gain_smooth_rms"],
                         "gain_smooth_length_px": p["gain_smooth_min_wavelength_mm"] / m.geom.pitch_u,
                         "dead_pixel_fraction": p["dead_fraction"], "ghost_fraction": p["lag_fraction"],
                         "quantize_16bit": True},
            "part": {"model": os.path.abspath(part_model), "dimensions": {k: float(v) for k, v in dims.items()}},
            "white_region": wr,
            "dark": "dark.tif", "flat": "flat.tif",
            "dead_pixels": [[int(u), int(v)] for v, u in zip(*np.nonzero(det.dead))],
            "transmission": {"path_mm": [float(v) for v in x],
                             "transmission": [float(v) for v in b.transmission(x, *AL)],
                             "note": "lab2's true polychromatic transmission of aluminium (2.699 g/cm3), energy-"
                                     "integrating CsI, narrow beam, every 0.05 mm to the part's bounding-box diagonal"},
            "shots": shots,
        }
        write_json(os.path.join(folder, "truth.json"), truth)
        return wr

    # ------------------------------------------------------------------
    def wedge(self):
        m = self.m
        g = m.geom
        rng = np.random.default_rng([m.seed, 0x3ED6E])
        pm = PartModel(os.path.join(PARTS, "wedge_block.json"))
        dims = dict(pm.nominal)
        root = pm.build(dims)
        fill = m.cfg.get("wedge", {}).get("fill", 0.8)
        rot = (float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-1.0, 1.0)))
        R = rotation_matrix(*rot)
        bb = Scene(root).bbox_corners_world()
        lo, hi = bb.min(0), bb.max(0)
        cpart = 0.5 * (lo + hi)
        wmm, hmm = m.panel_mm
        M = min(fill * wmm / (hi[0] - lo[0]), 0.88 * hmm / (hi[1] - lo[1]))
        target = (g.columns * rng.uniform(0.48, 0.52), g.rows * rng.uniform(0.48, 0.52))
        for _ in range(200):
            z = g.sdd * (1 - 1 / M)
            c = m.pixel_to_world(target[0], target[1], z)
            t = c - R @ cpart
            scene = Scene(root, R, t)
            P = scene.bbox_corners_world()
            if P[:, 2].min() < 1.0:
                M *= 1.01
                continue
            pu, pv = g.project(P)
            margin = 0.02 * max(g.columns, g.rows)
            if pu.min() >= margin and pv.min() >= margin and pu.max() <= g.columns - margin and pv.max() <= g.rows - margin:
                break
            M *= 0.985
        else:
            raise ValueError("the wedge does not fit on this panel")
        self.part_bbox_pts = bb
        st = {}
        T = render(scene, g, fn=m.lut_al, stats=st)
        raw = self.expose("calibration", T, rest=True)
        shadow = ndimage.binary_dilation(T < 1.0 - 1e-12, iterations=max(8, int(0.02 * g.columns)))
        folder = os.path.join(self.out, "wedge")
        os.makedirs(folder, exist_ok=True)
        shots = [{"name": "calibration", "file": "calibration.tif", "pattern": "free", "pose": pose_json(R, t),
                  "_raw": raw}]
        wr = self.write_dataset(folder, "wedge", pm.path, dims, shots, shadow,
                                f"lab2 {m.cfg['id']}: wedge block (nominal dimensions) calibration shot at "
                                f"magnification {M:.3f}", [T])
        job = {
            "description": f"lab2 {m.cfg['id']}: calibrate the aluminium curve from the wedge shot, the wedge "
                           "fitted as a known part at its caliper values (the true, nominal, values plus a caliper's "
                           f"error drawn with its stated u = {self.stated['caliper']['u_mm']} mm); scatter estimated "
                           "from the halo",
            "machine": "../machine.json",
            "radiograph": {"image": "calibration.tif", "dark": "dark.tif", "flat": "flat.tif", "white_region": wr},
            "wedge": {"model": pm.path, "dimensions": dict(self.stated["caliper"]["values"]),
                      "dimension_uncertainty_mm": self.stated["caliper"]["u_mm"]},
            "rate_floor": {"compound": AL[0], "density_g_cm3": AL[1], "tube_kv": m.beam.tube_kv},
        }
        write_json(os.path.join(folder, "calibrate_wedge.json"), job)
        return {"folder": "wedge", "magnification_bbox_centre": M, "rotation_deg": list(rot), "pose": pose_json(R, t),
                "dimensions": dims, "refined_pixels": st.get("refined_pixels"), "white_region": wr,
                "calibration_job": "wedge/calibrate_wedge.json"}

    # ------------------------------------------------------------------
    def prism(self):
        m = self.m
        g = m.geom
        pc = m.cfg["prism"]
        rng = np.random.default_rng([m.seed, 0x9A15])
        dims = dict(PRISM_A if pc.get("dimensions", "A") == "A" else PRISM_B)
        if isinstance(pc.get("dimensions"), dict):
            dims = dict(pc["dimensions"])
        pm = PartModel(os.path.join(PARTS, "prism_jaw.json"))
        imp = None
        if self.imperfect:
            imp = imperfect.draw(np.random.default_rng([m.seed, 0x1A9E]))
            V, Tr = imperfect.physical_prism(dims, imp)
            root = Node("leaf", solid=Mesh(V, Tr))
        else:
            root = pm.build(dims)
        rot = (float(rng.uniform(-2, 2)), float(rng.uniform(-15, 15)), float(rng.uniform(-2, 2)))
        R = rotation_matrix(*rot)
        L = 40.0
        cpart = np.array([dims["width"] / 2, L / 2, dims["thickness"] / 2])
        n = int(pc.get("shots", 3))
        step = float(pc.get("step_mm", 10.0))
        axis = np.array([1.0, rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03)])
        axis /= np.linalg.norm(axis)
        M = float(pc["magnification"])
        z = g.sdd * (1 - 1 / M)
        target = (g.columns * rng.uniform(0.45, 0.55), g.rows * rng.uniform(0.45, 0.55))
        cmid = m.pixel_to_world(target[0], target[1], z)
        c0 = cmid - axis * step * (n - 1) / 2
        scenes, poses = [], []
        for i in range(n):
            t = c0 + i * step * axis - R @ cpart
            sc = Scene(root, R, t)
            P = sc.bbox_corners_world()
            pu, pv = g.project(P)
            margin = 0.02 * max(g.columns, g.rows)
            if pu.min() < margin or pv.min() < margin or pu.max() > g.columns - margin or pv.max() > g.rows - margin:
                raise ValueError(f"prism shot t{i:02d} leaves the panel at magnification {M}: lower it")
            scenes.append(sc)
            poses.append((R, t))
        self.part_bbox_pts = Scene(pm.build(dims)).bbox_corners_world()
        folder = os.path.join(self.out, "prism")
        os.makedirs(folder, exist_ok=True)
        shots, Ts, shadow = [], [], np.zeros((g.rows, g.columns), bool)
        refined = []
        self.longest_path = 0.0
        for i, sc in enumerate(scenes):
            st = {}
            T = render(sc, g, fn=m.lut_al, stats=st)
            refined.append(st.get("refined_pixels"))
            self.longest_path = max(self.longest_path, st.get("max_centre_path_mm", 0.0))
            shadow |= T < 1.0 - 1e-12
            name = f"t{i:02d}"
            raw = self.expose(name, T, rest=(i == 0))
            s = {"name": name, "file": name + ".tif", "pattern": "free" if i == 0 else "translated",
                 "pose": pose_json(*poses[i]), "_raw": raw}
            if i:
                s.update(reference="t00", distance_mm=i * step, axis=[float(v) for v in axis])
            shots.append(s)
        shadow = ndimage.binary_dilation(shadow, iterations=max(8, int(0.02 * g.columns)))
        desc = (f"lab2 {m.cfg['id']}: prism jaw ({'Prism A' if dims == PRISM_A else 'Prism B' if dims == PRISM_B else 'custom'}) "
                f"at magnification {M:.3f}, {n} shots translated by exactly {step} mm")
        if imp:
            desc += f"; imperfections the model lacks: chamfers {imp['chamfers_mm']} mm, taper {imp['taper']} mm/mm (lab2_truth.json)"
            write_json(os.path.join(folder, "physical_part.json"), imperfect.part_json(V, Tr, dims, imp, pm.path))
        wr = self.write_dataset(folder, "prism", pm.path, dims, shots, shadow, desc, Ts)
        self.prism_jobs(folder, pm, dims, shots, wr, poses, cpart, rot, z)
        return {"folder": "prism", "dimensions": dims, "magnification_bbox_centre": M, "rotation_deg": list(rot),
                "axis": [float(v) for v in axis], "step_mm": step, "shots": n, "refined_pixels": refined,
                "white_region": wr, "imperfections": imp,
                "imperfections_note": None if imp is None else imperfect.__doc__.strip(),
                "jobs": ["prism/job.json", "prism/job_true_material.json", "prism/study.json"]}

    def prism_jobs(self, folder, pm, dims, shots, wr, poses, cpart, rot, z):
        m = self.m
        halo = m.detector.halo.truth()
        start = {k: float(np.clip(round(v * 2) / 2, pm.bounds[k][0], pm.bounds[k][1])) for k, v in dims.items()}
        bounds = {k: [max(pm.bounds[k][0], start[k] - 1.0), min(pm.bounds[k][1], start[k] + 1.0)] for k in dims}
        c_true = poses[0][0] @ cpart + poses[0][1]
        pose_bounds = {"rotation_deg": [[-5, 5], [-30, 30], [-5, 5]],
                       "centre_mm": [[math.floor(c_true[0] / 10) * 10 - 20, math.floor(c_true[0] / 10) * 10 + 30],
                                     [math.floor(c_true[1] / 10) * 10 - 20, math.floor(c_true[1] / 10) * 10 + 30],
                                     [math.floor(z / 10) * 10 - 20, math.floor(z / 10) * 10 + 30]]}
        radiographs = []
        for i, s in enumerate(shots[:2]):
            r = {"name": s["name"], "image": s["file"], "dark": "dark.tif", "flat": "flat.tif", "white_region": wr,
                 "pattern": s["pattern"]}
            if i:
                r.update(reference="t00", distance_mm=s["distance_mm"], previous=shots[i - 1]["file"])
            radiographs.append(r)
        scatter = {"weight": halo["weight"], "sigma_mm": round(halo["gaussian_equivalent_sigma_mm"], 4)}
        base = {"part": pm.path, "machine": "../machine.json",
                "dimensions": {"start": start, "bounds": bounds},
                "radiographs": radiographs, "pose_bounds": pose_bounds, "schedule": "default", "loss": "l1"}
        job = {"description": f"lab2 {m.cfg['id']}: prism jaw from t00 and t01 (translated by exactly "
                              f"{shots[1]['distance_mm']} mm, t00 its previous frame); the material from the wedge "
                              "calibration (run: xgauge calibrate wedge wedge/calibrate_wedge.json -o calibration)",
               **base, "material": "../calibration/material.json"}
        job_true = {"description": f"lab2 {m.cfg['id']}: as job.json but with lab2's true curve (material_true.json, "
                                   "an exponential sum fitted to truth.json's table) and a Gaussian scatter of the "
                                   f"halo's weight and second moment (the halo is {halo['shape']})",
                    **base, "material": "material_true.json", "scatter": scatter}
        write_json(os.path.join(folder, "job.json"), job)
        write_json(os.path.join(folder, "job_true_material.json"), job_true)
        write_json(os.path.join(folder, "material_true.json"), fit_material(m.beam, 1.05 * self.longest_path + 0.5))
        study = {"description": f"lab2 {m.cfg['id']}: study settings for the prism series (pairs); true curve, the "
                                "halo's Gaussian equivalent as scatter, lag subtracted with the previous frames",
                 "material": "fit", "dimensions": {"start": start, "bounds": bounds}, "scatter": scatter,
                 "pose_bounds": pose_bounds, "schedule": "default", "loss": "l1", "previous_frames": True}
        write_json(os.path.join(folder, "study.json"), study)


def fit_material(beam, max_mm, terms=6, target=2e-5):
    """An exponential sum fitted to the true curve over 0..max_mm (weights
    summing to 1), in xgauge's material format: the fewest terms (up to
    `terms`) whose largest residual is below `target`."""
    from scipy.optimize import least_squares, nnls
    x = np.linspace(0.0, max_mm, 600)
    y = beam.transmission(x, *AL)
    grid = np.geomspace(1e-3, 2.0, 60)
    A = np.exp(-np.outer(x, grid))
    w, _ = nnls(A, y)
    best = None
    for k in range(1, terms + 1):
        idx = np.argsort(w)[::-1][:k]
        p0 = np.concatenate([np.log(np.maximum(w[idx], 1e-6)), np.log(grid[idx])])

        def res(p, k=k):
            a, mu = np.exp(p[:k]), np.exp(p[k:])
            return np.exp(-np.outer(x, mu)) @ a - y
        r = least_squares(res, p0)
        a, mu = np.exp(r.x[:k]), np.exp(r.x[k:])
        err = np.abs(res(r.x)).max()
        if best is None or err < best[2]:
            best = (a, mu, err)
        if err < target:
            break
    a, mu, err = best
    a = a / a.sum()
    order = np.argsort(mu)[::-1]
    return {"model": "exponential_sum",
            "description": f"lab2's true curve (aluminium, {beam.tube_kv:g} kV) fitted over 0..{max_mm:.1f} mm with "
                           f"{len(a)} terms, largest residual {err:.1e}",
            "terms": [{"weight": float(a[i]), "mu_per_mm": float(mu[i])} for i in order],
            "calibrated_range_mm": [0.0, float(max_mm)]}


NOT_MODELLED = [
    "scatter in the part and in the air (narrow-beam attenuation only)",
    "the focal spot's size (a point source) and the spectrum's change with emission angle (the heel effect is an "
    "intensity slope only)",
    "the Swank factor and optical quantum noise of the scintillator (noise-equivalent quanta), the spatial "
    "correlation of the quantum noise by the scintillator's short-range blur (MTF); the halo's spreading of the "
    "noise (relative variance below 1e-6)",
    "non-linearity of the panel and its saturation below 65535 ADU",
    "lag beyond one frame's fraction (no multi-exponential decay), lag dependent on the exposure",
    "the scintillator's extent beyond the active area: the halo sees open beam beyond the panel",
    "temporal drift of the tube output between frames",
]
