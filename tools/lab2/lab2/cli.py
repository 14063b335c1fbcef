"""Command line: python3 -m lab2 (or tools/lab2/lab2.py) ..."""

import argparse
import json
import os
import sys
import time

from . import grid
from .physical import KINDS, ScrewBuilderError, screw_builder


def main(argv=None):
    ap = argparse.ArgumentParser(prog="lab2", description="lab2: an independent second virtual X-ray lab for xgauge")
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("list", help="list the machine grid")
    s = sub.add_parser("machine", help="generate one machine's folder")
    s.add_argument("id", help="a grid machine (m01 ...) or a lab2_machine.json file")
    s.add_argument("-o", "--output", required=True, help="output folder (the machine's folder is created inside)")
    s.add_argument("--imperfections", action="store_true", help="chamfers and a taper on the prism jaw, drawn per run")
    s.add_argument("--seed", type=int, help="override the machine's seed")
    s.add_argument("--frames", type=int, help="frames in the dark and flat series (default: the machine's, 8)")
    _parts_args(s)
    s = sub.add_parser("grid", help="generate every machine of the grid (or those named)")
    s.add_argument("-o", "--output", required=True)
    s.add_argument("--machines", help="comma-separated ids (default: all)")
    s.add_argument("--imperfections", action="store_true")
    _parts_args(s)
    s = sub.add_parser("suite", help="the measured-parts grid for xgauge's coverage and verification checks: a subset "
                                     "of machines, every measured part with its master sets, stated inputs drawn per run")
    s.add_argument("-o", "--output", required=True)
    s.add_argument("--machines", default=",".join(grid.SUITE), help=f"comma-separated ids (default: {','.join(grid.SUITE)})")
    s.add_argument("--parts", default="prism,wedge,bracket,shaft",
                   help="comma-separated measured parts (default prism,wedge,bracket,shaft; also screw)")
    s.add_argument("--masters", type=int, default=3, help="master shot sets per part (default 3)")
    s.add_argument("--master-specimens", type=int, default=1, help="master specimens per part, each drawn on its "
                                                                  "own with --masters shot sets (default 1)")
    s.add_argument("--runs", type=int, default=1, help="runs per machine, each with its own seed (machine seed + "
                                                      "7919 k) and so its own draws (default 1)")
    s.add_argument("--frames", type=int, default=4, help="frames in the dark and flat series (default 4)")
    s.add_argument("--defects", default="usual", choices=("usual", "strong", "none"),
                   help="the bracket's and the shaft's imperfections: usual (lab2's ranges), strong (a fillet of 1 "
                        "to 1.5 mm, holes 0.5 to 1 deg off, an upright chamfer of 0.3 to 0.6 mm, the small section "
                        "0.05 to 0.1 mm eccentric, the cross hole 0.5 to 1 deg off) or none (default usual)")
    s.add_argument("-j", "--jobs", type=int, default=1, help="machines generated at once, in separate processes "
                                                            "(default 1)")
    s = sub.add_parser("render", help="render one part (path or transmission) for cross-checks")
    s.add_argument("part")
    s.add_argument("-m", "--machine", required=True, help="an xgauge machine file")
    s.add_argument("--rotation-deg", type=float, nargs=3, default=[0, 0, 0])
    s.add_argument("--translation-mm", type=float, nargs=3, required=True)
    s.add_argument("--set", action="append", default=[], help="name=value")
    s.add_argument("--lattice", type=int, default=233)
    s.add_argument("-o", "--output", required=True)
    s = sub.add_parser("shots", help="shots of a measured part at given poses on a machine folder (written by "
                                     "`machine`), with the machine's full detector model, as an xgauge dataset")
    s.add_argument("machine_dir", help="a machine folder (lab2_machine.json, dark.tif, flat.tif)")
    s.add_argument("--part", required=True, help=f"the measured part ({', '.join(KINDS)})")
    s.add_argument("--poses", required=True, help='JSON: [{"name", "pose": {"rotation_deg", "translation_mm"}, '
                                                  '"rest"?}, ...] (or {"shots": [...]}), in exposure order')
    s.add_argument("-o", "--output", required=True, help="the dataset folder (created)")
    s.add_argument("--seed", type=int, required=True, help="the shots' noise (and a drawn specimen's) seed")
    s.add_argument("--specimen", default="draw", help="draw (lab2's usual drift and imperfections, from --seed; "
                                                      "default), nominal (the model, no imperfection), or a JSON "
                                                      "file with dimensions and imperfections")
    a = ap.parse_args(argv)
    if a.cmd == "shots":
        return _shots(a)
    if a.cmd == "list":
        for m in grid.MACHINES:
            g = m["geometry"]
            h = m["detector"]["halo"]
            print(f"{m['id']}  {g['columns']}x{g['rows']} x {g['pitch_mm'][0]} mm  {m['beam']['tube_kv']:>3} kV  "
                  f"M {m['prism']['magnification']}  halo {h['shape']} w {h['weight']}  {m['description']}")
        return 0
    if a.cmd == "render":
        return _render(a)
    ids = [a.id] if a.cmd == "machine" else (a.machines.split(",") if a.machines else [m["id"] for m in grid.MACHINES])
    runs = getattr(a, "runs", 1)
    parts = [p for p in (a.parts or "").split(",") if p]
    for p in parts:
        if p not in KINDS:
            ap.error(f"unknown part {p!r} (known: {', '.join(KINDS)})")
    if "screw" in parts:
        try:
            screw_builder()
        except ScrewBuilderError as e:
            print(f"lab2: error: {e}", file=sys.stderr)
            return 2
    tasks = []
    for mid, k in ((m, k) for m in ids for k in range(runs)):
        if os.path.isfile(mid):
            with open(mid) as f:
                cfg = json.load(f)
        else:
            cfg = grid.machine(mid)
        if getattr(a, "seed", None) is not None:
            cfg["seed"] = a.seed
        cfg["seed"] = int(cfg["seed"]) + 7919 * k
        if getattr(a, "frames", None):
            cfg["frames"] = {"darks": a.frames, "flats": a.frames}
        out = os.path.join(a.output, f"run{k:02d}", cfg["id"]) if runs > 1 else os.path.join(a.output, cfg["id"])
        tasks.append((cfg, out, getattr(a, "imperfections", True), parts, a.masters, a.master_specimens,
                      getattr(a, "defects", "usual")))
    jobs = max(1, int(getattr(a, "jobs", 1) or 1))
    if jobs == 1:
        for task in tasks:
            print(_one(task), flush=True)
    else:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(jobs) as ex:
            for line in ex.map(_one, tasks):
                print(line, flush=True)
    return 0


