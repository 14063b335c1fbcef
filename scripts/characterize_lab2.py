#!/usr/bin/env python3
"""Runs `xgauge characterize` on every machine of a lab2 grid and tabulates
the estimates against lab2's truth (docs/results.md, "Detector
characterisation on lab2's grid").

Usage: characterize_lab2.py XGAUGE LAB2_OUT JOBS_DIR OUT_DIR [MACHINE ...]

LAB2_OUT holds lab2's machine folders (tools/lab2: `lab2.py grid -o
LAB2_OUT`); a job per machine is written to JOBS_DIR/mNN.json and its
output to OUT_DIR/mNN/. Prints a Markdown table, then per machine the
weight's and the Gaussian-equivalent width's errors in units of their
stated standard uncertainties u (and u itself), and the pooled count of
machines within 2u (issue 62's acceptance: at least 90 %); writes the same
figures to OUT_DIR/coverage.json.
"""

import json
import math
import pathlib
import subprocess
import sys
import time


def job_for(machine_dir):
    return {
        "machine": str(machine_dir / "machine.json"),
        "darks": str(machine_dir / "darks" / "dark_*.tif"),
        "flats": str(machine_dir / "flats" / "flat_*.tif"),
        "shots": {
            "edge": str(machine_dir / "characterisation" / "edge.tif"),
            "crosstalk": str(machine_dir / "characterisation" / "crosstalk.tif"),
            "lag": {"bright": str(machine_dir / "characterisation" / "lag_bright.tif"),
                    "after": str(machine_dir / "characterisation" / "lag_dark_after_bright.tif")},
        },
    }


def main():
    xgauge, lab2, jobs, out = (pathlib.Path(a) for a in sys.argv[1:5])
    names = sys.argv[5:] or sorted(p.name for p in lab2.iterdir()
                                   if (p / "lab2_truth.json").exists() and p.name[1:].isdigit())
    jobs.mkdir(parents=True, exist_ok=True)
    rows = []
    coverage = []
    for name in names:
        machine = lab2 / name
        job = jobs / f"{name}.json"
        job.write_text(json.dumps(job_for(machine), indent=2) + "\n")
        start = time.time()
        run = subprocess.run([str(xgauge), "characterize", str(job), "-o", str(out / name), "-q"],
                             capture_output=True, text=True)
        seconds = time.time() - start
        truth = json.loads((machine / "lab2_truth.json").read_text())["detector"]
        m = json.loads((machine / "machine.json").read_text())["detector"]
        width_mm = min(m["columns"], m["rows"]) * m["pixel_pitch_mm"][0]
        halo = truth["halo"]
        if run.returncode != 0:
            rows.append(f"| {name} | {halo['shape']} | {halo['weight']:.3f} | "
                        f"{halo['gaussian_equivalent_sigma_mm']:.1f} | refused: "
                        f"{run.stderr.strip().splitlines()[-1] if run.stderr.strip() else run.returncode} |"
                        f" | | | | | | {seconds:.0f} |")
            continue
        d = json.loads((out / name / "detector.json").read_text())
        h = d["halo"]
        s = h["scatter"]
        w, uw = s["weight"], s["weight_uncertainty"]
        se, use = h["gaussian_equivalent_sigma_mm"], h["gaussian_equivalent_sigma_uncertainty_mm"]
        tw, ts = halo["weight"], halo["gaussian_equivalent_sigma_mm"]
        lag, xt = d["lag_fraction"], d["crosstalk"]
        bad = d["bad_pixels"]
        true_dead, true_hot = len(truth["dead_pixels"]), len(truth["hot_pixels"])
        rows.append(
            f"| {name} | {halo['shape']} | {tw:.3f} | {ts:.1f} | "
            f"{s['shape']}/{s['border']} | {w:.4f} ± {uw:.4f} ({100 * (w - tw) / tw:+.1f} %, "
            f"{(w - tw) / uw:+.1f} u) | {se:.1f} ± {use:.1f} ({100 * (se - ts) / ts:+.1f} %, "
            f"{(se - ts) / use if use > 0 else math.inf:+.1f} u){' *' if ts > 0.5 * width_mm else ''} | "
            f"{truth['lag_fraction']:.4f} / {lag['value']:.4f} ± {lag['uncertainty']:.4f} | "
            f"{truth['crosstalk']:.4f} / {xt['value']:.4f} ± {xt['uncertainty']:.4f} | "
            f"{true_dead}+{true_hot} / {bad['dead']}+{bad['hot']} ({bad['noisy']}) | "
            f"{h['noise_scale']:.2f} | {seconds:.0f} |")
        coverage.append({
            "machine": name, "true_shape": halo["shape"], "chosen": f"{s['shape']}/{s['border']}",
            "weight": w, "weight_u": uw, "true_weight": tw,
            "weight_error_u": (w - tw) / uw if uw > 0 else math.inf,
            "sigma_eq_mm": se, "sigma_eq_u_mm": use, "true_sigma_eq_mm": ts,
            "sigma_eq_error_u": (se - ts) / use if use > 0 else math.inf,
            "beyond_half_panel": ts > 0.5 * width_mm})
        print(rows[-1], file=sys.stderr)
    print("| machine | true shape | true w | true σ_eq mm | chosen | w ± u (error, error/u) | "
          "σ_eq ± u mm (error, error/u) | lag true / est. | crosstalk true / est. | "
          "dead+hot true / found (noisy) | noise scale | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(r)
    if not coverage:
        return
    print()
    print("| machine | true | chosen | weight error / u (u) | σ_eq error / u (u mm, u / σ_eq) |")
    print("|---|---|---|---|---|")
    for c in coverage:
        print(f"| {c['machine']} | {c['true_shape']} | {c['chosen']} | {c['weight_error_u']:+.2f} "
              f"({c['weight_u']:.5f}) | {c['sigma_eq_error_u']:+.2f} ({c['sigma_eq_u_mm']:.3f}, "
              f"{100 * c['sigma_eq_u_mm'] / c['sigma_eq_mm']:.1f} %) |")
    n = len(coverage)
    weight_in = sum(abs(c["weight_error_u"]) <= 2 for c in coverage)
    width_in = sum(abs(c["sigma_eq_error_u"]) <= 2 for c in coverage)
    mean_rel_u = sum(c["sigma_eq_u_mm"] / c["sigma_eq_mm"] for c in coverage) / n
    print(f"\nWithin 2u: weight {weight_in} of {n} ({100 * weight_in / n:.0f} %), "
          f"width {width_in} of {n} ({100 * width_in / n:.0f} %); mean u / width "
          f"{100 * mean_rel_u:.1f} %")
    (out / "coverage.json").write_text(json.dumps(
        {"machines": coverage, "weight_within_2u": weight_in, "width_within_2u": width_in,
         "count": n, "mean_u_over_width": mean_rel_u}, indent=1) + "\n")


if __name__ == "__main__":
    main()
