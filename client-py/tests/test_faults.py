"""Faults against a real actopo-server process: clients that vanish mid-call (kill -9), a burst
of cancels, SIGTERM during a job, SIGKILL and a restart on the same port.

Each test starts a server of its own. The job faulted is held at its start on the server
(--test-gate-dir) until the fault is in. Nothing is timed against a limit except liveness (a
process ends within 30 s, what a test waits for happens within a minute); what each fault took
is printed as one "FAULT ..." line (see with -s).
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import grpc
import numpy as np
import pytest
from harness import Hold, ServerProcess, free_port, server_process, start_server, wait_until

import actopo

LIVENESS_SECONDS = 30.0
STREAM_MESH = "jittered:40"
# morse-smale on compact runs for a few tenths of a second: held until the fault is in, the job
# is then cancelled long before it could end (a drain's cancel follows its NOT_SERVING at once).
JOB_MESH = "jittered:50"
THREAD_SLACK = 4

# A client that streams vertex_star over every vertex, again and again, on one StreamRelations
# call, printing a line per answered array. argv: target, session id, vertex count.
STREAM_CHILD = """
import sys
import numpy as np
import actopo

target, session_id, vertices = sys.argv[1], sys.argv[2], int(sys.argv[3])
ids = np.arange(vertices, dtype=np.int32)


def forever():
    while True:
        yield ids


with actopo.Client(target) as client:
    session = client.session(session_id)
    for n, batch in enumerate(session.relation_batches("vertex_star", forever()), 1):
        print(n, len(batch.values), flush=True)
"""

# A client that sends an UploadMesh header announcing about 1.5M tetrahedra and a few 1 MiB
# chunks, prints "sent", then waits without ending the call. argv: target, chunks to send.
UPLOAD_CHILD = """
import sys
import time
import grpc
import numpy as np
from actopo import _mesh, _requests, _upload
from actopo._proto import pb_grpc

target, chunks = sys.argv[1], int(sys.argv[2])
rng = np.random.default_rng(7)
vertices = 300_000
points = rng.random((vertices, 3))
tetrahedra = rng.integers(0, vertices, (1_500_000, 4), dtype=np.int32)
messages = _upload.requests(_mesh.mesh_arrays((points, tetrahedra), "vanishing"),
                            _requests.partition(0, ""))


def stalled():
    for n, message in enumerate(messages):
        yield message
        if n == chunks:
            print("sent", flush=True)
            time.sleep(3600)


stub = pb_grpc.TopologyServiceStub(grpc.insecure_channel(target))
stub.UploadMesh(stalled(), timeout=3600)
"""


def report(fault: str, **figures: Any) -> None:
    """One summary line per fault, for bench/RESULTS.md."""
    shown = ", ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}"
                      for k, v in figures.items())
    print(f"\nFAULT {fault}: {shown}")


@contextlib.contextmanager
def child_process(code: str, *args: str) -> Iterator[subprocess.Popen]:
    """A Python child running `code`; killed on the way out if the test did not kill it."""
    child = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        yield child
    finally:
        kill_child(child)


def child_lines(child: subprocess.Popen) -> Iterator[str]:
    """The child's stdout lines; fails with its stderr if it ends first."""
    assert child.stdout is not None
    yield from child.stdout
    stderr = child.stderr.read() if child.stderr else ""
    pytest.fail(f"the child ended ({child.wait()}) before the fault: {stderr}")


def kill_child(child: subprocess.Popen) -> None:
    """kill -9 (if still running), and reap it."""
    if child.poll() is None:
        child.kill()
    child.wait(timeout=LIVENESS_SECONDS)


def vertex_star_total(session: actopo.Session, vertices: int) -> int:
    """The values of vertex_star over all vertices, streamed in 4 arrays."""
    ids = np.arange(vertices, dtype=np.int32)
    return sum(len(b.values) for b in session.relation_batches("vertex_star",
                                                               np.array_split(ids, 4)))


def code_of(call: Callable[[], object]) -> grpc.StatusCode:
    """OK, or the code of the ActopoError that `call` raised."""
    try:
        call()
    except actopo.ActopoError as e:
        return e.code or grpc.StatusCode.UNKNOWN
    return grpc.StatusCode.OK


# a. A client killed in the middle of a relation stream.

