#!/usr/bin/env python3
"""The whole `xgauge measure` process, as a line runs it (issue: a part a
second): wall time, CPU time and peak memory of the process, and where its
time goes, against a baseline binary in the same run.

Cases (each measured --runs times per binary, the two binaries alternating
so that both see the same machine load):
- `3072-pair`: a 3072^2 pair (t00, t03 translated by 30 mm) of a replica
  Prism A on a characterised panel, its material calibrated from a wedge on
  that panel, naming a verification on a master of the same part type (three
  pairs of the master measured with `xgauge verify`);
- `3072-triple`: the same pair plus a rotated shot (r03, about 35 degrees);
- `demo`: the README demo's pair at 1024^2 (examples/prism_a_small_job.json).

The 3072^2 sessions are the demo's (datasets/wedge_small.json and
datasets/prism_a_small.json) on a panel of 3072^2 pixels of 0.4/3 mm in
the same cabinet (the same field of view, the halo the same width in mm);
the production part is another specimen (its own seed and dimensions).
They are simulated, characterised, calibrated and verified once into
--data (about a minute on 2 cores) with --xgauge; both binaries then
measure the same jobs.

Per run it prints nothing; per case: the median wall, CPU (user + system)
and peak resident memory of each binary, their ratios (xgauge / baseline),
and the median seconds of each stage, from the timestamps of measure.log's
lines: read (the process's start to the first line: arguments, part,
machine, material), normalise (radiographs read and corrected), pose (pose
search and refinement, mirrored and retried attempts included), joint (the
joint fit), budget and checks (the uncertainty budget and the self-checks)
and write (the result, pictures and report, to the process's end); a
binary whose measure.log does not split reading from normalising (before
this bench) shows both under read, so compare read + normalise. Last,
the slowest run against the median of each case.

Usage: bench/pipeline_bench.py [--xgauge build/apps/xgauge/xgauge]
       [--baseline BIN] [--runs 5] [--data data/pipeline_bench]
       [--cases 3072-pair,3072-triple,demo] [--threads 2]

--baseline: the same program built from the commit before the change
(e.g. `git worktree add /tmp/base COMMIT && cmake -S /tmp/base -B
/tmp/base/build -G Ninja -DCMAKE_BUILD_TYPE=Release && ninja -C
/tmp/base/build xgauge`); without it only --xgauge is timed.
"""

import argparse
import copy
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCALE = 3  # 1024^2 of 0.4 mm -> 3072^2 of 0.4/3 mm
CASES = ("3072-pair", "3072-triple", "demo")
STAGES = ("read", "normalise", "pose", "joint", "budget", "checks", "write")


def run(cmd, log=None):
    """Runs a preparation step; exits with its output when it fails."""
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if log:
        Path(log).write_text(p.stdout + p.stderr)
    if p.returncode not in (0, 2, 3):  # 2, 3: a verdict, not a failure
        sys.exit(f"pipeline_bench: {' '.join(map(str, cmd))} failed ({p.returncode}):\n"
                 f"{p.stdout[-2000:]}{p.stderr[-2000:]}")


def write_json(path, value):
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(value, indent=2) + "\n")
    tmp.replace(path)


def scaled_region(region):
    return [v * SCALE for v in region]


def machine_3072(data):
    """The demo's cabinet with a 3072^2 panel of the same size, its detector
    file the characterisation's."""
    m = json.loads((ROOT / "examples/machine_1024.json").read_text())
    m["description"] = "pipeline_bench: the replica cabinet's 409.6 mm panel as 3072^2 pixels"
    d = m["detector"]
    d["columns"] = d["rows"] = 1024 * SCALE
    d["pixel_pitch_mm"] = [p / SCALE for p in d["pixel_pitch_mm"]]
    d["principal_point_px"] = [p * SCALE for p in d["principal_point_px"]]
    write_json(data / "machine_3072.json", m)
    d["characterization"] = str(data / "detector/detector.json")
    write_json(data / "machine_3072_characterized.json", m)


