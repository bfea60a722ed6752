#!/usr/bin/env python3
"""What a server holds for a loaded mesh: its load's peak, its resident size once loaded, with
sessions open and after a job (Morse-Smale unless --job says); server builds in turn, medians
of the runs.

    .venv/bin/python bench/service_mesh_memory.py --data-dir /data --mesh wavelet128.vtu \\
        --scalar RTData --runs 3 --server old=/tmp/old/actopo-server \\
        --server new=build/server/cmd/actopo-server

Each run starts every server in turn (A B A B ...) on a free port and, through the Python
client: loads the mesh (timed; then the server's peak RSS is the load's, VmHWM), opens
`--sessions` actopo sessions (timed together), runs the job on the first with its arrays (timed
until the last array arrived) and reads the peak again; `total_s` is what the client waited
for in all. RSS is read from /proc, so the servers must
run on this machine.
"""
from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import time
from pathlib import Path

import actopo

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ["load_s", "load_peak_mib", "loaded_mib", "sessions_mib", "open_s", "job_s",
           "job_peak_mib", "total_s"]


def status_mib(pid: int, key: str) -> float:
    with open(f"/proc/{pid}/status") as f:
        match = re.search(rf"^{key}:\s+(\d+) kB", f.read(), re.MULTILINE)
    assert match, key
    return int(match.group(1)) / 1024


def start_server(binary: str, data_dir: str) -> tuple[subprocess.Popen[str], str]:
    reader = ROOT / "build/server/cmd/actopo-read-mesh"
    server = subprocess.Popen([binary, "--port", "0", "--data-dir", data_dir,
                               "--mesh-reader", str(reader)],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert server.stdout is not None
    for line in server.stdout:
        if match := re.search(r"listening on \S*:(\d+)", line):
            return server, f"127.0.0.1:{match.group(1)}"
    raise RuntimeError(f"{binary} exited before listening")


def measure(binary: str, args: argparse.Namespace) -> dict[str, float]:
    server, target = start_server(binary, args.data_dir)
    try:
        with actopo.Client(target) as client:
            start = time.perf_counter()
            mesh = client.load_mesh(args.mesh)
            figures = {"load_s": time.perf_counter() - start,
                       "load_peak_mib": status_mib(server.pid, "VmHWM"),
                       "loaded_mib": status_mib(server.pid, "VmRSS")}
            start = time.perf_counter()
            sessions = [client.open_session(mesh, scalar=args.scalar, structure="actopo")
                        for _ in range(args.sessions)]
            figures["open_s"] = time.perf_counter() - start
            figures["sessions_mib"] = status_mib(server.pid, "VmRSS")
            start = time.perf_counter()
            sessions[0].run(args.job)  # with its arrays, as a client gets them by default
            figures["job_s"] = time.perf_counter() - start
            figures["total_s"] = figures["load_s"] + figures["open_s"] + figures["job_s"]
            figures["job_peak_mib"] = status_mib(server.pid, "VmHWM")
            for session in sessions:
                session.close()
        return figures
    finally:
        server.terminate()
        server.wait()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data-dir", required=True, help="the servers' --data-dir")
    p.add_argument("--mesh", required=True, help="a file under the data directory")
    p.add_argument("--scalar", default=None, help="the sessions' scalar field")
    p.add_argument("--server", action="append", required=True,
                   help="NAME=PATH of an actopo-server binary (several: run in turn)")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--sessions", type=int, default=2)
    p.add_argument("--job", default="morse-smale", help="the algorithm the first session runs")
    args = p.parse_args()
    servers = dict(s.split("=", 1) for s in args.server)
    runs: dict[str, list[dict[str, float]]] = {name: [] for name in servers}
    for _ in range(args.runs):
        for name, binary in servers.items():
            runs[name].append(measure(binary, args))
    print("| server | " + " | ".join(FIGURES) + " |")
    print("|---" * (len(FIGURES) + 1) + "|")
    for name, figures in runs.items():
        cells = []
        for key in FIGURES:
            values = [f[key] for f in figures]
            cells.append(f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})")
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
