"""AsyncClient: the same methods as Client, as coroutines, with the same answers."""

from __future__ import annotations

import asyncio
import inspect

import numpy as np
import pytest
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


def test_async_errors_and_cancellation(server):
    async def scenario():
        async with actopo.AsyncClient(server) as aclient:
            with pytest.raises(actopo.NotFoundError):
                await aclient.get_mesh("mesh-nope")
            with pytest.raises(actopo.InvalidMeshError):
                await aclient.load_mesh("happi_tas_tri.vtu")
            mesh = await aclient.sample("jittered:50")
            try:
                async with aclient.open_session(mesh, structure="compact") as session:
                    running = asyncio.Event()
                    task = asyncio.ensure_future(
                        session.run("morse-smale", progress=lambda f: running.set()))
                    await running.wait()
                    task.cancel()  # what Ctrl-C does under asyncio.run
                    with pytest.raises(asyncio.CancelledError):
                        await task
                    for _ in range(250):
                        if (await session.describe()).running_job_id is None:
                            break
                        await asyncio.sleep(0.02)
                    assert (await session.describe()).running_job_id is None
                    job = await session.submit("morse-smale")
                    await job.cancel()
                    with pytest.raises(actopo.CancelledError):
                        await job.result()
                    with pytest.raises(actopo.DeadlineExceededError):
                        await session.run("morse-smale", timeout=0.01)
            finally:
                await aclient.delete_mesh(mesh)
            with pytest.raises(actopo.NotFoundError):
                await aclient.cancel_job("job-nope")

    asyncio.run(scenario())
