"""Shots of a measured part at poses of one's own on an existing machine
folder (`lab2.py shots`): for checks that need lab2's physics at views
another tool chose (e.g. the views `xgauge plan` planned).

The machine is the folder's `lab2_machine.json`; its fixed patterns (gain,
dark offsets, dead and hot pixels) follow from the machine's seed, so the
folder's `dark.tif` and `flat.tif` correct the new shots as they correct the
session's own.  The shots' noise comes from `--seed` alone (one stream per
shot, seeded by (seed, "shots/" + name)), so a seed gives bit-identical
files and another seed independent noise.  The shots are exposed in the
order given: the first after a rest, each later one carrying the lag of the
one before (unless it asks for a rest), as measured.py exposes t00, t01 and
r00.  The rendering is measured.py's: the physical specimen
(physical.physical_part: drawn dimensions and imperfections, or the model
at its nominal values) at each pose, lab2's full detector model
(detector.Detector.acquire: quantum noise, halo, gain, lag, crosstalk,
read-out)."""

import json
import os
import time
import zlib

import numpy as np

from . import detector as Dt
from . import physical, tiffio
from .scene import Scene

KEYS = ("name", "pose", "rest")


def read_poses(path):
    """[{"name", "pose": {"rotation_deg", "translation_mm"}, "rest"?}], from
    a list of such, or an object with "shots" holding one."""
    with open(path) as f:
        doc = json.load(f)
    shots = doc.get("shots") if isinstance(doc, dict) else doc
    if not isinstance(shots, list) or not shots:
        raise ValueError(f"{path}: expected a non-empty list of shots (or {{\"shots\": [...]}})")
    out, seen = [], set()
    for i, s in enumerate(shots):
        if not isinstance(s, dict):
            raise ValueError(f"{path}: shot {i} is not an object")
        bad = [k for k in s if k not in KEYS]
        if bad:
            raise ValueError(f"{path}: shot {i}: unknown keys {bad} (known: {', '.join(KEYS)})")
        name = s.get("name")
        if not isinstance(name, str) or not name or "/" in name or name in seen:
            raise ValueError(f"{path}: shot {i}: a unique name without '/' is required")
        seen.add(name)
        p = s.get("pose") or {}
        rot, tr = p.get("rotation_deg"), p.get("translation_mm")
        if not (isinstance(rot, list) and len(rot) == 3 and isinstance(tr, list) and len(tr) == 3):
            raise ValueError(f"{path}: shot {name}: pose needs rotation_deg and translation_mm, 3 numbers each")
        out.append({"name": name, "rotation_deg": [float(v) for v in rot],
                    "translation_mm": [float(v) for v in tr], "rest": bool(s.get("rest", i == 0))})
    return out


def specimen(kind, how, seed):
    """(dimensions, imperfections, what) of the specimen: "draw" (lab2's usual
    drift and imperfections, drawn from the seed), "nominal" (the model at
    its nominal values, no imperfection), or a JSON file with "dimensions"
    and optional "imperfections" (e.g. a lab2_truth.json measured.KIND
    entry)."""
    pm = physical.model(kind)
    if how == "nominal":
        return dict(pm.nominal), {}, "nominal"
    if how == "draw":
        rng = np.random.default_rng([int(seed), zlib.crc32(f"shots/specimen/{kind}".encode())])
        d = physical.draw_dimensions(kind, rng)
        return d, physical.draw_imperfections(kind, rng), f"drawn (seed {seed})"
    with open(how) as f:
        doc = json.load(f)
    d = {k: float(v) for k, v in doc["dimensions"].items()}
    missing = [k for k in pm.nominal if k not in d]
    if missing:
        raise ValueError(f"{how}: dimensions {missing} missing")
    bad = pm.check(d)
    if bad:
        raise ValueError(f"{how}: invalid dimensions: {'; '.join(bad)}")
    return d, doc.get("imperfections") or {}, f"from {os.path.abspath(how)}"


