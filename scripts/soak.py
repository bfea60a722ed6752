"""Soak test: many clients doing everything at once against one actopo-server for a while.

    python scripts/soak.py --build build --seconds 600 --clients 16 [--json FILE]

Starts its own actopo-server (so it can watch the process), then runs `--clients` threads, each
with its own channel, repeating a random mix: upload a small mesh, load a sample or a shared
data file, open a session (any structure), unary, batched and streamed relation queries, a job
to its end, a job cancelled mid-way (by CancelJob or by closing the session), asking for what
does not exist, closing and deleting. Every call's status code is checked against what that
step may return; anything else is an unexpected code.

Every second it samples the server's resident memory, threads and open file descriptors. It
passes (exit 0) when there were no unexpected codes, the server is alive and answering, RSS did
not drift (the median of the last quarter of the run within --rss-tolerance of the median of the
second quarter, the first being warm-up; single samples swing with what the clients hold at
that moment), threads and descriptors did not grow once idle, and SIGTERM ends it with 0. It prints the figures (and writes them as JSON).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import random
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import grpc
import numpy as np

import actopo

HERE = Path(__file__).resolve().parent.parent
SAMPLES = ["jittered:6", "jittered:10", "jittered:14", "wavelet:12"]
FILES = ["fertility_tet.vtu", "casting_tet.vtu", "manifoldCheck0_tet.vtu"]
STRUCTURES = ["explicit", "compact", "actopo"]
ALGORITHMS = ["critical-points", "discrete-gradient", "topo-relations"]
# What a step may legitimately end with besides OK: a cancelled job, limits under load.
ALLOWED = {
    "job-cancelled": {"CANCELLED"},
    "missing": {"NOT_FOUND"},
    "bad-id": {"OUT_OF_RANGE"},
}
UNDER_LOAD = {"RESOURCE_EXHAUSTED"}  # budget, sessions, threads: refused cleanly, retried later


def lattice(n: int, shift: float) -> tuple[np.ndarray, np.ndarray]:
    """An n^3 point lattice, each cube split into the 6 tetrahedra around its main diagonal."""
    ijk = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    points = ijk.astype(float) + shift
    base = np.stack(np.meshgrid(*[np.arange(n - 1)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    index = lambda c: (c[:, 0] * n + c[:, 1]) * n + c[:, 2]  # noqa: E731
    axes = np.eye(3, dtype=int)
    tets = []
    for a, b in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]:
        first = base + axes[a]
        tets.append(np.stack([index(base), index(first), index(first + axes[b]),
                              index(base + 1)], axis=1))
    return points, np.concatenate(tets)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """actopo-server as a child process, with /proc readings."""

    def __init__(self, build: Path, data_dir: Path) -> None:
        self.port = free_port()
        binary = build / "server" / "cmd" / "actopo-server"
        self.process = subprocess.Popen(
            [str(binary), "--port", str(self.port), "--host", "127.0.0.1",
             "--data-dir", str(data_dir), "--session-idle-timeout-s", "30"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.target = f"127.0.0.1:{self.port}"
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            try:
                actopo.Client(self.target).server_info()
                return
            except actopo.ActopoError:
                time.sleep(0.1)
        raise RuntimeError("actopo-server did not start")

    def sample(self) -> dict[str, int]:
        pid = self.process.pid
        status = Path(f"/proc/{pid}/status").read_text()
        field = lambda name: int(status.split(f"{name}:")[1].split()[0])  # noqa: E731
        return {"rss_kib": field("VmRSS"), "threads": field("Threads"),
                "fds": len(os.listdir(f"/proc/{pid}/fd"))}

    def stop(self) -> int:
        self.process.terminate()
        try:
            return self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            return -9


class Tally:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.calls: collections.Counter[str] = collections.Counter()
        self.codes: collections.Counter[tuple[str, str]] = collections.Counter()
        self.unexpected: list[str] = []

    def record(self, step: str, code: str, allowed: set[str], detail: str = "") -> None:
        with self.lock:
            self.calls[step] += 1
            self.codes[(step, code)] += 1
            if code != "OK" and code not in allowed and code not in UNDER_LOAD:
                if len(self.unexpected) < 50:
                    self.unexpected.append(f"{step}: {code}: {detail}")


def code_of(error: BaseException) -> str:
    code = getattr(error, "code", None)
    if isinstance(code, grpc.StatusCode):
        return code.name
    return type(error).__name__


class Client:
    """One soak client: a channel of its own and a random mix of steps."""

    def __init__(self, target: str, index: int, tally: Tally, stop: threading.Event) -> None:
        self.client = actopo.Client(target)
        self.rng = random.Random(index)
        self.tally = tally
        self.stop = stop

    def step(self, name: str, fn: Any, allowed: set[str] | None = None) -> Any:
        try:
            result = fn()
        except actopo.ActopoError as e:
            self.tally.record(name, code_of(e), allowed or set(), str(e))
            return None
        self.tally.record(name, "OK", set())
        return result

    def mesh(self) -> Any:
        choice = self.rng.random()
        if choice < 0.3:
            points, tets = lattice(self.rng.randint(4, 9), self.rng.random() * 0.01)
            field = points[:, 2] + 0.001 * np.arange(len(points))
            return self.step("upload",
                             lambda: self.client.upload_mesh((points, tets, {"h": field})))
        if choice < 0.6:
            return self.step("load-file", lambda: self.client.load_mesh(self.rng.choice(FILES)))
        return self.step("load-sample",
                         lambda: self.client.sample(self.rng.choice(SAMPLES), block_size=200))

    def session_work(self, mesh: Any) -> None:
        structure = self.rng.choice(STRUCTURES)
        session = self.step("open", lambda: self.client.open_session(mesh, structure=structure))
        if session is None:
            return
        n = mesh.vertices
        for _ in range(self.rng.randint(1, 5)):
            work = self.rng.random()
            if work < 0.25:
                self.step("unary", lambda: session.query("vertex_star", self.rng.randrange(n)))
            elif work < 0.45:
                ids = np.array([self.rng.randrange(n) for _ in range(200)])
                self.step("batch", lambda: session.relation("vertex_edges", ids))
            elif work < 0.6:
                self.step("stream", lambda: list(session.relation_batches(
                    "vertex_star", [np.arange(n)] * 3, chunk_size=max(n // 4, 1))))
            elif work < 0.7:
                self.step("bad-id", lambda: session.query("vertex_star", n + 5),
                          ALLOWED["bad-id"])
            elif work < 0.85:
                algorithm = self.rng.choice(ALGORITHMS)
                self.step("job", lambda: session.run(algorithm))
            elif self.cancelled_job(session):
                return
        if self.rng.random() < 0.5:
            self.step("stats", session.stats)
        self.step("close", session.close)

    def cancelled_job(self, session: Any) -> bool:
        """A job stopped mid-way by CancelJob or by closing its session; True if closed."""
        job = self.step("job-start", lambda: session.submit("morse-smale"))
        if job is None:
            return False
        closing = self.rng.random() < 0.3
        if closing:
            self.step("close-running", session.close)
        else:
            self.step("cancel", job.cancel, ALLOWED["missing"])  # it may have just ended
        self.step("job-cancelled", job.result, ALLOWED["job-cancelled"])
        return closing

    def run(self) -> None:
        while not self.stop.is_set():
            self.step("missing", lambda: self.client.get_mesh("mesh-0000"), ALLOWED["missing"])
            mesh = self.mesh()
            if mesh is None:
                time.sleep(0.05)
                continue
            for _ in range(self.rng.randint(1, 3)):
                self.session_work(mesh)
            self.step("delete", lambda: self.client.delete_mesh(mesh))
        self.client.close()


def wait_idle(server: Server, warm: dict[str, int], seconds: float = 60) -> dict[str, int]:
    """The server's figures once it is idle: it lists no mesh or session and its threads and
    descriptors are back to the warm-up's counts. Stops waiting after `seconds` (a hang bound,
    not a measure): the checks then report what was left."""
    client = actopo.Client(server.target)
    give_up = time.monotonic() + seconds
    while True:
        sample = server.sample()
        idle = not client.list_meshes() and not client.list_sessions()
        settled = sample["threads"] <= warm["threads"] and sample["fds"] <= warm["fds"] + 1
        if (idle and settled) or time.monotonic() > give_up:
            client.close()
            return server.sample()  # without this client's channel
        time.sleep(0.1)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--build", type=Path, default=HERE / "build")
    p.add_argument("--data-dir", type=Path,
                   default=Path(os.environ.get("ACTOPO_DATA_DIR", HERE.parent / "shared/data")))
    p.add_argument("--seconds", type=float, default=600)
    p.add_argument("--clients", type=int, default=16)
    p.add_argument("--rss-tolerance", type=float, default=0.05,
                   help="RSS growth allowed after the warm-up, as a fraction (default 0.05)")
    p.add_argument("--json", type=Path, help="also write the figures here")
    args = p.parse_args()

    server = Server(args.build, args.data_dir)
    tally = Tally()
    stop = threading.Event()
    samples: list[dict[str, Any]] = []
    start = time.monotonic()
    clients = [Client(server.target, i, tally, stop) for i in range(args.clients)]
    threads = [threading.Thread(target=c.run, daemon=True) for c in clients]
    for t in threads:
        t.start()
    while time.monotonic() - start < args.seconds:
        time.sleep(1)
        samples.append({"t": round(time.monotonic() - start, 1), **server.sample()})
        if len(samples) % 30 == 0:
            s = samples[-1]
            print(f"soak: {s['t']:.0f} s, {sum(tally.calls.values())} calls, "
                  f"rss {s['rss_kib'] >> 10} MiB, {s['threads']} threads, {s['fds']} fds",
                  file=sys.stderr, flush=True)
    stop.set()
    for t in threads:
        t.join(timeout=120)
    alive = server.process.poll() is None
    answering = alive and actopo.Client(server.target).server_info() is not None
    quarter = max(len(samples) // 4, 1)
    warm = samples[quarter] if len(samples) > quarter else server.sample()
    final = wait_idle(server, warm) if answering else server.sample()
    exit_code = server.stop()

    after = samples[quarter:] or [final]
    median = lambda xs: sorted(xs)[len(xs) // 2] if xs else final["rss_kib"]  # noqa: E731
    rss_second = median([s["rss_kib"] for s in samples[quarter:2 * quarter]])
    rss_last = median([s["rss_kib"] for s in samples[3 * quarter:]])
    rss_max = max(s["rss_kib"] for s in after)
    figures = {
        "seconds": args.seconds, "clients": args.clients,
        "calls": sum(tally.calls.values()), "calls_by_step": dict(tally.calls),
        "codes": {f"{step} {code}": n for (step, code), n in sorted(tally.codes.items())},
        "unexpected": tally.unexpected,
        "rss_mib": {"start": samples[0]["rss_kib"] >> 10 if samples else 0,
                    "warm": warm["rss_kib"] >> 10, "max_after_warm": rss_max >> 10,
                    "median_second_quarter": rss_second >> 10,
                    "median_last_quarter": rss_last >> 10,
                    "end": samples[-1]["rss_kib"] >> 10 if samples else 0,
                    "idle": final["rss_kib"] >> 10},
        "threads": {"warm": warm["threads"], "max_after_warm": max(s["threads"] for s in after),
                    "idle": final["threads"]},
        "fds": {"warm": warm["fds"], "max_after_warm": max(s["fds"] for s in after),
                "idle": final["fds"]},
        "server_exit": exit_code,
    }
    problems = []
    if tally.unexpected:
        problems.append(f"{len(tally.unexpected)}+ unexpected status codes")
    if not answering:
        problems.append("the server stopped answering")
    if rss_last > rss_second * (1 + args.rss_tolerance):
        problems.append(f"RSS drifted: median {rss_second >> 10} MiB in the second quarter, "
                        f"{rss_last >> 10} MiB in the last")
    if final["threads"] > warm["threads"]:
        problems.append(f"threads grew: {warm['threads']} -> {final['threads']} (idle)")
    if final["fds"] > warm["fds"]:
        problems.append(f"file descriptors grew: {warm['fds']} -> {final['fds']} (idle)")
    if exit_code != 0:
        problems.append(f"the server exited with {exit_code} on SIGTERM")
    figures["problems"] = problems
    print(json.dumps(figures, indent=1))
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
