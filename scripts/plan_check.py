#!/usr/bin/env python3
"""An independent check of `xgauge plan`'s predictions: measure simulated
radiographs taken at the views of a planned set and compare the measured U
and the errors against the truth with the U the plan predicted.

For each chosen set (`ranked:I` or `compared:I` of plan.json; the set must
have been given the measurement's budget, i.e. carry a "job") and each run
k = 1 .. --runs:

1. OUT/<set>/run<k>/recipe.json: the base recipe (--recipe) with its
   relative paths made absolute, "seed" = base seed + 1000 k, and "shots" =
   {"base_pose": the set's first view's pose, "extra": every view of the set,
   in the set's order, with its pose from plan.json "views"} (the recipe's
   translations and rotations, its detector characterisation session and
   its lot, if any, are left out);
2. `xgauge simulate` into OUT/<set>/run<k>/data (skipped when its
   truth.json exists);
3. OUT/<set>/run<k>/job.json: the set's "job" with each radiograph's image,
   the data folder's dark.tif and flat.tif and, for every radiograph but the
   session's first exposure, "previous" = the shot exposed just before it
   (truth.json's shot order), so that its lag is subtracted as in the demo;
4. `xgauge measure` into OUT/<set>/run<k>/measure with --truth (skipped
   when its result.json exists: the script resumes where it stopped).

A run is "measured" when result.json's status says so. xgauge's exit codes
2 and 3 (verdicts) are normal; 1 with result.json "not measured" counts as
not measured; any other failure (no result.json, a crash, a simulate that
failed) is recorded with the end of its stderr and the script goes on.
OUT/<set>/run<k>/run.json keeps each run's exit codes.

Then per set and dimension: the plan's predicted U and its statistical
component; the mean measured U over the measured runs and its ratio to the
prediction; the errors (value - truth.json's true value): mean (bias),
standard deviation over runs, RMS, 2 RMS and 2 RMS / U_pred with a 95 %
interval (chi-square with n = runs degrees of freedom, Wilson-Hilferty);
per set the measured worst U/T (tolerance widths from plan.json) against the
plan's score, the worst 2 RMS / T, the pooled RMS over dimensions and runs
of error / (U_pred / 2) (about 1 when the errors are as the plan predicts,
below when the plan is conservative), the runs measured and not, and the
dimensions the measurements flagged not identifiable against those the plan
did. Printed (stdout) and written to OUT/check.json; progress on stderr.

Usage:
  /usr/bin/python3 scripts/plan_check.py --plan out/plan_prism_a/plan.json \\
      --recipe datasets/prism_a_small.json --sets compared:0,ranked:0 \\
      --runs 10 --out out/plan_check_prism_a --xgauge build/apps/xgauge/xgauge

Exit 0 when every requested run was measured, 1 otherwise (the table and
check.json are written either way), 2 on bad arguments or a stale OUT.
"""

import argparse
import datetime
import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

SEED_STEP = 1000


def log(msg):
    print(f"[plan_check] {msg}", file=sys.stderr, flush=True)


