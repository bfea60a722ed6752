"""Soak test: many clients doing everything at once against one actopo-server for a while.

    python scripts/soak.py --build build --seconds 600 --clients 16 [--json FILE]

Starts its own actopo-server (so it can watch the process), then runs `--clients` threads, each
with its own channel, repeating a random mix: upload a small mesh, upload a shared data file as
its bytes (sometimes cut half-way and resumed from what the server holds), load a sample or a
shared data file, open a session (any structure), unary, batched and streamed relation queries, a job
to its end, a job cancelled mid-way (by CancelJob or by closing the session), asking for what
does not exist, closing and deleting. Every call's status code is checked against what that
step may return; anything else is an unexpected code.

The run has --rounds parts (2 by default). After each, the clients stop and the server is left
to go idle: no mesh, no session. Every second it samples the server's resident memory, threads
and open file descriptors, and at each idle point what the server has allocated and not freed
(its actopo_process_heap_bytes gauge; the server runs with glibc's per-thread caches off, so that
figure is exact). It passes (exit 0) when there were no unexpected codes, the server is alive and
answering, its idle heap after the last round is within --heap-tolerance (plus 256 KiB) of its
idle heap after the first (the warm-up), threads and descriptors did not grow once idle, and
SIGTERM ends it with 0. It prints the figures (and writes them as JSON).

Resident memory is reported, not checked: under load it swings with what the clients hold at
that moment, and at idle it moves with the allocator's caches and fragmentation. The heap figure
does not: a leak, or a thread that keeps what a job made it allocate, shows in it (the second is
how this check found the engine's consumers keeping their block scratch in the server's pools).
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import random
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

import grpc
import numpy as np

import actopo
from actopo._proto import pb

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
        self.metrics_port = free_port()
        binary = build / "server" / "cmd" / "actopo-server"
        self.process = subprocess.Popen(
            [str(binary), "--port", str(self.port), "--host", "127.0.0.1",
             "--data-dir", str(data_dir), "--session-idle-timeout-s", "30",
             "--metrics-port", str(self.metrics_port)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            env={**os.environ, "GLIBC_TUNABLES": "glibc.malloc.tcache_count=0"})
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

    def heap_kib(self) -> int:
        """What the server has allocated and not freed (its actopo_process_heap_bytes gauge)."""
        url = f"http://127.0.0.1:{self.metrics_port}/metrics"
        with urllib.request.urlopen(url, timeout=10) as response:
            for line in response.read().decode().splitlines():
                if line.startswith("actopo_process_heap_bytes "):
                    return int(float(line.split()[1])) >> 10
        raise RuntimeError("actopo_process_heap_bytes is not in the server's metrics")

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

    def __init__(self, target: str, index: int, tally: Tally, stop: threading.Event,
                 data_dir: Path) -> None:
        self.client = actopo.Client(target)
        self.data_dir = data_dir
        self.rng = random.Random(index)
        self.tally = tally
        self.stop = stop

    def step(self, name: str, fn: Any, allowed: set[str] | None = None) -> Any:
        try:
            result = fn()
        except (actopo.ActopoError, grpc.RpcError) as e:
            self.tally.record(name, code_of(e), allowed or set(), str(e))
            return None
        self.tally.record(name, "OK", set())
        return result

    def mesh(self) -> Any:
        choice = self.rng.random()
        if choice < 0.15:
            path = self.data_dir / self.rng.choice(FILES)
            return self.step("upload-file", lambda: self.client.upload_file(path))
        if choice < 0.2:
            return self.resumed_upload(self.data_dir / self.rng.choice(FILES))
        if choice < 0.35:
            points, tets = lattice(self.rng.randint(4, 9), self.rng.random() * 0.01)
            field = points[:, 2] + 0.001 * np.arange(len(points))
            return self.step("upload",
                             lambda: self.client.upload_mesh((points, tets, {"h": field})))
        if choice < 0.65:
            return self.step("load-file", lambda: self.client.load_mesh(self.rng.choice(FILES)))
        return self.step("load-sample",
                         lambda: self.client.sample(self.rng.choice(SAMPLES), block_size=200))

    def resumed_upload(self, path: Path) -> Any:
        """A file's upload whose first stream is cut half-way, resumed from what the server holds
        (GetUpload), then loaded; through the service's calls, as a client library makes them."""
        data = path.read_bytes()
        stub = self.client._stub
        info = pb.UploadFileInfo(path=path.name, size=len(data),
                                 sha256=hashlib.sha256(data).hexdigest())
        created = self.step("upload-create",
                            lambda: stub.CreateUpload(pb.CreateUploadRequest(files=[info])))
        if created is None:
            return None
        upload_id = created.upload.upload_id
        chunk = 64 << 10

        def chunks(offset: int, end: int) -> Any:
            yield pb.WriteUploadRequest(start=pb.WriteUploadStart(upload_id=upload_id,
                                                                  offset=offset))
            for at in range(offset, end, chunk):
                yield pb.WriteUploadRequest(chunk=data[at:min(at + chunk, end)])

        # The first stream is cancelled once half the bytes are sent: the server keeps what came.
        sent_half, cut = threading.Event(), threading.Event()

        def first() -> Any:
            yield from chunks(0, len(data) // 2)
            sent_half.set()
            cut.wait(60)  # a stalled connection, until the cancel

        call = stub.WriteUpload.future(first())
        sent_half.wait(60)
        call.cancel()
        cut.set()
        self.tally.record("upload-cut", "CANCELLED" if call.cancelled() else "NOT_CANCELLED",
                          {"CANCELLED"})
        held = self.step("upload-get",
                         lambda: stub.GetUpload(pb.GetUploadRequest(upload_id=upload_id)))
        if held is None:
            return None
        offset = held.upload.received_bytes[0]
        if self.step("upload-resume",
                     lambda: stub.WriteUpload(chunks(offset, len(data)))) is None:
            return None
        loaded = self.step("upload-load", lambda: stub.LoadMesh(
            pb.LoadMeshRequest(upload=upload_id)))
        return None if loaded is None else self.client.get_mesh(loaded.mesh.mesh_id)

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
    """The server's figures once it is idle: it lists no mesh or session, and its threads and
    descriptors are back to `warm`'s counts. Stops waiting after `seconds` (a hang bound, not a
    measure): the checks then report what was left."""
    give_up = time.monotonic() + seconds
    client = actopo.Client(server.target)
    while (client.list_meshes() or client.list_sessions()) and time.monotonic() < give_up:
        time.sleep(0.1)
    client.close()  # its connection must be gone too before the descriptors are counted
    while True:
        sample = server.sample()
        settled = sample["threads"] <= warm["threads"] and sample["fds"] <= warm["fds"]
        if settled or time.monotonic() > give_up:
            return {**sample, "heap_kib": server.heap_kib()}
        time.sleep(0.1)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--build", type=Path, default=HERE / "build")
    p.add_argument("--data-dir", type=Path,
                   default=Path(os.environ.get("ACTOPO_DATA_DIR", HERE.parent / "shared/data")))
    p.add_argument("--seconds", type=float, default=600)
    p.add_argument("--clients", type=int, default=16)
    p.add_argument("--heap-tolerance", type=float, default=0.05,
                   help="idle heap growth allowed from the first round to the last, as a fraction "
                        "(default 0.05; plus 256 KiB)")
    p.add_argument("--rounds", type=int, default=2,
                   help="parts of the run, each ended by an idle point (default 2)")
    p.add_argument("--json", type=Path, help="also write the figures here")
    args = p.parse_args()

    server = Server(args.build, args.data_dir)
    tally = Tally()
    samples: list[dict[str, Any]] = []
    start = time.monotonic()

    def run_round(index: int, until: float, baseline: dict[str, int] | None) -> dict[str, int]:
        """Clients (seeded per round) until `until` seconds; then the server's idle figures, once
        its threads and descriptors are back to `baseline`'s (the round's middle if None)."""
        stop = threading.Event()
        clients = [Client(server.target, index * args.clients + i, tally, stop, args.data_dir)
                   for i in range(args.clients)]
        threads = [threading.Thread(target=c.run, daemon=True) for c in clients]
        for t in threads:
            t.start()
        while time.monotonic() - start < until:
            time.sleep(1)
            samples.append({"t": round(time.monotonic() - start, 1), "round": index,
                            **server.sample()})
            if len(samples) % 30 == 0:
                s = samples[-1]
                print(f"soak: {s['t']:.0f} s, {sum(tally.calls.values())} calls, "
                      f"rss {s['rss_kib'] >> 10} MiB, {s['threads']} threads, {s['fds']} fds",
                      file=sys.stderr, flush=True)
        stop.set()
        for t in threads:
            t.join(timeout=120)
        if server.process.poll() is not None:
            return {"rss_kib": 0, "threads": 0, "fds": 0, "heap_kib": 0}
        loaded = [s for s in samples if s["round"] == index]
        middle = loaded[len(loaded) // 2] if loaded else server.sample()
        return wait_idle(server, baseline or middle)

    rounds = [run_round(0, args.seconds / args.rounds, None)]
    for r in range(1, args.rounds):
        if server.process.poll() is not None:
            break
        rounds.append(run_round(r, args.seconds * (r + 1) / args.rounds, rounds[0]))
    warm, final = rounds[0], rounds[-1]
    alive = server.process.poll() is None
    answering = alive and actopo.Client(server.target).server_info() is not None
    exit_code = server.stop()

    after = [s for s in samples if s["round"] > 0] or [final]
    median = lambda xs: sorted(xs)[len(xs) // 2] if xs else final["rss_kib"]  # noqa: E731
    heap_allowed = int(warm["heap_kib"] * (1 + args.heap_tolerance)) + 256
    figures = {
        "seconds": args.seconds, "clients": args.clients,
        "calls": sum(tally.calls.values()), "calls_by_step": dict(tally.calls),
        "codes": {f"{step} {code}": n for (step, code), n in sorted(tally.codes.items())},
        "unexpected": tally.unexpected,
        "heap_kib_idle": [r["heap_kib"] for r in rounds],
        "rss_mib": {"median_loaded": [median([s["rss_kib"] for s in samples if s["round"] == i])
                                      >> 10 for i in range(len(rounds))],
                    "max_loaded": max(s["rss_kib"] for s in samples) >> 10 if samples else 0,
                    "idle": [r["rss_kib"] >> 10 for r in rounds]},
        "threads": {"idle_after_warm_up": warm["threads"],
                    "max_loaded_after_warm_up": max(s["threads"] for s in after),
                    "idle": final["threads"]},
        "fds": {"idle_after_warm_up": warm["fds"],
                "max_loaded_after_warm_up": max(s["fds"] for s in after), "idle": final["fds"]},
        "server_exit": exit_code,
    }
    problems = []
    if tally.unexpected:
        problems.append(f"{len(tally.unexpected)}+ unexpected status codes")
    if not answering:
        problems.append("the server stopped answering")
    if final["heap_kib"] > heap_allowed:
        problems.append(f"idle heap grew: {warm['heap_kib']} KiB after the warm-up, "
                        f"{final['heap_kib']} KiB after the last round")
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
