#!/usr/bin/env python3
"""Our structures while other work holds every core, as on a shared server: BUSY processes that
spin at normal priority (one per core by default) run beside actopo-bench for the whole
measurement. For every mesh and workload the configurations run in turn, RUNS times (so a drift
of the machine hits all of them), each a whole process under /usr/bin/time. Prints a Markdown
table of medians (min-max) of wall seconds, peak RSS, the consumers' wait and the waits they
abandoned (a consumer computes a relation itself once a producer at idle priority is too slow).

    .venv/bin/python bench/busy_machine.py --runs 3 \\
        --mesh wavelet128.vtu:RTData --mesh part_5M.vtu:velocityMag \\
        --workloads critical-points,morse-smale \\
        --config "actopo=--structure actopo" \\
        --config "actopo, normal producers=--structure actopo --producer-priority normal" \\
        --config "compact=--structure compact" --config "explicit=--structure explicit"

A configuration is LABEL=ACTOPO-BENCH FLAGS; --bench LABEL=PATH runs that label with another
actopo-bench binary (an earlier build, for an A/B). --busy 0 measures the quiet machine.
"""
import argparse
import json
import multiprocessing
import os
import re
import shlex
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def spin(stop) -> None:
    while not stop.is_set():
        pass


def start_busy(kind: str, count: int) -> tuple[list, object]:
    """`count` busy processes: Python loops, or `yes > /dev/null` (a write per line: a
    kernel entry and exit each time, which starves idle-priority threads worse)."""
    if kind == "yes":
        procs = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(count)]
        return procs, None
    stop = multiprocessing.Event()
    procs = [multiprocessing.Process(target=spin, args=(stop,), daemon=True)
             for _ in range(count)]
    for p in procs:
        p.start()
    return procs, stop


def stop_busy(procs: list, stop) -> None:
    if stop is None:
        for p in procs:
            p.terminate()
            p.wait()
        return
    stop.set()
    for p in procs:
        p.join()


def timed(cmd: list[str], timeout: float) -> dict:
    """One whole process; past `timeout` seconds it is killed and counted as taking that long
    (a result of None), so a pathological configuration cannot hold up the rest."""
    try:
        proc = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", *cmd], capture_output=True,
                              text=True, check=False, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"wall_s": timeout, "peak_mib": 0.0, "wait_s": 0.0, "waits_abandoned": 0,
                "result": None, "timed_out": True}
    if proc.returncode != 0:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    wall, rss = re.search(r"TIME ([\d.]+) (\d+)", proc.stderr).groups()
    report = json.loads(proc.stdout)
    engine = report.get("engine") or {}
    return {"wall_s": float(wall), "peak_mib": int(rss) / 1024,
            "wait_s": engine.get("wait_s", 0.0),
            "waits_abandoned": engine.get("waits_abandoned", 0),
            "result": report["result"]}


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def print_case(c: dict) -> None:
    for label, runs in c["runs"].items():
        late = sum(r.get("timed_out", False) for r in runs)
        print(f"| {c['mesh']} | {c['workload']} | {label} | "
              f"{spread([r['wall_s'] for r in runs])}{f' ({late} killed)' if late else ''} | "
              f"{statistics.median(r['peak_mib'] for r in runs):.0f} | "
              f"{spread([r['wait_s'] for r in runs])} | "
              f"{statistics.median(r['waits_abandoned'] for r in runs):.0f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh", action="append", required=True, help="FILE:FIELD, repeatable")
    ap.add_argument("--workloads", default="critical-points,morse-smale")
    ap.add_argument("--config", action="append", required=True, help="LABEL=FLAGS, repeatable")
    ap.add_argument("--bench", action="append", default=[],
                    help="LABEL=PATH: that label's actopo-bench (default: this build's)")
    ap.add_argument("--busy", type=int, default=os.cpu_count() or 2,
                    help="spinning threads beside each run (default: one per core)")
    ap.add_argument("--spinner", choices=["python", "yes"], default="python",
                    help="what keeps the cores busy (default: Python loops)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=600,
                    help="seconds after which a run is killed and counted as that long")
    ap.add_argument("--json", default=str(ROOT / "bench/results/busy_machine.json"))
    args = ap.parse_args()
    default_bench = str(ROOT / "build/server/cmd/actopo-bench")
    benches = dict(b.split("=", 1) for b in args.bench)
    configs = [c.split("=", 1) for c in args.config]

    print(f"{args.busy} {args.spinner} spinners beside each run; medians (min-max) of "
          f"{args.runs}\n")
    print("| mesh | workload | configuration | wall s | peak MiB | consumer wait s | "
          "waits abandoned |")
    print("|---|---|---|---|---|---|---|", flush=True)
    spinners, stop = start_busy(args.spinner, args.busy)
    cases = []
    try:
        for spec in args.mesh:
            path, field = spec.rsplit(":", 1)
            for workload in args.workloads.split(","):
                case = {"mesh": Path(path).name, "workload": workload,
                        "runs": {label: [] for label, _ in configs}}
                for i in range(args.runs):
                    for label, flags in configs:
                        cmd = [benches.get(label, default_bench), "--mesh", path, "--scalar",
                               field, "--algorithm", workload, "--json", *shlex.split(flags)]
                        case["runs"][label].append(timed(cmd, args.timeout))
                    print(f"{case['mesh']} {workload}: run {i + 1}/{args.runs}", file=sys.stderr)
                results = {json.dumps(r["result"], sort_keys=True)
                           for runs in case["runs"].values() for r in runs
                           if r["result"] is not None}
                if len(results) != 1:
                    sys.exit(f"{case['mesh']} {workload}: the configurations' results differ")
                cases.append(case)
                print_case(case)
                Path(args.json).parent.mkdir(parents=True, exist_ok=True)
                Path(args.json).write_text(json.dumps(
                    {"busy": args.busy, "spinner": args.spinner, "cases": cases}, indent=1))
    finally:
        stop_busy(spinners, stop)



if __name__ == "__main__":
    main()
