"""Streamed relation batches (StreamRelations with numpy arrays in and CSR arrays out) against
the real server: the same answers as GetRelationBatch and single queries on every structure,
several messages per array, item errors by position, whole-message errors, int32 / int64 ids
and vertex tuples, the query readers option and the server's query breakdown."""

from __future__ import annotations

import asyncio

import grpc
import numpy as np
import pytest

import actopo
from actopo import _batches
from actopo._proto import pb
from actopo._types import FailedItem

STRUCTURES = ["explicit", "compact", "actopo"]
RELATIONS = [("vertex_star", "vertices"), ("edge_triangles", "edges"),
             ("triangle_star", "triangles"), ("tetrahedron_neighbors", "tetrahedra")]


@pytest.fixture(scope="module")
def mesh(client):
    info = client.sample("jittered:8", block_size=50)
    yield client.get_mesh(info, count_faces=True)  # the tests name every edge
    client.delete_mesh(info)


@pytest.fixture(scope="module", params=STRUCTURES)
def session(request, client, mesh):
    with client.open_session(mesh, structure=request.param, query_readers=2) as s:
        yield s


def _equal(a: actopo.RelationBatch, b: actopo.RelationBatch) -> None:
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.values, b.values)


@pytest.mark.parametrize("name,count", RELATIONS)
def test_streamed_batches_equal_batch_and_single_answers(session, mesh, name, count):
    n = getattr(mesh, count)
    ids = np.arange(n)
    arrays = [ids[:250], ids[250:251], ids[:0], ids[251:].astype(np.int32), ids[::-1]]
    batches = list(session.relation_batches(name, arrays, chunk_size=64))
    assert len(batches) == len(arrays)
    for array, batch in zip(arrays, batches, strict=True):
        assert batch.num_simplices == len(array) and not batch.errors
        assert batch.offsets.dtype == np.int64 and batch.values.dtype == np.int64
        _equal(batch, session.relation(name, array))  # one GetRelationBatch
    rows = batches[0].split() + batches[1].split() + batches[3].split()  # ids 0 .. n - 1
    assert all(np.array_equal(a, b) for a, b in zip(batches[4].split(), rows[::-1], strict=True))
    for i in (0, 1, 250, n // 2, n - 1):
        np.testing.assert_array_equal(rows[i], session.query(name, i).ids)


def test_relation_streams_what_exceeds_one_message(client, session, mesh):
    ids = np.arange(mesh.vertices)
    whole = session.relation("vertex_neighbors", ids)  # one GetRelationBatch
    before = session.stats().relation_queries.count
    saved = client._max_batch
    client._max_batch = 100  # as if the server allowed 100 simplices per message
    try:
        streamed = session.relation("vertex_neighbors", ids)
    finally:
        client._max_batch = saved
    _equal(streamed, whole)
    calls = -(-mesh.vertices // 100)
    assert session.stats().relation_queries.count - before == calls


def test_item_errors_by_position(session, mesh):
    ids = np.arange(300)
    ids[150] = mesh.vertices + 7  # past the end, in the third message of 64
    ids[3] = -1
    [batch] = session.relation_batches("vertex_star", [ids], chunk_size=64)
    assert [(e.index, e.code) for e in batch.errors] == [
        (3, grpc.StatusCode.OUT_OF_RANGE), (150, grpc.StatusCode.OUT_OF_RANGE)]
    assert batch.errors[1].message.startswith(f"ids[150]: vertex id {mesh.vertices + 7} ")
    assert isinstance(batch.errors[1].error, actopo.OutOfRangeError)
    assert len(batch.of(3)) == len(batch.of(150)) == 0
    good = np.delete(np.arange(300), [3, 150])
    expected = session.relation("vertex_star", good)
    np.testing.assert_array_equal(np.delete(np.diff(batch.offsets), [3, 150]),
                                  np.diff(expected.offsets))
    np.testing.assert_array_equal(batch.values, expected.values)
    same = session.relation("vertex_star", ids, raise_errors=False)
    _equal(same, batch)
    assert same.errors == batch.errors
    with pytest.raises(actopo.OutOfRangeError, match=r"ids\[3\]"):
        list(session.relation_batches("vertex_star", [ids], chunk_size=64, raise_errors=True))
    with pytest.raises(actopo.OutOfRangeError):
        session.relation("vertex_star", ids)


def test_vertex_tuples_and_dtypes(session, mesh):
    edges = np.arange(mesh.edges)
    tuples = session.relation("edge_vertices", edges).values.reshape(-1, 2)
    by_id = session.relation("edge_star", edges)
    for dtype in (np.int64, np.int32, np.uint16, ">i8"):
        [batch] = session.relation_batches("edge_star", [tuples[:, ::-1].astype(dtype)],
                                           chunk_size=100)
        _equal(batch, by_id)
        [batch] = session.relation_batches("edge_star", [edges.astype(dtype)], chunk_size=100)
        _equal(batch, by_id)
    bad = tuples[:10].copy()
    bad[4] = (0, 0)
    [batch] = session.relation_batches("edge_star", [bad], chunk_size=3)
    assert [(e.index, e.code) for e in batch.errors] == [(4, grpc.StatusCode.NOT_FOUND)]
    assert batch.errors[0].message.startswith("vertex_tuples[4]: (0, 0)")


def test_whole_message_errors_raise(client, mesh):
    session = client.open_session(mesh, structure="compact")
    ids = np.arange(10)
    with pytest.raises(actopo.InvalidArgumentError, match=r"vertex_tuples\.shape"):
        list(session.relation_batches("edge_star", [np.zeros((2, 3), dtype=np.int64)]))
    with pytest.raises(actopo.InvalidArgumentError, match="unknown relation"):
        list(session.relation_batches("vertex_stars", [ids]))
    with pytest.raises(actopo.InvalidArgumentError, match="chunk_size"):
        list(session.relation_batches("vertex_star", [ids], chunk_size=0))
    stale = client.session(session.session_id)
    session.close()
    with pytest.raises(actopo.NotFoundError, match="no session"):
        list(stale.relation_batches("vertex_star", [ids, ids]))
    with pytest.raises(actopo.NotFoundError):
        stale.relation("vertex_star", np.arange(mesh.vertices), raise_errors=False)


def test_errors_of_the_input_reach_the_caller(client, mesh):
    with client.open_session(mesh, structure="explicit") as session:
        seen = []
        with pytest.raises(actopo.InvalidArgumentError, match="must be integers"):
            for batch in session.relation_batches("vertex_star",
                                                  [np.arange(5), np.array([0.5])]):
                seen.append(batch)
        assert len(seen) == 1

        def failing():
            yield np.arange(5)
            raise KeyError("the caller's own")

        with pytest.raises(KeyError, match="the caller's own"):
            list(session.relation_batches("vertex_star", failing()))


def test_window_bounds_the_arrays_in_flight(client, mesh):
    pulled = []

    def arrays():
        for i in range(40):
            pulled.append(i)
            yield np.arange(i, i + 20)

    with client.open_session(mesh, structure="compact") as session:
        batches = session.relation_batches("vertex_star", arrays(), window=2)
        first = next(batches)
        assert len(pulled) <= 3  # two unanswered, and one sent after the first answer
        rest = list(batches)
    assert first.num_simplices == 20 and len(rest) == 39 and len(pulled) == 40


def test_query_readers_option(client, mesh):
    for readers in (1, 3):
        with client.open_session(mesh, structure="actopo", query_readers=readers) as s:
            assert s.info.engine.query_readers == readers
            assert s.describe().engine.query_readers == readers
    with client.open_session(mesh, structure="compact") as s:
        assert s.info.engine.query_readers >= 1  # the server's default
    with pytest.raises(actopo.InvalidArgumentError, match=r"engine\.query_readers"):
        client.open_session(mesh, query_readers=-1)  # decided on the client
    with pytest.raises(actopo.InvalidArgumentError, match=r"engine\.query_readers") as e:
        client.open_session(mesh, query_readers=1000)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT


def test_stats_breakdown_counts_the_simplices(session, mesh):
    before = session.stats()
    ids = np.arange(mesh.vertices)
    ids[10] = -5
    batches = list(session.relation_batches("vertex_edges", [ids, ids[:77]], chunk_size=128))
    session.query("vertex_edges", 0)
    after = session.stats()
    b0, b1 = before.query_breakdown, after.query_breakdown
    assert b1.simplices - b0.simplices == len(ids) - 1 + 76 + 1
    assert b1.compute_ns > b0.compute_ns and b1.serialize_ns > b0.serialize_ns
    assert b1.queue_ns >= b0.queue_ns and b1.compute_seconds > 0
    assert after.relation_queries.count > before.relation_queries.count
    assert [len(b.errors) for b in batches] == [1, 1]


def test_async_streamed_batches(server, client, mesh):
    ids = np.arange(mesh.vertices)
    bad = ids[:200].copy()
    bad[99] = 10**7

    async def scenario():
        async with actopo.AsyncClient(server) as aclient:
            async with aclient.open_session(mesh.mesh_id, structure="actopo",
                                            query_readers=2) as session:
                assert session.info.engine.query_readers == 2
                streamed = [b async for b in session.relation_batches(
                    "vertex_star", [ids, bad, ids[:0].astype(np.int32)], chunk_size=64)]
                aclient._max_batch = 50
                whole = await session.relation("vertex_star", ids)
                kept = await session.relation("vertex_star", bad, raise_errors=False)
                with pytest.raises(actopo.OutOfRangeError, match=r"ids\[99\]"):
                    await session.relation("vertex_star", bad)
                with pytest.raises(actopo.InvalidArgumentError, match="must be integers"):
                    [b async for b in session.relation_batches("vertex_star", [[0.5]])]
                stats = await session.stats()
                stale = await aclient.session(session.session_id)
            with pytest.raises(actopo.NotFoundError):
                [b async for b in stale.relation_batches("vertex_star", [ids])]
            return streamed, whole, kept, stats

    streamed, whole, kept, stats = asyncio.run(scenario())
    with client.open_session(mesh, structure="explicit") as session:
        expected = session.relation("vertex_star", ids)
    _equal(streamed[0], expected)
    _equal(whole, expected)
    assert [e.index for e in streamed[1].errors] == [99] and streamed[2].num_simplices == 0
    _equal(kept, streamed[1])
    assert stats.query_breakdown.simplices >= 2 * mesh.vertices


def _response(request_id: int, offsets, values, errors=()) -> pb.StreamRelationsResponse:
    r = pb.StreamRelationsResponse(request_id=request_id)
    r.offsets.CopyFrom(pb.Array(dtype=pb.DATA_TYPE_INT64, shape=[len(offsets)],
                                data=np.asarray(offsets, dtype="<i8").tobytes()))
    r.values.CopyFrom(pb.Array(dtype=pb.DATA_TYPE_INT64, shape=[len(values)],
                               data=np.asarray(values, dtype="<i8").tobytes()))
    for index, code, message in errors:
        r.item_errors.add(index=index, code=code, message=message)
    return r


def test_messages_and_collector_offline():
    arrays = [np.arange(5, dtype=np.int32), np.zeros((0,), dtype=np.int64), [[1, 2], [2, 3]]]
    sent = list(_batches.messages("s", pb.RELATION_VERTEX_STAR, arrays, 2))
    pieces = [p for _, p in sent]
    assert [(p.array, p.start, p.count, p.last) for p in pieces] == [
        (0, 0, 2, False), (0, 2, 2, False), (0, 4, 1, True), (1, 0, 0, True), (2, 0, 2, True)]
    assert [r.request_id for r, _ in sent] == [0, 1, 2, 3, 4]
    assert sent[0][0].ids.dtype == pb.DATA_TYPE_INT32 and sent[3][0].ids.dtype == \
        pb.DATA_TYPE_INT64
    assert list(sent[4][0].vertex_tuples.shape) == [2, 2] and not sent[4][0].HasField("ids")
    collector = _batches.Collector(raise_errors=False)
    assert collector.add(pieces[0], _response(0, [0, 2, 3], [7, 8, 9])) is None
    assert collector.add(pieces[1], _response(1, [0, 0, 1], [4],
                                              [(0, 11, "ids[0]: vertex id 99 is outside")])) \
        is None
    batch = collector.add(pieces[2], _response(2, [0, 2], [5, 6]))
    np.testing.assert_array_equal(batch.offsets, [0, 2, 3, 3, 4, 6])
    np.testing.assert_array_equal(batch.values, [7, 8, 9, 4, 5, 6])
    assert batch.errors == (FailedItem(2, grpc.StatusCode.OUT_OF_RANGE,
                                      "ids[2]: vertex id 99 is outside"),)
    empty = collector.add(pieces[3], _response(3, [0], []))
    assert empty.num_simplices == 0 and empty.errors == ()
    with pytest.raises(actopo.ActopoError, match="request 9 arrived where request 4"):
        collector.add(pieces[4], _response(9, [0, 1, 2], [1, 2]))
    whole = pb.StreamRelationsResponse(request_id=4, error=pb.ItemError(code=5, message="gone"))
    with pytest.raises(actopo.NotFoundError, match="gone"):
        collector.add(pieces[4], whole)
    strict = _batches.Collector(raise_errors=True)
    with pytest.raises(actopo.OutOfRangeError, match=r"ids\[2\]"):
        strict.add(pieces[1], _response(1, [0, 0, 1], [1], [(0, 11, "ids[0]: bad")]))
