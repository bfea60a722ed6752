"""Loads with progress (LoadMeshWithProgress): phases in order, the same mesh as LoadMesh,
errors mapped as elsewhere, and a raising callback, Ctrl-C or a cancelled task stop the load."""

from __future__ import annotations

import asyncio
import signal
import threading
from collections import Counter

import grpc
import pytest
from harness import ServerProcess, start_cli, wait_until

import actopo
from actopo._types import LOAD_PHASES

SHAPE = ("vertices", "edges", "triangles", "tetrahedra", "blocks", "block_size")
# About 3M tetrahedra. The tests that stop a load hold it on the server as its encoding begins
# (ENCODE) until the client has stopped it; the call's cancel reaches the server as a message of
# its own, which is in long before this encoding, let go, could end.
BIG = "jittered:80"
ENCODE = "LoadMeshWithProgress/encode"
LIVENESS_SECONDS = 30.0
"""Only bounds a hang: the command ends within a fraction of a second."""
CANCELLED = grpc.StatusCode.CANCELLED.value[0]


class Stop(Exception):
    """What the tests' callbacks raise."""


def _check_reports(reports: list[actopo.LoadProgress]) -> None:
    """Every phase, in order; each phase's fractions in [0, 1] and not decreasing."""
    assert all(isinstance(r, actopo.LoadProgress) for r in reports)
    phases = [r.phase for r in reports]
    assert list(dict.fromkeys(phases)) == list(LOAD_PHASES)
    assert phases == sorted(phases, key=LOAD_PHASES.index)
    for phase in LOAD_PHASES:
        fractions = [r.fraction for r in reports if r.phase == phase]
        assert fractions == sorted(fractions) and fractions[0] >= 0 and fractions[-1] <= 1
    elapsed = [r.elapsed_seconds for r in reports]
    assert elapsed == sorted(elapsed) and elapsed[0] >= 0


def _ids(meshes: list[actopo.MeshInfo]) -> set[str]:
    return {m.mesh_id for m in meshes}


def _loads(server: ServerProcess) -> Counter[int]:
    """The server's LoadMeshWithProgress calls so far, by status code."""
    return Counter(server.requests("LoadMeshWithProgress"))


def _assert_stopped(server: ServerProcess, client: actopo.Client, meshes_before: set[str],
                    loads_before: Counter[int], loads: int = 1) -> None:
    """The `loads` loads started since `loads_before` were stopped on the server: waits until
    the server has ended them (it counts a load once its work is over, finished or not), then
    checks that they all ended CANCELLED and left no mesh (deleting any they left).

    The callers keep the exception that stopped the load (and so the frames of its traceback,
    which hold the gRPC call) until this returns: the garbage collector, which cancels calls
    nobody holds, must not do the client's work.
    """
    try:
        wait_until(lambda: (_loads(server) - loads_before).total() >= loads,
                   "the server to end the loads the client stopped")
    finally:
        outcomes = _loads(server) - loads_before
        new = _ids(client.list_meshes()) - meshes_before
        for mesh_id in new:
            client.delete_mesh(mesh_id)
    assert outcomes == {CANCELLED: loads}, f"loads ended with codes {dict(outcomes)}"
    assert not new, "the load went on: its mesh is there"


@pytest.mark.parametrize("source,block_size", [("sample:jittered:20", 0),
                                               ("fertility_tet.vtu", 500)])
def test_phases_in_order_and_the_same_mesh_as_load_mesh(client, source, block_size):
    reports: list[actopo.LoadProgress] = []
    mesh = client.load_mesh(source, block_size=block_size, progress=reports.append)
    plain = client.load_mesh(source, block_size=block_size)
    try:
        _check_reports(reports)
        assert [getattr(mesh, k) for k in SHAPE] == [getattr(plain, k) for k in SHAPE]
        assert mesh.fields == plain.fields and mesh.source == plain.source
        assert mesh.mesh_id != plain.mesh_id
        assert {mesh.mesh_id, plain.mesh_id} <= _ids(client.list_meshes())
    finally:
        client.delete_mesh(mesh)
        client.delete_mesh(plain)


def test_sample_and_bar(client, capsys):
    mesh = client.sample("jittered:20", block_size=300, progress=True)
    client.delete_mesh(mesh)
    assert mesh.name == "jittered:20" and mesh.block_size == 300
    out, err = capsys.readouterr()
    assert out == ""
    for step in ("read 1/3", "partition 2/3", "encode 3/3"):
        assert f"load sample:jittered:20 ({step})" in err


@pytest.mark.parametrize("source,cls", [
    ("no_such_file.vtu", actopo.NotFoundError),
    ("../outside.vtu", actopo.InvalidMeshError),
    ("happi_tas_tri.vtu", actopo.InvalidMeshError),  # triangles
    ("sample:jittered:100000", actopo.InvalidMeshError),
])
def test_errors_map_as_for_load_mesh(client, source, cls):
    with pytest.raises(cls) as plain:
        client.load_mesh(source)
    with pytest.raises(cls) as reported:
        client.load_mesh(source, progress=lambda p: None)
    assert type(reported.value) is type(plain.value)
    assert (reported.value.code, reported.value.details) == (plain.value.code, plain.value.details)


