#!/usr/bin/env python3
"""Time `wip diagnose` on 30-s generated logs, one per case of the recovery matrix.

The cases are those of robots/tests/diagnose/recovery.rs and readings.rs at the
duration the issue's speed target names (30 s of log, 6,001 rows at 5 ms): the null log,
each effect of the WIP's catalogue with its magnitude drawn from the seed, the two
whole-sample delays (10 and 15 ms), a gyro offset and an encoder scale error. Each log is
generated once (`wip generate --effect … --seed … --duration 30`), then diagnosed with
`--threads 2 --quiet` (the default options, as the recovery matrix does). Prints a
Markdown table (case, named cause, E before → after, wall) and the median wall time;
`--json FILE` also writes the rows.

    python3 scripts/diagnose_speed.py                      # target/release/wip
    python3 scripts/diagnose_speed.py --bin target/release-lto --only stick_slip,none

Python 3 standard library only. About 10 minutes on 2 cores.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))

CATALOGUE = ["tilt_offset", "floor_slope", "input_delay", "voltage_gain", "friction",
             "wheel_radius_asymmetry", "payload", "dead_zone", "stick_slip", "tilt_filter",
             "gear_backlash", "reversal_lockout"]
# (label, --effect argument, seed)
CASES = ([("none", "none", 1)]
         + [(e, e, 1) for e in CATALOGUE]
         + [("input_delay 10 ms", "input_delay=0.010", 1),
            ("input_delay 15 ms", "input_delay=0.015", 1),
            ("reading_offset:v_alpha", "reading_offset:v_alpha=0.03", 1),
            ("reading_scale:phiR_rel", "reading_scale:phiR_rel=1.03", 1)])


def run(cmd):
    t0 = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr}")
    return wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release"))
    ap.add_argument("--threads", default="2")
    ap.add_argument("--duration", default="30")
    ap.add_argument("--only", help="comma-separated case labels")
    ap.add_argument("--json", help="also write the rows to this file")
    a = ap.parse_args()
    wip = os.path.join(a.bin, "wip")
    only = a.only.split(",") if a.only else None
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, effect, seed in CASES:
            if only and label not in only:
                continue
            d = os.path.join(tmp, label.replace(" ", "_").replace(":", "_"))
            run([wip, "generate", "--effect", effect, "--seed", str(seed),
                 "--duration", a.duration, "--out", d])
            wall = run([wip, "diagnose", os.path.join(d, "log.csv"), "--quiet",
                        "--threads", a.threads, "--out", os.path.join(d, "diag")])
            with open(os.path.join(d, "diag", "diagnosis.json")) as f:
                r = json.load(f)
            row = {"case": label, "cause": r["cause"], "effects": r["effects"],
                   "error_before": r["error_before"], "error_after": r["error_after"],
                   "wall_s": wall}
            rows.append(row)
            print(f"{label:26} {r['cause']:24} {r['error_before']:8.3f} -> "
                  f"{r['error_after']:6.3f}  {wall:6.1f} s", file=sys.stderr, flush=True)
    print("| case | named | E before → after | wall |")
    print("|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['cause']} | {r['error_before']:.3f} → "
              f"{r['error_after']:.3f} | {r['wall_s']:.1f} s |")
    walls = [r["wall_s"] for r in rows]
    print(f"\nmedian {statistics.median(walls):.1f} s, max {max(walls):.1f} s "
          f"({sum(w <= 30.0 for w in walls)} of {len(walls)} within 30 s)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
