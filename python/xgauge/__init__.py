"""xgauge from Python: radiographs (TIFF, raw, NXtomo, DICONDE) as numpy, the renderer and its exact
derivatives, measurements as `xgauge measure` makes them (docs/python.md).

Images are numpy float32 arrays of shape (rows, columns), row 0 the top of
the detector (docs/conventions.md). Files (part, machine, material, pose,
job) are given as paths or as dicts holding what the JSON file would
(docs/formats.md). Bad input raises xgauge.Error (a ValueError) carrying the
library's message. Long calls release the GIL.
"""

import json
import os

from ._xgauge import (Error, Measurement, __version__, read_radiograph, read_tiff, set_log_level,
                      write_tiff)
from . import _xgauge

__all__ = ["Error", "Measurement", "MeasurementSummary", "Rendering", "__version__", "calibrate",
           "measure", "plan", "read_radiograph", "read_tiff", "render", "set_log_level", "simulate",
           "write_tiff"]


class Rendering:
    """A rendered radiograph and, when asked for, its derivatives.

    image         float32 (rows, columns): intensity, 1 where nothing
                  attenuates (path length in mm without a material)
    d_dimensions  {dimension name: d image / d dimension (per mm or deg)},
                  in the part model's order
    d_pose        {"rx", "ry", "rz": per degree (R = Rz Ry Rx, fixed axes),
                   "x", "y", "z": per mm of the translation}
    dimensions    {dimension name: the value rendered}
    Every array is the library's own buffer (no copy; its base owns it).
    """

    def __init__(self, raw):
        self.image = raw["image"]
        self.d_dimensions = raw.get("d_dimensions", {})
        self.d_pose = raw.get("d_pose", {})
        self.dimensions = dict(zip(raw["dimension_names"], raw["dimensions"]))

    def jacobian(self, names):
        """(pixels, len(names)) float64: the derivatives of image.ravel()
        with respect to `names` (dimensions or pose parameters), a copy."""
        import numpy as np
        columns = [self.d_dimensions[n] if n in self.d_dimensions else self.d_pose[n]
                   for n in names]
        return np.stack([c.ravel() for c in columns], axis=1).astype(np.float64)


def render(part, dimensions=None, pose=None, machine=None, material=None, *, samples=1,
           edge_samples=0, region=None, derivatives=False, float64=False, base_dir="."):
    """Renders one radiograph of `part` as `xgauge render` does (the same
    pixels, to the bit).

    part        part model file (.json or .stl) or dict
    dimensions  None (nominal), {name: value} over nominal, or one value per
                dimension in the model's order
    pose        world_from_part: a 4x4 matrix, a pair (rotation_deg
                [rx, ry, rz], translation_mm [x, y, z]), a pose file or dict
    machine     machine file or dict;  material: material file or dict, or
                None for the path length (no derivatives then)
    samples     n x n samples per pixel;  edge_samples: m x m at edges (0: off)
    region      (x, y, width, height) of the detector, or None for all of it
    derivatives also d image / d dimension and d image / d pose parameter
                (xray/derivatives.h: exact, not differenced)
    float64     the image in float64 (not with derivatives): for finite
                differences, which float32 rounding would swamp
    base_dir    where a part dict's relative paths (an STL) start
    """
    if pose is None or machine is None:
        raise Error("render needs a pose and a machine")
    return Rendering(_xgauge.render(part, dimensions, pose, machine, material, samples,
                                    edge_samples, None if region is None else tuple(region),
                                    derivatives, float64, os.fspath(base_dir)))


class MeasurementSummary:
    """What `xgauge measure` reports, as Python objects.

    status       "measured" or "not measured"
    values       {name: value} of every dimension, measured or held fixed
    dimensions   {name: the result.json entry (value_mm, expanded_uncertainty,
                 verdict, ...)}
    result       result.json's contents as a dict (docs/formats.md)
    theta        the full parameter vector (numpy float64)
    simulated    the final simulated radiographs (read-only float32 views)
    to_json()    result.json's text, as `xgauge measure` writes it
    write_outputs(folder, report=True)
                 result.json, the simulated and difference images and
                 report.html, as `xgauge measure -o folder` writes them
    """

    def __init__(self, measurement):
        self._measurement = measurement
        self.result = json.loads(measurement.to_json())
        self.status = self.result.get("status")
        self.dimensions = {d["name"]: d for d in self.result.get("dimensions", [])}
        # result.json's key is value_mm whatever the unit (docs/formats.md).
        self.values = {name: d["value_mm"] for name, d in self.dimensions.items()}

    def to_json(self):
        return self._measurement.to_json()

    @property
    def theta(self):
        return self._measurement.theta

    @property
    def simulated(self):
        return self._measurement.simulated

    def write_outputs(self, folder, report=True):
        self._measurement.write_outputs(os.fspath(folder), report)

    def __repr__(self):
        values = ", ".join(f"{n}={v:.4f}" for n, v in self.values.items())
        return f"MeasurementSummary({self.status}: {values})"


def measure(job, *, base_dir=None, progress=None):
    """Measures a job as `xgauge measure` does (the same numbers, to the bit).

    job       a job file, or a dict holding what the job file would; its
              relative paths start at `base_dir` (default: the current folder)
    progress  None or callable(level, message), called with the library's
              log messages (each stage as it runs)
    Returns a MeasurementSummary. The GIL is released while measuring.
    """
    if isinstance(job, dict):
        base = os.fspath(base_dir if base_dir is not None else os.getcwd())
    else:
        if base_dir is not None:
            raise Error("base_dir is for a job given as a dict; a job file's paths are its own")
        job, base = os.fspath(job), ""
    return MeasurementSummary(_xgauge.measure(job, base, progress))


def calibrate(kind, job, output, *, report=True, truth=None, progress=None):
    """Calibrates a material as `xgauge calibrate KIND JOB -o OUTPUT` does:
    kind "wedge" or "part", a calibration job file; material.json,
    calibration.json and (with `report`) report.html written into `output`.
    `truth`: a virtual lab's truth.json, to report the deviation from its
    curve. Returns {"material": material.json's contents, "calibration":
    calibration.json's}. A failed calibration leaves its diagnostic
    (failed_calibration.json) in `output` and raises xgauge.Error naming the
    step. The GIL is released while calibrating."""
    _xgauge.calibrate(kind, os.fspath(job), os.fspath(output), report,
                      None if truth is None else os.fspath(truth), progress)
    with open(os.path.join(output, "material.json")) as file:
        material = json.load(file)
    with open(os.path.join(output, "calibration.json")) as file:
        calibration = json.load(file)
    return {"material": material, "calibration": calibration}


def plan(job, output):
    """Plans the views as `xgauge plan JOB -o OUTPUT` does: every set of the
    plan job's candidate views predicted and ranked (docs/method.md,
    "Planning the views"); plan.json, job.json (the best set's measurement
    job) and report.html written into `output`. Returns plan.json's contents
    with "table": what `xgauge plan` prints. A bad plan raises xgauge.Error
    naming the file and key, with nothing written. The GIL is released
    while planning."""
    table = _xgauge.plan(os.fspath(job), os.fspath(output))
    with open(os.path.join(output, "plan.json")) as file:
        result = json.load(file)
    result["table"] = table
    return result


def simulate(recipe, output, *, progress=None):
    """Simulates a dataset from a recipe file (`xgauge simulate`): raw
    radiographs, dark, flat and truth.json in `output`. Returns
    {"shots", "seconds", "white_region"}."""
    return _xgauge.simulate(os.fspath(recipe), os.fspath(output), progress)
