#!/usr/bin/env python3
"""Monte Carlo check of xgauge's uncertainty budget, in the spirit of JCGM 101.

Re-simulates one pair of a virtual-lab dataset N times (a new noise seed each
time, and the lab's truth drawn from the uncertainties the measurement states),
measures every copy with the same job, and compares the spread of the errors
(k = 2: 2 s) with the expanded uncertainty U that `xgauge measure` reports.

    scripts/monte_carlo.py [--runs 50] [--parallel 2] [--seed 1]
                           [--work out/monte_carlo] [--output FILE]

Per run i (its draws depend only on --seed and i, so runs are reproducible in
any order and a rerun resumes: a run whose out/result.json exists is kept):
  lab (the recipe):  noise seed new; source-detector distance + N(0, u_D);
                     pixel pitch x (1 + N(0, u_p)); scatter weight
                     N(w, u_w) and width N(sigma, u_sigma) (in the recipe's
                     px); the translated shot's distance + N(0, 0.005 mm).
                     Only t00 .. t<k> are simulated (the earlier shots are
                     kept as they give the detector's ghost).
  job (xgauge):      the nominal machine, the template job's scatter and
                     distance, and the unperturbed lab's true curve
                     (`xgauge material --from-truth`: at least 3 terms, over
                     the paths the shots show) with every mu scaled by (1 + eps),
                     eps ~ N(0, eps_u), eps_u = u / max over x in [0, S] of
                     |x sum_k a_k mu_k exp(-mu_k x)| (S: the part's nominal
                     bounding-box diagonal), as the budget's material term.
The standard uncertainties are the stated ones (the machine's, material's and
job's "uncertainty" keys, else xgauge's defaults: 0.5 mm, 1e-4, 0.001, 5 % of
the weight, 10 % of sigma, 0.005 mm).

Prints, per free dimension (and per measurable combination the budget
reports, over the runs that report it): mean error, s, 2 s, mean reported U,
their ratio U / 2 s, the coverage (|e| <= U). Then, from 9 runs on, each
influence's effect per standard uncertainty by least squares of the errors on
the draws, beside the budget's, and the spread the draws leave unexplained
beside the statistical component. Writes all of it with every run's draws,
errors and U to --output (JSON; default WORK/monte_carlo.json). A failed run
is reported and left out. Python 3 standard library only; run it from anywhere.
"""

import argparse
import concurrent.futures
import json
import math
import random
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

# xgauge's defaults for unstated uncertainties (internal/xgauge/...).
DEFAULT_U_DISTANCE_MM = 0.5
DEFAULT_U_PITCH_RELATIVE = 1e-4
DEFAULT_U_TRANSMISSION = 0.001
DEFAULT_U_WEIGHT_RELATIVE = 0.05
DEFAULT_U_SIGMA_RELATIVE = 0.10
U_TRANSLATION_MM = 0.005


def load(path):
    with open(path) as f:
        return json.load(f)


def save(path, data):
    tmp = Path(str(path) + ".tmp")
    with open(tmp, "w") as f:
        json.dump(data, f, indent=2)
        f.write("\n")
    tmp.replace(path)


def resolve(base_file, relative):
    return str((Path(base_file).parent / relative).resolve())


def part_diagonal_mm(part_file, true_dimensions):
    """Bounding-box diagonal of an extruded part at its nominal values (what
    ForwardModel::partSizeMm uses); other shapes need --part-size-mm."""
    part = load(part_file)
    shape = part["shape"]
    if shape.get("type") != "extrusion":
        sys.exit(f"{part_file}: not an extrusion; give --part-size-mm")
    names = {d["name"]: d["nominal"] for d in part["dimensions"]}
    names.update({c["name"]: c["value"] for c in part.get("constants", [])})
    evaluate = lambda e: float(eval(str(e), {"__builtins__": {}}, names))  # noqa: E731
    points = [(evaluate(a), evaluate(b)) for a, b in shape["profile"]]
    extent = [max(p[i] for p in points) - min(p[i] for p in points) for i in (0, 1)]
    extent.append(abs(evaluate(shape["to"]) - evaluate(shape["from"])))
    return math.sqrt(sum(e * e for e in extent))


