"""Resident memory of a running actopo-server across load / session / close / delete cycles.

    actopo-server --port 50051 --metrics-port 9464 &
    python bench/service_rss_cycles.py --server 127.0.0.1:50051 --metrics-port 9464 \
        --pid $(pgrep -f 'actopo-server --port 50051') --cycles 3

Each cycle loads the sample, opens one session per structure, streams every vertex star (or
runs a job with --job), closes the session, deletes the mesh, and prints the server's RSS and
its memory-budget gauge after each step. The budget must come back to 0; RSS shows what the
allocator keeps.
"""

from __future__ import annotations

import argparse
import time
import urllib.request

import numpy as np

import actopo


def rss_mib(pid: int) -> int:
    with open(f"/proc/{pid}/status") as f:
        return int(f.read().split("VmRSS:")[1].split()[0]) // 1024


def budget_used(metrics_port: int) -> int:
    text = urllib.request.urlopen(f"http://127.0.0.1:{metrics_port}/metrics").read().decode()
    for line in text.splitlines():
        if line.startswith("actopo_memory_budget_used_bytes"):
            return int(float(line.split()[-1]))
    return -1


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--server", required=True)
    p.add_argument("--metrics-port", type=int, required=True)
    p.add_argument("--pid", type=int, required=True)
    p.add_argument("--sample", default="wavelet:80")
    p.add_argument("--structures", default="actopo,compact,explicit")
    p.add_argument("--cycles", type=int, default=3)
    p.add_argument("--job", action="store_true", help="run critical points instead of streaming")
    args = p.parse_args()
    client = actopo.Client(args.server)

    def report(step: str) -> None:
        time.sleep(0.3)  # the server frees after answering
        print(f"{step:32s} rss {rss_mib(args.pid):5d} MiB  budget used "
              f"{budget_used(args.metrics_port) >> 20} MiB", flush=True)

    report("start")
    for cycle in range(args.cycles):
        mesh = client.sample(args.sample)
        report(f"cycle {cycle}: loaded")
        for structure in args.structures.split(","):
            session = client.open_session(mesh, structure=structure)
            if args.job:
                session.run("critical-points")
            else:
                list(session.relation_batches("vertex_star", [np.arange(mesh.vertices)]))
            session.close()
            report(f"cycle {cycle}: {structure} closed")
        client.delete_mesh(mesh)
        report(f"cycle {cycle}: mesh deleted")


if __name__ == "__main__":
    main()