def load_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def write_json(path, data):
    tmp = Path(str(path) + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


def parse_sets(text):
    sets = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        kind, _, index = item.partition(":")
        if kind not in ("ranked", "compared") or not index.isdigit():
            raise ValueError(f"--sets: '{item}' is not ranked:I or compared:I")
        sets.append((kind, int(index)))
    if not sets:
        raise ValueError("--sets: no set given")
    return sets


def absolute_recipe(recipe_path):
    """The recipe with the paths it names (machine, part.model, part.physical)
    made absolute: relative paths are relative to the recipe's folder."""
    recipe = load_json(recipe_path)
    folder = Path(recipe_path).resolve().parent

    def fix(value):
        p = Path(value)
        return str(p if p.is_absolute() else (folder / p).resolve())

    recipe["machine"] = fix(recipe["machine"])
    part = recipe["part"]
    part["model"] = fix(part["model"])
    if "physical" in part:
        part["physical"] = fix(part["physical"])
    return recipe


def run_recipe(base, views_by_name, set_views, seed):
    recipe = json.loads(json.dumps(base))
    recipe["seed"] = seed
    # A dataset of the set's views only: no characterisation session, no lot.
    recipe.pop("characterization", None)
    recipe.pop("lot", None)
    recipe.pop("white_region", None)
    first = views_by_name[set_views[0]]["pose"]
    recipe["shots"] = {
        "base_pose": {"rotation_deg": list(first["rotation_deg"]),
                      "translation_mm": list(first["translation_mm"])},
        "extra": [{"name": v,
                   "pose": {"rotation_deg": list(views_by_name[v]["pose"]["rotation_deg"]),
                            "translation_mm": list(views_by_name[v]["pose"]["translation_mm"])}}
                  for v in set_views],
    }
    if "description" in recipe:
        recipe["description"] = (f"plan_check: {recipe['description']} -- shots replaced by the views "
                                 f"{', '.join(set_views)}, seed {seed}")
    return recipe


def run_job(plan_job, data, truth):
    """The set's job with its radiographs pointing into the data folder."""
    job = json.loads(json.dumps(plan_job))
    order = [s["name"] for s in truth["shots"]]
    files = {s["name"]: s.get("file", s["name"] + ".tif") for s in truth["shots"]}
    dark = data / truth.get("dark", "dark.tif")
    flat = data / truth.get("flat", "flat.tif")
    for r in job["radiographs"]:
        shot = r["name"]
        if shot not in files:
            # The plan writes "<view>.tif": the shot is named by the view.
            shot = Path(r["image"]).stem
        if shot not in files:
            raise RuntimeError(f"radiograph {r['name']}: no shot '{shot}' in {data / 'truth.json'}")
        r["image"] = str(data / files[shot])
        r["dark"] = str(dark)
        r["flat"] = str(flat)
        i = order.index(shot)
        r.pop("previous", None)
        if i > 0:
            r["previous"] = str(data / files[order[i - 1]])
    return job


def tail(text, n=1500):
    text = text.strip()
    return text if len(text) <= n else "..." + text[-n:]


def call(cmd, timeout, attempts=4, wait_s=15):
    """Runs cmd; a binary that cannot be started (being relinked by a build
    beside us: permission denied, text file busy) is tried again."""
    for attempt in range(1, attempts + 1):
        t0 = time.time()
        try:
            p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               timeout=timeout if timeout and timeout > 0 else None)
            return p.returncode, p.stdout, p.stderr, time.time() - t0
        except subprocess.TimeoutExpired as e:
            err = e.stderr.decode(errors="replace") if isinstance(e.stderr, bytes) else (e.stderr or "")
            return None, "", err + f"\n(timed out after {timeout} s)", time.time() - t0
        except OSError as e:
            if attempt == attempts:
                return None, "", f"could not run {cmd[0]} ({attempts} tries): {e}", time.time() - t0
            log(f"could not run {cmd[0]}: {e}; trying again in {wait_s} s")
            time.sleep(wait_s)


_FINGERPRINTS = {}


def binary_fingerprint(path):
    """sha256 (first 16 hex digits) of the xgauge binary as it is now: a
    build beside us may replace it between runs."""
    try:
        st = os.stat(path)
    except OSError as e:
        return f"unreadable: {e.strerror}"
    key = (st.st_mtime_ns, st.st_size)
    if key not in _FINGERPRINTS:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _FINGERPRINTS[key] = h.hexdigest()[:16]
    return _FINGERPRINTS[key]