def rate_scale_uncertainty(material, u, size_mm):
    """eps_u: the scale of every rate that moves I(x) by u at the worst path."""
    slope = 0.0
    for k in range(401):
        x = size_mm * k / 400.0
        d = sum(t["weight"] * t["mu_per_mm"] * math.exp(-t["mu_per_mm"] * x) for t in material["terms"])
        slope = max(slope, x * d)
    return u / slope


class Setup:
    """Everything shared by the runs: paths, the nominal inputs, the stated
    uncertainties."""

    def __init__(self, args):
        self.args = args
        self.xgauge = str(Path(args.xgauge).resolve())
        self.work = Path(args.work).resolve()
        self.recipe_file = Path(args.recipe).resolve()
        self.job_file = Path(args.job).resolve()
        self.recipe = load(self.recipe_file)
        self.job = load(self.job_file)
        self.machine_file = resolve(self.recipe_file, self.recipe["machine"])
        self.machine = load(self.machine_file)
        self.job_machine_file = resolve(self.job_file, self.job["machine"])
        self.part_file = resolve(self.recipe_file, self.recipe["part"]["model"])

        # The pair: the job's free radiograph and its translated one, which
        # must be the recipe's t00 and t<k> with k * distance = the job's.
        spec = {r["pattern"]: r for r in self.job["radiographs"]}
        if set(spec) != {"free", "translated"} or len(self.job["radiographs"]) != 2:
            sys.exit(f"{self.job_file}: expected one free and one translated radiograph")
        self.free_name, self.moved_name = spec["free"]["name"], spec["translated"]["name"]
        self.distance_mm = spec["translated"]["distance_mm"]
        translations = self.recipe["shots"]["translations"]
        steps = self.distance_mm / translations["distance_mm"]
        self.moved_index = round(steps)
        if abs(steps - self.moved_index) > 1e-9 or not 1 <= self.moved_index < translations["count"]:
            sys.exit(f"{self.recipe_file}: no translated shot at {self.distance_mm} mm")

        # Stated standard uncertainties.
        stated = self.machine.get("uncertainty", {})
        self.u_distance_mm = stated.get("source_detector_distance_mm", DEFAULT_U_DISTANCE_MM)
        self.u_pitch_relative = stated.get("pixel_pitch_relative", DEFAULT_U_PITCH_RELATIVE)
        self.pitch_mm = self.machine["detector"]["pixel_pitch_mm"][0]
        # The job's scatter; a job that takes its scatter from its material's
        # calibration states none, and the runs (whose material is fitted to
        # the lab's table, without a scatter) state the lab's nominal one.
        if "scatter" not in self.job:
            lab = self.recipe["detector"]["scatter"]
            self.job["scatter"] = {"weight": lab["weight"], "sigma_mm": lab["sigma_px"] * self.pitch_mm}
        scatter = self.job["scatter"]
        self.u_weight = scatter.get("weight_uncertainty", DEFAULT_U_WEIGHT_RELATIVE * scatter["weight"])
        self.u_sigma_mm = scatter.get("sigma_uncertainty_mm", DEFAULT_U_SIGMA_RELATIVE * scatter["sigma_mm"])
        self.part_size_mm = args.part_size_mm or part_diagonal_mm(
            self.part_file, self.recipe["part"].get("dimensions", {}))

    def lab_recipe(self, seed, distance_mm):
        """The recipe reduced to shots t00 .. t<k>, t<k> at `distance_mm`."""
        recipe = json.loads(json.dumps(self.recipe))
        recipe["seed"] = seed
        recipe["part"]["model"] = self.part_file
        shots = recipe["shots"]
        shots.pop("rotations", None)
        shots.pop("extra", None)
        shots["translations"]["count"] = self.moved_index + 1
        shots["translations"]["distance_mm"] = distance_mm / self.moved_index
        if "defects" in recipe:
            sys.exit(f"{self.recipe_file}: defects are not supported")
        return recipe

    def simulate(self, recipe, recipe_file, folder, log):
        if (folder / "truth.json").exists():
            return
        shutil.rmtree(folder, ignore_errors=True)
        save(recipe_file, recipe)
        command = [self.xgauge, "-q", "-j", "1", "simulate", str(recipe_file), "-o", str(folder)]
        done = subprocess.run(command, capture_output=True, text=True)
        log.write_text(done.stdout + done.stderr)
        if done.returncode != 0 or not (folder / "truth.json").exists():
            raise RuntimeError(f"simulate exited {done.returncode}: {tail(done.stdout + done.stderr)}")

    def material(self):
        """The material fitted once to the unperturbed lab's transmission."""
        path = self.work / "material.json"
        if not path.exists():
            nominal = self.work / "nominal"
            nominal.mkdir(parents=True, exist_ok=True)
            recipe = self.lab_recipe(self.recipe["seed"], self.distance_mm)
            recipe["machine"] = self.machine_file
            self.simulate(recipe, nominal / "lab_recipe.json", nominal / "data", nominal / "simulate.log")
            command = [self.xgauge, "-q", "material", "--from-truth", str(nominal / "data" / "truth.json"),
                       "--terms", str(self.args.terms), "-o", str(path)]
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                sys.exit(f"xgauge material exited {done.returncode}: {tail(done.stdout + done.stderr)}")
            for tif in (nominal / "data").glob("*.tif"):
                tif.unlink()
        material = load(path)
        self.u_transmission = material.get("uncertainty", {}).get("transmission", DEFAULT_U_TRANSMISSION)
        self.eps_u = rate_scale_uncertainty(material, self.u_transmission, self.part_size_mm)
        return material


