"""AsyncClient: the same methods as Client, as coroutines, with the same answers."""

from __future__ import annotations

import asyncio
import dataclasses
import inspect
from typing import Any

import numpy as np
import pytest
from harness import wait_until_async
from meshes import lattice

import actopo


def test_same_public_methods():
    pairs = [(actopo.Client, actopo.AsyncClient), (actopo.Session, actopo.AsyncSession),
             (actopo.Job, actopo.AsyncJob)]
    for sync, asynchronous in pairs:
        public = {n for n in dir(sync) if not n.startswith("_")}
        assert public <= set(dir(asynchronous)), public - set(dir(asynchronous))
        for name in public:
            method = getattr(asynchronous, name)
            if callable(method) and name != "open_session":
                is_async = inspect.iscoroutinefunction(method) or inspect.isasyncgenfunction(method)
                assert is_async, f"{asynchronous.__name__}.{name} is not async"
                assert (inspect.signature(method).parameters.keys()
                        == inspect.signature(getattr(sync, name)).parameters.keys()), name


def test_async_parity(server, client):
    points, tets, fields = lattice(5)

    async def scenario():
        async with actopo.AsyncClient(server) as aclient:
            info = await aclient.server_info()
            assert info == client.server_info()
            mesh = await aclient.upload_mesh((points, tets, fields), name="async", block_size=20)
            assert (await aclient.get_mesh(mesh)).mesh_id == mesh.mesh_id
            assert mesh.mesh_id in [m.mesh_id for m in await aclient.list_meshes()]
            sample = await aclient.sample("jittered:4")
            await aclient.delete_mesh(sample)
            async with aclient.open_session(mesh, scalar="f", structure="compact") as session:
                assert (await session.describe()).session_id == session.session_id
                assert session.session_id in [s.session_id for s in await aclient.list_sessions()]
                assert (await aclient.get_session(session.session_id)).scalar_field == "f"
                assert (await aclient.session(session.session_id)).info.mesh_id == mesh.mesh_id
                batch = await session.relation("vertex_edges", np.arange(mesh.vertices))
                one = await session.query("edge_triangles", (0, 1), include_vertices=True)
                items = [i async for i in session.relations_stream("vertex_star", [0, 10**6])]
                result = await session.run("morse-smale", progress=lambda f: None)
                stats = await session.stats()
            opened = await aclient.open_session(mesh, scalar="f", structure="explicit")
            await aclient.close_session(opened.session_id)
            return mesh, batch, one, items, result, stats

    mesh, batch, one, items, result, stats = asyncio.run(scenario())
    try:
        with client.open_session(mesh, scalar="f", structure="actopo") as session:
            expected = session.relation("vertex_edges", np.arange(mesh.vertices))
            np.testing.assert_array_equal(batch.offsets, expected.offsets)
            np.testing.assert_array_equal(batch.values, expected.values)
            same = session.query("edge_triangles", (0, 1), include_vertices=True)
            np.testing.assert_array_equal(one.ids, same.ids)
            np.testing.assert_array_equal(one.vertices, same.vertices)
            sync_result = session.run("morse-smale")
            assert result.summary == sync_result.summary
            assert result.arrays.keys() == sync_result.arrays.keys()
            for name, values in result.arrays.items():
                np.testing.assert_array_equal(values, sync_result.arrays[name])
    finally:
        client.delete_mesh(mesh)
    assert items[0].error is None and isinstance(items[1].error, actopo.OutOfRangeError)
    assert stats.jobs.count == 1 and stats.relation_queries.count >= 3


async def _stopped(session: actopo.AsyncSession) -> bool:
    """Whether the session's job was stopped on the server: waits until it runs no job any
    more, then checks that it finished none (the session counts finished jobs only)."""
    async def idle() -> bool:
        return (await session.describe()).running_job_id is None

    await wait_until_async(idle, "the session to run no job")
    return (await session.stats()).jobs.count == 0


async def _assert_stopped(session: actopo.AsyncSession, when: str, log: list[str]) -> None:
    """Fails unless _stopped(), saying what the server says of the session and the last job
    lines of its log (each job's start and end)."""
    if await _stopped(session):
        return
    jobs = "".join([line for line in log if " job job-" in line][-8:])
    pytest.fail(f"the job ran on {when}: {await session.describe()} "
                f"{(await session.stats()).jobs}\nserver log:\n{jobs}")