def session(name, data, seed=None, dimensions=None, translations=None, angles=None):
    """A demo dataset recipe on the 3072^2 panel."""
    r = json.loads((ROOT / f"datasets/{name}_small.json").read_text())
    r["machine"] = str(data / "machine_3072.json")
    r["detector"]["scatter"]["sigma_px"] *= SCALE
    if seed is not None:
        r["seed"] = seed
    if dimensions:
        r["part"]["dimensions"].update(dimensions)
    if translations:
        r["shots"]["translations"]["count"] = translations
    if angles:
        r["shots"]["rotations"]["angles_deg"] = angles
    for key in ("model",):
        r["part"][key] = str((ROOT / "datasets" / r["part"][key]).resolve())
    return r


def job(session_dir, data, shots, verification=None):
    """A measurement job of Prism A like the demo's, on the 3072^2 panel."""
    j = json.loads((ROOT / "examples/prism_a_small_job.json").read_text())
    j["description"] = "pipeline_bench"
    j["part"] = str(ROOT / "parts/prism_jaw.json")
    j["machine"] = str(data / "machine_3072_characterized.json")
    j["material"] = str(data / "calibration/material.json")
    truth = json.loads((session_dir / "truth.json").read_text())
    order = [s["name"] for s in truth["shots"]]
    radiographs = []
    for name, pattern in shots:
        r = {"name": name, "image": str(session_dir / f"{name}.tif"), "pattern": pattern,
             "dark": str(session_dir / "dark.tif"), "flat": str(session_dir / "flat.tif"),
             "white_region": scaled_region([20, 20, 51, 51])}
        if pattern == "translated":
            r.update(reference=shots[0][0], distance_mm=30.0)
        if pattern == "rotated":
            r.update(reference=shots[0][0])
        i = order.index(name)
        if i > 0:
            r["previous"] = str(session_dir / f"{order[i - 1]}.tif")
        radiographs.append(r)
    j["radiographs"] = radiographs
    if verification:
        j["verification"] = str(verification)
    return j


def prepare(args):
    """Simulates, characterises, calibrates and verifies into --data once;
    returns {case: job file}."""
    data = args.data.resolve()
    jobs = {"3072-pair": data / "job_pair.json", "3072-triple": data / "job_triple.json",
            "demo": ROOT / "examples/prism_a_small_job.json"}
    x = args.xgauge
    if "demo" in args.cases:
        if not (ROOT / "data/wedge_small/characterization/characterize.json").exists():
            run([x, "simulate", ROOT / "datasets/wedge_small.json", "-o", ROOT / "data/wedge_small", "-q"])
        if not (ROOT / "data/prism_a_small/truth.json").exists():
            run([x, "simulate", ROOT / "datasets/prism_a_small.json", "-o", ROOT / "data/prism_a_small", "-q"])
        if not (ROOT / "out/calibration_wedge_small/material.json").exists():
            run([x, "characterize", ROOT / "data/wedge_small/characterization/characterize.json",
                 "-o", ROOT / "out/detector_small", "-q"])
            run([x, "calibrate", "wedge", ROOT / "examples/calibrate_wedge_small_characterized.json",
                 "-o", ROOT / "out/calibration_wedge_small", "-q"])
    if not any(c.startswith("3072") for c in args.cases) or (data / "job_triple.json").exists():
        return jobs
    print(f"pipeline_bench: preparing the 3072^2 sessions in {data} (once)", file=sys.stderr)
    machine_3072(data)
    recipes = {
        "wedge": session("wedge", data),
        # The master: the demo's specimen, six translations for three pairs.
        "master": session("prism_a", data, translations=6, angles=[0, 35]),
        # The production part: another specimen of the same drawing.
        "part": session("prism_a", data, seed=2077, translations=4, angles=[0, 20, 35],
                        dimensions={"width": 21.012, "thickness": 12.991, "slot_width": 4.061,
                                    "groove_depth": 6.958}),
    }
    for name, recipe in recipes.items():
        if not (data / name / "truth.json").exists():
            write_json(data / f"{name}.json", recipe)
            run([x, "simulate", data / f"{name}.json", "-o", data / name, "-q"])
    run([x, "characterize", data / "wedge/characterization/characterize.json", "-o",
         data / "detector", "-q"])
    cal = json.loads((ROOT / "examples/calibrate_wedge_small_characterized.json").read_text())
    cal["machine"] = str(data / "machine_3072_characterized.json")
    for key in ("image", "dark", "flat"):
        cal["radiograph"][key] = str(data / "wedge" / Path(cal["radiograph"][key]).name)
    cal["radiograph"]["previous"] = str(data / "wedge/t16.tif")
    cal["radiograph"]["white_region"] = scaled_region(cal["radiograph"]["white_region"])
    write_json(data / "calibrate.json", cal)
    run([x, "calibrate", "wedge", data / "calibrate.json", "-o", data / "calibration", "-q"])
    measurements = []
    for a, b in (("t00", "t03"), ("t01", "t04"), ("t02", "t05")):
        f = data / f"master_{a}_{b}.json"
        write_json(f, job(data / "master", data, [(a, "free"), (b, "translated")]))
        measurements.append(str(f))
    write_json(data / "verify.json", {
        "description": "pipeline_bench: the master (the replica's truth, 1 um per dimension)",
        "master": {"truth": str(data / "master/truth.json"), "standard_uncertainty": 0.001},
        "measurements": measurements})
    run([x, "verify", data / "verify.json", "-o", data / "verification", "-q"])
    verification = data / "verification/verification.json"
    write_json(data / "job_pair.json",
               job(data / "part", data, [("t00", "free"), ("t03", "translated")], verification))
    write_json(data / "job_triple.json",
               job(data / "part", data, [("t00", "free"), ("t03", "translated"), ("r02", "rotated")],
                   verification))
    return jobs


