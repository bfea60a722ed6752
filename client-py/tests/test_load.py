"""Loads with progress (LoadMeshWithProgress): phases in order, the same mesh as LoadMesh,
errors mapped as elsewhere, and a raising callback, Ctrl-C or a cancelled task stop the load."""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

import actopo
from actopo._types import LOAD_PHASES

SHAPE = ("vertices", "edges", "triangles", "tetrahedra", "blocks", "block_size")
BIG = "jittered:80"  # about 3M tetrahedra: its encoding runs long enough to be stopped mid-way
# Longer than a whole load of BIG (about 1 s): a load that goes on shows its mesh by then.
SETTLE_SECONDS = 2.0


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


def _no_new_mesh(client: actopo.Client, before: set[str]) -> bool:
    """Watches the server for SETTLE_SECONDS: False (deleting them) once meshes not in
    `before` appear, True if none does.

    The callers keep the exception that stopped the load (and so the frames of its traceback,
    which hold the gRPC call) until this returns: the garbage collector, which cancels calls
    nobody holds, must not do the client's work.
    """
    deadline = time.monotonic() + SETTLE_SECONDS
    while time.monotonic() < deadline:
        new = _ids(client.list_meshes()) - before
        if new:
            for mesh_id in new:
                client.delete_mesh(mesh_id)
            return False
        time.sleep(0.05)
    return True


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


def test_a_raising_callback_stops_the_load(client):
    before = _ids(client.list_meshes())
    reports: list[actopo.LoadProgress] = []

    def stop_at_encode(report: actopo.LoadProgress) -> None:
        reports.append(report)
        if report.phase == "encode":
            raise Stop(report.fraction)

    with pytest.raises(Stop) as stopped:
        client.sample(BIG, progress=stop_at_encode)
    assert reports[-1].phase == "encode" and [r.phase for r in reports].count("encode") == 1
    assert _no_new_mesh(client, before), "the load went on after the callback raised"
    assert stopped.value.args == (reports[-1].fraction,)


def test_ctrl_c_stops_the_load(client):
    """SIGINT while the client waits for the next report (not inside the callback)."""
    before = _ids(client.list_meshes())
    encoding = threading.Event()

    def interrupt_soon(report: actopo.LoadProgress) -> None:
        if report.phase == "encode" and not encoding.is_set():
            encoding.set()
            threading.Timer(0.02, os.kill, (os.getpid(), signal.SIGINT)).start()

    with pytest.raises(KeyboardInterrupt) as interrupted:
        client.sample(BIG, progress=interrupt_soon)
    assert encoding.is_set()
    assert _no_new_mesh(client, before), "the load went on after Ctrl-C"
    del interrupted
    mesh = client.sample("jittered:4", progress=lambda p: None)  # the client still works
    client.delete_mesh(mesh)


def test_ctrl_c_stops_the_cli_load(server, client):
    """SIGINT while `actopo load --progress` shows the encoding: exit 130, no mesh."""
    before = _ids(client.list_meshes())
    process = subprocess.Popen(
        [sys.executable, "-m", "actopo", "--server", server, "load", f"sample:{BIG}",
         "--progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    err = ""
    try:
        while "encode 3/3" not in err:  # the bar ends its lines with \r, not \n
            chunk = process.stderr.read(1)
            assert chunk, f"actopo load ended before encoding: {err}"
            err += chunk
        process.send_signal(signal.SIGINT)
        out, rest = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130 and "actopo: cancelled" in rest
    assert out == ""
    assert _no_new_mesh(client, before), "the load went on after Ctrl-C"


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


def test_async_raising_callback_and_cancelled_task_stop_the_load(server, client):
    before = _ids(client.list_meshes())

    def stop_at_encode(report: actopo.LoadProgress) -> None:
        if report.phase == "encode":
            raise Stop

    async def scenario() -> bool:
        async with actopo.AsyncClient(server) as aclient:  # closing it would cancel its calls
            with pytest.raises(Stop) as stopped:
                await aclient.sample(BIG, progress=stop_at_encode)
            encoding = asyncio.Event()
            task = asyncio.ensure_future(aclient.load_mesh(
                f"sample:{BIG}", progress=lambda r: r.phase == "encode" and encoding.set()))
            await encoding.wait()
            task.cancel()  # what Ctrl-C does under asyncio.run
            with pytest.raises(asyncio.CancelledError) as cancelled:
                await task
            settled = await asyncio.to_thread(_no_new_mesh, client, before)
            del stopped, cancelled
            return settled

    assert asyncio.run(scenario()), "a load went on after its caller stopped it"