def test_client_killed_mid_stream_leaves_the_session_usable():
    with server_process() as server, actopo.Client(server.target) as client:
        mesh = client.sample(STREAM_MESH)
        session = client.open_session(mesh, structure="compact", query_readers=2)
        expected = vertex_star_total(session, mesh.vertices)  # warms the readers too
        threads_before = server.threads()

        with child_process(STREAM_CHILD, server.target, session.session_id,
                           str(mesh.vertices)) as child:
            lines = child_lines(child)
            for _ in range(3):
                assert int(next(lines).split()[1]) == expected
            threads_streaming = server.threads()
            kill_child(child)
        killed = time.monotonic()

        assert client.server_info().algorithms
        assert vertex_star_total(session, mesh.vertices) == expected
        session.close()
        assert all(s.session_id != session.session_id for s in client.list_sessions())
        wait_until(lambda: server.threads() <= threads_before + THREAD_SLACK,
                   f"the server's threads ({threads_before} before the stream) to settle")
        threads_after = server.threads()
        report("client killed mid-stream", threads_before=threads_before,
               threads_streaming=threads_streaming, threads_after=threads_after,
               settle_s=time.monotonic() - killed)


# b. A client killed in the middle of an upload.

def test_client_killed_mid_upload_frees_the_budget():
    flags = ("--metrics-port", str(free_port()), "--memory-budget-mib", "2048")
    with server_process(*flags) as server, actopo.Client(server.target) as client:
        assert server.metric("actopo_memory_budget_used_bytes") == 0
        with child_process(UPLOAD_CHILD, server.target, "8") as child:
            assert next(child_lines(child)).strip() == "sent"
            reserved = wait_until(lambda: server.metric("actopo_memory_budget_used_bytes"),
                                  "the upload's header to reserve memory")
            assert reserved > 0, "the upload's header reserved nothing"
            kill_child(child)
        killed = time.monotonic()

        wait_until(lambda: server.metric("actopo_memory_budget_used_bytes") == 0,
                   "the upload's memory to be freed")
        freed_s = time.monotonic() - killed
        assert client.list_meshes() == []
        report("client killed mid-upload", reserved_mib=reserved / 2**20, freed_s=freed_s)


# c and d fault a job that the server holds at its start.

@pytest.fixture
def server_with_held_job(tmp_path) -> Iterator[tuple[ServerProcess, actopo.Client,
                                                     actopo.Session, actopo.Job, Hold]]:
    """A server of its own with a morse-smale job held at its start (it has its id, and the
    session runs it), and the hold, which the test releases once the fault is in."""
    with server_process("--grace-s", "5", gate_dir=tmp_path) as server, \
            actopo.Client(server.target) as client:
        mesh = client.sample(JOB_MESH)
        session = client.open_session(mesh, structure="compact")
        with server.hold("RunJob") as hold:
            job = session.submit("morse-smale", include_arrays=False)
            hold.wait_held()
            yield server, client, session, job, hold
        if server.process.poll() is None:
            session.close()


# c. 1000 CancelJob calls at once.

