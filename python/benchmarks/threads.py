"""Two plans of the zigzag in two Python threads against the same two in series.

The solves run without the GIL, so on a machine with two free cores the two threads take
about half the time of the series. Each plan is given one solver thread (``threads=1``):
with the solver's default (all cores) a single plan already keeps both cores busy and
there is nothing for a second Python thread to gain. Prints the medians of ``--rounds``
alternated rounds and their ratio; a benchmark, not a test (the machine's load decides
the figures)."""

import argparse
import statistics
import threading
import time

import dmech


def one():
    dmech.wip.plan("zigzag", threads=1)


def series():
    t0 = time.perf_counter()
    one()
    one()
    return time.perf_counter() - t0


def concurrent():
    t0 = time.perf_counter()
    workers = [threading.Thread(target=one) for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    one()  # warm up (page faults, thread pool)
    s, c = [], []
    for _ in range(a.rounds):
        s.append(series())
        c.append(concurrent())
    ms, mc = statistics.median(s), statistics.median(c)
    print(f"series {ms:.3f} s, two threads {mc:.3f} s (medians of {a.rounds}); ratio {mc / ms:.3f}")


if __name__ == "__main__":
    main()
