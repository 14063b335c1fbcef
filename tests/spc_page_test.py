#!/usr/bin/env python3
"""`xgauge spc` end to end and its page in a real browser (CTest `spc.page_browser`).

A results store (SQLite, the schema docs/formats.md gives, created by
xgauge itself) holds a lot of 24 parts: width steady for 16 parts, then
drifting; height steady. Then:
- `xgauge spc` with the default baseline (30) and with `--baseline 30` is
  refused: non-zero exit, the message names the lot, the 24 parts and the
  30 asked for, and nothing is written;
- `--baseline 16` is taken: pages and spc.json written, the baseline 16
  parts, the histogram's bin count the Freedman-Diaconis rule's (worked out
  here from the values, not by xgauge's code);
- run again with other rules, the store's alarms are that run's only;
- `xgauge inspect --spc N` over a simulated lot of 4 cuboids
  (tests/data/lot_cuboid.json): with N = 5 phase I never completes, so no
  analysis, no alarm and exit 0 (not the refusal); with N = 2 the alarms
  printed as parts arrive, and the store at the end holds the last
  analysis's alarms, those `xgauge spc --baseline 2` finds;
- the width page in headless Chromium (tests/browser.py): every chart's
  legend shows its values with no hovering (the last point, the centre
  line and limits, the bins), equal to spc.json's; hovering a point shows
  that point and leaving shows the last again; as printed (print media)
  the charts are one per row, the legends still there and their values
  drawn (screenshots of the legend's values are not blank).

Usage: spc_page_test.py --xgauge BIN --source DIR --work DIR [--chromium BIN]
"""
import json
import math
import os
import random
import sqlite3
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from browser import Browser, page_test_arguments  # noqa: E402

FAILURES = []
PARTS = 24


def check(condition, message):
    if not condition:
        FAILURES.append(message)
        print("FAIL:", message)


def xgauge(binary, *args):
    proc = subprocess.run([binary, *args], capture_output=True, text=True)
    print(f"xgauge {' '.join(args)}: exit {proc.returncode}")
    return proc


def width_of(i, rng):
    return 20.0 + rng.gauss(0.0, 0.01) + (0.012 * (i - 15) if i >= 16 else 0.0)


def make_store(binary, path):
    """The store's schema from xgauge (spc over a new, empty store), the lot by SQL."""
    proc = xgauge(binary, "spc", path, "-o", "empty_out", "-q")
    if proc.returncode != 0:
        sys.exit(f"xgauge spc on an empty store failed:\n{proc.stdout}\n{proc.stderr}")
    rng = random.Random(61)
    db = sqlite3.connect(path)
    db.execute("INSERT INTO lots (name, created_at) VALUES ('L1', '2026-12-04T10:00:00Z')")
    lot = db.execute("SELECT id FROM lots WHERE name = 'L1'").fetchone()[0]
    values = {"width": [], "height": []}
    for i in range(PARTS):
        name = f"p{i + 1:04d}"
        part = db.execute("INSERT INTO parts (lot_id, name, part_index, acquired_at) VALUES (?, ?, ?, ?)",
                          (lot, name, i, f"2026-12-04T10:{i:02d}:00Z")).lastrowid
        m = db.execute(
            "INSERT INTO measurements (part_id, inputs_digest, inputs_sha256, software, plan, plan_sha256, "
            "station, measured_at, status, seconds, report, verification) VALUES "
            "(?, ?, '{}', 'test', 'plan.json', 'ab', 's1', ?, 'measured', 1.0, '', '')",
            (part, name, f"2026-12-04T11:{i:02d}:00Z")).lastrowid
        for seq, (dim, value, nominal) in enumerate((("width", width_of(i, rng), 20.0),
                                                      ("height", 10.0 + rng.gauss(0.0, 0.01), 10.0))):
            values[dim].append(value)
            db.execute(
                "INSERT INTO dimensions (measurement_id, seq, name, value, unit, expanded_uncertainty, "
                "identifiable, verified, nominal, lower_limit, upper_limit, verdict) VALUES "
                "(?, ?, ?, ?, 'mm', 0.004, 1, 1, ?, ?, ?, 'conforms')",
                (m, seq, dim, value, nominal, nominal - 0.1, nominal + 0.1))
    db.commit()
    db.close()
    return values


def stored_alarms(path):
    db = sqlite3.connect(path)
    rows = db.execute("SELECT dimension, rule, part FROM alarms ORDER BY dimension, position, rule").fetchall()
    db.close()
    return sorted(rows)


def hits_of(spc_json):
    return sorted((a["dimension"], h["rule"], h["part"]) for a in spc_json for h in a["hits"])


