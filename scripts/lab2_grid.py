#!/usr/bin/env python3
"""xgauge on the second lab's grid (tools/lab2): calibration and measurement
on machines that xgauge's own lab never simulated.

For every machine folder that `tools/lab2/lab2.py grid -o LAB2` wrote
(m01 ... m13), in order:

1. with --characterize: `xgauge characterize` on the machine's dark and
   flat series and characterisation shots, into OUT/<m>/detector/; the
   halo, lag and crosstalk it finds against lab2_truth.json's;
2. `xgauge calibrate wedge` on the machine's wedge shot (the wedge at its
   caliper values, the halo estimated or, with --characterize, taken from
   the detector file), into OUT/<m>/calibration/; its curve against the
   lab's true curve (truth.json's `transmission`) over the calibrated range:
   the largest deviation, and the share of the range where the deviation is
   within twice the curve's stated standard uncertainty;
3. `xgauge measure` of the prism pair (t00, t01) with that material, into
   OUT/<m>/prism/: status, misfit ratios, the along-beam dimensions'
   (thickness, groove_depth, slot_depth) errors and U, errors within U.

The lab's folders are read only: the jobs are copied into OUT with their
paths made absolute. Writes OUT/grid.json and prints a Markdown table
(--table: only tabulate OUT/grid.json). Exit status 0 when every step ran
(whatever its figures), 1 when one could not run, 2 on a usage error.

Usage: scripts/lab2_grid.py LAB2 [--out out/lab2_grid]
       [--xgauge build/apps/xgauge/xgauge] [--only m01 m04 ...]
       [--characterize] [--threads 1] [--table]
"""

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

from characterize_lab2 import job_for as characterization_job

ROOT = Path(__file__).resolve().parent.parent
ALONG_BEAM = ("thickness", "groove_depth", "slot_depth")


def absolutize(job, base):
    """A job's relative file names made absolute against its folder."""
    def fix(value, key):
        if isinstance(value, str) and key in ("machine", "material", "image", "dark", "flat",
                                              "model", "part", "previous", "detector"):
            p = Path(value)
            return str(p if p.is_absolute() else (base / p).resolve())
        return value

    def walk(node):
        if isinstance(node, dict):
            return {k: walk(fix(v, k)) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v) for v in node]
        return node
    return walk(job)


def curve(terms, x):
    return sum(t["weight"] * math.exp(-t["mu_per_mm"] * x) for t in terms)


def curve_against_truth(material, truth):
    """Largest |deviation| from the true curve over the calibrated range, and
    the share of that range (truth's 0.05 mm grid) within 2 stated u(x), u(x)
    from the material's curve moves (docs/formats.md, material.json)."""
    lo, hi = material["calibrated_range_mm"]
    unc = material.get("uncertainty", {})
    besides = unc.get("besides_curve_moves", 0.0)
    moves = [m["curve"]["terms"] for m in unc.get("curve_moves", [])]
    worst, at, inside, count = 0.0, None, 0, 0
    for x, t in zip(truth["path_mm"], truth["transmission"]):
        if x < lo or x > hi:
            continue
        c = curve(material["terms"], x)
        u = math.sqrt(besides ** 2 + sum((curve(m, x) - c) ** 2 for m in moves))
        d = c - t
        count += 1
        inside += abs(d) <= 2.0 * u
        if abs(d) > abs(worst):
            worst, at = d, x
    return {"max_deviation": worst, "at_mm": at, "within_2u": inside / count if count else None}


def run(cmd, log):
    t = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    log.write_text(p.stdout + p.stderr)
    return p.returncode, time.time() - t


def characterize(args, m, lab, out):
    """The characterisation job (docs/formats.md, "Characterisation job"),
    as scripts/characterize_lab2.py writes it."""
    job = characterization_job(lab)
    out.mkdir(parents=True, exist_ok=True)
    (out / "characterize.json").write_text(json.dumps(job, indent=2))
    rc, seconds = run([args.xgauge, "characterize", str(out / "characterize.json"), "-o",
                       str(out / "detector"), "--quiet", "-j", str(args.threads)],
                      out / "characterize.log")
    row = {"rc": rc, "seconds": seconds}
    truth = json.loads((lab / "lab2_truth.json").read_text())["detector"]
    row["true_halo"] = truth["halo"]
    if rc == 0:
        det = json.loads((out / "detector" / "detector.json").read_text())
        row["halo"] = det.get("halo")
    else:
        row["reason"] = (out / "characterize.log").read_text().strip().splitlines()[-1:]
    # A machine file that names the detector file, for the calibration.
    machine = json.loads((lab / "machine.json").read_text())
    if rc == 0:
        machine["detector"]["characterization"] = str(out / "detector" / "detector.json")
    (out / "machine.json").write_text(json.dumps(machine, indent=2))
    return row


def calibrate(args, m, lab, out, machine):
    job = absolutize(json.loads((lab / "wedge" / "calibrate_wedge.json").read_text()),
                     lab / "wedge")
    if machine:
        job["machine"] = str(machine)
    (out / "calibrate_wedge.json").write_text(json.dumps(job, indent=2))
    rc, seconds = run([args.xgauge, "calibrate", "wedge", str(out / "calibrate_wedge.json"),
                       "--truth", str(lab / "wedge" / "truth.json"), "-o",
                       str(out / "calibration"), "--quiet", "-j", str(args.threads)],
                      out / "calibrate.log")
    row = {"rc": rc, "seconds": seconds}
    if rc != 0:
        row["reason"] = (out / "calibrate.log").read_text().strip().splitlines()[-1:]
        return row
    material = json.loads((out / "calibration" / "material.json").read_text())
    truth = json.loads((lab / "wedge" / "truth.json").read_text())["transmission"]
    row.update(curve_against_truth(material, truth))
    row["scatter"] = material.get("scatter")
    return row


