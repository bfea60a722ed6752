#!/usr/bin/env python3
"""How steady this machine's cores are right now: a fixed integer loop (no memory traffic, no
allocation) timed ROUNDS times on one core alone, then on every core at once, one process per
core pinned to it. On a dedicated machine every loop takes the same time in both; on a virtual
machine whose host is busy, the loop's CPU time itself varies (steal time in /proc/stat does not
show it), and a benchmark figure from such a moment is not comparable with another moment's.
Run it beside a benchmark set and quote it; compare programs only within one run (versus_ttk.py,
configs_ab.py alternate them).

    python3 bench/steadiness.py --rounds 5
"""
import argparse
import os
import statistics
import time
from multiprocessing import Pool

LOOP = 5_000_000


def spin(core: int) -> float:
    """CPU seconds of the fixed loop, pinned to `core`."""
    os.sched_setaffinity(0, {core})
    start = time.process_time()
    x = 0
    for i in range(LOOP):
        x += i * i
    return time.process_time() - start


def summary(values: list[float]) -> str:
    return (f"median {statistics.median(values):.3f} s (min {min(values):.3f}, max "
            f"{max(values):.3f}, max/min {max(values) / min(values):.2f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    cores = sorted(os.sched_getaffinity(0))
    alone: list[float] = []
    together: list[float] = []
    with Pool(len(cores)) as pool:
        for _ in range(args.rounds):
            alone += pool.map(spin, cores[:1])
            together += pool.map(spin, cores)
    print(f"{len(cores)} cores, {args.rounds} rounds of a {LOOP:,}-step loop")
    print(f"one core alone:   {summary(alone)}")
    print(f"all cores at once: {summary(together)}")
    print(f"all at once / alone (medians): "
          f"{statistics.median(together) / statistics.median(alone):.2f}")


if __name__ == "__main__":
    main()
