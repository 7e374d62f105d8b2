#!/usr/bin/env python3
"""Benchmark: `accelcal select` against the PyPI `gmdh` package's Combi on the very same data.

Data (issue 5): 2,000 samples at random orientations (uniform on the sphere), one sample per
orientation; u = 30000 + 3000*ax + 15*ay - 10*az + 2*ax*ay + noise(sigma = 80); the cubic basis
(19 terms besides the intercept); A = first 2/3 of the samples, B = last 1/3, no shuffle;
regularity criterion. Both programs must select the same model; the script prints both times and
their ratio. Usage: gmdh_compare.py ACCELCAL_BINARY WORKDIR [--threads N]
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time

import numpy as np
import gmdh

G = 9.81
VARS = ("ax", "ay", "az")


def cubic_terms():
    """The 19 non-intercept terms in accelcal's canonical order, as power triples."""
    out = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (2, 0, 0), (0, 2, 0), (0, 0, 2), (1, 1, 0), (1, 0, 1), (0, 1, 1)]
    out += [(3, 0, 0), (2, 1, 0), (2, 0, 1), (1, 2, 0), (1, 1, 1), (1, 0, 2), (0, 3, 0), (0, 2, 1), (0, 1, 2), (0, 0, 3)]
    return out


def name(p):
    parts = []
    for v, e in zip(VARS, p):
        if e:
            parts.append(v if e == 1 else f"{v}^{e}")
    return "*".join(parts)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("accelcal")
    ap.add_argument("workdir")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--n", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=2014)
    ap.add_argument("--repeat", type=int, default=5, help="accelcal runs (gmdh runs half as many)")
    a = ap.parse_args()
    os.makedirs(a.workdir, exist_ok=True)

    rng = np.random.RandomState(a.seed)
    alpha = rng.uniform(0.0, 360.0, a.n)
    beta = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, a.n)))
    ra, rb = np.radians(alpha), np.radians(beta)
    ax, ay, az = -G * np.cos(rb) * np.sin(ra), -G * np.sin(rb), -G * np.cos(ra) * np.cos(rb)
    u = 30000 + 3000 * ax + 15 * ay - 10 * az + 2 * ax * ay + rng.normal(0.0, 80.0, a.n)
    terms = cubic_terms()
    X = np.column_stack([ax ** p[0] * ay ** p[1] * az ** p[2] for p in terms])

    csv = os.path.join(a.workdir, "gmdh-bench.csv")
    with open(csv, "w") as f:
        f.write("t_s,alpha_deg,beta_deg,u\n")
        for i in range(a.n):
            f.write(f"{i},{alpha[i]!r},{beta[i]!r},{u[i]!r}\n")

    # accelcal: the whole process (read CSV, sweep 2^19 models, write JSON) and the sweep alone.
    # gmdh reports the model with the smallest criterion, so the comparison uses --tolerance 0;
    # accelcal's own rule (the simplest model within one code of the best) is reported beside it.
    def accelcal(tolerance, tag):
        out = os.path.join(a.workdir, f"accelcal-select-{tag}.json")
        t0 = time.perf_counter()
        subprocess.run([a.accelcal, "select", csv, "--basis", "cubic", "--split", f"tail:{1/3!r}",
                        "--criterion", "regularity", "--tolerance", str(tolerance),
                        "--threads", str(a.threads), "--json", out],
                       check=True, stdout=subprocess.DEVNULL)
        dt = time.perf_counter() - t0
        with open(out) as f:
            sel = json.load(f)["channels"][0]
        return dt, sel
    runs = [accelcal(0, "min") for _ in range(a.repeat)]
    t_accel_process = statistics.median(r[0] for r in runs)
    t_accel_sweep = statistics.median(r[1]["search_seconds"] for r in runs)
    sel = runs[0][1]
    ours = sorted(t for t in sel["selected"]["terms"] if t != "1")
    _, sel_rule = accelcal(1, "rule")
    ours_rule = sorted(t for t in sel_rule["selected"]["terms"] if t != "1")

    # gmdh Combi on the same rows, same split (test_size = 1/3, no shuffle), same criterion.
    # gmdh 1.0.3 accepts only limit >= 0, so its search always stops early once a level's best
    # criterion no longer improves: only that mode can be timed.
    results = {}
    for mode, limit in (("early-stopping, limit=0", 0.0),):
        times = []
        for _ in range(max(1, a.repeat // 2)):
            model = gmdh.Combi()
            t0 = time.perf_counter()
            model.fit(X, u, criterion=gmdh.Criterion(gmdh.CriterionType.REGULARITY), test_size=1 / 3,
                      n_jobs=a.threads, limit=limit)
            times.append(time.perf_counter() - t0)
        poly = model.get_best_polynomial()
        used = sorted({int(m) for m in re.findall(r"x(\d+)", poly)})
        results[mode] = (statistics.median(times), sorted(name(terms[i - 1]) for i in used), poly)

    print(f"data: {a.n} samples at random orientations, cubic basis (2^19 = 524,288 models), "
          f"A = first 2/3, B = last 1/3, regularity criterion, {a.threads} threads")
    print(f"accelcal select: sweep {t_accel_sweep * 1e3:.1f} ms "
          f"({sel['candidates_total'] / t_accel_sweep / 1e6:.1f} M models/s), whole process "
          f"{t_accel_process * 1e3:.0f} ms (medians of {a.repeat}); minimum-criterion model {ours}; "
          f"with the one-code rule: {ours_rule}")
    same = True
    for mode, (dt, theirs, poly) in results.items():
        agree = theirs == ours
        same &= agree
        print(f"gmdh Combi ({mode}): {dt:.2f} s (median of {max(1, a.repeat // 2)}); selected {theirs} ({'same' if agree else 'DIFFERENT'}); {poly}")
        print(f"  ratio gmdh/accelcal: {dt / t_accel_sweep:.0f}x on the sweep, {dt / t_accel_process:.0f}x on the whole process")
    if not same:
        print("the selected models differ", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