STAMP = re.compile(r"^\[(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3})\] \[\w+\] (.*)$")
# The stage whose work a measure.log line reports (a line is logged when its
# work ends).
KINDS = (
    ("read", re.compile(r"radiograph files read in")),
    ("normalise", re.compile(r"normalised in")),
    ("pose", re.compile(r"^\S+: (pose|axis)")),
    ("joint", re.compile(r"^joint")),
    ("budget", re.compile(r"^uncertainty budget and self-checks in")),
    ("write", re.compile(r"^\d+ evaluations in")),
)
DURATION = re.compile(r" in \d+ evaluations, (\d+\.\d+) s")
SPLIT = re.compile(r"in (\d+\.\d+) s \(the Jacobian at the solution (\d+\.\d+) s, "
                   r"the influences (\d+\.\d+) s, the self-checks (\d+\.\d+) s\)")


def stages(log_text, started, ended):
    """Seconds per stage from measure.log's timestamps: the time between two
    stage lines goes to the stage of the later one (lines of no stage, a lag
    subtracted or a warning, are passed over). A binary whose log starts at
    the pose search (before this bench) has its reading and normalising in
    the first interval: the pose line's own duration goes to pose, the rest
    to read. One whose budget line does not split the self-checks off has
    them in budget (checks then shows 0)."""
    out = {s: 0.0 for s in STAGES}
    previous, stage = started, "read"
    for line in log_text.splitlines():
        m = STAMP.match(line)
        if not m:
            continue
        t = datetime.strptime(m.group(1), "%Y-%m-%d %H:%M:%S.%f").timestamp()
        text = m.group(2)
        kind = next((k for k, pattern in KINDS if pattern.search(text)), None)
        if kind is None:
            continue
        interval = max(0.0, t - previous)
        if kind == "pose" and stage == "read":
            own = float(DURATION.search(text).group(1)) if DURATION.search(text) else 0.0
            out["read"] += max(0.0, interval - own)
            out["pose"] += min(interval, own)
        elif kind == "budget" and SPLIT.search(text):
            total, jacobian, influences, checks = map(float, SPLIT.search(text).groups())
            out["checks"] += interval * checks / total if total > 0 else 0.0
            out["budget"] += interval - (interval * checks / total if total > 0 else 0.0)
        else:
            out[kind] += interval
        stage = kind
        previous = t
    out["write"] += max(0.0, ended - previous)
    return out