def run(machine_dir, kind, poses, out, seed, how="draw", log=print):
    """Renders and exposes the shots; writes out/ as an xgauge dataset
    (truth.json, raw NAME.tif, normalized/, dark.tif, flat.tif) plus
    physical_part.json and lab2_shots.json.  Returns lab2_shots.json's
    document."""
    from .session import Machine, Session, frame_rng, pose_json, write_json
    from .partmodel import rotation_matrix
    from .render import render

    t0 = time.time()
    machine_dir = os.path.abspath(machine_dir)
    with open(os.path.join(machine_dir, "lab2_machine.json")) as f:
        cfg = json.load(f)
    m = Machine(cfg)
    g = m.geom
    sess = Session(m, machine_dir, log=log)
    dark = tiffio.read(os.path.join(machine_dir, "dark.tif")).astype(np.float32).astype(float)
    flat = tiffio.read(os.path.join(machine_dir, "flat.tif")).astype(np.float32).astype(float)
    if dark.shape != (g.rows, g.columns) or flat.shape != dark.shape:
        raise ValueError(f"{machine_dir}: dark.tif/flat.tif are {dark.shape}, the machine's panel "
                         f"{(g.rows, g.columns)}")
    sess.dark, sess.flat = dark, flat
    sess.bad = Dt.bad_pixel_mask(dark, flat, m.detector.dead | m.detector.hot)

    out = os.path.abspath(out)
    os.makedirs(out, exist_ok=True)
    dims, imp, what = specimen(kind, how, seed)
    pm = physical.model(kind)
    doc, root = physical.physical_part(kind, dims, imp, folder=out)
    if doc is not None:
        write_json(os.path.join(out, "physical_part.json"), doc)
    sess.part_bbox_pts = Scene(pm.build(dims)).bbox_corners_world()

    shots, records, warnings = [], [], []
    shadow = np.zeros((g.rows, g.columns), bool)
    prev, prev_name = None, None
    margin = 0.02 * max(g.columns, g.rows)
    for s in poses:
        R = rotation_matrix(*s["rotation_deg"])
        t = np.asarray(s["translation_mm"], float)
        sc = Scene(root, R, t)
        pu, pv = g.project(sc.bbox_corners_world())
        if pu.min() < margin or pv.min() < margin or pu.max() > g.columns - margin or pv.max() > g.rows - margin:
            warnings.append(f"{s['name']}: the part's bounding box comes within 2 % of the panel's border or "
                            "leaves it")
        t1 = time.time()
        st = {}
        T = render(sc, g, fn=m.lut_al, stats=st)
        shadow |= T < 1.0 - 1e-12
        if s["rest"]:
            prev, prev_name = None, None
        raw, sig = m.detector.acquire(frame_rng(seed, "shots/" + s["name"]), T, prev)
        records.append({"name": s["name"], "previous": prev_name, "render_s": round(time.time() - t1, 2),
                        "refined_pixels": st.get("refined_pixels"),
                        "max_centre_path_mm": st.get("max_centre_path_mm")})
        prev, prev_name = sig, s["name"]
        shots.append({"name": s["name"], "file": s["name"] + ".tif", "pattern": "free", "pose": pose_json(R, t),
                      "_raw": raw})
        log(f"lab2 shots: {s['name']} rendered and exposed in {time.time() - t1:.1f} s")
    from scipy import ndimage
    shadow = ndimage.binary_dilation(shadow, iterations=max(8, int(0.02 * g.columns)))
    desc = (f"lab2 {cfg['id']}: {kind} ({what} specimen, {pm.path}) in {len(shots)} shots at given poses "
            f"({', '.join(s['name'] for s in shots)}), exposed in that order (each after the first with the lag of "
            f"the one before unless it rests); noise seed {seed}, the machine's fixed patterns from its seed "
            f"{m.seed}")
    if imp:
        desc += f"; imperfections the model lacks (physical_part.json): {imp}"
    wr = sess.write_dataset(out, kind, pm.path, dims, shots, shadow, desc, [])
    tp = os.path.join(out, "truth.json")
    with open(tp) as f:
        truth = json.load(f)
    truth["seed"] = int(seed)
    write_json(tp, truth)
    info = {"lab": "lab2 (tools/lab2) shots", "machine_folder": machine_dir, "machine_id": cfg["id"],
            "machine_seed": m.seed, "noise_seed": int(seed), "part": kind, "model": pm.path,
            "specimen": what, "dimensions": dims, "imperfections": imp, "white_region": wr,
            "exposure_order": records, "warnings": warnings, "seconds": round(time.time() - t0, 1)}
    write_json(os.path.join(out, "lab2_shots.json"), info)
    for w in warnings:
        log(f"lab2 shots: warning: {w}")
    return info
