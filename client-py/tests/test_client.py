"""Client and Session against a real server: server info, meshes, sessions, relations, stats."""

from __future__ import annotations

import numpy as np
import pytest
from meshes import Oracle, lattice

import actopo


@pytest.fixture(scope="module")
def cube(client):
    points, tets, fields = lattice(4)
    mesh = client.upload_mesh((points, tets, fields), name="cube", block_size=8)
    # Counted, so the tests can name every edge and triangle.
    yield client.get_mesh(mesh, count_faces=True), Oracle(tets)
    client.delete_mesh(mesh)


@pytest.fixture(scope="module")
def session(client, cube):
    with client.open_session(cube[0], scalar="f", structure="compact") as s:
        yield s


def test_server_info(client):
    info = client.server_info()
    assert info.version
    assert info.algorithms == ["topo-relations", "critical-points", "discrete-gradient",
                               "morse-smale", "persistence-diagram",
                               "topological-simplification", "diagram-distance", "tracking",
                               "merge-tree", "contour-tree"]
    assert "vertex_edges" in info.relations and "triangle_on_boundary" in info.relations
    assert any(s.startswith("jittered:N") for s in info.samples)
    assert info.limits.max_batch_size > 0 and info.limits.max_message_bytes > 0


def test_upload_numpy_arrays(cube):
    mesh, oracle = cube
    assert (mesh.vertices, mesh.tetrahedra) == (64, 162)
    assert (mesh.edges, mesh.triangles) == (len(oracle.edges), len(oracle.triangles))
    assert mesh.source == "upload" and mesh.name == "cube"
    assert [f.name for f in mesh.fields] == ["f", "z"]
    assert mesh.blocks > 1 and mesh.block_size == 8


def test_mesh_lifecycle(client):
    mesh = client.load_mesh("manifoldCheck0_tet.vtu")
    # Edges and triangles are built on their first need, or when asked for.
    assert (mesh.vertices, mesh.edges, mesh.triangles, mesh.tetrahedra) == (29, None, None, 24)
    assert client.get_mesh(mesh).edges is None
    counted = client.get_mesh(mesh, count_faces=True)
    assert (counted.edges, counted.triangles) == (76, 72)
    assert counted.bytes > mesh.bytes
    mesh = counted
    assert mesh.fields[0].name == "height" and mesh.fields[0].max == pytest.approx(2.42)
    assert mesh.created is not None and mesh.load_seconds >= 0
    sample = client.sample("jittered:5", block_size=20)
    assert sample.tetrahedra == 6 * 4**3 and sample.source == "sample:jittered:5"
    assert {mesh.mesh_id, sample.mesh_id} <= {m.mesh_id for m in client.list_meshes()}
    assert client.get_mesh(mesh.mesh_id) == client.get_mesh(mesh)
    client.delete_mesh(mesh)
    client.delete_mesh(sample.mesh_id)
    assert not {mesh.mesh_id, sample.mesh_id} & {m.mesh_id for m in client.list_meshes()}
    with pytest.raises(actopo.NotFoundError):
        client.get_mesh(mesh)


def test_session_lifecycle(client, cube):
    mesh = cube[0]
    session = client.open_session(mesh, scalar="z", structure="actopo", consumers=2,
                                  producers=1, buffer_ratio=0.5, prefetch="spatial",
                                  precompute="declared", query_readers=3)
    info = session.info
    assert info.mesh_id == mesh.mesh_id and info.scalar_field == "z"
    assert info.structure == "actopo"
    assert info.engine == actopo.types.EngineOptions(consumers=2, producers=1,
                                                     buffer_ratio=0.5, prefetch="spatial",
                                                     precompute="declared", query_readers=3)
    assert session.describe().session_id == session.session_id
    assert client.get_session(session.session_id) == session.describe()
    assert session.session_id in {s.session_id for s in client.list_sessions()}
    assert client.session(session.session_id).info.scalar_field == "z"
    assert client.get_mesh(mesh).sessions >= 1
    session.close()
    session.close()  # idempotent
    with pytest.raises(actopo.NotFoundError):
        client.get_session(info.session_id)
    with pytest.raises(ValueError, match="closed"):
        session.stats()
    with client.open_session(mesh.mesh_id, structure="explicit") as s:
        assert s.info.scalar_field == "f"  # the first floating-point field
        opened = s.session_id
    assert opened not in {x.session_id for x in client.list_sessions()}


def test_close_session_by_id(client, cube):
    session = client.open_session(cube[0])
    client.close_session(session.session_id)
    with pytest.raises(actopo.NotFoundError):
        session.describe()


