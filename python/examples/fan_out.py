"""Fan a Monte Carlo of closed-loop runs, or a folder of logs, out over worker processes,
and the same over a cluster with Dask or Ray.

Every function of dmech takes and returns picklable values, so one task is one call:

    track_seed(plan, seed)      one Monte Carlo seed: the plant of that seed, its sensors
    diagnose_file(path)         one log's verdict

and the fan-out is ``executor.map`` over any ``concurrent.futures.Executor``:

- on this machine: ``concurrent.futures.ProcessPoolExecutor(max_workers=n)``;
- Dask: ``dask.distributed.Client("scheduler:8786").get_executor()``;
- Ray: ``ray.util.multiprocessing.Pool()`` (its ``map`` has the same form).

    python python/examples/fan_out.py [SEEDS]
"""

import concurrent.futures
import sys

import dmech


def track_seed(plan, seed):
    """Monte Carlo seed ``seed`` as ``wip track --monte-carlo`` runs it: the plant with
    seed's ±10 % parameter error, the sensors drawn from the same seed."""
    run = dmech.wip.track(plan, seed=seed, plant_seed=seed, param_error=0.1)
    return seed, run.figures


def diagnose_file(path):
    d = dmech.wip.diagnose(path, threads=1)
    return str(path), d.cause, d.parameters, d.error_after


def monte_carlo(plan, seeds, executor):
    """``{seed: tracking figures}`` with one task per seed on ``executor``."""
    return dict(executor.map(track_seed, [plan] * len(seeds), seeds))


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    plan = dmech.wip.plan("eight")
    with concurrent.futures.ProcessPoolExecutor(max_workers=2) as pool:
        figures = monte_carlo(plan, list(range(1, n + 1)), pool)
    falls = [s for s, f in figures.items() if f["fell"]]
    worst = max(f["position_error_max_m"] for f in figures.values())
    print(f"{n} seeds on 2 processes: {len(falls)} fell; largest position error {1e3 * worst:.2f} mm")