def freedman_diaconis_bins(values):
    """The rule's bin count, worked out here: IQR by linear interpolation."""
    x = sorted(values)
    n = len(x)

    def q(p):
        at = p * (n - 1)
        k = math.floor(at)
        return x[k] + (at - k) * (x[k + 1] - x[k]) if k + 1 < n else x[k]
    width = 2.0 * (q(0.75) - q(0.25)) / n ** (1.0 / 3.0)
    return min(100, max(1, math.ceil((x[-1] - x[0]) / width))), width


def check_cli(binary, store, values):
    for extra in ([], ["--baseline", "30"]):
        proc = xgauge(binary, "spc", store, "-o", "refused", *extra)
        message = proc.stdout + proc.stderr
        check(proc.returncode != 0, f"spc {extra}: a 24-part lot against a 30-part baseline exited 0")
        for needed in ("lot L1", "24 measured part", "30", "--baseline N with N at most 24"):
            check(needed in message, f"spc {extra}: the refusal does not say {needed!r}: {message!r}")
        written = [os.path.join(d, f) for d, _, fs in os.walk("refused") for f in fs]
        check(not written, f"spc {extra}: a refused run wrote {written}")
    check(stored_alarms(store) == [], "a refused run stored alarms")

    proc = xgauge(binary, "spc", store, "-o", "spc", "--baseline", "16")
    check(proc.returncode == 0, f"spc --baseline 16 failed: {proc.stdout}{proc.stderr}")
    with open("spc/L1/spc.json") as f:
        first = json.load(f)
    width = next(a for a in first if a["dimension"] == "width")
    check(width["baseline"] == {"description": "first 16 parts", "n": 16},
          f"spc --baseline 16: baseline {width['baseline']}")
    check(any(h["rule"] == "nelson-1" and h["index"] >= 16 for h in width["hits"]),
          f"spc --baseline 16: the drift from part 17 raised no nelson-1: {width['hits']}")
    for a in first:
        bins, bin_width = freedman_diaconis_bins(values[a["dimension"]])
        h = a["histogram"]
        check(h["rule"] == "freedman-diaconis" and h["bins"] == bins and len(h["counts"]) == bins
              and abs(h["width"] - bin_width) < 1e-12 and sum(h["counts"]) == PARTS,
              f"{a['dimension']}: histogram {h}, the rule gives {bins} bins of {bin_width}")
        if a["dimension"] == "height":  # steady: bins of a fifth of the tolerance put most in one bar
            check(max(h["counts"]) <= PARTS // 2, f"height: {max(h['counts'])} of {PARTS} parts in one bin")
        print(f"{a['dimension']}: {h['bins']} bins of {h['width']:.4f} mm: {h['counts']}")
    first_alarms = stored_alarms(store)
    check(first_alarms == hits_of(first) and first_alarms,
          f"the store's alarms {first_alarms} are not the run's {hits_of(first)}")
    alarm_lines = [line for line in proc.stdout.splitlines() if line.startswith("ALARM L1 ")]
    check(len(alarm_lines) == len(first_alarms), f"{len(alarm_lines)} ALARM lines for {len(first_alarms)} alarms")

    # Re-run: fewer rules, another baseline. The store keeps this run's alarms only.
    proc = xgauge(binary, "spc", store, "-o", "spc_again", "--baseline", "20", "--rules", "1")
    check(proc.returncode == 0, f"spc --baseline 20 --rules 1 failed: {proc.stdout}{proc.stderr}")
    with open("spc_again/L1/spc.json") as f:
        second = json.load(f)
    second_alarms = stored_alarms(store)
    check(second_alarms == hits_of(second),
          f"after a re-run the store holds {second_alarms}, the run raised {hits_of(second)}")
    check(set(first_alarms) - set(second_alarms),
          f"the test's re-run should drop some of the first run's alarms {first_alarms}")
    return width


def check_inspect(binary, source):
    """inspect --spc over a lot of 4 cuboids, as tests/report_test.py makes it."""
    data = os.path.join(source, "tests", "data")
    for args in (("simulate", os.path.join(data, "lot_cuboid.json"), "-o", "lot", "-q"),
                 ("material", "--from-truth", "lot/truth/p0001.json", "-o", "lot_material.json", "-q")):
        proc = xgauge(binary, *args)
        if proc.returncode != 0:
            sys.exit(f"xgauge {args[0]} failed:\n{proc.stdout}\n{proc.stderr}")
    frames = {"dark": "dark.tif", "flat": "flat.tif", "white_region": [2, 2, 20, 20]}
    job = {"part": os.path.join(source, "parts", "cuboid.json"), "machine": os.path.join(data, "report_machine.json"),
           "material": "lot_material.json", "schedule": "gauss-newton",
           "radiographs": [dict(name="t00", image="t00.tif", **frames),
                           dict(name="t01", image="t01.tif", pattern="translated", reference="t00",
                                distance_mm=10.0, **frames)],
           "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                           "centre_mm": [[-40, 40], [-20, 20], [480, 520]]},
           "dimensions": {"fixed": {"size_y": 29.98}}, "unverified_verdicts": True,
           "tolerances": {"size_x": {"nominal": 20.03, "lower": -0.1, "upper": 0.1},
                          "size_z": {"nominal": 10.02, "lower": -0.1, "upper": 0.1}}}
    for n, store in ((5, "inspect_short.sqlite"), (2, "inspect.sqlite")):
        with open(f"plan_{n}.json", "w") as f:
            json.dump({"lot": "L1", "store": store, "source": "lot/parts", "output": f"inspect_out_{n}",
                       "job": job}, f, indent=1)
        proc = xgauge(binary, "inspect", f"plan_{n}.json", "--no-report", "--spc", str(n))
        check(proc.returncode == 0, f"inspect --spc {n} failed: {proc.stdout}{proc.stderr}")
        printed = sorted(tuple(line.split()[2:5]) for line in proc.stdout.splitlines()
                         if line.startswith("ALARM L1 "))
        db = sqlite3.connect(store)
        analyses = db.execute("SELECT COUNT(*) FROM spc_analyses").fetchone()[0]
        db.close()
        if n == 5:
            check(printed == [] and stored_alarms(store) == [] and analyses == 0,
                  f"inspect --spc 5 on 4 parts analysed: {printed}, {stored_alarms(store)}, {analyses} analyses")
            continue
        check(analyses == 1, f"inspect --spc 2: {analyses} analyses of the lot in the store")
        stored = stored_alarms(store)
        proc = xgauge(binary, "spc", store, "-o", "inspect_spc", "--baseline", "2", "-q")
        with open("inspect_spc/L1/spc.json") as f:
            expected = hits_of(json.load(f))
        check(stored == expected and stored, f"inspect --spc 2 left {stored}, the lot's analysis raises {expected}")
        check(set(printed) >= set(stored), f"inspect --spc 2 printed {printed}, stored {stored}")


def legend_of(browser, chart):
    return browser.evaluate(
        "Object.fromEntries(Array.from(document.querySelectorAll("
        f"'ul.spc-legend[data-chart=\"{chart}\"] li')).map(li => [li.dataset.series, "
        "{text: li.querySelector('.value').textContent, value: li.dataset.value === undefined ? null : "
        "Number(li.dataset.value), height: li.getBoundingClientRect().height}]))")


def check_legends(browser, s, media):
    last = len(s["values"]) - 1
    ind = legend_of(browser, "individuals")
    expected = {"CL": s["limits"]["centre"], "UCL": s["limits"]["upper"], "LCL": s["limits"]["lower"],
                "USL": s["tolerance"]["upper"], "LSL": s["tolerance"]["lower"]}
    for label, v in expected.items():
        e = ind.get(label)
        check(e is not None and e["text"] == f"{v:.4f}" and e["value"] == v and e["height"] > 0,
              f"{media}: individuals legend {label} is {e}, spc.json {v}")
    e = ind.get("width")
    check(e is not None and e["text"].startswith(f"{s['values'][last]:.4f} last") and s["parts"][last] in e["text"],
          f"{media}: the legend's last point is {e}, spc.json {s['values'][last]} at {s['parts'][last]}")
    n_alarms = sum(1 for h in s["hits"] if h["chart"] == "individuals")
    check(ind.get("alarm", {}).get("value") == n_alarms, f"{media}: legend alarm {ind.get('alarm')} != {n_alarms}")
    mr = legend_of(browser, "moving range")
    for label, v in (("MR-bar", s["limits"]["mr_centre"]), ("UCL", s["limits"]["mr_upper"])):
        e = mr.get(label)
        check(e is not None and e["text"] == f"{v:.4f}" and e["height"] > 0,
              f"{media}: moving-range legend {label} is {e}, spc.json {v}")
    hist = legend_of(browser, "histogram")
    e = hist.get("parts")
    check(e is not None and e["value"] == s["histogram"]["bins"] and "Freedman" in e["text"]
          and f"{s['histogram']['bins']} bins" in e["text"],
          f"{media}: histogram legend {e}, spc.json {s['histogram']['bins']} bins")
    for label in ("LSL", "USL"):
        v = s["tolerance"][label == "USL" and "upper" or "lower"]
        check(hist.get(label, {}).get("text") == f"{v:.4f}", f"{media}: histogram legend {label} {hist.get(label)}")
    text = browser.evaluate("document.body.innerText")
    check("--" not in text, f"{media}: the page shows '--' somewhere")
    check(browser.evaluate("document.querySelectorAll('.u-legend').length") == 0,
          f"{media}: uPlot's hover-only legend is still drawn")


def value_clip_stats(browser, selector, name):
    rect = browser.evaluate(
        f"(() => {{ const r = document.querySelector({json.dumps(selector)}).getBoundingClientRect();"
        " return {x: r.left + window.scrollX, y: r.top + window.scrollY, width: r.width, height: r.height}; })()")
    check(rect["width"] > 0 and rect["height"] > 0, f"{name}: {selector} takes no room: {rect}")
    png = browser._call("Page.captureScreenshot", {
        "format": "png", "captureBeyondViewport": True,
        "clip": dict(rect, scale=2)}, browser._current())["data"]
    import base64
    data = base64.b64decode(png)
    with open(name + ".png", "wb") as f:
        f.write(data)
    return browser.colour_stats(data)


def check_page(chromium, page, s):
    with Browser(chromium=chromium, width=1280, height=900, timeout_s=120) as browser:
        load = browser.open(os.path.abspath(page))
        check(not load.console_errors, f"console errors {load.console_errors}")
        check(not load.exceptions, f"exceptions {load.exceptions}")
        check(browser.evaluate("window.xgaugeErrors") == [], "the page reported errors")
        check(browser.evaluate("document.querySelectorAll('.uplot').length") == 3, "three charts expected")
        check_legends(browser, s, "screen")

        # Hover a point of the individuals chart, then leave the chart.
        over = browser.evaluate(
            "(() => { const r = document.querySelectorAll('.u-over')[0].getBoundingClientRect();"
            " return {x: r.left + r.width * 0.5, y: r.top + r.height * 0.5}; })()")
        session = browser._current()
        browser._call("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": over["x"], "y": over["y"]}, session)
        hovered = legend_of(browser, "individuals")["width"]["text"]
        check("at part p00" in hovered and "last" not in hovered, f"hovering shows {hovered!r}")
        browser._call("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": 2, "y": 2}, session)
        left = legend_of(browser, "individuals")["width"]["text"]
        check(left.startswith(f"{s['values'][-1]:.4f} last"), f"after leaving the chart the legend shows {left!r}")

        screen = browser.screenshot("spc_screen.png")
        stats = browser.colour_stats(screen)
        check(stats["distinct_colours"] >= 50 and stats["dominant_fraction"] < 0.97, f"screen: {stats}")

        # As printed.
        browser._call("Emulation.setEmulatedMedia", {"media": "print"}, session)
        columns = browser.evaluate(
            "getComputedStyle(document.querySelector('.charts')).gridTemplateColumns.split(' ').length")
        check(columns == 1, f"print: the charts are in {columns} columns, one expected")
        check_legends(browser, s, "print")
        printed = browser.screenshot("spc_print.png")
        stats = browser.colour_stats(printed)
        check(stats["distinct_colours"] >= 50 and stats["dominant_fraction"] < 0.97, f"print: {stats}")
        for chart, series in (("individuals", "UCL"), ("moving range", "MR-bar"), ("histogram", "parts")):
            sel = f'ul.spc-legend[data-chart="{chart}"] li[data-series="{series}"] .value'
            stats = value_clip_stats(browser, sel, f"print_{chart.replace(' ', '_')}_{series}")
            # Text drawn: more than the background and one ink colour (antialiasing).
            check(stats["distinct_colours"] >= 3 and stats["dominant_fraction"] < 0.95,
                  f"print: the {chart} legend's {series} value looks blank: {stats}")
        swatch = browser.evaluate(
            "getComputedStyle(document.querySelector('ul.spc-legend[data-chart=\"individuals\"] "
            "li[data-series=\"UCL\"] .swatch')).borderTopColor")
        check(swatch == "rgb(255, 127, 14)", f"print: the UCL swatch is {swatch}, the chart's line #ff7f0e")


def main():
    args = page_test_arguments(__doc__.splitlines()[0])
    binary, source = args.xgauge, args.source
    values = make_store(binary, "lot.sqlite")
    width = check_cli(binary, "lot.sqlite", values)
    check_page(args.chromium, "spc/L1/width.html", width)
    print("the width page checked on screen, hovered and as printed")
    check_inspect(binary, source)
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
