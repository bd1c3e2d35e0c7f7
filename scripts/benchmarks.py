#!/usr/bin/env python3
"""Measure the headline figures again and write docs/benchmarks.md.

Runs the release binaries `wip` and `car` on the headline cases, each case REPS times
(default 3), the cases interleaved round by round so that a change in the host's speed
touches every case alike, and writes a page of medians (with min–max) together with the
machine (CPU model from /proc/cpuinfo, cores), the date and the commit the binaries come
from. It also writes the README's picture (the planned path of the eight, from the first run)
and the README's figure table (between its markers, the same numbers as the page), and
quotes the latest side-by-side results file of scripts/peers/ (not rerun here: it needs
CasADi and some 25 minutes; scripts/peers/README.md).

    python3 scripts/benchmarks.py                       # target/release-lto/, 3 repetitions
    python3 scripts/benchmarks.py --bin /path/to/target/release --reps 5

Python 3 standard library only. The default run takes 2–4 minutes on 2 cores.

Cases (flags as in `wip plan --help`, keys as in docs/formats.md):
  wip plan eight | zigzag | eight --integrator rk1 | eight --integrator midpoint |
  eight --current algebraic   (summary.json: status, iterations, objective, max_violation)
  wip plan eight --step 0.02 … 0.00125   (the scale series; fitted exponent of time in N)
  car plan parallel-park | lane-change
  wip plan eight --u-max 4.4, then wip track (--ideal; --seed 1, 2, 3; --controller mpc)
                                                           (tracking.json)
  wip generate --effect floor_slope --seed 7, then wip diagnose          (diagnosis.json)
"""

import argparse
import datetime
import glob
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))

# The independent reference objectives (CasADi + IPOPT, docs/problems.md).
REFERENCE = {("eight", "varint"): 4877.1583, ("eight", "rk1"): 4876.4865,
             ("zigzag", "varint"): 2320.0254, ("zigzag", "rk1"): 2319.8944}

SCALE_STEPS = [0.02, 0.01, 0.005, 0.0025, 0.00125]


# ---------------------------------------------------------------------------------------
# running


class Failed(Exception):
    pass


def run(cmd, log):
    """Run one command; return wall and CPU seconds and peak memory (MiB) of the process."""
    with open(log, "wb") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {"exit": proc.returncode, "wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime,
            "rss_mib": ru.ru_maxrss / 1024.0}


def load(path):
    with open(path) as f:
        return json.load(f)


def tail(path, n=400):
    try:
        with open(path, "rb") as f:
            return f.read()[-n:].decode(errors="replace").strip()
    except OSError:
        return ""


class Case:
    """One command, run once per round; `result` reads its output files."""

    def __init__(self, key, cmd, result, ok_exits=(0,)):
        self.key, self.cmd, self.result, self.ok_exits = key, cmd, result, ok_exits
        self.runs = []

    def once(self, work, i):
        out = os.path.join(work, f"{self.key}-{i}")
        shutil.rmtree(out, ignore_errors=True)
        cmd = [c.replace("{out}", out) for c in self.cmd]
        rec = run(cmd, out + ".log")
        if rec["exit"] not in self.ok_exits:
            raise Failed(f"{' '.join(cmd)}: exit {rec['exit']}: {tail(out + '.log')}")
        rec.update(self.result(out))
        rec["out"] = out
        self.runs.append(rec)
        return rec


def plan_result(out):
    s = load(os.path.join(out, "summary.json"))
    rec = {k: s.get(k) for k in ("status", "iterations", "objective", "max_violation",
                                 "solve_time_s", "N", "h")}
    for k, v in (s.get("time_breakdown_s") or {}).items():
        rec["t_" + k] = v
    return rec


def track_result(out):
    t = load(os.path.join(out, "tracking.json"))
    return {k: t.get(k) for k in ("position_error_max_m", "position_error_rms_m",
                                  "heading_error_max_rad", "heading_error_rms_rad",
                                  "tilt_max_rad", "feedback_voltage_max", "fell",
                                  "qp_solve_ms_median", "qp_solve_ms_max", "qp_fallbacks")}