def tail(text, lines=6):
    return " | ".join(text.strip().splitlines()[-lines:])


def draws_for(setup, run):
    """Run `run`'s draws: a function of --seed and the run number only."""
    rng = random.Random(f"xgauge-monte-carlo:{setup.args.seed}:{run}")
    lab_scatter = setup.recipe["detector"]["scatter"]
    return {
        "noise_seed": rng.getrandbits(48),
        "source_detector_distance_mm": setup.machine["source_detector_distance_mm"]
        + rng.gauss(0.0, setup.u_distance_mm),
        "pitch_scale": 1.0 + rng.gauss(0.0, setup.u_pitch_relative),
        "scatter_weight": rng.gauss(lab_scatter["weight"], setup.u_weight),
        "scatter_sigma_px": rng.gauss(lab_scatter["sigma_px"], setup.u_sigma_mm / setup.pitch_mm),
        "translation_mm": setup.distance_mm + rng.gauss(0.0, U_TRANSLATION_MM),
        "material_eps": rng.gauss(0.0, setup.eps_u),
    }


def measure_run(setup, material, run):
    """Simulate and measure run `run`; returns its record (errors and U)."""
    folder = setup.work / "runs" / f"run_{run:03d}"
    folder.mkdir(parents=True, exist_ok=True)
    result_file = folder / "out" / "result.json"
    draws = draws_for(setup, run)
    record = {"run": run, "draws": draws}
    started = time.monotonic()
    if not result_file.exists():
        # The lab: perturbed machine and recipe.
        machine = json.loads(json.dumps(setup.machine))
        machine["source_detector_distance_mm"] = draws["source_detector_distance_mm"]
        machine["detector"]["pixel_pitch_mm"] = [p * draws["pitch_scale"] for p in
                                                 machine["detector"]["pixel_pitch_mm"]]
        machine.pop("uncertainty", None)
        save(folder / "lab_machine.json", machine)
        recipe = setup.lab_recipe(draws["noise_seed"], draws["translation_mm"])
        recipe["machine"] = str(folder / "lab_machine.json")
        recipe["detector"]["scatter"] = {"weight": draws["scatter_weight"], "sigma_px": draws["scatter_sigma_px"]}
        data = folder / "data"
        setup.simulate(recipe, folder / "lab_recipe.json", data, folder / "simulate.log")
        truth = load(data / "truth.json")

        # The job: nominal machine, scatter and distance; perturbed material.
        job_material = json.loads(json.dumps(material))
        for t in job_material["terms"]:
            t["mu_per_mm"] *= 1.0 + draws["material_eps"]
        job_material["description"] = f"{material.get('description', '')}; rates x (1 + {draws['material_eps']:.3e})"
        save(folder / "material.json", job_material)
        job = json.loads(json.dumps(setup.job))
        job["description"] = f"Monte Carlo run {run} of {setup.job_file.name}"
        job["part"] = resolve(setup.job_file, setup.job["part"])
        job["machine"] = setup.job_machine_file
        job["material"] = str(folder / "material.json")
        files = {setup.free_name: "t00.tif", setup.moved_name: f"t{setup.moved_index:02d}.tif"}
        for r in job["radiographs"]:
            r["image"] = str(data / files[r["name"]])
            if "previous" in r:  # the shot simulated just before it
                if r["name"] != setup.moved_name:
                    sys.exit(f"{setup.job_file}: only the translated radiograph may name a previous frame")
                r["previous"] = str(data / f"t{setup.moved_index - 1:02d}.tif")
            r["dark"], r["flat"] = str(data / truth["dark"]), str(data / truth["flat"])
            r["white_region"] = truth["white_region"]
        save(folder / "job.json", job)

        out = folder / "out"
        shutil.rmtree(out, ignore_errors=True)
        command = [setup.xgauge, "-q", "-j", "1", "measure", str(folder / "job.json"), "-o", str(out)]
        done = subprocess.run(command, capture_output=True, text=True)
        (folder / "measure.txt").write_text(done.stdout + done.stderr)
        if done.returncode not in (0, 2, 3) or not result_file.exists():
            raise RuntimeError(f"measure exited {done.returncode}: {tail(done.stdout + done.stderr)}")
        if not setup.args.keep_images:
            for tif in list(data.glob("*.tif")) + list(out.glob("*.tif")):
                tif.unlink()
        record["seconds"] = time.monotonic() - started

    truth = load(folder / "data" / "truth.json")
    result = load(result_file)
    true_dims = truth["part"]["dimensions"]
    record["error_mm"], record["expanded_uncertainty_mm"] = {}, {}
    for d in result["dimensions"]:
        if d["free"]:
            record["error_mm"][d["name"]] = d["value_mm"] - true_dims[d["name"]]
            record["expanded_uncertainty_mm"][d["name"]] = d.get("expanded_uncertainty")
    # Combinations the budget reports as measurable (dimensions it finds hard
    # to separate): their errors too.
    for c in result.get("uncertainty", {}).get("combinations", []):
        true_value = sum(t["coefficient"] * true_dims[t["dimension"]] for t in c["terms"])
        record["error_mm"][c["expression"]] = c["value"] - true_value
        record["expanded_uncertainty_mm"][c["expression"]] = c["expanded_uncertainty"]
    # The standard uncertainties the budget states, to compare with the draws'.
    # and each component's signed effect (sensitivity x u) per dimension.
    record["stated"], record["budget_mm"] = {}, {}
    for d in result.get("uncertainty", {}).get("dimensions", []):
        record["budget_mm"][d["name"]] = {c["name"]: c["sensitivity"] * c["standard_uncertainty"]
                                          for c in d["components"]}
        for c in d["components"]:
            if c["name"] != "statistical":
                record["stated"][c["name"]] = c["standard_uncertainty"]
    record["warnings"] = result.get("warnings", [])
    return record


