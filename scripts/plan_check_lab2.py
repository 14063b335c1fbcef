#!/usr/bin/env python3
"""scripts/plan_check.py's check of `xgauge plan` with lab2's physics: the
shots of a planned set are rendered by tools/lab2 (an independent
simulator: its own geometry, spectrum and detector model, a physical
specimen with the imperfections lab2 gives it) instead of xgauge's own
`xgauge simulate`, then measured with the set's job and tabulated exactly as
plan_check.py does (its table logic is imported from it).

For each chosen set (`ranked:I` or `compared:I` of plan.json; the set must
carry a "job") and each run k = 1 .. --runs (the runs go round the sets, run 1
of every set first, so a check stopped early has as many runs per set):

1. OUT/<set>/run<k>/poses.json: the set's views with their poses from
   plan.json "views", in the set's order;
2. `/usr/bin/python3 tools/lab2/lab2.py shots MACHINE_DIR --part PART --poses
   poses.json -o OUT/<set>/run<k>/data --seed (base seed + 1000 k)
   --specimen SPECIMEN` (skipped when its truth.json exists): the views
   exposed in the set's order, the first after a rest, each later one with
   the lag of the one before; the specimen drawn from the run's seed by
   default (lab2's usual dimension drift and imperfections: the same
   specimen for run k of every set), or `nominal`, or a file;
3. OUT/<set>/run<k>/job.json: the set's job with each radiograph's image,
   the data folder's dark.tif and flat.tif (the machine folder's) and
   "previous" = the shot exposed before it (plan_check.run_job);
4. `xgauge -j THREADS -q measure job.json -o measure --truth data/truth.json`
   (skipped when result.json exists).

Then the tables and OUT/check.json as plan_check.py writes them.

Usage:
  /usr/bin/python3 scripts/plan_check_lab2.py --plan out/plan_lab2_m01/plan/plan.json \\
      --machine-dir out/r61/lab2/m01 --part bracket --sets ranked:0,compared:0,compared:1,compared:2 \\
      --runs 10 --out out/plan_lab2_m01/check --xgauge /tmp/xgauge_lab2 --threads 1

Exit 0 when every requested run was measured, 1 otherwise, 2 on bad
arguments or a stale OUT.
"""

import argparse
import datetime
import json
import os
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import plan_check as pc  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
LAB2 = REPO / "tools" / "lab2" / "lab2.py"
PYTHON = "/usr/bin/python3"  # Debian's python3-xraylib (tools/lab2/README.md)


def log(msg):
    print(f"[plan_check_lab2] {msg}", file=sys.stderr, flush=True)


