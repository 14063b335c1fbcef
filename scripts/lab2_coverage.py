#!/usr/bin/env python3
"""Coverage of U on the second lab's measured parts (tools/lab2 `suite`):
every part (prism jaw, wedge block, angle bracket, stepped shaft, each with
the imperfections lab2 draws), from a translated pair and from the pair
plus a rotated shot, from round starting values, on the machine's
characterised detector with the material xgauge calibrated on it.

For every machine folder that `lab2.py suite -o SUITE` wrote (and every
runNN/ folder of `--runs`):

1. `xgauge characterize` and `xgauge calibrate wedge` as
   scripts/lab2_grid.py --characterize does (the detector file named by the
   machine, its halo, lag and crosstalk in use);
2. `xgauge measure` of each part's `job_pair.json` and
   `job_pair_rotated.json` with that material and machine, the job's own
   stated halo left out (the detector file's is the one measured); with
   --stated, the jobs as lab2 wrote them (their drawn halo and the machine's
   drawn lag, machine_stated.json) with the calibrated material.

Writes OUT/coverage.json and prints, per part and pattern, the runs
measured, the dimensions' pooled coverage (|error| <= U) and mean |error|,
then the pooled coverage and each dimension's. Exit status 0 when every
step ran (whatever its figures), 1 when one could not run, 2 on a usage
error.

Usage: scripts/lab2_coverage.py SUITE [--out out/lab2_coverage]
       [--xgauge build/apps/xgauge/xgauge] [--threads 2] [--stated]
       [--parts prism wedge bracket shaft] [--verified] [--table]

With --verified, each part and pattern is first verified on lab2's master of
the same part type (its three shot sets measured under the same conditions,
its CMM certificate; `xgauge verify`) and the production part is measured
naming that verification: its values corrected by the master's bias, its U
the substitution's.
"""

import argparse
import json
import os
import sys
from collections import defaultdict
from pathlib import Path

from lab2_grid import absolutize, calibrate, characterize, run

ROOT = Path(__file__).resolve().parent.parent
PATTERNS = ("job_pair.json", "job_pair_rotated.json")


def prepare_job(args, job_file, out, machine, material):
    """The lab's job with the calibrated material and, unless --stated, the
    characterised machine (its detector file's halo in use, the job's own
    stated halo left out), written to OUT/job.json."""
    job = absolutize(json.loads(job_file.read_text()), job_file.parent)
    job["material"] = str(material)
    if not args.stated:
        job["machine"] = str(machine)
        job.pop("scatter", None)
    out.mkdir(parents=True, exist_ok=True)
    (out / "job.json").write_text(json.dumps(job, indent=2))
    return job


def verify_master(args, lab, part, pattern, out, machine, material):
    """`xgauge verify` of the part's master (lab2's master sets, its CMM
    certificate) under the production job's conditions; the verification
    file's path, or None with the reason in the row."""
    stem = pattern.replace("job_", "").replace(".json", "")
    mroot = lab / "measured" / f"{part}_master"
    vfile = mroot / f"verify_{stem}.json"
    if not vfile.exists():
        return None, {"reason": f"no {vfile}"}
    vjob = json.loads(vfile.read_text())

    def prepared(jobs):
        files = []
        for m in jobs:
            set_out = out / stem / Path(m).parent
            prepare_job(args, mroot / m, set_out, machine, material)
            files.append(str(set_out / "job.json"))
        return files
    # One master (its "measurements") or several (lab2 --master-specimens).
    for master in vjob.get("masters", [vjob]):
        master["measurements"] = prepared(master["measurements"])
    (out / f"verify_{stem}.json").write_text(json.dumps(vjob, indent=2))
    folder = out / f"verification_{stem}"
    rc, seconds = run([args.xgauge, "verify", str(out / f"verify_{stem}.json"), "-o", str(folder),
                       "--quiet", "-j", str(args.threads)], out / f"verify_{stem}.log")
    row = {"rc": rc, "seconds": seconds}
    if rc != 0:
        row["reason"] = (out / f"verify_{stem}.log").read_text().strip().splitlines()[-1:]
        return None, row
    return folder / "verification.json", row


