#!/usr/bin/env python3
"""The HTML reports in a real browser (CTest `report.browser`).

Simulates two small sessions with the virtual lab (tests/data/report_*.json),
runs every command that writes a report.html (calibrate wedge, calibrate
part, measure, study), a calibration that fails (failed_calibration.html)
and an SPC page (a lot of 4 cuboids inspected, then `xgauge spc`: its alarm
rows, Cpk and charts against spc.json), opens each page in headless Chromium (tests/browser.py)
and checks that:
- the page draws itself with no console error, no exception and no request
  beyond its own file;
- the DOM shows every dimension's value, U and verdict (measurement), every
  dimension's mean |error|, mean U and coverage (study), every term of the
  material (calibration) or the failed step and its error (a calibration of
  an open-beam shot) exactly as the JSON result beside it has them;
- the residual pictures of the radiographs of one fit share one colour scale,
  the one the colour bar shows;
- a full-page screenshot is neither blank nor mostly one colour.

Usage: report_test.py --xgauge BIN --source DIR --work DIR [--chromium BIN]
"""
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from browser import Browser, page_test_arguments  # noqa: E402

FAILURES = []


def check(condition, message):
    if not condition:
        FAILURES.append(message)
        print("FAIL:", message)


def run(xgauge, *args, expect=(0,)):
    start = time.time()
    proc = subprocess.run([xgauge, *args, "-q"], capture_output=True, text=True)
    print(f"xgauge {' '.join(args)}: exit {proc.returncode} in {time.time() - start:.1f} s")
    if proc.returncode not in expect:
        sys.exit(f"xgauge {' '.join(args)} failed with {proc.returncode}:\n{proc.stdout}\n{proc.stderr}")
    return proc


def write_json(path, value):
    with open(path, "w") as f:
        json.dump(value, f, indent=1)
    return path


