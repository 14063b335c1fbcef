#!/usr/bin/env python3
"""A deliberately wrong material for testing whether a measurement's
uncertainty covers a curve error it is told about.

Fits the simulated dataset's true curve (`xgauge material --from-truth`), then
scales every rate mu_k by (1 - eps), eps chosen so that the curve at --at-mm
is raised by --raise (a curve that reads too bright there: every path it
implies comes out longer), and declares --uncertainty as the material's
standard transmission uncertainty. The same form of error as the budget's
material component (a common relative change of the rates).

    python3 scripts/wrong_material.py data/prism_a_small/truth.json \\
        out/wrong_inputs/material_raised.json --raise 0.003 --at-mm 10 --uncertainty 0.003
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def transmission(terms, x, eps=0.0):
    return sum(t["weight"] * math.exp(-t["mu_per_mm"] * (1.0 - eps) * x) for t in terms)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("truth", help="truth.json of a simulated dataset")
    parser.add_argument("output", help="material file to write")
    parser.add_argument("--raise", dest="raise_by", type=float, default=0.003,
                        help="transmission added at --at-mm (negative: lowered)")
    parser.add_argument("--at-mm", type=float, default=10.0)
    parser.add_argument("--uncertainty", type=float, help="declared standard uncertainty (default |--raise|)")
    parser.add_argument("--xgauge", default=str(REPO / "build" / "apps" / "xgauge" / "xgauge"))
    args = parser.parse_args()
    if not args.at_mm > 0:
        sys.exit("--at-mm must be positive")

    with tempfile.TemporaryDirectory() as tmp:
        true_file = Path(tmp) / "true.json"
        subprocess.run([args.xgauge, "-q", "material", "--from-truth", args.truth, "-o", str(true_file)],
                       check=True)
        material = json.loads(true_file.read_text())
    terms = material["terms"]
    target = transmission(terms, args.at_mm) + args.raise_by
    if not 0.0 < target < 1.0:
        sys.exit(f"the raised curve would read {target:.4f} at {args.at_mm} mm")
    # I(x; eps) rises monotonically with eps; bisect on (-1, 1).
    low, high = -1.0, 1.0
    for _ in range(200):
        mid = 0.5 * (low + high)
        if transmission(terms, args.at_mm, mid) < target:
            low = mid
        else:
            high = mid
    eps = 0.5 * (low + high)
    for t in terms:
        t["mu_per_mm"] *= 1.0 - eps
    uncertainty = abs(args.raise_by) if args.uncertainty is None else args.uncertainty
    material["uncertainty"] = {"transmission": uncertainty}
    material["description"] = (
        f"deliberately wrong: the true curve of {args.truth} with every rate scaled by {1 - eps:.6f}, "
        f"so {args.raise_by:+g} at {args.at_mm:g} mm; declared transmission uncertainty {uncertainty:g}")
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(material, indent=2) + "\n")
    os.replace(tmp, out)
    print(f"wrote {out}: {material['description']}")


if __name__ == "__main__":
    main()