def do_run(args, label, set_entry, base_recipe, base_seed, views_by_name, k, set_dir):
    """Simulate and measure one run; returns its record (resumable)."""
    run_dir = set_dir / f"run{k}"
    data = run_dir / "data"
    measure = run_dir / "measure"
    result_path = measure / "result.json"
    record_path = run_dir / "run.json"
    seed = base_seed + SEED_STEP * k
    record = {"run": k, "seed": seed, "folder": str(run_dir)}
    if record_path.exists():
        try:
            old = load_json(record_path)
            record.update({key: old[key] for key in ("simulate_rc", "measure_rc", "simulate_s", "measure_s",
                                                     "simulate_xgauge", "measure_xgauge") if key in old})
        except (OSError, ValueError):
            pass
    if result_path.exists():
        log(f"{label} run {k}: result.json exists, skipped")
        record["skipped"] = True
        return record
    run_dir.mkdir(parents=True, exist_ok=True)
    xg = [args.xgauge, "-j", str(args.threads), "-q"]

    # 1-2: the dataset
    if not (data / "truth.json").exists():
        recipe = run_recipe(base_recipe, views_by_name, set_entry["views"], seed)
        write_json(run_dir / "recipe.json", recipe)
        if data.exists():
            shutil.rmtree(data)  # an interrupted simulate: start it again
        log(f"{label} run {k}: simulating {', '.join(set_entry['views'])} (seed {seed})")
        record["simulate_xgauge"] = binary_fingerprint(args.xgauge)
        rc, out, err, secs = call(xg + ["simulate", str(run_dir / "recipe.json"), "-o", str(data)],
                                  args.timeout)
        record.update({"simulate_rc": rc, "simulate_s": round(secs, 1)})
        if rc != 0 or not (data / "truth.json").exists():
            record["error"] = f"xgauge simulate exited {rc}: {tail(err or out)}"
            log(f"{label} run {k}: SIMULATE FAILED (exit {rc}): {tail(err or out, 400)}")
            write_json(record_path, record)
            return record
    truth = load_json(data / "truth.json")

    # 3-4: the measurement
    try:
        job = run_job(set_entry["job"], data.resolve(), truth)
    except (RuntimeError, KeyError, ValueError) as e:
        record["error"] = f"job: {e}"
        log(f"{label} run {k}: JOB FAILED: {e}")
        write_json(record_path, record)
        return record
    write_json(run_dir / "job.json", job)
    if measure.exists():
        shutil.rmtree(measure)  # an interrupted measurement: start it again
    log(f"{label} run {k}: measuring")
    record["measure_xgauge"] = binary_fingerprint(args.xgauge)
    rc, out, err, secs = call(xg + ["measure", str(run_dir / "job.json"), "-o", str(measure),
                                    "--truth", str(data / "truth.json")], args.timeout)
    record.update({"measure_rc": rc, "measure_s": round(secs, 1)})
    if rc not in (0, 2, 3):
        if result_path.exists():
            record["error"] = f"xgauge measure exited {rc} (result.json written)"
        else:
            record["error"] = f"xgauge measure exited {rc}, no result.json: {tail(err or out)}"
        log(f"{label} run {k}: measure exited {rc}: {tail(err or out, 400)}")
    else:
        log(f"{label} run {k}: measured in {secs:.0f} s (exit {rc})")
    write_json(record_path, record)
    return record


# ---------------------------------------------------------------- statistics

def chi2_quantile(p, n):
    """Wilson-Hilferty approximation of the chi-square quantile."""
    z = normal_quantile(p)
    h = 2.0 / (9.0 * n)
    return n * max(1.0 - h + z * math.sqrt(h), 1e-9) ** 3


def normal_quantile(p):
    # Acklam's rational approximation (|error| < 1.2e-9).
    a = [-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
         1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00]
    b = [-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
         6.680131188771972e+01, -1.328068155288572e+01]
    c = [-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
         -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00]
    d = [7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00, 3.754408661907416e+00]
    lo = 0.02425
    if p < lo:
        q = math.sqrt(-2 * math.log(p))
        return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) / \
            ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1)
    if p > 1 - lo:
        return -normal_quantile(1 - p)
    q = p - 0.5
    r = q * q
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q / \
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1)


def mean(xs):
    return sum(xs) / len(xs) if xs else None


def rms(xs):
    return math.sqrt(sum(x * x for x in xs) / len(xs)) if xs else None