def make_reports(xgauge, source, work):
    """Runs the four commands; returns {kind label: (report.html, result json)}."""
    data = os.path.join(source, "tests", "data")
    parts = os.path.join(source, "parts")
    run(xgauge, "simulate", os.path.join(data, "report_cuboid.json"), "-o", "cuboid")
    run(xgauge, "simulate", os.path.join(data, "report_wedge.json"), "-o", "wedge")
    frames = {"dark": "cuboid/dark.tif", "flat": "cuboid/flat.tif", "white_region": [2, 2, 20, 20]}
    machine = os.path.join(data, "report_machine.json")
    bounds = {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
              "centre_mm": [[-40, 40], [-20, 20], [480, 520]]}
    reports = {}

    write_json("wedge_job.json", {
        "machine": os.path.join(data, "report_wedge_machine.json"),
        "radiograph": {"image": "wedge/calibration.tif", "dark": "wedge/dark.tif",
                       "flat": "wedge/flat.tif", "white_region": [5, 5, 13, 13]},
        "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0},
        "scatter": {"weight": 0.139, "sigma_mm": 50.0}})
    run(xgauge, "calibrate", "wedge", "wedge_job.json", "-o", "wedge_cal", "--truth", "wedge/truth.json")
    reports["calibration (wedge)"] = ("wedge_cal/report.html", "wedge_cal/material.json")

    # A wedge calibration of an open-beam shot fails; it leaves its diagnostic.
    write_json("no_wedge_job.json", {
        "machine": machine,
        "radiograph": dict(image="cuboid/flat.tif", **frames),
        "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0}})
    run(xgauge, "calibrate", "wedge", "no_wedge_job.json", "-o", "no_wedge", expect=(1,))
    check(not os.path.exists("no_wedge/material.json"), "a failed calibration left a material.json")
    reports["failed calibration"] = ("no_wedge/failed_calibration.html", "no_wedge/failed_calibration.json")

    write_json("part_job.json", {
        "part": os.path.join(parts, "cuboid.json"), "machine": machine,
        "dimensions": {"fixed": {"size_x": 20.03, "size_y": 29.98, "size_z": 10.02}},
        "radiographs": [dict(name="t00", image="cuboid/t00.tif", **frames),
                        dict(name="r00", image="cuboid/r00.tif", pattern="rotated", reference="t00", **frames)],
        "pose_bounds": dict(bounds, rotation_deg=[[-5, 5], [0, 60], [-5, 5]]),
        "loss": "l1",
        "calibration": {"terms": 2, "initial": {"radiograph": "t00", "region": [50, 90, 30, 40], "path_mm": 10.02}}})
    run(xgauge, "calibrate", "part", "part_job.json", "-o", "part_cal", "--truth", "cuboid/truth.json")
    reports["calibration (part)"] = ("part_cal/report.html", "part_cal/material.json")

    # Tolerances: a wide zone, a zone far from the part and one narrower than U
    # (size_y's nominal from the job's "nominals").
    write_json("measure_job.json", {
        "part": os.path.join(parts, "cuboid.json"), "machine": machine, "material": "part_cal/material.json",
        "radiographs": [dict(name="t00", image="cuboid/t00.tif", **frames),
                        dict(name="t02", image="cuboid/t02.tif", pattern="translated", reference="t00",
                             distance_mm=20.0, **frames)],
        "pose_bounds": bounds, "unverified_verdicts": True, "nominals": {"size_y": 31.0},
        "tolerances": {"size_x": {"nominal": 20.0, "lower": -1.0, "upper": 1.0},
                       "size_y": {"lower": -0.05, "upper": 0.05},
                       "size_z": {"nominal": 10.0, "lower": -0.01, "upper": 0.01}}})
    run(xgauge, "measure", "measure_job.json", "-o", "measurement", "--truth", "cuboid/truth.json",
        expect=(0, 2, 3))
    reports["measurement"] = ("measurement/report.html", "measurement/result.json")

    write_json("study_settings.json", {
        "material": "fit",
        "dimensions": {"start": {"size_x": 20.0, "size_y": 30.0, "size_z": 10.0},
                       "bounds": {"size_x": [19.0, 21.0], "size_y": [29.0, 31.0], "size_z": [9.0, 11.0]}},
        "pose_bounds": bounds, "schedule": "default", "loss": "l1"})
    run(xgauge, "study", "cuboid", "-s", "study_settings.json", "--limit", "2", "-o", "study")
    reports["study"] = ("study/report.html", "study/study.json")

    # An SPC page: a lot of 4 cuboids (size_x drifting from part 3) inspected, then charted.
    run(xgauge, "simulate", os.path.join(data, "lot_cuboid.json"), "-o", "lot", "-q")
    run(xgauge, "material", "--from-truth", "lot/truth/p0001.json", "-o", "lot_material.json", "-q")
    lot_frames = {"dark": "dark.tif", "flat": "flat.tif", "white_region": [2, 2, 20, 20]}
    write_json("lot_plan.json", {
        "lot": "L1", "store": "lot.sqlite", "source": "lot/parts", "output": "lot_out",
        "job": {"part": os.path.join(parts, "cuboid.json"), "machine": machine,
                "material": "lot_material.json", "schedule": "gauss-newton",
                "radiographs": [dict(name="t00", image="t00.tif", **lot_frames),
                                dict(name="t01", image="t01.tif", pattern="translated", reference="t00",
                                     distance_mm=10.0, **lot_frames)],
                "pose_bounds": bounds, "dimensions": {"fixed": {"size_y": 29.98}},
                "unverified_verdicts": True,
                "tolerances": {"size_x": {"nominal": 20.03, "lower": -0.1, "upper": 0.1},
                               "size_z": {"nominal": 10.02, "lower": -0.1, "upper": 0.1}}}})
    run(xgauge, "inspect", "lot_plan.json", "--no-report", "-q")
    run(xgauge, "spc", "lot.sqlite", "-o", "spc", "--baseline", "2", "-q")
    reports["spc"] = ("spc/L1/size_x.html", "spc/L1/spc.json")
    return reports


def text_of(browser, selector):
    return browser.evaluate(
        f"(() => {{ const e = document.querySelector({json.dumps(selector)}); return e ? e.textContent : null; }})()")


def check_measurement(browser, result):
    for d in result["dimensions"]:
        row = f'tr.dimension[data-dimension="{d["name"]}"]'
        check(text_of(browser, row) is not None, f"measurement: no row for {d['name']}")
        value = text_of(browser, row + " td.value")
        check(value == f"{d['value_mm']:.4f}", f"measurement: {d['name']} shows {value!r}, result.json {d['value_mm']}")
        shown = browser.evaluate(
            f"Number(document.querySelector({json.dumps(row + ' td.value')}).dataset.value)")
        check(shown == d["value_mm"], f"measurement: {d['name']} data-value {shown} != {d['value_mm']}")
        u = text_of(browser, row + " td.u")
        if d["free"]:
            expected = (f"{d['expanded_uncertainty']:.4f}" if d["expanded_uncertainty"] is not None
                        else "not identifiable")
        else:
            expected = ""
        check(u == expected, f"measurement: {d['name']} U shows {u!r}, expected {expected!r}")
        basis = text_of(browser, row + " td.basis")
        expected = ("verified" if d["verified"] else "unverified") if d["free"] else ""
        check(basis == expected, f"measurement: {d['name']} U is {basis!r}, expected {expected!r}")
        # Deviation (the fourth cell) only from a nominal result.json states.
        deviation = browser.evaluate(f"document.querySelector({json.dumps(row)}).children[3].textContent")
        expected = f"{d['value_mm'] - d['nominal']:+.4f}" if "nominal" in d else "–"
        check(deviation == expected, f"measurement: {d['name']} deviation {deviation!r}, expected {expected!r}")
        verdict = text_of(browser, row + " td.verdict")
        check(verdict == d.get("verdict", ""), f"measurement: {d['name']} verdict {verdict!r} != {d.get('verdict')!r}")
    nominals = {d["name"]: d.get("nominal") for d in result["dimensions"]}
    check(nominals == {"size_x": 20.0, "size_y": 31.0, "size_z": 10.0},
          f"measurement: nominals {nominals}, the job states 20.0, 31.0 (its \"nominals\") and 10.0")
    verdicts = {d.get("verdict") for d in result["dimensions"]} - {None}
    check(len(verdicts) >= 2, f"measurement: the test job should give several verdicts, got {verdicts}")
    # One colour scale for every radiograph's residual, the colour bar's.
    scales = browser.evaluate(
        "Array.from(document.querySelectorAll('figure.residual')).map(f => [f.dataset.radiograph, Number(f.dataset.scale)])")
    bar = browser.evaluate("Number(document.querySelector('.colourbar').dataset.scale)")
    names = [r["name"] for r in result["radiographs"]]
    check(sorted(s[0] for s in scales) == sorted(names), f"measurement: residual figures {scales} for {names}")
    check(len({s[1] for s in scales}) == 1 and scales[0][1] == bar and bar > 0,
          f"measurement: residual scales {scales} differ or differ from the colour bar's {bar}")
    outline = browser.evaluate("document.querySelectorAll('figure.measured .outline line').length")
    check(outline >= 4 * len(names), f"measurement: {outline} outline segments for {len(names)} radiographs")


def check_study(browser, study):
    for name, d in study["dimensions"].items():
        row = f'tr.dimension[data-dimension="{name}"]'
        for cls, expected in (("mean-abs", f"{d['mean_abs_mm']:.4f}"), ("mean-u", f"{d['mean_u_mm']:.4f}"),
                              ("coverage", f"{100 * d['coverage']:.1f} %")):
            shown = text_of(browser, f"{row} td.{cls}")
            check(shown == expected, f"study: {name} {cls} shows {shown!r}, study.json gives {expected!r}")
    charts = browser.evaluate("document.querySelectorAll('.uplot').length")
    check(charts >= len(study["dimensions"]) + 1, f"study: {charts} charts for {len(study['dimensions'])} dimensions")


def check_failure(browser, diagnostic):
    shown = text_of(browser, "#failure")
    check(shown is not None and diagnostic["step"] in shown and diagnostic["error"] in shown,
          f"failed calibration: the banner shows {shown!r}, the diagnostic {diagnostic['step']!r}: {diagnostic['error']!r}")
    picture = browser.evaluate("document.querySelectorAll('figure.measured image').length")
    check(picture == 1, f"failed calibration: {picture} pictures of the radiograph")


def check_calibration(browser, material):
    terms = material["terms"]
    rows = browser.evaluate("document.querySelectorAll('tr.term').length")
    check(rows == len(terms), f"calibration: {rows} term rows, material.json has {len(terms)}")
    for k, t in enumerate(terms):
        for cls, key in (("weight", "weight"), ("mu", "mu_per_mm")):
            shown = text_of(browser, f'tr.term[data-term="{k}"] td.{cls}')
            check(shown == f"{t[key]:.6f}", f"calibration: term {k} {cls} shows {shown!r}, material.json {t[key]}")
    charts = browser.evaluate("document.querySelectorAll('.uplot').length")
    check(charts >= 3, f"calibration: {charts} charts (curve, residual, deviation from the truth)")


def check_spc(browser, analyses):
    spc = next(a for a in analyses if a["dimension"] == "size_x")
    rows = browser.evaluate("Array.from(document.querySelectorAll('tr.alarm')).map(r => [r.dataset.rule, r.dataset.part])")
    check(rows == [[h["rule"], h["part"]] for h in spc["hits"]], f"spc: alarm rows {rows} != {spc['hits']}")
    check(len(rows) >= 1, "spc: the test lot's drift should raise an alarm")
    cpk = browser.evaluate("Number(document.querySelector('td.cpk').dataset.value)")
    check(cpk == spc["capability"]["cpk"]["value"], f"spc: Cpk shows {cpk}, spc.json {spc['capability']['cpk']['value']}")
    charts = browser.evaluate("document.querySelectorAll('.uplot').length")
    check(charts == 3, f"spc: {charts} charts, expected the individuals, moving-range and histogram charts")
    warning = browser.evaluate("document.querySelectorAll('.ut-warning').length")
    check(warning == (1 if spc["u_over_t_warning"] else 0), f"spc: U/T warning shown {warning} times, u_over_t {spc['u_over_t']}")


def main():
    args = page_test_arguments(__doc__.splitlines()[0])
    xgauge, source = args.xgauge, args.source
    reports = make_reports(xgauge, source, args.work)

    checks = {"measurement": check_measurement, "study": check_study, "spc": check_spc}
    with Browser(chromium=args.chromium, width=1280, height=900, timeout_s=120) as browser:
        for label, (page, json_file) in reports.items():
            path = os.path.abspath(page)
            load = browser.open(path)
            check(not load.console_errors, f"{label}: console errors {load.console_errors}")
            check(not load.exceptions, f"{label}: exceptions {load.exceptions}")
            check(not load.external_requests(path), f"{label}: requests {load.external_requests(path)}")
            errors = browser.evaluate("window.xgaugeErrors")
            check(errors == [], f"{label}: the page reported {errors}")
            kind = browser.evaluate("document.documentElement.dataset.report")
            with open(json_file) as f:
                result = json.load(f)
            if isinstance(result, dict) and result.get("failed"):
                check_failure(browser, result)
            else:
                (checks.get(kind) or check_calibration)(browser, result)
            png = browser.screenshot(os.path.join(args.work, label.replace(" ", "_").replace("(", "").replace(")", "") + ".png"))
            stats = browser.colour_stats(png)
            print(f"{label}: {stats}")
            check(stats["distinct_colours"] >= 50 and stats["dominant_fraction"] < 0.97,
                  f"{label}: the screenshot is blank or mostly one colour: {stats}")
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed")
        return 1
    print(f"all checks passed on {len(reports)} reports")
    return 0


if __name__ == "__main__":
    sys.exit(main())