def summarise(records):
    """Per dimension (then per combination, over the runs that report it)."""
    names = []
    for r in records:
        names += [n for n in r["error_mm"] if n not in names]
    table = {}
    for name in names:
        having = [r for r in records if name in r["error_mm"]]
        errors = [r["error_mm"][name] for r in having]
        if len(errors) < 2:
            continue
        us = [r["expanded_uncertainty_mm"][name] for r in having if r["expanded_uncertainty_mm"][name]]
        s = statistics.stdev(errors)
        mean_u = statistics.fmean(us) if us else None
        covered = [abs(r["error_mm"][name]) <= r["expanded_uncertainty_mm"][name]
                   for r in having if r["expanded_uncertainty_mm"][name]]
        table[name] = {
            "runs": len(errors),
            "mean_error_mm": statistics.fmean(errors),
            "s_mm": s,
            "monte_carlo_U_mm": 2.0 * s,
            # 2 s from n runs is itself uncertain by about 1 / sqrt(2 (n - 1)).
            "monte_carlo_U_relative_uncertainty": 1.0 / math.sqrt(2.0 * (len(errors) - 1)),
            "mean_reported_U_mm": mean_u,
            "min_reported_U_mm": min(us) if us else None,
            "max_reported_U_mm": max(us) if us else None,
            "ratio_reported_over_monte_carlo": mean_u / (2.0 * s) if mean_u and s > 0 else None,
            "coverage": sum(covered) / len(covered) if covered else None,
            "rms_error_mm": math.sqrt(statistics.fmean([e * e for e in errors])),
        }
    return table


