#!/usr/bin/env python3
"""The figures of a lot_bench.sh run: where the drift was flagged and by
which rule, alarms before the drift's onset, Cpk of the stable phase from
the measurements (with its confidence interval) against Cpk computed the
same way from the true dimensions, parts per minute."""
import json, math, os, sys

work = sys.argv[1]
t0, t1, t2, t3 = (float(v) for v in sys.argv[2:6])
truth = json.load(open(os.path.join(work, "lot", "truth.json")))
parts = truth["parts"]
process = truth["process"]
spc = json.load(open(os.path.join(work, "spc", truth["lot"], "spc.json")))
print(f"lot {truth['lot']}: {len(parts)} parts")
print(f"simulate {t1 - t0:.0f} s; inspect {t3 - t2:.0f} s: {60 * len(parts) / (t3 - t2):.1f} parts per minute")
for d in spc:
    name = d["dimension"]
    onset = process.get(name, {}).get("drift", {}).get("from_part")
    hits = d["hits"]
    position = lambda h: h["position"]
    print(f"{name}: baseline {d['baseline']['description']}, {len(hits)} alarm(s)")
    if onset:
        before = [h for h in hits if position(h) < onset]
        after = sorted((h for h in hits if position(h) >= onset), key=position)
        print(f"  alarms before part {onset}: {len(before)} " +
              ", ".join(f"{h['rule']}@{h['part']}" for h in before))
        if after:
            first = after[0]
            print(f"  drift (from part {onset}) first flagged at part {first['part']} by {first['rule']} "
                  f"({first['description']}), {position(first) - onset} parts after its onset")
        else:
            print(f"  drift (from part {onset}) not flagged")
    c = d.get("capability")
    tol = d["tolerance"]
    if c and tol["lower"] is not None:
        n = c["n"]
        true_values = [p["dimensions"][name] for p in parts[:n]]
        mean = sum(true_values) / n
        s = math.sqrt(sum((v - mean) ** 2 for v in true_values) / (n - 1))
        cpk_true = min(tol["upper"] - mean, mean - tol["lower"]) / (3 * s)
        inside = c["cpk"]["low"] <= cpk_true <= c["cpk"]["high"]
        print(f"  Cpk of the first {n} parts: measured {c['cpk']['value']:.2f} "
              f"[{c['cpk']['low']:.2f}, {c['cpk']['high']:.2f}], from the truth {cpk_true:.2f} "
              f"({'inside' if inside else 'OUTSIDE'} the interval); U/T {d['u_over_t']:.3f}")