def test_relations_match_the_oracle(session, cube):
    mesh, oracle = cube
    vertices = np.arange(mesh.vertices)
    offsets, values = session.relation("vertex_star", vertices)
    assert offsets.dtype == np.int64 and len(offsets) == mesh.vertices + 1
    for v in vertices:  # sorted: see test_relations_are_ascending_in_input_ids
        assert sorted(values[offsets[v]:offsets[v + 1]].tolist()) == oracle.vertex_star[v]
    batch = session.relation("vertex_neighbors", vertices)
    assert [sorted(a.tolist()) for a in batch.split()] == [oracle.neighbors(v) for v in vertices]
    edges = session.relation("edge_vertices", np.arange(mesh.edges))
    assert sorted(map(tuple, edges.values.reshape(-1, 2).tolist())) == oracle.edges
    tets = session.relation("tetrahedron_vertices", np.arange(mesh.tetrahedra))
    assert list(map(tuple, tets.values.reshape(-1, 4).tolist())) == oracle.tets
    tt = session.relation("tetrahedron_neighbors", np.arange(mesh.tetrahedra))
    assert [sorted(tt.of(t).tolist()) for t in range(10)] == [
        oracle.tetrahedron_neighbors(t) for t in range(10)]
    boundary = session.relation("vertex_on_boundary", vertices)
    assert {int(v) for v in vertices if boundary.of(v)[0]} == oracle.boundary_vertices


def test_relation_by_vertex_tuples_and_split_batches(client, session, cube):
    oracle = cube[1]
    tuples = np.array(oracle.edges[:20])
    star = session.relation("edge_star", tuples)
    assert [sorted(a.tolist()) for a in star.split()] == [oracle.star(e) for e in tuples.tolist()]
    whole = session.relation("vertex_edges", np.arange(64))
    saved = client._max_batch
    client._max_batch = 7  # as if the server allowed 7 simplices per batch
    try:
        pieces = session.relation("vertex_edges", np.arange(64))
    finally:
        client._max_batch = saved
    np.testing.assert_array_equal(pieces.offsets, whole.offsets)
    np.testing.assert_array_equal(pieces.values, whole.values)
    single = session.relation("vertex_star", 5)
    assert sorted(single.values.tolist()) == oracle.vertex_star[5]


def test_query_one_simplex(session, cube):
    oracle = cube[1]
    answer = session.query("vertex_star", 3)
    assert sorted(answer.ids.tolist()) == oracle.vertex_star[3] and answer.vertices is None
    edge = oracle.edges[4]
    triangles = session.query("edge_triangles", edge[::-1], include_vertices=True)
    assert triangles.vertices.shape == (len(triangles.ids), 3)
    assert all(set(edge) <= set(t) for t in triangles.vertices.tolist())
    by_id = session.query("triangle_vertices", int(triangles.ids[0]))
    assert by_id.ids.tolist() == sorted(triangles.vertices[0].tolist())


def test_relations_stream_goes_on_after_item_errors(session, cube):
    oracle = cube[1]
    items = list(session.relations_stream("vertex_star", [0, 1, 10**6, 2]))
    assert [i.index for i in items] == [0, 1, 2, 3]
    assert [sorted(i.ids.tolist()) for i in items if i.error is None] == [
        oracle.vertex_star[v] for v in (0, 1, 2)]
    assert isinstance(items[2].error, actopo.OutOfRangeError)
    assert "1000000" in items[2].error.details
    with pytest.raises(actopo.OutOfRangeError):
        list(session.relations_stream("vertex_star", [0, 10**6], raise_errors=True))
    lazy = (v for v in range(64))
    assert sum(len(i.ids) for i in session.relations_stream("vertex_star", lazy)) == 4 * 162


def test_stats_count_queries_and_jobs(session):
    before = session.stats()
    session.relation("vertex_star", [0, 1])
    result = session.run("critical-points")
    after = session.stats()
    assert after.relation_queries.count > before.relation_queries.count
    assert after.jobs.count == before.jobs.count + 1 and after.jobs.ns > before.jobs.ns
    assert after.engine.requests >= before.engine.requests
    assert after.memory.static_bytes > 0 and after.preprocess_seconds >= 0
    assert result.stats is not None and result.stats.run_seconds > 0


def test_relations_are_ascending_in_input_ids(session, cube):
    mesh = cube[0]
    for name, count in [("vertex_neighbors", mesh.vertices), ("vertex_star", mesh.vertices),
                        ("edge_star", mesh.edges), ("tetrahedron_neighbors", mesh.tetrahedra)]:
        for values in session.relation(name, np.arange(count)).split():
            assert values.tolist() == sorted(values.tolist()), name


def test_field_dtype_is_as_loaded(cube):
    assert [(f.name, f.dtype) for f in cube[0].fields] == [("f", "float64"), ("z", "float32")]
