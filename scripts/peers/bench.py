#!/usr/bin/env python3
"""Side by side: `wip plan` against CasADi + IPOPT and CasADi + FATROP, alternated run by run.

For R rounds, each round runs every entry of RUNS once, in an order rotated by one per
round (so that no run always follows the same neighbour), one process at a time. It records

* for `wip plan …`: the wall time of the whole command (process start to exit: set-up,
  the planner's own start, every phase and mesh, writing the result files), and the
  iterations, objective and solve time of its summary.json;
* for the peers: the solve time `t_wall_total` from the solver's stats (the whole nlpsol
  call from the start), iterations and objective. Each peer is one persistent process
  (`wip_casadi.py serve`) that constructs its solver once before the first round (model,
  NLP, nlpsol with C code generation and compilation: timed and reported separately; for
  FATROP this takes minutes, see README) and then solves from the same start when its turn
  comes; `--fresh-peers` starts a new process, construction included, for every run;
* for every run the process's CPU time (user + system), which shows how many cores it used.

Prints medians, min and max and the ratios peer solve time / our whole command, and writes
every run to a JSON file.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))


def runs_for(args):
    wip = args.wip
    py = args.python
    peer = [py, os.path.join(HERE, "wip_casadi.py"), "solve", "--problem", args.problem,
            "--step", repr(args.step)]
    plan = [wip, "plan", args.problem, "--step", repr(args.step), "--quiet"]
    one_core = ["taskset", "-c", str(args.core)]
    runs = {
        # The planner takes its thread count from the CPU set it may run on
        # (std::thread::available_parallelism): `taskset -c 0` makes it one thread.
        "wip varint": ("ours", plan),
        "wip varint 1 thread": ("ours", one_core + plan),
        "wip rk1": ("ours", plan + ["--integrator", "rk1"]),
        "wip rk1 1 thread": ("ours", one_core + plan + ["--integrator", "rk1"]),
        "ipopt rk1": ("peer", peer + ["--solver", "ipopt"]),
        "fatrop rk1": ("peer", peer + ["--solver", "fatrop"]),
    }
    chosen = args.runs or ["wip varint", "wip rk1", "wip varint 1 thread", "wip rk1 1 thread",
                           "ipopt rk1", "fatrop rk1"]
    unknown = [r for r in chosen if r not in runs]
    if unknown:
        raise SystemExit(f"unknown runs {unknown}; choose from {list(runs)}")
    return [(name, *runs[name]) for name in chosen]


class Worker:
    """A persistent peer: `wip_casadi.py serve`, one JSON line per `solve`."""

    def __init__(self, name, cmd, tmp):
        self.name = name
        self.log = open(os.path.join(tmp, name.replace(" ", "_") + ".log"), "w")
        t0 = time.perf_counter()
        self.proc = subprocess.Popen([cmd[0], cmd[1], "serve"] + cmd[3:],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self.log, text=True)
        ready = json.loads(self.proc.stdout.readline())
        self.construct_s = ready["t_construct_s"]
        self.construct_wall_s = time.perf_counter() - t0

    def solve(self):
        self.proc.stdin.write("solve\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise OSError(f"{self.name}: the worker stopped (log: {self.log.name})")
        return json.loads(line)

    def close(self):
        try:
            self.proc.stdin.write("quit\n")
            self.proc.stdin.flush()
        except OSError:
            pass
        self.proc.wait(timeout=60)
        self.log.close()


def run_worker(name, worker):
    t0 = time.perf_counter()
    try:
        s = worker.solve()
    except (OSError, ValueError) as e:
        return {"run": name, "exit": 1, "wall_s": time.perf_counter() - t0, "cpu_s": 0.0,
                "loadavg": os.getloadavg(), "status": f"no result ({e})", "time_s": None}
    return {"run": name, "exit": 0, "wall_s": time.perf_counter() - t0, "cpu_s": s["cpu_s"],
            "loadavg": os.getloadavg(), "status": s["status"], "iterations": s["iterations"],
            "objective": s["objective"], "solve_time_s": s["t_wall_total"],
            "construct_s": worker.construct_s, "max_violation": s["max_violation"],
            "casadi": s["casadi"], "time_s": s["t_wall_total"],
            "t_wall_nlp_jac_g": s.get("t_wall_nlp_jac_g"),
            "t_wall_nlp_hess_l": s.get("t_wall_nlp_hess_l")}


def run_once(name, kind, cmd, tmp):
    out = os.path.join(tmp, name.replace(" ", "_"))
    os.makedirs(out, exist_ok=True)
    if kind == "ours":
        cmd = cmd + ["--out", out]
    else:
        cmd = cmd + ["--json", os.path.join(out, "peer.json")]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    proc.returncode = os.waitstatus_to_exitcode(status)
    rec = {"run": name, "cmd": cmd, "exit": proc.returncode, "wall_s": wall,
           "cpu_s": ru.ru_utime + ru.ru_stime, "max_rss_mb": ru.ru_maxrss / 1024,
           "loadavg": os.getloadavg()}
    try:
        if kind == "ours":
            with open(os.path.join(out, "summary.json")) as f:
                s = json.load(f)
            rec.update({"status": s["status"], "iterations": s["iterations"],
                        "objective": s["objective"], "solve_time_s": s["solve_time_s"],
                        "setup_time_s": s.get("setup_time_s"),
                        "time_s": wall})
        else:
            with open(os.path.join(out, "peer.json")) as f:
                s = json.load(f)
            rec.update({"status": s["status"], "iterations": s["iterations"],
                        "objective": s["objective"], "solve_time_s": s["t_wall_total"],
                        "construct_s": s["t_construct_s"], "max_violation": s["max_violation"],
                        "casadi": s["casadi"], "time_s": s["t_wall_total"]})
    except (OSError, KeyError, ValueError) as e:
        rec.update({"status": f"no result ({e}); stderr: {err[-300:]}", "time_s": None})
    return rec


def summarise(records, names, kinds):
    rows = {}
    for name in names:
        rs = [r for r in records if r["run"] == name and r.get("time_s") is not None]
        if not rs:
            rows[name] = None
            continue
        t = [r["time_s"] for r in rs]
        row = {
            "kind": kinds[name],
            "n": len(rs),
            "median": statistics.median(t),
            "min": min(t),
            "max": max(t),
            "iterations": sorted({r["iterations"] for r in rs}),
            "objective": statistics.median(r["objective"] for r in rs),
            "cpu_median": statistics.median(r["cpu_s"] for r in rs),
            "wall_median": statistics.median(r["wall_s"] for r in rs),
            "status": sorted({r["status"] for r in rs}),
        }
        if kinds[name] == "peer":
            row["construct_median"] = statistics.median(r["construct_s"] for r in rs)
        else:
            row["solve_median"] = statistics.median(r["solve_time_s"] for r in rs)
        rows[name] = row
    return rows


def print_table(rows, names):
    print()
    print("| run | what is timed | median | min | max | CPU (median) | iterations | objective |")
    print("|---|---|---|---|---|---|---|---|")
    for name in names:
        r = rows[name]
        if r is None:
            print(f"| {name} | – | no result | | | | | |")
            continue
        what = ("whole command" if r["kind"] == "ours" else
                f"solve (t_wall_total); construction {r['construct_median']:.1f} s")
        its = "/".join(str(i) for i in r["iterations"])
        print(f"| {name} | {what} | {r['median']:.2f} s | {r['min']:.2f} s | {r['max']:.2f} s "
              f"| {r['cpu_median']:.2f} s | {its} | {r['objective']:.4f} |")
    ours = [n for n in names if rows[n] and rows[n]["kind"] == "ours"]
    peers = [n for n in names if rows[n] and rows[n]["kind"] == "peer"]
    if ours and peers:
        print()
        print("Ratios of medians, peer solve time / our whole command (above 1: ours faster):")
        print()
        print("| ours | " + " | ".join(f"{p}" for p in peers) + " |")
        print("|---|" + "---|" * len(peers))
        for o in ours:
            cells = [f"{rows[p]['median'] / rows[o]['median']:.2f}×" for p in peers]
            print(f"| {o} | " + " | ".join(cells) + " |")


def machine():
    model = "?"
    try:
        with open("/proc/cpuinfo") as f:
            for ln in f:
                if ln.startswith("model name"):
                    model = ln.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {"cpu": model, "cores": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version()}


def git_head():
    try:
        return subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--wip", default=os.path.join(ROOT, "target", "release", "wip"),
                    help="the wip binary (release build; default target/release/wip)")
    ap.add_argument("--python", default=sys.executable,
                    help="the Python with casadi (default: this one)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=1,
                    help="untimed rounds first (disk caches, page cache of the binaries)")
    ap.add_argument("--problem", default="eight", choices=["eight", "zigzag"])
    ap.add_argument("--step", type=float, default=0.005)
    ap.add_argument("--core", type=int, default=0, help="the CPU of the one-thread runs")
    ap.add_argument("--runs", nargs="+",
                    help="which runs (default: wip varint, wip rk1, wip varint 1 thread, "
                         "wip rk1 1 thread, ipopt rk1, fatrop rk1)")
    ap.add_argument("--fresh-peers", action="store_true",
                    help="a new peer process (construction included) for every run")
    ap.add_argument("--out", default="bench_peers.json", help="JSON of all runs")
    args = ap.parse_args()
    if not os.path.exists(args.wip):
        raise SystemExit(f"no wip binary at {args.wip} (build it or pass --wip)")
    runs = runs_for(args)
    names = [r[0] for r in runs]
    kinds = {r[0]: r[1] for r in runs}
    info = {"machine": machine(), "git": git_head(), "wip": os.path.abspath(args.wip),
            "problem": args.problem, "step": args.step, "rounds": args.rounds,
            "loadavg_start": os.getloadavg(), "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    print(f"machine: {info['machine']['cpu']}, {info['machine']['cores']} cores; "
          f"load average {info['loadavg_start'][0]:.2f} {info['loadavg_start'][1]:.2f} "
          f"{info['loadavg_start'][2]:.2f}", flush=True)
    records = []
    with tempfile.TemporaryDirectory(prefix="bench_peers_") as tmp:
        workers = {}
        if not args.fresh_peers:
            # One at a time: construction is a heavy job (gcc; FATROP's block layout).
            for name, kind, cmd in runs:
                if kind == "peer":
                    print(f"constructing {name} ...", flush=True)
                    workers[name] = Worker(name, cmd, tmp)
                    print(f"  {name}: constructed in {workers[name].construct_s:.1f} s",
                          flush=True)
        info["construct_s"] = {n: w.construct_s for n, w in workers.items()}

        def run(name, kind, cmd):
            if name in workers:
                return run_worker(name, workers[name])
            return run_once(name, kind, cmd, tmp)

        for w in range(args.warmup):
            for name, kind, cmd in runs:
                rec = run(name, kind, cmd)
                print(f"warm-up {w + 1}: {name}: {rec.get('time_s')} s "
                      f"({rec.get('status')})", flush=True)
        for rnd in range(args.rounds):
            shift = rnd % len(runs)
            order = runs[shift:] + runs[:shift]
            for name, kind, cmd in order:
                rec = run(name, kind, cmd)
                rec["round"] = rnd
                records.append(rec)
                t = rec.get("time_s")
                extra = (f", construction {rec['construct_s']:.1f} s" if "construct_s" in rec
                         else "")
                print(f"round {rnd + 1}/{args.rounds}: {name}: "
                      f"{'–' if t is None else f'{t:.2f} s'} ({rec.get('status')}, "
                      f"{rec.get('iterations')} its, J = {rec.get('objective')}, "
                      f"CPU {rec['cpu_s']:.2f} s{extra}; load {rec['loadavg'][0]:.2f})",
                      flush=True)
        for w in workers.values():
            w.close()
    info["loadavg_end"] = os.getloadavg()
    rows = summarise(records, names, kinds)
    print(f"\nload average at the end: {info['loadavg_end'][0]:.2f} "
          f"{info['loadavg_end'][1]:.2f} {info['loadavg_end'][2]:.2f}")
    print_table(rows, names)
    with open(args.out, "w") as f:
        json.dump({"info": info, "summary": rows, "runs": records}, f, indent=1)
    print(f"\nall runs: {args.out}")
    bad = [r for r in records if r.get("time_s") is None or r["exit"] != 0]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