def test_unreachable_server_is_unavailable():
    with actopo.Client("127.0.0.1:1") as client, pytest.raises(actopo.UnavailableError):
        client.sample("jittered:4", progress=True)


def test_a_raising_callback_stops_the_load(shared_server, client):
    """The callback raises at the partition's end, once the load is held as its encoding
    begins."""
    before, loads = _ids(client.list_meshes()), _loads(shared_server)
    reports: list[actopo.LoadProgress] = []
    with shared_server.hold(ENCODE) as hold:
        def stop_at_encode(report: actopo.LoadProgress) -> None:
            reports.append(report)
            if report.phase == "partition" and report.fraction == 1:
                hold.wait_held()
                raise Stop(report.fraction)

        with pytest.raises(Stop) as stopped:
            client.sample(BIG, progress=stop_at_encode)
        assert hold.is_held
    assert (reports[-1].phase, reports[-1].fraction) == ("partition", 1)
    assert "encode" not in [r.phase for r in reports]
    _assert_stopped(shared_server, client, before, loads)
    assert stopped.value.args == (reports[-1].fraction,)


def test_ctrl_c_stops_the_load(shared_server, client):
    """SIGINT while the client waits for the next report (not inside the callback), the load
    held as its encoding begins."""
    before, loads = _ids(client.list_meshes()), _loads(shared_server)
    reports: list[actopo.LoadProgress] = []
    with shared_server.hold(ENCODE) as hold:
        sent = threading.Event()

        interrupter = threading.Thread(target=hold.interrupt_when_held, args=(sent,))
        interrupter.start()
        try:
            with pytest.raises(KeyboardInterrupt) as interrupted:
                client.sample(BIG, progress=reports.append)
        finally:
            interrupter.join()
        assert sent.is_set() and hold.is_held
    assert reports and "encode" not in [r.phase for r in reports]
    _assert_stopped(shared_server, client, before, loads)
    del interrupted
    mesh = client.sample("jittered:4", progress=lambda p: None)  # the client still works
    client.delete_mesh(mesh)


def test_ctrl_c_stops_the_cli_load(shared_server, client):
    """SIGINT while `actopo load --progress` waits for the encoding, held on the server: exit
    130, no mesh."""
    server = shared_server.target
    before, loads = _ids(client.list_meshes()), _loads(shared_server)
    with shared_server.hold(ENCODE) as hold:
        process = start_cli("--server", server, "load", f"sample:{BIG}", "--progress")
        err = ""
        try:
            # Read as it comes, so that the bar never waits for room in the pipe.
            while "partition 2/3" not in err:  # the bar ends its lines with \r, not \n
                chunk = process.stderr.read(1)
                assert chunk, f"actopo load ended before partitioning: {err}"
                err += chunk
            hold.wait_held()
            process.send_signal(signal.SIGINT)
            out, rest = process.communicate(timeout=LIVENESS_SECONDS)
        finally:
            if process.poll() is None:
                process.kill()
    assert process.returncode == 130 and "actopo: cancelled" in rest
    assert out == "" and "encode" not in err + rest
    _assert_stopped(shared_server, client, before, loads)


def test_async_load_with_progress(server, client):
    async def scenario():
        async with actopo.AsyncClient(server) as aclient:
            reports: list[actopo.LoadProgress] = []
            mesh = await aclient.sample("jittered:20", progress=reports.append)
            plain = await aclient.load_mesh("sample:jittered:20")
            for m in (mesh, plain):
                await aclient.delete_mesh(m)
            with pytest.raises(actopo.NotFoundError):
                await aclient.load_mesh("no_such_file.vtu", progress=True)
            return reports, mesh, plain

    reports, mesh, plain = asyncio.run(scenario())
    _check_reports(reports)
    assert [getattr(mesh, k) for k in SHAPE] == [getattr(plain, k) for k in SHAPE]


def test_async_raising_callback_and_cancelled_task_stop_the_load(shared_server, client):
    """Each load is held as its encoding begins until the client has stopped it."""
    before, loads = _ids(client.list_meshes()), _loads(shared_server)

    async def scenario() -> None:
        # Not closed before the check: closing the client would cancel its calls.
        async with actopo.AsyncClient(shared_server.target) as aclient:
            with shared_server.hold(ENCODE) as hold:
                def stop_at_encode(report: actopo.LoadProgress) -> None:
                    if report.phase == "partition" and report.fraction == 1:
                        hold.wait_held()  # the event loop has nothing else to do meanwhile
                        raise Stop

                with pytest.raises(Stop) as stopped:
                    await aclient.sample(BIG, progress=stop_at_encode)
            with shared_server.hold(ENCODE) as hold:
                task = asyncio.ensure_future(aclient.load_mesh(f"sample:{BIG}",
                                                               progress=lambda r: None))
                await asyncio.to_thread(hold.wait_held)
                task.cancel()  # what Ctrl-C does under asyncio.run
                with pytest.raises(asyncio.CancelledError) as cancelled:
                    await task
            await asyncio.to_thread(_assert_stopped, shared_server, client, before, loads, 2)
            del stopped, cancelled

    asyncio.run(scenario())