def test_async_errors_and_cancellation(shared_server):
    """The jobs are held on the server until the client has cancelled them, or until their
    deadline has passed. A cancelled task's call reaches the server as a message of its own:
    jittered:50's Morse-Smale complex, let go, runs far longer than that takes."""
    server, log = shared_server.target, shared_server.stderr

    async def scenario():
        async with actopo.AsyncClient(server) as aclient:
            with pytest.raises(actopo.NotFoundError):
                await aclient.get_mesh("mesh-nope")
            with pytest.raises(actopo.InvalidMeshError):
                await aclient.load_mesh("happi_tas_tri.vtu")
            mesh = await aclient.sample("jittered:50")
            try:
                async with aclient.open_session(mesh, structure="compact") as session:
                    with shared_server.hold("RunJob") as hold:
                        task = asyncio.ensure_future(session.run("morse-smale"))
                        await asyncio.to_thread(hold.wait_held)
                        task.cancel()  # what Ctrl-C does under asyncio.run
                        with pytest.raises(asyncio.CancelledError):
                            await task
                    await _assert_stopped(session, "after task.cancel()", log)
                    with shared_server.hold("RunJob") as hold:
                        job = await session.submit("morse-smale")
                        await asyncio.to_thread(hold.wait_held)
                        await job.cancel()
                        hold.release()
                        with pytest.raises(actopo.CancelledError):
                            await job.result()
                    await _assert_stopped(session, "after CancelJob", log)
                    with shared_server.hold("RunJob") as hold:
                        with pytest.raises(actopo.DeadlineExceededError):
                            await session.run("morse-smale", timeout=1.0)
                        assert hold.is_held, "the deadline passed while the job was not held"
                    await _assert_stopped(session, "past its deadline", log)
                    result = await session.run("critical-points", include_arrays=False)
                    assert result.summary["counts"]
            finally:
                await aclient.delete_mesh(mesh)
            with pytest.raises(actopo.NotFoundError):
                await aclient.cancel_job("job-nope")

    asyncio.run(scenario())


# Both clients on one session of one server: the same requests, the same decoded answers.

FERTILITY = "fertility_tet.vtu"
SIMPLIFY = {"relative_threshold": "0.05"}


def _sync_answers(client: actopo.Client, session: actopo.Session,
                  tuples: np.ndarray) -> dict[str, Any]:
    ids = np.arange(client.get_mesh(session.info.mesh_id).vertices, dtype=np.int32)
    fractions: list[float] = []
    answers = {
        "server_info": client.server_info(),
        # Counted: the faces the first client's jobs build would otherwise tell the two apart.
        "mesh": client.get_mesh(session.info.mesh_id, count_faces=True),
        "session": _stable(client.get_session(session.session_id)),
        "relation": session.relation("vertex_edges", ids[:1000]),
        "tuples": session.relation("edge_triangles", tuples),
        "failed": session.relation("vertex_star", [0, 10**9, 2], raise_errors=False),
        "batches": list(session.relation_batches("vertex_link", np.array_split(ids, 3),
                                                 chunk_size=2000, window=2)),
        "batch_errors": list(session.relation_batches("vertex_star", [[1, -1], [10**9]])),
        "query": session.query("edge_triangles", tuple(tuples[0]), include_vertices=True),
        "stream": list(session.relations_stream("vertex_star", [0, 10**9, 5, (0, 1)])),
        "morse-smale": session.run("morse-smale", progress=fractions.append),
        "persistence-diagram": session.run("persistence-diagram"),
        "topological-simplification": session.run("topological-simplification",
                                                  parameters=SIMPLIFY),
        "summary_only": session.run("critical-points", include_arrays=False),
    }
    answers["fractions"] = fractions
    return answers


async def _async_answers(aclient: actopo.AsyncClient, session: actopo.AsyncSession,
                         tuples: np.ndarray) -> dict[str, Any]:
    ids = np.arange((await aclient.get_mesh(session.info.mesh_id)).vertices, dtype=np.int32)
    fractions: list[float] = []
    answers = {
        "server_info": await aclient.server_info(),
        "mesh": await aclient.get_mesh(session.info.mesh_id, count_faces=True),
        "session": _stable(await aclient.get_session(session.session_id)),
        "relation": await session.relation("vertex_edges", ids[:1000]),
        "tuples": await session.relation("edge_triangles", tuples),
        "failed": await session.relation("vertex_star", [0, 10**9, 2], raise_errors=False),
        "batches": [b async for b in session.relation_batches(
            "vertex_link", np.array_split(ids, 3), chunk_size=2000, window=2)],
        "batch_errors": [b async for b in session.relation_batches("vertex_star",
                                                                   [[1, -1], [10**9]])],
        "query": await session.query("edge_triangles", tuple(tuples[0]), include_vertices=True),
        "stream": [i async for i in session.relations_stream("vertex_star",
                                                             [0, 10**9, 5, (0, 1)])],
        "morse-smale": await session.run("morse-smale", progress=fractions.append),
        "persistence-diagram": await session.run("persistence-diagram"),
        "topological-simplification": await session.run("topological-simplification",
                                                         parameters=SIMPLIFY),
        "summary_only": await session.run("critical-points", include_arrays=False),
    }
    answers["fractions"] = fractions
    return answers