def measure_part(args, folder, job_file, out, machine, material, verification=None):
    job = prepare_job(args, job_file, out, machine, material)
    if verification is not None:
        job["verification"] = str(verification)
        (out / "job.json").write_text(json.dumps(job, indent=2))
    rc, seconds = run([args.xgauge, "measure", str(out / "job.json"), "--truth",
                       str(job_file.parent / "truth.json"), "-o", str(out / "result"), "--quiet",
                       "-j", str(args.threads)], out / "measure.log")
    row = {"rc": rc, "seconds": seconds}
    try:
        result = json.loads((out / "result" / "result.json").read_text())
    except (OSError, ValueError):
        row["reason"] = (out / "measure.log").read_text().strip().splitlines()[-1:]
        return row
    truth = json.loads((job_file.parent / "truth.json").read_text())["part"]["dimensions"]
    row["status"] = result["status"]
    row["failures"] = result.get("failures", [])
    row["misfit"] = [c["misfit_ratio"] for c in result.get("fit_checks", [])]
    # A run that was not measured keeps its values under another name: kept
    # here to see how far off the refused values were, never counted.
    dims = result.get("dimensions") or result.get("rejected_dimensions") or []
    row["dimensions"] = {}
    for d in dims:
        if not d.get("free") or d["name"] not in truth:
            continue
        item = {"error": d["value_mm"] - truth[d["name"]], "U": d.get("expanded_uncertainty")}
        if v := d.get("verification"):
            # The same measurement unverified: the fit's value and the model's own U.
            item.update(own_error=v["fitted_value"] - truth[d["name"]],
                        own_U=v["own_expanded_uncertainty"], k=v.get("coverage_factor"))
        row["dimensions"][d["name"]] = item
    return row


def _within(rows, err, unc):
    """(inside, count, |errors|, per dimension) over measured runs' dimensions
    that have both keys."""
    inside = count = 0
    errors, per_dim = [], defaultdict(lambda: [0, 0])
    for part, r in rows:
        if r.get("status") != "measured":
            continue
        for name, d in r["dimensions"].items():
            if d.get(unc) is None or d.get(err) is None:
                continue
            ok = abs(d[err]) <= d[unc]
            count += 1
            inside += ok
            errors.append(abs(d[err]))
            per_dim[f"{part}.{name}"][0] += ok
            per_dim[f"{part}.{name}"][1] += 1
    return inside, count, errors, per_dim