def measure(args, m, lab, out, machine):
    job = absolutize(json.loads((lab / "prism" / "job.json").read_text()), lab / "prism")
    job["material"] = str(out / "calibration" / "material.json")
    if machine:
        job["machine"] = str(machine)
    (out / "job.json").write_text(json.dumps(job, indent=2))
    rc, seconds = run([args.xgauge, "measure", str(out / "job.json"), "--truth",
                       str(lab / "prism" / "truth.json"), "-o", str(out / "prism"), "--quiet",
                       "-j", str(args.threads)], out / "measure.log")
    row = {"rc": rc, "seconds": seconds}
    try:
        result = json.loads((out / "prism" / "result.json").read_text())
    except (OSError, ValueError):
        row["reason"] = (out / "measure.log").read_text().strip().splitlines()[-1:]
        return row
    truth = json.loads((lab / "prism" / "truth.json").read_text())["part"]["dimensions"]
    dims = result.get("dimensions") or result.get("rejected_dimensions") or []
    row["status"] = result["status"]
    row["failures"] = result.get("failures", [])
    row["misfit"] = [c["misfit_ratio"] for c in result["fit_checks"]]
    row["dimensions"] = {d["name"]: {"error": d["value_mm"] - truth[d["name"]],
                                     "U": d.get("expanded_uncertainty")}
                         for d in dims if d.get("free")}
    return row


def table(grid):
    lines = ["| machine | halo (true) | halo found | calibration | curve max dev | within 2u "
             "| prism | misfit | thickness err / U | groove_depth | slot_depth | within U |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m, row in grid.items():
        th = row.get("true_halo", {})
        true_halo = f"{th.get('shape', '?')} w {th.get('weight', 0):.3f} " \
                    f"σ≈{th.get('gaussian_equivalent_sigma_mm', 0):.0f} mm" if th else ""
        found = ""
        cal = row.get("calibrate", {})
        sc = cal.get("scatter") or {}
        if sc:
            found = f"w {sc.get('weight', 0):.3f} σ {sc.get('sigma_mm', 0):.0f} mm"
        ch = row.get("characterize", {}).get("halo")
        if ch:
            sc = ch.get("scatter", {})
            found = f"{sc.get('shape', 'gaussian')}/{sc.get('border', 'mirror')} " \
                f"w {sc.get('weight', 0):.3f} σ≈{ch.get('gaussian_equivalent_sigma_mm', 0):.0f} mm"
        elif row.get("characterize", {}).get("rc"):
            found = "characterize failed: " + " ".join(row["characterize"].get("reason", []))[:200]
        dev = f"{cal['max_deviation']:+.4f} at {cal['at_mm']:.1f}" if "max_deviation" in cal else \
            "failed"
        within = f"{100 * cal['within_2u']:.0f} %" if cal.get("within_2u") is not None else ""
        me = row.get("measure", {})
        d = me.get("dimensions", {})
        def cell(name):
            if name not in d:
                return ""
            u = d[name]["U"]
            return f"{d[name]['error']:+.3f} / {u:.3f}" if u is not None else \
                f"{d[name]['error']:+.3f} / –"
        inside = sum(1 for v in d.values() if v["U"] is not None and abs(v["error"]) <= v["U"])
        lines.append(f"| {m} | {true_halo} | {found} | {cal.get('rc', '')} ({cal.get('seconds', 0):.0f} s) "
                     f"| {dev} | {within} | {me.get('status', 'failed')} "
                     f"| {' '.join(f'{x:.2f}' for x in me.get('misfit', []))} | {cell('thickness')} "
                     f"| {cell('groove_depth')} | {cell('slot_depth')} | {inside}/{len(d)} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("lab2", type=Path, help="the folder lab2.py grid wrote")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "lab2_grid")
    ap.add_argument("--xgauge", default=str(ROOT / "build" / "apps" / "xgauge" / "xgauge"))
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--characterize", action="store_true")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--table", action="store_true")
    args = ap.parse_args()
    grid_file = args.out / "grid.json"
    if args.table:
        print(table(json.loads(grid_file.read_text())))
        return 0
    machines = sorted(p for p in args.lab2.iterdir()
                      if p.is_dir() and (p / "lab2_truth.json").exists())
    if args.only:
        machines = [p for p in machines if p.name in args.only]
    if not machines:
        print(f"lab2_grid: no machine folders in {args.lab2}", file=sys.stderr)
        return 2
    grid = json.loads(grid_file.read_text()) if grid_file.exists() else {}
    ok = True
    for lab in machines:
        m = lab.name
        out = args.out / m
        out.mkdir(parents=True, exist_ok=True)
        row = {"true_halo": json.loads((lab / "lab2_truth.json").read_text())["detector"]["halo"]}
        machine = None
        if args.characterize:
            row["characterize"] = characterize(args, m, lab, out)
            machine = out / "machine.json"
        row["calibrate"] = calibrate(args, m, lab, out, machine)
        if row["calibrate"]["rc"] == 0:
            row["measure"] = measure(args, m, lab, out, machine)
        ok &= row["calibrate"]["rc"] == 0
        grid[m] = row
        grid_file.write_text(json.dumps(grid, indent=1))
        print(table({m: row}).splitlines()[-1], flush=True)
    print(table(grid))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