def sd(xs):
    if len(xs) < 2:
        return None
    m = mean(xs)
    return math.sqrt(sum((x - m) ** 2 for x in xs) / (len(xs) - 1))


def ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None


def read_result(run_dir):
    path = run_dir / "measure" / "result.json"
    if not path.exists():
        return None
    try:
        return load_json(path)
    except (OSError, ValueError) as e:
        return {"status": f"unreadable result.json: {e}"}


def summarize_set(label, spec, set_entry, records, set_dir):
    pdims = set_entry["dimensions"]
    comps = set_entry.get("components", {})
    names = list(pdims.keys())
    per = {n: {"values": [], "errors": [], "u": [], "not_identifiable": 0, "u_stat": []} for n in names}
    runs_out = []
    measured = 0
    worst_ut = []
    noise = []
    for rec in records:
        run_dir = Path(rec["folder"])
        res = read_result(run_dir)
        entry = {k: rec[k] for k in ("run", "seed", "simulate_rc", "measure_rc", "simulate_s", "measure_s",
                                     "simulate_xgauge", "measure_xgauge", "error", "skipped") if k in rec}
        if res is None:
            entry["status"] = "failed"
            entry.setdefault("error", "no result.json")
            runs_out.append(entry)
            continue
        entry["status"] = res.get("status")
        if res.get("failures"):
            entry["failures"] = res["failures"]
        entry["warnings"] = len(res.get("warnings", []))
        if res.get("status") != "measured":
            runs_out.append(entry)
            continue
        truth_path = run_dir / "data" / "truth.json"
        true_dims = load_json(truth_path)["part"]["dimensions"]
        measured += 1
        dims = {d["name"]: d for d in res.get("dimensions", [])}
        budget = (res.get("uncertainty") or {}).get("dimensions", {})
        if isinstance(budget, list):
            budget = {b.get("name"): b for b in budget}
        errors = {}
        run_worst = None
        for n in names:
            d = dims.get(n)
            if d is None or not d.get("free", True):
                continue
            err = d["value_mm"] - true_dims[n]
            errors[n] = err
            per[n]["values"].append(d["value_mm"])
            per[n]["errors"].append(err)
            if not d.get("identifiable", True):
                per[n]["not_identifiable"] += 1
            u = d.get("expanded_uncertainty")
            if u is not None:
                per[n]["u"].append(u)
                tw = pdims[n].get("tolerance_width")
                if tw:
                    run_worst = max(run_worst or 0.0, u / tw)
            for c in (budget.get(n) or {}).get("components", []):
                if c.get("name") == "statistical":
                    per[n]["u_stat"].append(c.get("contribution"))
        entry["errors"] = errors
        entry["worst_u_over_t"] = run_worst
        if run_worst is not None:
            worst_ut.append(run_worst)
        for fc in res.get("fit_checks", []):
            if fc.get("noise_sigma") is not None:
                noise.append(fc["noise_sigma"])
        runs_out.append(entry)

    dims_out = {}
    pooled = []
    worst_2rms_t = None
    for n in names:
        p = pdims[n]
        u_pred = p.get("expanded_uncertainty")
        u_stat_pred = None
        for c in comps.get(n, []):
            if c.get("name") == "statistical":
                u_stat_pred = c.get("contribution")
        e = per[n]["errors"]
        r = rms(e)
        nn = len(e)
        two_rms = 2 * r if r is not None else None
        interval = None
        if nn >= 1 and u_pred:
            # sigma from n errors about the truth: n RMS^2 / sigma^2 ~ chi2(n)
            interval = [two_rms * math.sqrt(nn / chi2_quantile(0.975, nn)) / u_pred,
                        two_rms * math.sqrt(nn / chi2_quantile(0.025, nn)) / u_pred]
        if u_pred:
            pooled.extend(x / (u_pred / 2) for x in e)
        tw = p.get("tolerance_width")
        if tw and two_rms is not None:
            worst_2rms_t = max(worst_2rms_t or 0.0, two_rms / tw)
        dims_out[n] = {
            "predicted_U": u_pred,
            "predicted_identifiable": p.get("identifiable"),
            "predicted_statistical_u": u_stat_pred,
            "tolerance_width": tw,
            "measured_runs": nn,
            "mean_measured_U": mean(per[n]["u"]),
            "measured_U_runs": len(per[n]["u"]),
            "U_ratio_measured_over_predicted": ratio(mean(per[n]["u"]), u_pred),
            "mean_measured_statistical_u": mean(per[n]["u_stat"]),
            "mean_error": mean(e),
            "sd_error": sd(e),
            "sd_over_predicted_statistical_u": ratio(sd(e), u_stat_pred),
            "rms_error": r,
            "max_abs_error": max((abs(x) for x in e), default=None),
            "two_rms_error": two_rms,
            "two_rms_over_predicted_U": ratio(two_rms, u_pred),
            "two_rms_over_predicted_U_95": interval,
            "runs_not_identifiable": per[n]["not_identifiable"],
        }
    plan_ni = sorted(n for n in names if not pdims[n].get("identifiable", True))
    meas_ni = {n: per[n]["not_identifiable"] for n in names if per[n]["not_identifiable"]}
    requested = len(records)
    binaries = sorted({r[k] for r in runs_out for k in ("simulate_xgauge", "measure_xgauge") if r.get(k)})
    failed = [r["run"] for r in runs_out if r["status"] == "failed"]
    not_measured = [r["run"] for r in runs_out if r["status"] not in ("measured", "failed")]
    return {
        "set": spec,
        "label": label,
        "views": set_entry["views"],
        "patterns": set_entry.get("patterns"),
        "predicted_by": set_entry.get("predicted_by"),
        "predicted_score": set_entry.get("score"),
        "folder": str(set_dir),
        "runs": {"requested": requested, "measured": measured, "not_measured": len(not_measured) + len(failed),
                 "not_measured_runs": not_measured, "failed_runs": failed},
        "measured_worst_u_over_t": {"mean": mean(worst_ut), "max": max(worst_ut, default=None),
                                    "per_run": worst_ut},
        "worst_two_rms_over_t": worst_2rms_t,
        "pooled_rms_error_over_half_U_pred": {"value": rms(pooled), "samples": len(pooled)},
        "identifiability": {"plan_not_identifiable": plan_ni, "measured_not_identifiable_runs": meas_ni},
        "open_beam_noise": {"measured_mean": mean(noise)},
        "xgauge_binaries": binaries,
        "dimensions": dims_out,
        "run_details": runs_out,
    }