def standardised_draws(setup, draws):
    """Each influence's draw in units of its standard uncertainty, named as
    the budget's components."""
    lab_scatter = setup.recipe["detector"]["scatter"]
    return {
        "material": draws["material_eps"] / setup.eps_u,
        "scatter weight": (draws["scatter_weight"] - lab_scatter["weight"]) / setup.u_weight,
        "scatter width": (draws["scatter_sigma_px"] - lab_scatter["sigma_px"]) * setup.pitch_mm / setup.u_sigma_mm,
        "source-detector distance": (draws["source_detector_distance_mm"]
                                     - setup.machine["source_detector_distance_mm"]) / setup.u_distance_mm,
        "pixel pitch": (draws["pitch_scale"] - 1.0) / setup.u_pitch_relative,
        f"translation {setup.moved_name}": (draws["translation_mm"] - setup.distance_mm) / U_TRANSLATION_MM,
    }


def solve(a, b):
    """Solve a x = b (small, dense) by Gauss-Jordan with partial pivoting."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        for r in range(n):
            if r != c:
                f = m[r][c] / m[c][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return [m[i][n] / m[i][i] for i in range(n)]


def influences(setup, records):
    """Per dimension, each influence's effect on the error for a draw of one
    standard uncertainty, by least squares of the errors on the standardised
    draws (with an intercept), beside the budget's. The lab is moved while the
    job stays nominal, so the lab's influences act with the opposite sign of
    the budget's (which moves the job); the material is drawn in the job and
    keeps its sign. `residual_s_mm` is the spread the draws do not explain
    (noise, and what is not linear), to compare with the statistical part."""
    z = [standardised_draws(setup, r["draws"]) for r in records]
    keys = list(z[0])
    x = [[1.0] + [zi[k] for k in keys] for zi in z]
    xtx = [[sum(row[i] * row[j] for row in x) for j in range(len(keys) + 1)] for i in range(len(keys) + 1)]
    out = {}
    for name in records[0].get("budget_mm", {}):
        e = [r["error_mm"][name] for r in records]
        b = solve(xtx, [sum(row[i] * ei for row, ei in zip(x, e)) for i in range(len(keys) + 1)])
        fitted = [sum(bi * xi for bi, xi in zip(b, row)) for row in x]
        dof = len(e) - len(b)
        residual = math.sqrt(sum((ei - fi) ** 2 for ei, fi in zip(e, fitted)) / dof) if dof > 0 else None
        budget = {k: statistics.fmean(r["budget_mm"][name].get(k, 0.0) for r in records)
                  for k in keys + ["statistical"]}
        out[name] = {"residual_s_mm": residual, "budget_statistical_mm": budget["statistical"],
                     "per_influence_mm": {k: {"monte_carlo": bk, "budget": budget[k] * (1 if k == "material" else -1)}
                                          for k, bk in zip(keys, b[1:])}}
    return out


def print_influences(table):
    keys = list(next(iter(table.values()))["per_influence_mm"])
    short = {k: k.replace("source-detector distance", "distance").replace("scatter ", "sc.") for k in keys}
    print("\nEffect of a one-u draw on the error (mm), Monte Carlo regression / budget (sign as seen in the lab):")
    print(f"{'dimension':<15}" + "".join(f"{short[k]:>20}" for k in keys) + f"{'residual s / stat u':>22}")
    for name, t in table.items():
        cells = "".join(f"{v['monte_carlo']:>+10.4f}/{v['budget']:<+9.4f}" for v in t["per_influence_mm"].values())
        print(f"{name:<15}{cells}{t['residual_s_mm']:>12.4f}/{t['budget_statistical_mm']:.4f}")


def print_table(table):
    print(f"{'dimension':<27}{'runs':>5}{'mean err':>11}{'s':>10}{'2s (MC)':>10}"
          f"{'mean U':>10}{'U / 2s':>8}{'coverage':>10}")
    for name, t in table.items():
        ratio = t["ratio_reported_over_monte_carlo"]
        flag = "" if ratio and 1 / 1.5 <= ratio <= 1.5 else "  <- outside 1.5x"
        print(f"{name:<27}{t['runs']:>5}{t['mean_error_mm']:>+11.4f}{t['s_mm']:>10.4f}"
              f"{t['monte_carlo_U_mm']:>10.4f}{t['mean_reported_U_mm'] or float('nan'):>10.4f}"
              f"{ratio if ratio else float('nan'):>8.2f}{100 * (t['coverage'] or 0):>9.0f}%{flag}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=50, help="number of Monte Carlo runs (default 50)")
    parser.add_argument("--parallel", type=int, default=2, help="runs at once (default 2; each uses -j 1)")
    parser.add_argument("--seed", type=int, default=1, help="seeds every draw (default 1)")
    parser.add_argument("--work", default=str(REPO / "out" / "monte_carlo"), help="work folder (resumable)")
    parser.add_argument("--output", help="table and runs as JSON (default WORK/monte_carlo.json)")
    parser.add_argument("--recipe", default=str(REPO / "datasets" / "prism_a_small.json"))
    parser.add_argument("--job", default=str(REPO / "examples" / "prism_a_small_job.json"),
                        help="template job: one free and one translated radiograph")
    parser.add_argument("--terms", type=int, default=3, help="fewest exponentials of the fitted material")
    parser.add_argument("--part-size-mm", type=float, help="the part's nominal bounding-box diagonal")
    parser.add_argument("--xgauge", default=str(REPO / "build" / "apps" / "xgauge" / "xgauge"))
    parser.add_argument("--keep-images", action="store_true", help="keep each run's TIFF files")
    args = parser.parse_args()
    if args.runs < 2 or args.parallel < 1:
        sys.exit("--runs must be >= 2 and --parallel >= 1")

    setup = Setup(args)
    setup.work.mkdir(parents=True, exist_ok=True)
    material = setup.material()
    print(f"part size S = {setup.part_size_mm:.3f} mm; u_transmission = {setup.u_transmission:g} "
          f"-> eps_u = {setup.eps_u:.4e}; u_D = {setup.u_distance_mm:g} mm, u_pitch = {setup.u_pitch_relative:g}, "
          f"u_w = {setup.u_weight:.4g}, u_sigma = {setup.u_sigma_mm:.4g} mm "
          f"({setup.u_sigma_mm / setup.pitch_mm:.4g} px), u_translation = {U_TRANSLATION_MM} mm", flush=True)

    started = time.monotonic()
    records, failures = [], []
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.parallel) as pool:
        futures = {pool.submit(measure_run, setup, material, i): i for i in range(1, args.runs + 1)}
        for future in concurrent.futures.as_completed(futures):
            run = futures[future]
            try:
                record = future.result()
                records.append(record)
                took = f"{record['seconds']:.0f} s" if "seconds" in record else "kept"
                print(f"run {run:3d}: {took}; {len(records) + len(failures)}/{args.runs} done", flush=True)
            except Exception as e:  # a failed run is reported, the others go on
                failures.append({"run": run, "error": str(e)})
                print(f"run {run:3d}: FAILED: {e}", flush=True)
    records.sort(key=lambda r: r["run"])
    if len(records) < 2:
        sys.exit("fewer than two runs succeeded")

    table = summarise(records)
    print(f"\n{len(records)} runs ({len(failures)} failed) in {time.monotonic() - started:.0f} s; "
          f"errors are measured - true; U / 2s: mean reported U over the Monte Carlo 2 s")
    print_table(table)
    effects = influences(setup, records) if len(records) > 8 else {}
    if effects:
        print_influences(effects)
    stated = {k: v for k, v in records[0]["stated"].items()}
    drawn = {"material": setup.u_transmission, "scatter weight": setup.u_weight,
             "scatter width": setup.u_sigma_mm, "source-detector distance": setup.u_distance_mm,
             "pixel pitch": setup.u_pitch_relative, f"translation {setup.moved_name}": U_TRANSLATION_MM}
    for name, u in drawn.items():
        if name in stated and not math.isclose(stated[name], u, rel_tol=1e-6):
            print(f"note: the budget states u({name}) = {stated[name]:g}, the draws used {u:g}")
    output = Path(args.output) if args.output else setup.work / "monte_carlo.json"
    save(output, {
        "recipe": str(setup.recipe_file), "job": str(setup.job_file), "seed": args.seed,
        "runs_requested": args.runs, "part_size_mm": setup.part_size_mm,
        "draw_standard_uncertainties": dict(drawn, material_rate_scale=setup.eps_u),
        "budget_standard_uncertainties": stated,
        "dimensions": table, "influences": effects, "failures": failures, "runs": records,
    })
    print(f"written {output}")


if __name__ == "__main__":
    main()
