#!/usr/bin/env python3
"""Prints an inspection plan for a simulated lot (lot_bench.sh): the job of
examples/prism_a_lot_plan.json for the Prism A lot, else a cuboid job on the
recipe's machine with the shots t00 and t01 and tolerances of +-0.05 mm."""
import json, os, sys

recipe_file, work, lot = sys.argv[1], sys.argv[2], sys.argv[3]
root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
recipe = json.load(open(recipe_file))
here = os.path.dirname(os.path.abspath(recipe_file))
if "prism_jaw" in recipe["part"]["model"]:
    plan = json.load(open(os.path.join(root, "examples", "prism_a_lot_plan.json")))
    job = plan["job"]
    job["part"] = os.path.join(root, "parts", "prism_jaw.json")
    job["machine"] = os.path.join(root, "examples", "machine_1024.json")
else:
    frames = {"dark": "dark.tif", "flat": "flat.tif", "white_region": [2, 2, 20, 20]}
    dims = recipe["part"]["dimensions"]
    job = {
        "part": os.path.normpath(os.path.join(here, recipe["part"]["model"])),
        "machine": os.path.normpath(os.path.join(here, recipe["machine"])),
        "radiographs": [dict(name="t00", image="t00.tif", **frames),
                        dict(name="t01", image="t01.tif", pattern="translated", reference="t00",
                             distance_mm=recipe["shots"]["translations"]["distance_mm"], **frames)],
        "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                        "centre_mm": [[-40, 40], [-20, 20], [480, 520]]},
        "dimensions": {"fixed": {"size_y": dims["size_y"]}},
        "schedule": "gauss-newton",
        "unverified_verdicts": True,
        "tolerances": {name: {"nominal": dims[name], "lower": -0.05, "upper": 0.05}
                       for name in ("size_x", "size_z")},
    }
job["material"] = os.path.join(work, "material.json")
print(json.dumps({"description": "lot_bench.sh", "lot": lot, "station": "bench", "job": job}, indent=2))
