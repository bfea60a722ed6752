#!/usr/bin/env python3
"""Alternates actopo-bench configurations on the same meshes and prints medians and ratios.

Each configuration is a name and actopo-bench flags; every run starts each configuration in
turn (A B C A B C ...), so a drift of the machine's speed falls on all of them alike. Figures
are the whole process: wall time from start to exit, and the peak RSS actopo-bench reports for
itself. Ratios are to the first configuration, median over the runs of the per-run ratios.

    bench/configs_ab.py --runs 3 --mesh /data/part_5M.vtu:velocityMag \\
        --workloads CP,MS --config explicit='--structure explicit' \\
        --config normal='--structure actopo --producer-priority normal' \\
        --config idle='--structure actopo --producer-priority idle'
"""
from __future__ import annotations

import argparse
import json
import shlex
import statistics
import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORKLOADS = {
    "CP": ["--algorithm", "critical-points"],
    "DG": ["--algorithm", "discrete-gradient"],
    "MS": ["--algorithm", "morse-smale"],
    "PD": ["--algorithm", "persistence-diagram"],
    "SMS": ["--algorithm", "morse-smale", "--relative-threshold", "0.01"],
}


def run_once(command: list[str]) -> dict[str, float]:
    """Wall seconds and peak RSS (MiB) of one whole process, and its run phase."""
    start = time.monotonic()
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = child.communicate()
    wall = time.monotonic() - start
    if child.returncode != 0:
        raise SystemExit(f"{shlex.join(command)} failed ({child.returncode}): {err.decode()}")
    report = json.loads(out)
    return {"wall_s": wall, "peak_mib": report["memory"]["peak_rss_bytes"] / 2**20,
            "run_s": report["times_s"]["run"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", action="append", required=True, help="FILE:FIELD, repeatable")
    ap.add_argument("--workloads", default="CP,DG,MS,PD,SMS", help=",".join(WORKLOADS))
    ap.add_argument("--config", action="append", required=True,
                    help="NAME='actopo-bench flags', repeatable; the first is the yardstick")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--bench", default=str(ROOT / "build/server/cmd/actopo-bench"))
    ap.add_argument("--json", help="write every run here")
    args = ap.parse_args()

    configs = {}
    for c in args.config:
        name, _, flags = c.partition("=")
        configs[name] = shlex.split(flags)
    everything = {}
    for mesh in args.mesh:
        path, _, field = mesh.rpartition(":")
        for workload in args.workloads.split(","):
            runs: dict[str, list[dict[str, float]]] = {name: [] for name in configs}
            for _ in range(args.runs):
                for name, flags in configs.items():
                    command = [args.bench, "--mesh", path, "--scalar", field,
                               *WORKLOADS[workload], *flags, "--json"]
                    runs[name].append(run_once(command))
            first = next(iter(configs))
            cells = []
            for name in configs:
                wall = statistics.median(r["wall_s"] for r in runs[name])
                ratio = statistics.median(
                    r["wall_s"] / b["wall_s"] for r, b in zip(runs[name], runs[first], strict=True))
                peak = statistics.median(r["peak_mib"] for r in runs[name])
                lo = min(r["wall_s"] for r in runs[name])
                hi = max(r["wall_s"] for r in runs[name])
                cells.append(f"{name} {wall:.2f} s ({lo:.2f}-{hi:.2f}) {ratio:.2f}x {peak:.0f} MiB")
            print(f"{Path(path).name} {workload}: " + " | ".join(cells), flush=True)
            everything[f"{path} {workload}"] = runs
    if args.json:
        Path(args.json).write_text(json.dumps(everything, indent=1))


if __name__ == "__main__":
    main()
