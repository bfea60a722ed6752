#!/usr/bin/env python3
"""A session's first job with its result arrays, as a client runs it by default: how long it
takes beyond the algorithm's run. Server builds in turn, medians of the runs.

    .venv/bin/python bench/first_job_arrays.py --data-dir /tmp/meshes \\
        --mesh wavelet128.vtu --mesh part_5M.vtu --algorithm critical-points \\
        --algorithm discrete-gradient --runs 3 \\
        --server old=/tmp/old/build/server/cmd/actopo-server \\
        --server new=build/server/cmd/actopo-server

Each run starts every server in turn (A B A B ...) and, per mesh: loads it, runs each
algorithm once on a first session without arrays (so the mesh's faces are built and not timed
below), then opens a new actopo session per algorithm and runs it with its arrays. `job_s`: the
client's wait for that job; `run_s`: the server's run; `beyond_run_s`: the difference, the
result arrays' building and sending. With --trace the jobs are traced (which slows their run)
and `outputs_s` is the server's span `outputs`, the arrays built before the first is sent, and
`results_s` its span `results`, which also covers sending them at the client's pace.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time

from service_mesh_memory import start_server

import actopo

FIGURES = ["job_s", "run_s", "beyond_run_s"]
TRACED = ["outputs_s", "results_s"]


def span_seconds(trace: bytes, name: str) -> float | None:
    """The duration of the job's span `name` (category phase) in seconds; None when the
    server records no such span."""
    spans = [e["dur"] for e in json.loads(trace)["traceEvents"]
             if e.get("name") == name and e.get("cat") == "phase" and "dur" in e]
    return sum(spans) / 1e6 if spans else None


def measure(binary: str, args: argparse.Namespace) -> dict[tuple[str, str], dict[str, float]]:
    server, target = start_server(binary, args.data_dir)
    out: dict[tuple[str, str], dict[str, float]] = {}
    try:
        with actopo.Client(target) as client:
            for name in args.mesh:
                mesh = client.load_mesh(name)
                with client.open_session(mesh, structure="actopo") as warm:
                    for algorithm in args.algorithm:
                        warm.run(algorithm, include_arrays=False)
                for algorithm in args.algorithm:
                    with client.open_session(mesh, structure="actopo") as session:
                        start = time.perf_counter()
                        result = session.run(algorithm, trace=args.trace)
                        job_s = time.perf_counter() - start
                    assert result.stats is not None
                    out[name, algorithm] = {"job_s": job_s, "run_s": result.stats.run_seconds,
                                            "beyond_run_s": job_s - result.stats.run_seconds}
                    if args.trace:
                        assert result.trace is not None
                        for k in TRACED:
                            if (seconds := span_seconds(result.trace, k[:-2])) is not None:
                                out[name, algorithm][k] = seconds
                client.delete_mesh(mesh)
        return out
    finally:
        server.terminate()
        server.wait()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data-dir", required=True)
    p.add_argument("--mesh", action="append", required=True)
    p.add_argument("--algorithm", action="append", required=True)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--server", action="append", required=True, metavar="NAME=BINARY")
    p.add_argument("--trace", action="store_true",
                   help="trace the jobs; adds outputs_s and results_s (see above)")
    args = p.parse_args()
    figures_shown = FIGURES + (TRACED if args.trace else [])
    servers = dict(s.split("=", 1) for s in args.server)
    runs: dict[str, list[dict[tuple[str, str], dict[str, float]]]] = {n: [] for n in servers}
    for run in range(args.runs):
        for name, binary in servers.items():
            figures = measure(binary, args)
            runs[name].append(figures)
            for (mesh, algorithm), f in figures.items():
                print(f"run {run + 1} {name} {mesh} {algorithm}: " +
                      ", ".join(f"{k} {f[k]:.3f}" for k in figures_shown if k in f),
                      flush=True)
    print("\nmedians (min-max) over", args.runs, "runs")
    for mesh in args.mesh:
        for algorithm in args.algorithm:
            for name in servers:
                cells = []
                for k in figures_shown:
                    if k not in runs[name][0][mesh, algorithm]:
                        continue  # a server without the span
                    values = [r[mesh, algorithm][k] for r in runs[name]]
                    cells.append(f"{k} {statistics.median(values):.3f} "
                                 f"({min(values):.3f}-{max(values):.3f})")
                print(f"{mesh} {algorithm} {name}: " + ", ".join(cells))


if __name__ == "__main__":
    main()