def fmt(v, spec=".4f"):
    if v is None:
        return "-"
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    return format(v, spec)


def print_table(check, out):
    w = out.write
    w(f"plan {check['plan']}   recipe {check['recipe']}   runs {check['runs_requested']} per set\n")
    for s in check["sets"]:
        r = s["runs"]
        w("\n")
        w(f"{s['set']} ({s['label']}): views {' '.join(f'{v}:{p}' for v, p in zip(s['views'], s['patterns'] or []))}"
          f", predicted by {s['predicted_by']}; runs measured {r['measured']}/{r['requested']}")
        if r["not_measured_runs"]:
            w(f", not measured: {r['not_measured_runs']}")
        if r["failed_runs"]:
            w(f", FAILED: {r['failed_runs']}")
        w("\n")
        head = (f"  {'dimension':<14}{'U_pred':>8}{'U_meas':>8}{'ratio':>7}{'bias':>9}{'sd':>8}"
                f"{'u_stat':>8}{'sd/us':>7}{'rms':>8}{'2rms':>8}{'2rms/U':>8}  {'95% of 2rms/U':<14}{'maxerr':>8}{'n':>3}\n")
        w(head)
        for n, d in s["dimensions"].items():
            iv = d["two_rms_over_predicted_U_95"]
            ivs = f"[{iv[0]:.2f}, {iv[1]:.2f}]" if iv else "-"
            flag = ""
            if d["runs_not_identifiable"]:
                flag += f"  not identifiable in {d['runs_not_identifiable']} runs"
            if d["predicted_identifiable"] is False:
                flag += "  plan: not identifiable"
            w(f"  {n:<14}{fmt(d['predicted_U']):>8}{fmt(d['mean_measured_U']):>8}"
              f"{fmt(d['U_ratio_measured_over_predicted'], '.2f'):>7}{fmt(d['mean_error'], '+.4f'):>9}"
              f"{fmt(d['sd_error']):>8}{fmt(d['predicted_statistical_u']):>8}"
              f"{fmt(d['sd_over_predicted_statistical_u'], '.2f'):>7}{fmt(d['rms_error']):>8}"
              f"{fmt(d['two_rms_error']):>8}{fmt(d['two_rms_over_predicted_U'], '.2f'):>8}  {ivs:<14}"
              f"{fmt(d['max_abs_error']):>8}{d['measured_runs']:>3}{flag}\n")
        wu = s["measured_worst_u_over_t"]
        w(f"  worst U/T: predicted (score) {fmt(s['predicted_score'])}, measured mean {fmt(wu['mean'])}"
          f" (max {fmt(wu['max'])}); worst 2rms/T {fmt(s['worst_two_rms_over_t'])}\n")
        pr = s["pooled_rms_error_over_half_U_pred"]
        w(f"  pooled RMS of error/(U_pred/2) over dimensions and runs: {fmt(pr['value'], '.3f')}"
          f" ({pr['samples']} errors)\n")
        idf = s["identifiability"]
        w(f"  not identifiable: plan {idf['plan_not_identifiable'] or 'none'}, measurements "
          f"{idf['measured_not_identifiable_runs'] or 'none'}\n")
        w(f"  open-beam noise: plan {fmt(check.get('plan_open_beam_noise'))}, measured mean "
          f"{fmt(s['open_beam_noise']['measured_mean'])}\n")
        if len(s["xgauge_binaries"]) > 1:
            w(f"  WARNING: the runs used {len(s['xgauge_binaries'])} different xgauge binaries "
              f"(sha256 {', '.join(s['xgauge_binaries'])}): rebuilt while running; see run_details\n")
        for rd in s["run_details"]:
            if rd.get("error") or rd["status"] != "measured":
                w(f"  run {rd['run']}: {rd['status']}"
                  f"{'; ' + '; '.join(rd['failures']) if rd.get('failures') else ''}"
                  f"{'; ' + rd['error'] if rd.get('error') else ''}\n")
    w("\ncolumns: U_pred the plan's U (k=2); U_meas the mean of the measurements' U; ratio U_meas/U_pred; "
      "bias the mean error (value - truth); sd its standard deviation over runs; u_stat the plan's "
      "statistical component (k=1) and sd/us their ratio; rms and 2rms of the errors; 2rms/U = 2 rms / "
      "U_pred with its 95% interval from n runs (chi-square); maxerr the largest |error|.\n")