def test_a_burst_of_cancels(server_with_held_job):
    server, client, session, job, hold = server_with_held_job
    unknown = [f"job-{i:032x}" for i in range(500)]
    targets = [job.job_id if i % 2 == 0 else unknown[i // 2] for i in range(1000)]
    started = time.monotonic()
    with ThreadPoolExecutor(16) as pool:
        codes = Counter(pool.map(lambda job_id: code_of(lambda: client.cancel_job(job_id)),
                                 targets))
    burst_s = time.monotonic() - started
    # The job, held, is running for every cancel of its id; the unknown ids are not.
    assert codes == {grpc.StatusCode.OK: 500, grpc.StatusCode.NOT_FOUND: 500}, codes
    hold.release()
    with pytest.raises(actopo.CancelledError):
        job.result()
    assert client.server_info().algorithms
    result = session.run("morse-smale", include_arrays=False)
    assert result.summary["critical_cells"]
    report("1000 cancels", burst_s=burst_s, ok=codes[grpc.StatusCode.OK],
           not_found=codes[grpc.StatusCode.NOT_FOUND], threads=server.threads())


# d. SIGTERM while a job runs.

HEALTH_CHECK = "/grpc.health.v1.Health/Check"
HEALTH_WATCH = "/grpc.health.v1.Health/Watch"
HEALTH_STATUS = ("UNKNOWN", "SERVING", "NOT_SERVING", "SERVICE_UNKNOWN")


def health_status(response: bytes) -> str:
    """The status of a grpc.health.v1.HealthCheckResponse: field 1, a varint (absent: 0)."""
    return HEALTH_STATUS[response[1]] if response[:1] == b"\x08" else "UNKNOWN"


def health_check(channel: grpc.Channel) -> str:
    """Health/Check of the whole server (an empty HealthCheckRequest); the status, or the
    gRPC code's name when the call fails."""
    check = channel.unary_unary(HEALTH_CHECK)
    try:
        return health_status(check(b"", timeout=10))
    except grpc.RpcError as e:
        return e.code().name


def test_sigterm_during_a_job_drains_and_exits_0(server_with_held_job):
    server, _client, _session, job, hold = server_with_held_job
    with grpc.insecure_channel(server.target) as channel:
        assert health_check(channel) == "SERVING"
        watch = channel.unary_stream(HEALTH_WATCH)(b"", timeout=LIVENESS_SECONDS)
        statuses = map(health_status, watch)
        assert next(statuses) == "SERVING"

        server.signal(signal.SIGTERM)
        signalled = time.monotonic()
        watched = next(statuses)  # the drain has begun
        checked = health_check(channel)
        watch.cancel()
        hold.release()  # the job goes on, cancelled by the drain
        with pytest.raises((actopo.CancelledError, actopo.UnavailableError)) as ended:
            job.result()
        job_s = time.monotonic() - signalled
        code = server.process.wait(timeout=LIVENESS_SECONDS)
        exit_s = time.monotonic() - signalled
    assert watched == "NOT_SERVING"
    # A Check made once the drain has begun races the server's shutdown, which follows within
    # milliseconds: NOT_SERVING while draining, UNAVAILABLE once it stopped listening, and
    # CANCELLED when the call arrived as gRPC's shutdown began.
    assert checked in ("NOT_SERVING", "UNAVAILABLE", "CANCELLED")
    assert code == 0, "".join(server.stderr)
    report("SIGTERM during a job", job_end=f"{ended.value.code.name} ({ended.value.details})",
           job_end_s=job_s, exit_code=code, exit_s=exit_s, health_watch=watched,
           health_check=checked)


# e. SIGKILL, and a restart on the same port.

def kill_server(server: ServerProcess) -> None:
    server.process.kill()
    server.process.wait(timeout=LIVENESS_SECONDS)


def start_when(go: threading.Event, port: int, servers: list[ServerProcess]) -> threading.Thread:
    """A thread that starts a server on `port` once `go` is set, and adds it to `servers`."""
    def run() -> None:
        go.wait(LIVENESS_SECONDS)
        servers.append(start_server(port=port))

    thread = threading.Thread(target=run)
    thread.start()
    return thread


def carry_on(client: actopo.Client) -> int:
    """What a client does after a restart: load, open a session, ask, run; returns edges."""
    mesh = client.sample("jittered:10")
    with client.open_session(mesh, structure="compact") as session:
        edges = len(session.relation("vertex_edges", np.arange(mesh.vertices)).values)
        assert session.run("critical-points").summary["counts"]
    client.delete_mesh(mesh)
    return edges


def test_sigkill_and_restart_on_the_same_port():
    first = start_server()
    servers = [first]
    try:
        with actopo.Client(first.target) as client:
            edges = carry_on(client)
            mesh = client.sample("jittered:10")
            old_session = client.open_session(mesh, structure="compact").session_id

            # Restarted at once: the next reads reconnect the same channel.
            kill_server(first)
            killed = time.monotonic()
            servers.append(start_server(port=first.port))
            restart_s = time.monotonic() - killed
            assert client.server_info().algorithms
            first_read_s = time.monotonic() - killed
            assert client.list_meshes() == []
            with pytest.raises(actopo.NotFoundError):
                client.get_session(old_session)  # state died with the process
            with pytest.raises(actopo.NotFoundError):
                client.get_mesh(mesh)
            assert carry_on(client) == edges

            # Restarted while a read is under way: the read is retried until the server is back
            # (within its ~3 s of attempts; the server listens again well within that).
            kill_server(servers[-1])
            killed = time.monotonic()
            read_begins = threading.Event()
            restarter = start_when(read_begins, first.port, servers)
            with pytest.raises(actopo.UnavailableError):
                client.delete_mesh("mesh-0")  # not idempotent: never retried
            try:
                read_begins.set()  # the server starts as the read begins: no server at first
                assert client.server_info().algorithms
                retried_read_s = time.monotonic() - killed
            finally:
                read_begins.set()
                restarter.join()
            assert client.list_meshes() == []
            assert carry_on(client) == edges
    finally:
        for server in servers:
            server.stop()
    report("SIGKILL and restart", restart_s=restart_s, first_read_s=first_read_s,
           read_during_restart_s=retried_read_s)