def diagnose_result(out):
    d = load(os.path.join(out, "diagnosis.json"))
    return {k: d.get(k) for k in ("cause", "effects", "parameters", "uncertainty",
                                  "error_before", "error_after", "gain", "elapsed_s",
                                  "windows")}


# ---------------------------------------------------------------------------------------
# statistics and formatting


def med(runs, key):
    vals = [r[key] for r in runs if r.get(key) is not None]
    return statistics.median(vals) if vals else None


def span(runs, key, fmt="{:.2f}", unit=" s"):
    vals = [r[key] for r in runs if r.get(key) is not None]
    if not vals:
        return "–"
    m = fmt.format(statistics.median(vals))
    lo, hi = fmt.format(min(vals)), fmt.format(max(vals))
    if len(vals) == 1 or lo == hi:
        return m + unit
    return f"{m}{unit} ({lo}–{hi})"


def same(runs, key):
    """The value every run agrees on, or the list of distinct values."""
    vals = []
    for r in runs:
        if r.get(key) not in vals:
            vals.append(r.get(key))
    return vals[0] if len(vals) == 1 else vals


def fmt_same(runs, key, fmt):
    v = same(runs, key)
    if isinstance(v, list):
        return " / ".join(fmt.format(x) if x is not None else "–" for x in v)
    return fmt.format(v) if v is not None else "–"


def sci(x):
    return "–" if x is None else f"{x:.1e}"


def fit_exponent(ns, ts):
    """Least-squares slope of log t against log N."""
    xs = [math.log(n) for n in ns]
    ys = [math.log(t) for t in ts]
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx


