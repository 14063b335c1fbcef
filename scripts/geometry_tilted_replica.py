#!/usr/bin/env python3
"""The geometry calibration on tilted replica set-ups (docs/results.md,
"The geometry calibration on tilted panels").

Usage: geometry_tilted_replica.py XGAUGE OUT_DIR [--setups N] [--seed S]

Set-up 0 is datasets/prism_a_small_tilted.json as it is (the panel tilted
(0.4, -0.3) deg, turned 0.2 deg); set-ups 1 .. N-1 the same dataset with the
panel's tilts drawn in +-0.8 deg and its turn in +-0.3 deg, and the
dataset's seed changed (its noise, gains, lag and dead pixels). Each: `xgauge
simulate`, `xgauge material --from-truth`, and `xgauge calibrate geometry`
with examples/geometry_prism_a_tilted_job.json's five shots on the ideal
machine. Prints a Markdown table of each tilt's error against the truth in
units of its stated u (and of the least squares' u alone) and the share of
set-ups whose two tilts lie within 2u.
"""

import argparse
import json
import pathlib
import random
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent


def run(*args):
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(str(a) for a in args)} failed:\n{done.stderr}")
    return done.stdout


def setup(xgauge, folder, tilts, turn, seed):
    folder.mkdir(parents=True, exist_ok=True)
    machine = json.loads((ROOT / "examples/machine_1024_tilted.json").read_text())
    machine["detector"]["tilt_deg"] = list(tilts)
    machine["detector"]["rotation_deg"] = turn
    (folder / "machine_true.json").write_text(json.dumps(machine, indent=2) + "\n")
    dataset = json.loads((ROOT / "datasets/prism_a_small_tilted.json").read_text())
    dataset["seed"] = seed
    dataset["machine"] = str(folder / "machine_true.json")
    dataset["part"]["model"] = str(ROOT / "parts/prism_jaw.json")
    (folder / "dataset.json").write_text(json.dumps(dataset, indent=2) + "\n")
    data = folder / "data"
    run(xgauge, "simulate", folder / "dataset.json", "-o", data, "-q")
    run(xgauge, "material", "--from-truth", data / "truth.json", "-o", folder / "material.json", "-q")
    job = json.loads((ROOT / "examples/geometry_prism_a_tilted_job.json").read_text())
    job["part"] = str(ROOT / "parts/prism_jaw.json")
    job["machine"] = str(ROOT / "examples/machine_1024.json")
    job["material"] = str(folder / "material.json")
    for r in job["radiographs"]:
        for key in ("image", "dark", "flat"):
            r[key] = str(data / pathlib.Path(r[key]).name)
    (folder / "job.json").write_text(json.dumps(job, indent=2) + "\n")
    run(xgauge, "calibrate", "geometry", folder / "job.json", "-o", folder / "geometry", "-q")
    return json.loads((folder / "geometry" / "geometry.json").read_text())["detector"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("xgauge")
    ap.add_argument("out")
    ap.add_argument("--setups", type=int, default=8)
    ap.add_argument("--seed", type=int, default=62)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    out = pathlib.Path(a.out).resolve()
    print("| set-up | true tilts (deg) | found | u (least squares, leave-one-out) | error / u | "
          "error / least-squares u |")
    print("|---|---|---|---|---|---|")
    within = within_ls = 0
    for k in range(a.setups):
        if k == 0:
            tilts, turn, seed = (0.4, -0.3), 0.2, 2020
        else:
            tilts = (round(rng.uniform(-0.8, 0.8), 3), round(rng.uniform(-0.8, 0.8), 3))
            turn, seed = round(rng.uniform(-0.3, 0.3), 3), 2020 + k
        d = setup(pathlib.Path(a.xgauge).resolve(), out / f"setup{k}", tilts, turn, seed)
        found, u = d["tilt_deg"], d["standard_uncertainty_deg"]
        ls, loo = d["statistical_uncertainty_deg"], d["leave_one_out"]["uncertainty_deg"]
        e = [found[i] - tilts[i] for i in (0, 1)]
        z = [e[i] / u[i] for i in (0, 1)]
        zl = [e[i] / ls[i] for i in (0, 1)]
        within += all(abs(x) <= 2 for x in z)
        within_ls += all(abs(x) <= 2 for x in zl)
        print(f"| {k} (seed {seed}, turn {turn:+.3f}) | ({tilts[0]:+.3f}, {tilts[1]:+.3f}) | "
              f"({found[0]:+.4f}, {found[1]:+.4f}) | ({u[0]:.4f}, {u[1]:.4f}): ({ls[0]:.4f}, {loo[0]:.4f}), "
              f"({ls[1]:.4f}, {loo[1]:.4f}) | {z[0]:+.1f}, {z[1]:+.1f} | {zl[0]:+.1f}, {zl[1]:+.1f} |",
              flush=True)
    print(f"\nBoth tilts within 2u: {within} of {a.setups} set-ups "
          f"(with the least squares' u alone: {within_ls} of {a.setups}).")


if __name__ == "__main__":
    main()
