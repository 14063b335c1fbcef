#!/usr/bin/env python3
"""docs/your-part.md run as written: every `xgauge ...` line of its ```sh
blocks, in order, in a fresh folder holding copies of examples/, datasets/
and parts/ (the tutorial's relative paths then write data/ and out/ there,
never into the source tree). Then what the page says must be so:

- `part faces` lists the bracket's 17 faces, the base holes as cylinders
  #973 and #1000, and writes faces.json and faces.html;
- `part check` finds every dimension buildable over its bounds and moving
  at least one face;
- the verification names every dimension with a finite bias;
- the measurement is verified, and every dimension's error against the
  virtual lab's truth lies within its U.

Usage: your_part_test.py --xgauge XGAUGE --source SOURCE --work FOLDER
Exit 0 when all holds, 1 with the reason otherwise. Debian's python3,
standard library only.
"""

import argparse
import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path


def commands(page):
    """The `xgauge` lines of the page's ```sh blocks, in order."""
    out, inside = [], False
    for line in page.splitlines():
        if line.startswith("```"):
            inside = line.strip() == "```sh"
            continue
        if inside and line.startswith("xgauge "):
            out.append(shlex.split(line)[1:])
    return out


def fail(message):
    print(f"your_part_test: {message}", file=sys.stderr)
    sys.exit(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--xgauge", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    source, work = Path(a.source).resolve(), Path(a.work).resolve()
    xgauge = str(Path(a.xgauge).resolve())
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    for folder in ("examples", "datasets", "parts"):
        shutil.copytree(source / folder, work / folder)
    steps = commands((source / "docs" / "your-part.md").read_text())
    if len(steps) < 8:
        fail(f"docs/your-part.md has {len(steps)} xgauge commands; expected the 8 of the tutorial")
    printed = {}
    for argv in steps:
        print("+ xgauge", " ".join(argv), flush=True)
        r = subprocess.run([xgauge] + argv, cwd=work, capture_output=True, text=True)
        print(r.stdout, r.stderr, sep="", flush=True)
        # A measurement's exit status is its verdict: 0 conforms, 2
        # inconclusive, 3 does not conform; 1 is a failure.
        allowed = (0, 2, 3) if argv[0] == "measure" else (0,)
        if r.returncode not in allowed:
            fail(f"xgauge {' '.join(argv)} exited {r.returncode}")
        printed[" ".join(argv[:2])] = r.stdout

    # 1. The faces.
    faces = json.loads((work / "out/bracket_faces/faces.json").read_text())["faces"]
    if len(faces) != 17:
        fail(f"part faces: {len(faces)} faces, the page shows 17")
    holes = {f["entity"]: f for f in faces if f["type"] == "cylinder"}
    for entity in (973, 1000, 649):
        if entity not in holes:
            fail(f"part faces: no cylinder #{entity} (the page names it)")
    if abs(holes[973]["radius_mm"] - 3.3) > 1e-6:
        fail(f"part faces: #973's radius {holes[973]['radius_mm']}, not 3.3")
    if not re.search(r"^\s+16\s+#973\s+-\s+cylinder", printed["part faces"], re.M):
        fail("part faces: the printed table has no line for face 16 (#973, cylinder)")
    if not (work / "out/bracket_faces/faces.html").stat().st_size > 10000:
        fail("part faces: faces.html is missing or empty")

    # 3. The check.
    check = json.loads((work / "out/bracket_check/check.json").read_text())
    model = json.loads((work / "examples/step/bracket.json").read_text())
    bounds = {d["name"]: (d["min"], d["max"]) for d in model["dimensions"]}
    for d in check["dimensions"]:
        low, high = bounds[d["name"]]
        if d["buildable"] != [low, high]:
            fail(f"part check: {d['name']} buildable over {d['buildable']}, not its bounds {[low, high]}")
        if not d["moved_faces"]:
            fail(f"part check: {d['name']} moves no face")

    # 5. The verification.
    verification = json.loads((work / "out/bracket_verification/verification.json").read_text())
    named = {d["name"]: d for d in verification["dimensions"]}
    if set(named) != set(bounds):
        fail(f"verification: dimensions {sorted(named)}, not the part's {sorted(bounds)}")

    # 6. The measurement: verified, every error within its U.
    result = json.loads((work / "out/bracket_measurement/result.json").read_text())
    truth = json.loads((work / "data/bracket_step/truth.json").read_text())["part"]["dimensions"]
    if result.get("status") != "measured":
        fail(f"measure: status {result.get('status')}: {result.get('failures')}")
    for d in result["dimensions"]:
        error = d["value_mm"] - truth[d["name"]]
        if not d.get("verified"):
            fail(f"measure: {d['name']} is not verified")
        if abs(error) > d["expanded_uncertainty"]:
            fail(f"measure: {d['name']} = {d['value_mm']:.4f}, {error:+.4f} from the truth, outside "
                 f"its U {d['expanded_uncertainty']:.4f}")
        print(f"{d['name']:<24} {d['value_mm']:>10.4f} {error:>+9.4f} U {d['expanded_uncertainty']:.4f} "
              f"{d.get('verdict', '')}")
    print("your_part_test: every step of docs/your-part.md ran and holds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