def measure_once(binary, job_file, threads):
    """One `xgauge measure` process: wall, CPU, peak RSS (MB), stages."""
    with tempfile.TemporaryDirectory(prefix="pipeline_bench_") as tmp:
        out = Path(tmp) / "out"
        cmd = [str(binary), "measure", str(job_file), "-o", str(out), "-j", str(threads)]
        started = time.time()
        t0 = time.monotonic()
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.monotonic() - t0
        ended = time.time()
        err = p.stderr.read().decode(errors="replace")
        p.stderr.close()
        rc = os.waitstatus_to_exitcode(status)
        if rc not in (0, 2, 3):
            sys.exit(f"pipeline_bench: {' '.join(cmd)} failed ({rc}):\n{err[-2000:]}")
        log = (out / "measure.log").read_text() if (out / "measure.log").exists() else ""
        result = json.loads((out / "result.json").read_text())
        return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
                "peak_mb": usage.ru_maxrss / 1024.0, "stages": stages(log, started, ended),
                "dimensions": {d["name"]: (d["value_mm"], d.get("expanded_uncertainty"))
                               for d in result["dimensions"] if d.get("free")}}


def summary(runs):
    return {"wall": statistics.median(r["wall"] for r in runs),
            "cpu": statistics.median(r["cpu"] for r in runs),
            "peak_mb": statistics.median(r["peak_mb"] for r in runs),
            "slowest": max(r["wall"] for r in runs),
            "stages": {**{s: statistics.median(r["stages"][s] for r in runs) for s in STAGES},
                       "read+normalise": statistics.median(
                           r["stages"]["read"] + r["stages"]["normalise"] for r in runs)}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--xgauge", type=Path, default=ROOT / "build/apps/xgauge/xgauge")
    ap.add_argument("--baseline", type=Path)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--data", type=Path, default=ROOT / "data/pipeline_bench")
    ap.add_argument("--cases", default=",".join(CASES))
    args = ap.parse_args()
    args.cases = args.cases.split(",")
    for c in args.cases:
        if c not in CASES:
            ap.error(f"unknown case '{c}' (known: {', '.join(CASES)})")
    for b in (args.xgauge, args.baseline):
        if b and not os.access(b, os.X_OK):
            ap.error(f"{b}: not an executable")
    jobs = prepare(args)
    binaries = {"xgauge": args.xgauge}
    if args.baseline:
        binaries["baseline"] = args.baseline
    print(f"pipeline_bench: {args.runs} runs per binary and case, -j {args.threads}; "
          f"xgauge = {args.xgauge}" + (f", baseline = {args.baseline}" if args.baseline else ""))
    figures = {}
    for case in args.cases:
        runs = {b: [] for b in binaries}
        for _ in range(args.runs):
            for b, path in binaries.items():
                runs[b].append(measure_once(path, jobs[case], args.threads))
        figures[case] = {b: summary(r) for b, r in runs.items()}
        print(f"\n{case} ({jobs[case].relative_to(ROOT) if jobs[case].is_relative_to(ROOT) else jobs[case]})")
        head = f"{'':12}" + "".join(f"{b:>12}" for b in binaries) + \
            (f"{'ratio':>9}" if args.baseline else "")
        print(head)
        rows = [("wall s", "wall"), ("CPU s", "cpu"), ("peak MB", "peak_mb"), ("slowest s", "slowest")]
        rows += [(f"  {s} s", s) for s in STAGES]
        rows.insert(4, ("read+norm s", "read+normalise"))
        for label, key in rows:
            vals = [figures[case][b][key] if key in figures[case][b] else figures[case][b]["stages"][key]
                    for b in binaries]
            line = f"{label:12}" + "".join(f"{v:12.2f}" for v in vals)
            if args.baseline and vals[1] > 0:
                line += f"{vals[0] / vals[1]:9.2f}"
            print(line)
        if args.baseline:
            # The results of both binaries: each dimension's largest difference
            # against the smaller of the two U.
            worst = 0.0
            for a, b in zip(runs["xgauge"], runs["baseline"]):
                for d, (v, u) in a["dimensions"].items():
                    vb, ub = b["dimensions"][d]
                    if u and ub:
                        worst = max(worst, abs(v - vb) / min(u, ub))
            print(f"largest |value - baseline's| / U over the dimensions: {worst:.3f}")
    print("\nslowest run / median wall: " + ", ".join(
        f"{c} {figures[c]['xgauge']['slowest'] / figures[c]['xgauge']['wall']:.2f}" for c in figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
