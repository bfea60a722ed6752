#!/usr/bin/env python3
"""Two actopo-server builds under the same `actopo bench` load, in turn: is B slower than A?

Starts server A, runs `actopo bench` against it, stops it, does the same for B, and repeats
`--runs` times (A, B, A, B, ...), so the machine's drift falls on both. Prints, per structure,
mode and client count, the median over the runs of A and of B and their ratio, for simplices/s
(jobs/s for jobs), p50 and p99 latency.

    python3 bench/servers_ab.py --a /tmp/before/build --b build --runs 3 \\
        --sample wavelet:80 --structure actopo,explicit --modes unary,batch,stream,job \\
        --clients 1,8 --duration 3

Each build directory must hold server/cmd/actopo-server (and actopo-read-mesh beside it).
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent.parent
ACTOPO = HERE / ".venv" / "bin" / "actopo"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def bench_once(build: Path, bench_args: list[str]) -> list[dict[str, Any]]:
    """One server from `build`, one `actopo bench` run against it; the run's records."""
    port = free_port()
    server = subprocess.Popen(
        [str(build / "server/cmd/actopo-server"), "--port", str(port), "--host", "127.0.0.1"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(100):  # a hang bound for the start, not a measure
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.1)
        out = subprocess.run([str(ACTOPO), "bench", "--server", f"127.0.0.1:{port}", "--json",
                              *bench_args], check=True, capture_output=True, text=True).stdout
        return list(json.loads(out)["runs"])
    finally:
        server.terminate()
        server.wait(timeout=60)


def key(run: dict[str, Any]) -> tuple[str, str, int]:
    return (run["structure"], run["mode"], run["clients"])


def figures(run: dict[str, Any]) -> dict[str, float]:
    rate = run["requests_per_s"] if run["mode"] == "job" else run["simplices_per_s"]
    return {"rate": rate, "p50": run["latency_ms"]["p50"], "p99": run["latency_ms"]["p99"]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--a", type=Path, required=True, help="build directory of server A (before)")
    p.add_argument("--b", type=Path, required=True, help="build directory of server B (after)")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--json", type=Path, help="also write every record here")
    args, bench_args = p.parse_known_args()
    records: dict[str, list[list[dict[str, Any]]]] = {"a": [], "b": []}
    for i in range(args.runs):
        for name, build in (("a", args.a), ("b", args.b)):
            print(f"servers_ab: run {i + 1}/{args.runs}, {name} = {build}", file=sys.stderr)
            records[name].append(bench_once(build, bench_args))
    if args.json:
        args.json.write_text(json.dumps(records, indent=1))
    print("| structure | mode | clients | A rate | B rate | B/A | A p50 ms | B p50 ms | A p99 ms "
          "| B p99 ms |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    keys = [key(r) for r in records["a"][0]]
    for k in keys:
        med = {}
        for name in ("a", "b"):
            runs = [figures(r) for rec in records[name] for r in rec if key(r) == k]
            med[name] = {f: statistics.median(x[f] for x in runs) for f in ("rate", "p50", "p99")}
        a, b = med["a"], med["b"]
        print(f"| {k[0]} | {k[1]} | {k[2]} | {a['rate']:,.1f} | {b['rate']:,.1f} "
              f"| {b['rate'] / a['rate']:.2f} | {a['p50']:.3f} | {b['p50']:.3f} | {a['p99']:.3f} "
              f"| {b['p99']:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