def _stable(info: actopo.types.SessionInfo) -> actopo.types.SessionInfo:
    """The session without its last use, which each call moves."""
    return dataclasses.replace(info, last_used=None)


def _assert_same(sync: Any, asynchronous: Any, where: str) -> None:
    """Equal values, arrays equal in dtype and values, errors of one class and message; job
    results equal but for their job id and timings."""
    assert type(sync) is type(asynchronous), where
    if isinstance(sync, actopo.JobResult):
        assert (sync.algorithm, sync.summary, sync.trace) == \
            (asynchronous.algorithm, asynchronous.summary, asynchronous.trace), where
        assert list(sync.arrays) == list(asynchronous.arrays), where
        for name, values in sync.arrays.items():
            _assert_same(values, asynchronous.arrays[name], f"{where} {name}")
        assert sync.stats is not None and asynchronous.stats is not None, where
        assert sync.job_id != asynchronous.job_id, where
    elif isinstance(sync, actopo.RelationBatch):
        _assert_same(sync.offsets, asynchronous.offsets, f"{where} offsets")
        _assert_same(sync.values, asynchronous.values, f"{where} values")
        assert sync.errors == asynchronous.errors, where
    elif isinstance(sync, tuple | list):
        assert len(sync) == len(asynchronous), where
        for i, (a, b) in enumerate(zip(sync, asynchronous, strict=True)):
            _assert_same(a, b, f"{where}[{i}]")
    elif isinstance(sync, actopo.types.StreamItem):
        assert sync.index == asynchronous.index, where
        _assert_same(sync.ids, asynchronous.ids, f"{where} ids")
        assert type(sync.error) is type(asynchronous.error), where
        assert str(sync.error) == str(asynchronous.error), where
    elif isinstance(sync, np.ndarray):
        assert sync.dtype == asynchronous.dtype, where
        np.testing.assert_array_equal(sync, asynchronous, err_msg=where)
    else:
        assert sync == asynchronous, where


def test_both_clients_give_the_same_answers(server, client, meshes):
    """Everything a session answers, asked once through each client on the same session: the
    relations (one call, vertex tuples, failed items, streamed arrays, single simplices) and
    the jobs' summaries and arrays."""
    mesh = meshes(FERTILITY)
    with client.open_session(mesh, scalar="eigenfunction4", structure="actopo") as session:
        neighbors = session.query("vertex_neighbors", 0).ids
        tuples = np.stack([np.zeros_like(neighbors), neighbors], axis=1)
        synchronous = _sync_answers(client, session, tuples)

        async def scenario() -> dict[str, Any]:
            async with actopo.AsyncClient(server) as aclient:
                return await _async_answers(aclient, await aclient.session(session.session_id),
                                            tuples)

        asynchronous = asyncio.run(scenario())
    assert list(synchronous) == list(asynchronous)
    for fractions in (synchronous.pop("fractions"), asynchronous.pop("fractions")):
        assert fractions and fractions == sorted(fractions) and fractions[-1] == pytest.approx(1)
    for key, value in synchronous.items():
        _assert_same(value, asynchronous[key], key)
    # What is compared is what it should be: answers, errors where the inputs were bad, arrays.
    assert len(synchronous["tuples"].offsets) == len(tuples) + 1
    assert [e.index for e in synchronous["failed"].errors] == [1]
    assert [len(b.errors) for b in synchronous["batch_errors"]] == [1, 1]
    assert [type(i.error).__name__ for i in synchronous["stream"]] == [
        "NoneType", "OutOfRangeError", "NoneType", "InvalidArgumentError"]  # (0, 1): an edge
    assert sum(len(b.offsets) - 1 for b in synchronous["batches"]) == mesh.vertices
    assert synchronous["morse-smale"].groups == ["critical_points", "separatrices",
                                                 "segmentation"]
    assert synchronous["persistence-diagram"].diagram is not None
    assert synchronous["topological-simplification"].simplified is not None
    assert synchronous["summary_only"].arrays == {}