def _one(task):
    from . import physical
    from .session import Machine, Session
    cfg, out, imperfections, parts, masters, specimens, defects = task
    physical.defect_profile = defects
    t, c = time.time(), time.process_time()
    truth = Session(Machine(cfg), out, imperfections=imperfections, parts=parts, masters=masters,
                    master_specimens=specimens).run()
    summary = {k: round(v, 1) for k, v in truth["timings_s"].items()}
    return f"{cfg['id']}: {out} in {time.time() - t:.1f} s, {time.process_time() - c:.1f} s CPU ({summary})"


def _parts_args(s):
    s.add_argument("--parts", default="", help="comma-separated measured parts (prism, wedge, bracket, shaft, screw) "
                                               "with their master sets, under measured/ (the screw's true solids "
                                               "need OpenCASCADE's builder: XGAUGE_SCREW_SOLID or "
                                               "build/bench/screw_solid)")
    s.add_argument("--masters", type=int, default=3, help="master shot sets per part (default 3)")
    s.add_argument("--master-specimens", type=int, default=1, help="master specimens per part, each drawn on its "
                                                                  "own with --masters shot sets (default 1)")


def _shots(a):
    from . import shots
    if a.part not in KINDS:
        print(f"lab2: error: unknown part {a.part!r} (known: {', '.join(KINDS)})", file=sys.stderr)
        return 2
    try:
        poses = shots.read_poses(a.poses)
        info = shots.run(a.machine_dir, a.part, poses, a.output, a.seed, how=a.specimen,
                         log=lambda msg: print(msg, file=sys.stderr, flush=True))
    except (OSError, ValueError, KeyError, ScrewBuilderError) as e:
        print(f"lab2: error: {e}", file=sys.stderr)
        return 1
    print(f"{a.output}: {len(poses)} shots of the {a.part} ({info['specimen']}) on {info['machine_id']} in "
          f"{info['seconds']} s")
    return 0


def _render(a):
    import numpy as np
    from . import tiffio
    from .partmodel import PartModel
    from .render import Geometry, render
    from .scene import Scene
    with open(a.machine) as f:
        mj = json.load(f)
    d = mj["detector"]
    cx, cy = d.get("principal_point_px", [None, None])
    g = Geometry(mj["source_detector_distance_mm"], d["columns"], d["rows"], *d["pixel_pitch_mm"], cx, cy)
    pm = PartModel(a.part)
    vals = {k: float(v) for k, v in (x.split("=") for x in a.set)}
    sc = Scene.from_pose(pm.build(vals), a.rotation_deg, a.translation_mm)
    img = render(sc, g, lattice=a.lattice)
    tiffio.write_f32(a.output, img.astype(np.float32))
    return 0


if __name__ == "__main__":
    sys.exit(main())