def tabulate(rows):
    """The table per part and pattern; with --verified runs, the same
    measurements unverified (the fit's value, the model's own U) beside."""
    verified = any("own_U" in d for r in rows.values() for d in r.get("dimensions", {}).values())
    head = "| part | pattern | runs measured | dimensions within U | coverage | mean abs error mm |"
    if verified:
        head += " unverified: within own U | coverage | mean abs error mm |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    by = defaultdict(list)
    for (machine, part, pattern), row in rows.items():
        by[(part, pattern)].append((part, row))

    def cells(rs, err, unc):
        inside, count, errors, _ = _within(rs, err, unc)
        cov = f"{100 * inside / count:.0f} %" if count else "–"
        mean = f"{sum(errors) / len(errors):.4f}" if errors else "–"
        return f" {inside} of {count} | {cov} | {mean} |"

    for (part, pattern), rs in sorted(by.items()):
        ok = sum(r.get("status") == "measured" for _, r in rs)
        line = (f"| {part} | {pattern.replace('job_', '').replace('.json', '')} | {ok} of {len(rs)} |"
                + cells(rs, "error", "U"))
        if verified:
            line += cells(rs, "own_error", "own_U")
        lines.append(line)
    lines.append("")
    everything = [(k[1], r) for k, r in rows.items()]
    measured = sum(r.get("status") == "measured" for _, r in everything)
    for label, err, unc in (("", "error", "U"), ("Unverified (the same runs, the model's own U): ",
                                                 "own_error", "own_U")):
        if not label or verified:
            inside, count, _, per_dim = _within(everything, err, unc)
            if not count:
                continue
            low = [f"{k} {100 * v[0] / v[1]:.0f} % ({v[0]}/{v[1]})" for k, v in sorted(per_dim.items())
                   if v[1] and v[0] / v[1] < 0.8]
            lines.append(f"{label or 'Pooled: '}{inside} of {count} dimensions within U "
                         f"({100 * inside / count:.1f} %); {measured} of {len(everything)} runs measured. "
                         "Dimensions below 80 %: " + (", ".join(low) if low else "none") + ".")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("suite", type=Path, help="the folder lab2.py suite wrote")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "lab2_coverage")
    ap.add_argument("--xgauge", default=str(ROOT / "build" / "apps" / "xgauge" / "xgauge"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--stated", action="store_true")
    ap.add_argument("--verified", action="store_true",
                    help="verify each part and pattern on its master first (xgauge verify on lab2's "
                         "master sets and certificate) and measure with that verification")
    ap.add_argument("--parts", nargs="*", default=["prism", "wedge", "bracket", "shaft"])
    ap.add_argument("--table", action="store_true")
    args = ap.parse_args()
    out_file = args.out / "coverage.json"
    if args.table:
        rows = {tuple(k.split("|")): v for k, v in json.loads(out_file.read_text()).items()}
        print(tabulate(rows))
        return 0
    # Machine folders, linked ones too (a suite assembled from several).
    labs = sorted(Path(d) for d, _, files in os.walk(args.suite, followlinks=True)
                  if "lab2_truth.json" in files)
    if not labs:
        print(f"lab2_coverage: no machine folders in {args.suite}", file=sys.stderr)
        return 2
    rows = {}
    ok = True
    for lab in labs:
        name = str(lab.relative_to(args.suite))
        out = args.out / name
        out.mkdir(parents=True, exist_ok=True)
        ch = characterize(args, name, lab, out)
        cal = calibrate(args, name, lab, out, out / "machine.json")
        if ch["rc"] != 0 or cal["rc"] != 0:
            print(f"{name}: characterize rc {ch['rc']}, calibrate rc {cal['rc']}: "
                  f"{ch.get('reason') or cal.get('reason')}", flush=True)
            ok = False
            continue
        for part in args.parts:
            for pattern in PATTERNS:
                job_file = lab / "measured" / part / pattern
                if not job_file.exists():
                    continue
                machine, material = out / "machine.json", out / "calibration" / "material.json"
                verification = None
                if args.verified:
                    verification, vrow = verify_master(args, lab, part, pattern, out / f"{part}_master",
                                                       machine, material)
                    if verification is None:
                        rows[(name, part, pattern)] = {"rc": vrow["rc"] if "rc" in vrow else 1,
                                                       "seconds": vrow.get("seconds", 0.0),
                                                       "verify_failed": vrow.get("reason")}
                        print(f"{name} {part} {pattern}: verification failed: {vrow.get('reason')}",
                              flush=True)
                        continue
                row = measure_part(args, lab, job_file, out / part / pattern.replace(".json", ""),
                                   machine, material, verification)
                rows[(name, part, pattern)] = row
                d = row.get("dimensions", {})
                inside = sum(1 for v in d.values() if v["U"] is not None and abs(v["error"]) <= v["U"])
                print(f"{name} {part} {pattern}: {row.get('status', 'failed')} "
                      f"{row.get('failures', '')} {inside}/{len(d)} within U "
                      f"({row['seconds']:.0f} s)", flush=True)
                out_file.write_text(json.dumps({"|".join(k): v for k, v in rows.items()}, indent=1))
    print(tabulate(rows))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