# ---------------------------------------------------------------------------------------
# machine, commit


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for ln in f:
                if ln.startswith("model name"):
                    return ln.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def git(repo, *args):
    try:
        return subprocess.run(["git", "-C", repo, *args], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def is_commit(repo, word):
    return subprocess.run(["git", "-C", repo, "cat-file", "-e", word + "^{commit}"],
                          capture_output=True).returncode == 0


def without_hashes(text, repos):
    """Replace every word that names a commit (docs/ carry no commit hashes)."""
    def sub(m):
        w = m.group(0)
        return "…" if any(r and is_commit(r, w) for r in repos) else w
    return re.sub(r"\b[0-9a-fA-F]{7,40}\b", sub, text)


def commit_of(bindir):
    """The commit the binaries were built from, described without its hash."""
    repo = git(bindir, "rev-parse", "--show-toplevel")
    if repo is None:
        return None, "binaries outside a git repository (commit unknown)"
    count = git(repo, "rev-list", "--count", "HEAD")
    date = git(repo, "log", "-1", "--format=%cd", "--date=format-local:%Y-%m-%d %H:%M UTC")
    subject = git(repo, "log", "-1", "--format=%s")
    dirty = git(repo, "status", "--porcelain", "--untracked-files=no")
    text = (f"the commit of {date}, number {count} of its history "
            f"(`git rev-list --reverse HEAD | sed -n {count}p`), \u201c{subject}\u201d")
    if dirty:
        text += ", with uncommitted changes"
    binary = os.path.join(bindir, "wip")
    ctime = git(repo, "log", "-1", "--format=%ct")
    if ctime and os.path.exists(binary) and os.path.getmtime(binary) < int(ctime):
        text += " (the `wip` binary is older than that commit: rebuild before measuring)"
    return repo, without_hashes(text, [repo, ROOT])


def newest_peers_file():
    best = None
    for path in glob.glob(os.path.join(ROOT, "scripts", "peers", "results_*.json")):
        try:
            started = load(path)["info"]["started"]
        except (OSError, KeyError, ValueError):
            continue
        if best is None or started > best[0]:
            best = (started, path)
    return best[1] if best else None


# ---------------------------------------------------------------------------------------
# the figure


def write_figure(svg_in, svg_out, keep_every=4):
    """The plan's path.svg with the planned polyline thinned (the picture is the same)."""
    with open(svg_in) as f:
        svg = f.read()

    def thin(m):
        pts = m.group(2).split()
        kept = pts[::keep_every]
        if kept[-1] != pts[-1]:
            kept.append(pts[-1])
        out = []
        for p in kept:
            x, y = p.split(",")
            out.append(f"{float(x):.1f},{float(y):.1f}")
        return m.group(1) + " ".join(out) + m.group(3)

    svg = re.sub(r'(<polyline[^>]*points=")([^"]*)(")', thin, svg)
    os.makedirs(os.path.dirname(svg_out), exist_ok=True)
    with open(svg_out, "w") as f:
        f.write(svg)


# ---------------------------------------------------------------------------------------
# the page


def rel(a, b):
    return abs(a - b) / abs(b)


def page(args, cases, machine, peers_path):
    c = cases
    L = []
    w = L.append
    w("# Benchmarks")
    w("")
    w("Written by [`scripts/benchmarks.py`](../scripts/benchmarks.py), which runs the release")
    w("binaries on the headline cases and writes this page; run it again rather than edit it:")
    w("")
    w("```sh")
    w("cargo build --profile release-lto --bin wip --bin car")
    w("python3 scripts/benchmarks.py            # --bin DIR (default target/release-lto/), --reps N")
    w("```")
    w("")
    times = "once" if args.reps == 1 else f"{args.reps} times"
    w(f"**Measured** {machine['date']} on {machine['cpu']}, {machine['cores']} cores "
      f"({machine['platform']}); the binaries of `{machine['bindir']}`, built from "
      f"{machine['commit']}. Every case ran {times}, the cases interleaved round "
      f"by round; each time is the median, with the range of the runs in brackets. Load "
      f"average {machine['load_start']:.2f} at the start and {machine['load_end']:.2f} at the "
      f"end{machine['shared']}. Times move with the host's load by more than with the code; "
      f"iterations, objectives and errors do not move from run to run.")
    w("")
    w("Times are wall-clock times of the whole command as a user sees it (start-up, the "
      "planner's own start, every phase and mesh, the result files); `solve` is "
      "summary.json's `solve_time_s`; CPU is user + system time of all threads; memory is "
      "the peak resident set. `wip plan` runs one worker thread per core (at most 8).")
    w("")

    # planning
    w("## `wip plan`")
    w("")
    w("| command | status | iterations | objective | reference | max violation "
      "| wall | solve | CPU | peak memory |")
    w("|---|---|---|---|---|---|---|---|---|---|")
    for key, label, ref in [
            ("eight", "`wip plan eight`", ("eight", "varint")),
            ("zigzag", "`wip plan zigzag`", ("zigzag", "varint")),
            ("eight-rk1", "`wip plan eight --integrator rk1`", ("eight", "rk1")),
            ("eight-midpoint", "`wip plan eight --integrator midpoint`", None),
            ("eight-algebraic", "`wip plan eight --current algebraic`", None)]:
        runs = c[key].runs
        obj = same(runs, "objective")
        refs = "–"
        if ref and not isinstance(obj, list):
            r = REFERENCE[ref]
            refs = f"{r} ({rel(obj, r):.0e})"
        w(f"| {label} | {fmt_same(runs, 'status', '{}')} | "
          f"{fmt_same(runs, 'iterations', '{}')} | {fmt_same(runs, 'objective', '{:.4f}')} | "
          f"{refs} | {fmt_same(runs, 'max_violation', '{:.1e}')} | {span(runs, 'wall_s')} | "
          f"{span(runs, 'solve_time_s')} | {span(runs, 'cpu_s')} | "
          f"{span(runs, 'rss_mib', '{:.0f}', ' MiB')} |")
    w("")
    w("The reference is the independent CasADi + IPOPT optimum of the same problem "
      "(docs/problems.md), with the relative difference in brackets; the midpoint and "
      "algebraic-current problems have none. The variational and RK1 objectives differ "
      "by the discretisation of the cost's current, `O(h)`.")
    w("")

    # where the time goes
    e = c["eight"].runs
    parts = [("t_derivatives", "stage derivatives (and the SR1 updates, the KKT error's parts)"),
             ("t_kkt", "the Newton steps' linear algebra (condensing, Riccati sweeps, recovery)"),
             ("t_kkt_riccati", "of it, the factorisations and solves"),
             ("t_line_search", "the line search (trial points, their values and measures)")]
    w("Where the eight's solve time goes (summary.json's `time_breakdown_s`, medians; "
      "docs/solver.md):")
    w("")
    w("| part | time | share of the solve |")
    w("|---|---|---|")
    solve = med(e, "solve_time_s")
    for k, lab in parts:
        v = med(e, k)
        if v is not None:
            w(f"| {lab} | {v:.2f} s | {100 * v / solve:.0f} % |")
    w(f"| factorisations; second-order corrections | {fmt_same(e, 't_kkt_factorizations', '{}')}; "
      f"{fmt_same(e, 't_second_order_corrections', '{}')} | |")
    w("")

    # scale
    w("## Scale series (`wip plan eight --step h`)")
    w("")
    w("| step | N | iterations | wall | solve | peak memory |")
    w("|---|---|---|---|---|---|")
    ns, walls, solves = [], [], []
    for h in SCALE_STEPS:
        runs = c[f"scale-{h}"].runs
        n = same(runs, "N")
        ns.append(n)
        walls.append(med(runs, "wall_s"))
        solves.append(med(runs, "solve_time_s"))
        w(f"| {h * 1000:g} ms | {n} | {fmt_same(runs, 'iterations', '{}')} | "
          f"{span(runs, 'wall_s')} | {span(runs, 'solve_time_s')} | "
          f"{span(runs, 'rss_mib', '{:.0f}', ' MiB')} |")
    w("")
    fastest = [min(r["wall_s"] for r in c[f"scale-{h}"].runs) for h in SCALE_STEPS]
    w(f"Fitted exponent (least squares in log–log over the five medians): wall time "
      f"**N^{fit_exponent(ns, walls):.2f}**, solve time N^{fit_exponent(ns, solves):.2f}; "
      f"over each step's fastest run, the least disturbed by the host's other work, wall "
      f"time N^{fit_exponent(ns, fastest):.2f}. Variational plans are solved by mesh "
      f"sequencing (docs/ocp.md), so the iterations are those of every mesh added.")
    w("")

    # car
    w("## `car plan`")
    w("")
    w("| command | status | iterations | objective | max violation | wall |")
    w("|---|---|---|---|---|---|")
    for key, label in [("car-park", "`car plan parallel-park`"),
                       ("car-lane", "`car plan lane-change`")]:
        runs = c[key].runs
        w(f"| {label} | {fmt_same(runs, 'status', '{}')} | "
          f"{fmt_same(runs, 'iterations', '{}')} | {fmt_same(runs, 'objective', '{:.6f}')} | "
          f"{fmt_same(runs, 'max_violation', '{:.1e}')} | {span(runs, 'wall_s', '{:.3f}')} |")
    w("")

    # tracking
    p44 = c["plan-4.4"].runs
    w("## `wip track`")
    w("")
    w(f"The eight planned with a voltage margin, `wip plan eight --u-max 4.4`: "
      f"{fmt_same(p44, 'iterations', '{}')} iterations, objective "
      f"{fmt_same(p44, 'objective', '{:.4f}')}, {span(p44, 'wall_s')}. Then "
      f"`wip track DIR …` (LQ unless said; docs/tracking.md):")
    w("")
    w("| command | position error max / RMS | heading error max / RMS | tilt max "
      "| feedback max | fell | wall |")
    w("|---|---|---|---|---|---|---|")
    for key, label in [("track-ideal", "`--ideal`"), ("track-1", "`--seed 1`"),
                       ("track-2", "`--seed 2`"), ("track-3", "`--seed 3`"),
                       ("track-mpc", "`--controller mpc --seed 1`")]:
        r = c[key].runs
        w(f"| {label} | {1e3 * same(r, 'position_error_max_m'):.2f} mm / "
          f"{1e3 * same(r, 'position_error_rms_m'):.2f} mm | "
          f"{math.degrees(same(r, 'heading_error_max_rad')):.2f}° / "
          f"{math.degrees(same(r, 'heading_error_rms_rad')):.2f}° | "
          f"{math.degrees(same(r, 'tilt_max_rad')):.2f}° | "
          f"{fmt_same(r, 'feedback_voltage_max', '{:.2f}')} V | "
          f"{'yes' if same(r, 'fell') else 'no'} | "
          f"{span(r, 'wall_s', '{:.3f}')} |")
    mpc = c["track-mpc"].runs
    w("")
    w(f"The paper's hardware on the eight: 24 mm / 8.3 mm, 12.1° / 3.2° (`paper_hardware` "
      f"of tracking.json). The MPC's QP per 5-ms sample: median "
      f"{span(mpc, 'qp_solve_ms_median', '{:.2f}', ' ms')}, largest "
      f"{span(mpc, 'qp_solve_ms_max', '{:.2f}', ' ms')} of thread CPU time; "
      f"{fmt_same(mpc, 'qp_fallbacks', '{}')} fallbacks to the LQ move.")
    w("")

    # diagnose
    d = c["diagnose"].runs
    truth = load(os.path.join(c["generate"].runs[0]["out"], "truth.json"))
    w("## `wip diagnose`")
    w("")
    w("`wip generate --effect floor_slope --seed 7` (a 30-s closed-loop log, 6,001 rows, "
      "with a hidden floor slope), then `wip diagnose DIR/log.csv --quiet` "
      "(docs/diagnose.md):")
    w("")
    w("| cause | error before → after (1 = noise floor) | wall | CPU |")
    w("|---|---|---|---|")
    w(f"| {fmt_same(d, 'cause', '{}')} | {fmt_same(d, 'error_before', '{:.3f}')} → "
      f"{fmt_same(d, 'error_after', '{:.3f}')} | {span(d, 'wall_s', '{:.1f}')} | "
      f"{span(d, 'cpu_s', '{:.1f}')} |")
    w("")
    params = d[0]["parameters"] or {}
    unc = d[0]["uncertainty"] or {}
    hidden = {}
    for e in truth.get("effects", []):
        hidden.update(e.get("parameters", {}))
    parts = []
    for k, v in params.items():
        s = f"`{k}` = {v:.6g}"
        if unc.get(k) is not None:
            s += f" ± {unc[k]:.2g}"
        if k in hidden:
            s += f" (hidden: {hidden[k]:.6g})"
        parts.append(s)
    w("Refitted: " + "; ".join(parts) + ".")
    w("")

    # peers
    w("## Side by side with CasADi + IPOPT and CasADi + FATROP")
    w("")
    if peers_path is None:
        w("No results file in scripts/peers/.")
    else:
        p = load(peers_path)
        info, summ = p["info"], p["summary"]
        relp = os.path.relpath(peers_path, os.path.join(ROOT, "docs"))
        name = os.path.basename(peers_path)
        m = info.get("machine", {})
        w(f"Not rerun by this script: `scripts/peers/bench.py` needs CasADi and about 25 "
          f"minutes (scripts/peers/README.md). Its latest results file, "
          f"[`{name}`]({relp}), was measured {info.get('started', '?')[:10]} on "
          f"{m.get('cpu', '?')}, {m.get('cores', '?')} cores, {info.get('rounds', '?')} "
          f"rounds, load average {info['loadavg_start'][0]:.1f} at the start and "
          f"{info['loadavg_end'][0]:.1f} at the end. The RK1 problem of "
          f"`wip plan eight --integrator rk1` in CasADi, solved by IPOPT (MUMPS) and "
          f"FATROP; ours is the whole command, theirs the solve alone (construction "
          f"apart). Medians:")
        w("")
        w("| run | median | iterations | vs IPOPT | vs FATROP |")
        w("|---|---|---|---|---|")
        ip, fa = summ["ipopt rk1"]["median"], summ["fatrop rk1"]["median"]
        labels = {"wip varint": "`wip plan eight`, 2 threads",
                  "wip varint 1 thread": "`wip plan eight`, 1 thread",
                  "wip rk1": "`wip plan eight --integrator rk1`, 2 threads",
                  "wip rk1 1 thread": "`wip plan eight --integrator rk1`, 1 thread"}
        for k, lab in labels.items():
            if k in summ:
                s = summ[k]
                w(f"| {lab} | {s['median']:.2f} s | {s['iterations'][0]} | "
                  f"{ip / s['median']:.2f}× | {fa / s['median']:.2f}× |")
        w(f"| CasADi + IPOPT 3.14 / MUMPS, RK1 | {ip:.2f} s | "
          f"{summ['ipopt rk1']['iterations'][0]} | | |")
        w(f"| CasADi + FATROP 1.1, RK1 | {fa:.2f} s | "
          f"{summ['fatrop rk1']['iterations'][0]} | | |")
        w("")
        w("The ratios move with the host's load by more than with the code (the planner's "
          "two threads wait for each other at every stage loop; the peers run on one).")
    w("")
    return without_hashes(wrap(L), [machine.get("repo"), ROOT])


def wrap(lines, width=90):
    """Paragraph lines wrapped for the source's sake; tables, code and headings kept."""
    out, code = [], False
    for ln in lines:
        if ln.startswith("```"):
            code = not code
        if code or ln.startswith(("|", "#", "```")) or len(ln) <= width:
            out.append(ln)
        else:
            out.extend(textwrap.wrap(ln, width, break_long_words=False,
                                     break_on_hyphens=False))
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------------------------------


def readme_table(args, cases, machine, peers_path):
    """The README's figure table: a few of this page's figures, the same numbers."""
    c = cases
    e, rk1, park = c["eight"].runs, c["eight-rk1"].runs, c["car-park"].runs
    t1, d = c["track-1"].runs, c["diagnose"].runs
    ns = [same(c[f"scale-{h}"].runs, "N") for h in SCALE_STEPS]
    walls = [med(c[f"scale-{h}"].runs, "wall_s") for h in SCALE_STEPS]
    fastest = [min(r["wall_s"] for r in c[f"scale-{h}"].runs) for h in SCALE_STEPS]
    cpu = machine["cpu"]
    L = [f"Measured {machine['date'][:10]} on a {machine['cores']}-core {cpu} shared with other "
         f"work, medians of {args.reps} runs, whole commands ([docs/benchmarks.md](docs/benchmarks.md)):",
         "",
         "| run | figure |",
         "|---|---|",
         f"| `wip plan eight` | {fmt_same(e, 'iterations', '{}')} iterations, J = "
         f"{fmt_same(e, 'objective', '{:.4f}')} (reference {REFERENCE[('eight', 'varint')]}), "
         f"{med(e, 'wall_s'):.2f} s |",
         f"| `wip plan eight --integrator rk1` | {fmt_same(rk1, 'iterations', '{}')} iterations, "
         f"J = {fmt_same(rk1, 'objective', '{:.4f}')} (reference {REFERENCE[('eight', 'rk1')]}), "
         f"{med(rk1, 'wall_s'):.2f} s |",
         f"| the eight at `--step` 20 … 1.25 ms (N = {ns[0]:,} … {ns[-1]:,}) | "
         f"{walls[0]:.2f} … {walls[-1]:.2f} s, time ∝ N^{fit_exponent(ns, walls):.2f} "
         f"(fastest runs: N^{fit_exponent(ns, fastest):.2f}) |",
         f"| `car plan parallel-park` | {fmt_same(park, 'iterations', '{}')} iterations, "
         f"{med(park, 'wall_s'):.2f} s |",
         f"| `wip track` of the eight planned at 4.4 V, `--seed 1` | position error "
         f"{1e3 * same(t1, 'position_error_max_m'):.2f} mm at most (the paper's hardware: 24 mm) |",
         f"| `wip diagnose`, 30 s of log with a hidden floor slope | "
         f"{fmt_same(d, 'cause', '{}')} found, error {fmt_same(d, 'error_before', '{:.2f}')} → "
         f"{fmt_same(d, 'error_after', '{:.2f}')} × noise, {med(d, 'wall_s'):.1f} s |"]
    if peers_path:
        p = load(peers_path)
        info, summ = p["info"], p["summary"]
        ours = summ["wip varint"]["median"]
        L.append(f"| the eight against CasADi + IPOPT / FATROP (scripts/peers, "
                 f"{info.get('started', '?')[:10]}) | "
                 f"{summ['ipopt rk1']['median'] / ours:.1f}× / "
                 f"{summ['fatrop rk1']['median'] / ours:.1f}× faster |")
    return without_hashes("\n".join(L) + "\n", [machine.get("repo"), ROOT])


def update_readme(path, table):
    """Replace the block between the README's figure markers by `table`."""
    start, end = "<!-- figures: scripts/benchmarks.py -->", "<!-- /figures -->"
    with open(path) as f:
        text = f.read()
    i, j = text.find(start), text.find(end)
    if i < 0 or j < i:
        return False
    text = text[:i + len(start)] + "\n" + table + text[j:]
    with open(path, "w") as f:
        f.write(text)
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release-lto"),
                    help="directory of the wip and car binaries (default: target/release-lto/, "
                         "the benchmark profile)")
    ap.add_argument("--reps", type=int, default=3, help="repetitions of each case (3)")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "benchmarks.md"),
                    help="the page to write (docs/benchmarks.md); '-' for stdout")
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "eight-path.svg"),
                    help="where to write the eight's planned path (docs/figures/eight-path.svg)")
    ap.add_argument("--no-figure", action="store_true", help="leave the figure alone")
    ap.add_argument("--readme", default=os.path.join(ROOT, "README.md"),
                    help="README whose figure table (between its markers) to rewrite; '' for none")
    ap.add_argument("--peers", default=None,
                    help="side-by-side results file to quote (default: the newest in scripts/peers/)")
    ap.add_argument("--shared", default="",
                    help="a note on the host's state to print beside the load average")
    ap.add_argument("--work", default=None, help="directory for the runs' files (default: a temporary one)")
    args = ap.parse_args()
    if args.reps < 1:
        ap.error("--reps must be at least 1")

    bindir = os.path.abspath(args.bin)
    wip, car = os.path.join(bindir, "wip"), os.path.join(bindir, "car")
    for b in (wip, car):
        if not os.access(b, os.X_OK):
            sys.exit(f"benchmarks: no executable {b} (cargo build --profile release-lto --bin wip --bin car, or --bin DIR)")

    work = args.work or tempfile.mkdtemp(prefix="dmech-bench-")
    os.makedirs(work, exist_ok=True)
    repo, commit = commit_of(bindir)
    load_start = os.getloadavg()[0]
    started = datetime.datetime.now(datetime.timezone.utc)

    P = [wip, "plan"]
    cases = {}

    def add(key, cmd, result, ok_exits=(0,)):
        cases[key] = Case(key, cmd, result, ok_exits)

    add("eight", P + ["eight", "--quiet", "--out", "{out}"], plan_result)
    add("zigzag", P + ["zigzag", "--quiet", "--out", "{out}"], plan_result)
    add("eight-rk1", P + ["eight", "--integrator", "rk1", "--quiet", "--out", "{out}"], plan_result)
    add("eight-midpoint", P + ["eight", "--integrator", "midpoint", "--quiet", "--out", "{out}"],
        plan_result)
    add("eight-algebraic", P + ["eight", "--current", "algebraic", "--quiet", "--out", "{out}"],
        plan_result)
    for h in SCALE_STEPS:
        if h == 0.005:
            continue  # the eight itself
        add(f"scale-{h}", P + ["eight", "--step", str(h), "--quiet", "--out", "{out}"], plan_result)
    add("car-park", [car, "plan", "parallel-park", "--quiet", "--out", "{out}"], plan_result)
    add("car-lane", [car, "plan", "lane-change", "--quiet", "--out", "{out}"], plan_result)
    add("plan-4.4", P + ["eight", "--u-max", "4.4", "--quiet", "--out", "{out}"], plan_result)
    add("generate", [wip, "generate", "--effect", "floor_slope", "--seed", "7", "--out", "{out}"],
        lambda out: {})
    add("diagnose", [wip, "diagnose", "GENERATED", "--quiet", "--out", "{out}"], diagnose_result)
    # the tracking runs read the --u-max 4.4 plan; the same plan every round (deterministic)
    track = {"track-ideal": ["--ideal"], "track-1": ["--seed", "1"], "track-2": ["--seed", "2"],
             "track-3": ["--seed", "3"], "track-mpc": ["--controller", "mpc", "--seed", "1"]}
    for key, extra in track.items():
        add(key, [wip, "track", "PLAN"] + extra + ["--out", "{out}"], track_result)

    once = {"generate"}  # deterministic, not a figure
    order = [k for k in cases if k not in once]
    total = len(order) * args.reps + len(once)
    done = 0
    try:
        for key in once:
            cases[key].once(work, 0)
            done += 1
        log = os.path.join(cases["generate"].runs[0]["out"], "log.csv")
        cases["diagnose"].cmd = [log if c == "GENERATED" else c for c in cases["diagnose"].cmd]
        for i in range(args.reps):
            for key in order:
                if key.startswith("track-"):
                    plan_dir = cases["plan-4.4"].runs[-1]["out"]
                    cases[key].cmd = [plan_dir if c == "PLAN" else c
                                      for c in [wip, "track", "PLAN"] + track[key] + ["--out", "{out}"]]
                rec = cases[key].once(work, i)
                done += 1
                print(f"[{done}/{total}] {key}: {rec['wall_s']:.2f} s", file=sys.stderr)
    except Failed as e:
        sys.exit(f"benchmarks: {e}")

    # the scale series' 5 ms point is the eight
    cases["scale-0.005"] = cases["eight"]

    machine = {"cpu": cpu_model(), "cores": os.cpu_count(),
               "platform": f"{platform.system()} {platform.release()}",
               "date": started.strftime("%Y-%m-%d %H:%M UTC"), "commit": commit, "repo": repo,
               "bindir": os.path.relpath(bindir, ROOT) if bindir.startswith(ROOT + os.sep) else bindir,
               "load_start": load_start, "load_end": os.getloadavg()[0],
               "shared": args.shared and f" ({args.shared})" or ""}
    peers = args.peers or newest_peers_file()
    text = page(args, cases, machine, peers)
    if args.out == "-":
        sys.stdout.write(text)
    else:
        with open(args.out, "w") as f:
            f.write(text)
        print(f"wrote {args.out}", file=sys.stderr)
    if args.readme and args.out != "-":
        if update_readme(args.readme, readme_table(args, cases, machine, peers)):
            print(f"wrote the figure table of {args.readme}", file=sys.stderr)
    if not args.no_figure:
        write_figure(os.path.join(cases["eight"].runs[0]["out"], "path.svg"), args.figure)
        print(f"wrote {args.figure}", file=sys.stderr)
    if args.work is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