def do_run(args, spec, entry, views_by_name, k, set_dir, base_seed):
    run_dir = set_dir / f"run{k}"
    data = run_dir / "data"
    measure = run_dir / "measure"
    result_path = measure / "result.json"
    record_path = run_dir / "run.json"
    seed = base_seed + pc.SEED_STEP * k
    record = {"run": k, "seed": seed, "folder": str(run_dir)}
    if record_path.exists():
        try:
            old = pc.load_json(record_path)
            record.update({key: old[key] for key in ("simulate_rc", "measure_rc", "simulate_s", "measure_s",
                                                     "measure_xgauge") if key in old})
        except (OSError, ValueError):
            pass
    if result_path.exists():
        log(f"{spec} run {k}: result.json exists, skipped")
        record["skipped"] = True
        return record
    run_dir.mkdir(parents=True, exist_ok=True)

    if not (data / "truth.json").exists():
        poses = [{"name": v, "pose": {"rotation_deg": list(views_by_name[v]["pose"]["rotation_deg"]),
                                      "translation_mm": list(views_by_name[v]["pose"]["translation_mm"])}}
                 for v in entry["views"]]
        pc.write_json(run_dir / "poses.json", poses)
        if data.exists():
            shutil.rmtree(data)
        log(f"{spec} run {k}: lab2 shots {', '.join(entry['views'])} (seed {seed}, specimen {args.specimen})")
        rc, out, err, secs = pc.call([PYTHON, str(LAB2), "shots", str(args.machine_dir), "--part", args.part,
                                      "--poses", str(run_dir / "poses.json"), "-o", str(data), "--seed", str(seed),
                                      "--specimen", args.specimen], args.timeout)
        record.update({"simulate_rc": rc, "simulate_s": round(secs, 1)})
        (run_dir / "lab2_shots.log").write_text((out or "") + (err or ""))
        if rc != 0 or not (data / "truth.json").exists():
            record["error"] = f"lab2 shots exited {rc}: {pc.tail(err or out)}"
            log(f"{spec} run {k}: LAB2 SHOTS FAILED (exit {rc}): {pc.tail(err or out, 400)}")
            pc.write_json(record_path, record)
            return record
    truth = pc.load_json(data / "truth.json")
    try:
        job = pc.run_job(entry["job"], data.resolve(), truth)
    except (RuntimeError, KeyError, ValueError) as e:
        record["error"] = f"job: {e}"
        pc.write_json(record_path, record)
        return record
    pc.write_json(run_dir / "job.json", job)
    if measure.exists():
        shutil.rmtree(measure)
    log(f"{spec} run {k}: measuring")
    record["measure_xgauge"] = pc.binary_fingerprint(args.xgauge)
    rc, out, err, secs = pc.call([args.xgauge, "-j", str(args.threads), "-q", "measure", str(run_dir / "job.json"),
                                  "-o", str(measure), "--truth", str(data / "truth.json")], args.timeout)
    record.update({"measure_rc": rc, "measure_s": round(secs, 1)})
    (run_dir / "measure.log").write_text((out or "") + (err or ""))
    if rc not in (0, 2, 3):
        record["error"] = (f"xgauge measure exited {rc} (result.json written)" if result_path.exists() else
                           f"xgauge measure exited {rc}, no result.json: {pc.tail(err or out)}")
        log(f"{spec} run {k}: measure exited {rc}: {pc.tail(err or out, 400)}")
    else:
        log(f"{spec} run {k}: measured in {secs:.0f} s (exit {rc})")
    pc.write_json(record_path, record)
    return record


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plan", required=True, help="plan.json written by xgauge plan")
    ap.add_argument("--machine-dir", required=True, help="a lab2 machine folder (lab2.py machine ...)")
    ap.add_argument("--part", required=True, help="lab2's measured part (bracket, prism, wedge, shaft, screw)")
    ap.add_argument("--specimen", default="draw", help="draw (default), nominal, or a JSON file (lab2.py shots)")
    ap.add_argument("--seed", type=int, help="base seed (default: the machine's seed); run k uses base + 1000 k")
    ap.add_argument("--sets", default="ranked:0", help="comma-separated ranked:I / compared:I (default ranked:0)")
    ap.add_argument("--runs", type=int, default=10, help="runs per set (default 10)")
    ap.add_argument("--out", required=True, help="output folder (resumable)")
    ap.add_argument("--xgauge", default="build/apps/xgauge/xgauge", help="the xgauge binary")
    ap.add_argument("--threads", type=int, default=1, help="xgauge worker threads (default 1)")
    ap.add_argument("--timeout", type=float, default=0, help="seconds per command (0: none)")
    ap.add_argument("--summary-only", action="store_true", help="render and measure nothing; tabulate what is there")
    args = ap.parse_args()

    try:
        specs = pc.parse_sets(args.sets)
    except ValueError as e:
        ap.error(str(e))
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    args.xgauge = str(Path(args.xgauge).resolve())
    args.machine_dir = Path(args.machine_dir).resolve()
    if args.specimen not in ("draw", "nominal"):
        args.specimen = str(Path(args.specimen).resolve())
    if not args.summary_only and not os.access(args.xgauge, os.X_OK):
        ap.error(f"--xgauge {args.xgauge} is not an executable")
    if not (args.machine_dir / "lab2_machine.json").exists():
        ap.error(f"--machine-dir {args.machine_dir}: no lab2_machine.json")
    lab2_cfg = pc.load_json(args.machine_dir / "lab2_machine.json")
    base_seed = args.seed if args.seed is not None else int(lab2_cfg["seed"])
    plan = pc.load_json(args.plan)
    views_by_name = {v["name"]: v for v in plan["views"]}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    chosen = pc.choose_sets(plan, specs, ap)
    source = {"lab2_machine_dir": str(args.machine_dir), "part": args.part, "specimen": args.specimen,
              "base_seed": base_seed}
    for spec, label, entry in chosen:
        set_dir = out / label
        set_dir.mkdir(parents=True, exist_ok=True)
        ident = {"set": spec, "views": entry["views"], "poses": [views_by_name[v]["pose"] for v in entry["views"]],
                 "job": entry["job"], "source": source}
        ident_path = set_dir / "set.json"
        if ident_path.exists():
            if pc.load_json(ident_path) != json.loads(json.dumps(ident)):
                print(f"plan_check_lab2: {ident_path} was made for another set, plan or source; use another --out",
                      file=sys.stderr)
                return 2
        else:
            pc.write_json(ident_path, ident)

    records = {label: [] for _, label, _ in chosen}
    for k in range(1, args.runs + 1):
        for spec, label, entry in chosen:
            set_dir = out / label
            if args.summary_only:
                rec = {"run": k, "seed": base_seed + pc.SEED_STEP * k, "folder": str(set_dir / f"run{k}")}
                rp = set_dir / f"run{k}" / "run.json"
                if rp.exists():
                    rec.update({kk: vv for kk, vv in pc.load_json(rp).items() if kk not in rec})
                records[label].append(rec)
                continue
            try:
                records[label].append(do_run(args, spec, entry, views_by_name, k, set_dir, base_seed))
            except Exception as e:  # visible, not fatal
                log(f"{spec} run {k}: ERROR {type(e).__name__}: {e}")
                records[label].append({"run": k, "seed": base_seed + pc.SEED_STEP * k,
                                       "folder": str(set_dir / f"run{k}"), "error": f"{type(e).__name__}: {e}"})
    summaries = [pc.summarize_set(label, spec, entry, records[label], out / label) for spec, label, entry in chosen]

    check = {
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "plan": args.plan,
        "plan_source": plan.get("plan"),
        "plan_criterion": plan.get("criterion"),
        "plan_open_beam_noise": plan.get("open_beam_noise"),
        "recipe": (f"lab2 shots on {args.machine_dir} ({lab2_cfg.get('id')}), part {args.part}, specimen "
                   f"{args.specimen}"),
        "lab2": source,
        "xgauge": args.xgauge,
        "xgauge_sha256_16": pc.binary_fingerprint(args.xgauge),
        "runs_requested": args.runs,
        "seeds": f"base seed {base_seed} + {pc.SEED_STEP} k, k = 1 .. {args.runs} (noise and, with draw, the "
                 "specimen; the same specimen for run k of every set)",
        "sets": summaries,
    }
    pc.write_json(out / "check.json", check)
    pc.print_table(check, sys.stdout)
    print(f"\nwrote {out / 'check.json'}")
    return 0 if all(s["runs"]["measured"] == s["runs"]["requested"] for s in summaries) else 1


if __name__ == "__main__":
    sys.exit(main())