def choose_sets(plan, specs, ap):
    """The sets `specs` ([(kind, i)]) names in plan.json, as (spec, label,
    entry); ap.error() where one is missing, has no job or names views
    plan.json does not list."""
    views_by_name = {v["name"]: v for v in plan["views"]}
    chosen = []
    for kind, i in specs:
        spec = f"{kind}:{i}"
        lst = plan.get(kind, [])
        if i >= len(lst):
            ap.error(f"{spec}: plan.json has {len(lst)} {kind} sets")
        entry = lst[i]
        if "job" not in entry:
            ap.error(f"{spec} ({' '.join(entry['views'])}) has no job: it was predicted by "
                     f"{entry.get('predicted_by')}, not given the measurement's budget (or plan.json is "
                     f"from an xgauge before plan sets carried their job: run xgauge plan again)")
        missing = [v for v in entry["views"] if v not in views_by_name]
        if missing:
            ap.error(f"{spec}: views {missing} not in plan.json's views")
        chosen.append((spec, f"{kind}{i}", entry))
    return chosen


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plan", required=True, help="plan.json written by xgauge plan")
    ap.add_argument("--recipe", required=True, help="the base lab recipe (e.g. datasets/prism_a_small.json)")
    ap.add_argument("--sets", default="ranked:0", help="comma-separated ranked:I / compared:I (default ranked:0)")
    ap.add_argument("--runs", type=int, default=10, help="runs per set (default 10)")
    ap.add_argument("--out", required=True, help="output folder (resumable)")
    ap.add_argument("--xgauge", default="build/apps/xgauge/xgauge", help="the xgauge binary")
    ap.add_argument("--threads", type=int, default=2, help="xgauge worker threads (default 2)")
    ap.add_argument("--timeout", type=float, default=0, help="seconds per xgauge command (0: none)")
    ap.add_argument("--summary-only", action="store_true", help="simulate and measure nothing; tabulate what is there")
    args = ap.parse_args()

    try:
        specs = parse_sets(args.sets)
    except ValueError as e:
        ap.error(str(e))
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    args.xgauge = str(Path(args.xgauge).resolve())
    if not args.summary_only and not os.access(args.xgauge, os.X_OK):
        ap.error(f"--xgauge {args.xgauge} is not an executable")
    plan = load_json(args.plan)
    base_recipe = absolute_recipe(args.recipe)
    base_seed = int(base_recipe.get("seed", 0))
    if "lot" in base_recipe:
        log("the recipe's lot is left out: each run is one dataset")
    views_by_name = {v["name"]: v for v in plan["views"]}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    chosen = choose_sets(plan, specs, ap)

    # A set folder made for another plan's set must not be mixed in.
    for spec, label, entry in chosen:
        set_dir = out / label
        set_dir.mkdir(parents=True, exist_ok=True)
        ident = {"set": spec, "views": entry["views"],
                 "poses": [views_by_name[v]["pose"] for v in entry["views"]],
                 "job": entry["job"], "recipe": base_recipe}
        ident_path = set_dir / "set.json"
        if ident_path.exists():
            old = load_json(ident_path)
            if old != json.loads(json.dumps(ident)):
                print(f"plan_check: {ident_path} was made for another set, plan or recipe "
                      f"({' '.join(old.get('views', []))}); use another --out", file=sys.stderr)
                return 2
        else:
            write_json(ident_path, ident)

    summaries = []
    for spec, label, entry in chosen:
        set_dir = out / label
        records = []
        for k in range(1, args.runs + 1):
            if args.summary_only:
                rec = {"run": k, "seed": base_seed + SEED_STEP * k, "folder": str(set_dir / f"run{k}")}
                rp = set_dir / f"run{k}" / "run.json"
                if rp.exists():
                    rec.update({kk: vv for kk, vv in load_json(rp).items() if kk not in rec})
                records.append(rec)
                continue
            try:
                records.append(do_run(args, spec, entry, base_recipe, base_seed, views_by_name, k, set_dir))
            except Exception as e:  # visible, not fatal
                log(f"{spec} run {k}: ERROR {type(e).__name__}: {e}")
                records.append({"run": k, "seed": base_seed + SEED_STEP * k, "folder": str(set_dir / f"run{k}"),
                                "error": f"{type(e).__name__}: {e}"})
        summaries.append(summarize_set(label, spec, entry, records, set_dir))

    check = {
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "plan": args.plan,
        "plan_source": plan.get("plan"),
        "plan_criterion": plan.get("criterion"),
        "plan_open_beam_noise": plan.get("open_beam_noise"),
        "recipe": args.recipe,
        "xgauge": args.xgauge,
        "xgauge_sha256_16": binary_fingerprint(args.xgauge),
        "runs_requested": args.runs,
        "seeds": f"recipe seed {base_seed} + {SEED_STEP} k, k = 1 .. {args.runs}",
        "sets": summaries,
    }
    write_json(out / "check.json", check)
    print_table(check, sys.stdout)
    print(f"\nwrote {out / 'check.json'}")
    ok = all(s["runs"]["measured"] == s["runs"]["requested"] for s in summaries)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
