"""What the client decides alone: mesh checks, the upload stream, error mapping, assembly."""

from __future__ import annotations

import hashlib
import sys

import grpc
import meshio
import numpy as np
import pytest
import pyvista as pv

import actopo
from actopo import _batches, _mesh, _messages, _names, _requests, _upload
from actopo._download import MeshStream
from actopo._errors import error_for, error_for_number, translate
from actopo._progress import make_load_progress, make_progress
from actopo._proto import pb
from actopo._results import Assembler
from actopo._types import JobProgress

POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=np.float64)
TETS = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])


def test_tuple_mesh_becomes_little_endian_arrays():
    mesh = _mesh.mesh_arrays((POINTS.astype(">f8"), TETS.astype(np.uint16),
                              {"h": POINTS[:, 2], "label": np.arange(5, dtype=np.int8),
                               "normals": POINTS}), name="two")
    assert mesh.name == "two"
    assert mesh.points.dtype == np.dtype("<f8") and mesh.tetrahedra.dtype == np.dtype("<i4")
    assert list(mesh.point_data) == ["h", "label"]  # vector fields are left out
    assert mesh.point_data["label"].dtype == np.int64
    np.testing.assert_array_equal(mesh.tetrahedra, TETS)


@pytest.mark.parametrize("arrays,message", [
    ((POINTS, [[0, 1, 2]]), "found cell types: 1 triangle; hint:"),
    ((POINTS[:, :2], TETS), "points must have shape (n, 3)"),
    ((POINTS, [[0, 1, 2, 9]]), "vertex 9, outside [0, 5)"),
    ((POINTS, np.zeros((0, 4), dtype=int)), "no tetrahedra"),
    ((POINTS, TETS.astype(float)), "must be integers"),
    ((POINTS,), "a mesh tuple is"),
])
def test_bad_arrays_are_rejected_before_sending(arrays, message):
    with pytest.raises(actopo.InvalidMeshError, match=None) as e:
        _mesh.mesh_arrays(arrays)
    assert message in str(e.value)
    assert e.value.code is None


def test_unknown_objects_are_rejected():
    with pytest.raises(actopo.InvalidMeshError, match="cannot upload a dict"):
        _mesh.mesh_arrays({"points": POINTS})


def test_triangle_files_are_rejected_with_cell_types_and_hint(data_dir):
    mesh = meshio.read(data_dir / "happi_tas_tri.vtu")
    with pytest.raises(actopo.InvalidMeshError) as e:
        _mesh.mesh_arrays(mesh, "happi")
    assert "found cell types: 36290 triangle" in str(e.value)
    assert "hint:" in str(e.value) and "tetrahedral" in str(e.value)


def test_pyvista_non_tetrahedral_grids_are_rejected():
    with pytest.raises(actopo.InvalidMeshError, match="8 voxel; hint: split the cells"):
        _mesh.mesh_arrays(pv.ImageData(dimensions=(3, 3, 3)))
    grid = pv.ImageData(dimensions=(3, 3, 3)).triangulate()
    assert _mesh.mesh_arrays(grid).tetrahedra.shape[1] == 4


def test_upload_stream_chunks_and_digest():
    mesh = _mesh.mesh_arrays((POINTS, TETS, {"h": POINTS[:, 2].astype(np.float32)}))
    messages = list(_upload.requests(mesh, pb.PartitionOptions(block_size=7), chunk_bytes=50))
    header = messages[0].header
    payload = b"".join(m.chunk for m in messages[1:])
    expected = mesh.points.tobytes() + mesh.tetrahedra.tobytes() + mesh.point_data["h"].tobytes()
    assert payload == expected
    assert all(len(m.chunk) == 50 for m in messages[1:-1])
    assert header.sha256 == hashlib.sha256(expected).hexdigest()
    assert (header.num_vertices, header.num_tetrahedra) == (5, 2)
    assert header.points_dtype == pb.DATA_TYPE_FLOAT64
    assert header.tetrahedra_dtype == pb.DATA_TYPE_INT32
    assert [(f.name, f.dtype) for f in header.fields] == [("h", pb.DATA_TYPE_FLOAT32)]
    assert header.partition.block_size == 7
    strided = _mesh.mesh_arrays((POINTS, TETS, {"h": POINTS[:, 2]}))  # a non-contiguous view
    assert b"".join(m.chunk for m in list(_upload.requests(strided, pb.PartitionOptions()))[1:]) \
        == POINTS.tobytes() + TETS.astype("<i4").tobytes() + POINTS[:, 2].copy().tobytes()


@pytest.mark.parametrize("code,cls", [
    (grpc.StatusCode.INVALID_ARGUMENT, actopo.InvalidArgumentError),
    (grpc.StatusCode.NOT_FOUND, actopo.NotFoundError),
    (grpc.StatusCode.ALREADY_EXISTS, actopo.AlreadyExistsError),
    (grpc.StatusCode.RESOURCE_EXHAUSTED, actopo.ResourceExhaustedError),
    (grpc.StatusCode.OUT_OF_RANGE, actopo.OutOfRangeError),
    (grpc.StatusCode.FAILED_PRECONDITION, actopo.FailedPreconditionError),
    (grpc.StatusCode.UNAVAILABLE, actopo.UnavailableError),
    (grpc.StatusCode.UNAUTHENTICATED, actopo.AuthenticationError),
    (grpc.StatusCode.CANCELLED, actopo.CancelledError),
    (grpc.StatusCode.DEADLINE_EXCEEDED, actopo.DeadlineExceededError),
    (grpc.StatusCode.INTERNAL, actopo.ActopoError),
])
def test_every_code_maps_to_one_class(code, cls):
    class FakeError(grpc.RpcError):
        def code(self):
            return code

        def details(self):
            return "field: bad value"

    error = translate(FakeError())
    assert type(error) is cls
    assert error.code == code and error.details == "field: bad value"
    assert str(error) == f"field: bad value [{code.name}]"
    assert type(error_for_number(code.value[0], "x")) is cls


def test_mesh_calls_turn_invalid_argument_into_invalid_mesh():
    error = error_for(grpc.StatusCode.INVALID_ARGUMENT, "tetrahedra[3]: vertex 9", mesh=True)
    assert isinstance(error, actopo.InvalidMeshError)
    assert isinstance(error, actopo.InvalidArgumentError) and isinstance(error, ValueError)


def test_names():
    assert _names.lookup(_names.RELATIONS, "vertex_edges", "relation") == pb.RELATION_VERTEX_EDGES
    assert _names.lookup(_names.ALGORITHMS, "morse_smale", "algorithm") == pb.ALGORITHM_MORSE_SMALE
    assert _names.lookup(_names.PREFETCH, "auto", "prefetch") == pb.PREFETCH_UNSPECIFIED
    with pytest.raises(actopo.InvalidArgumentError, match="unknown relation 'vv'; available: "
                       "vertex_neighbors, vertex_edges"):
        _names.lookup(_names.RELATIONS, "vv", "relation")


def _int64(values) -> pb.Array:
    values = np.asarray(values, dtype="<i8")
    return pb.Array(dtype=pb.DATA_TYPE_INT64, shape=list(values.shape), data=values.tobytes())


def test_a_relation_batch_request_and_its_answer():
    code = _requests.relation("vertex_star")
    request = _messages.build_get_relation_batch("s", code, _requests.simplex_array(range(5)))
    assert (request.session_id, request.relation) == ("s", pb.RELATION_VERTEX_STAR)
    assert np.frombuffer(request.ids.data, "<i8").tolist() == [0, 1, 2, 3, 4]
    tuples = _messages.build_get_relation_batch(
        "s", code, _requests.simplex_array(np.array([[0, 1], [1, 2]], dtype=np.int32)))
    assert list(tuples.vertex_tuples.shape) == [2, 2] and not tuples.HasField("ids")
    assert tuples.vertex_tuples.dtype == pb.DATA_TYPE_INT32
    batch = _messages.decode_get_relation_batch(pb.GetRelationBatchResponse(
        offsets=_int64(np.arange(6) * 2), values=_int64(np.repeat(np.arange(5), 2))))
    np.testing.assert_array_equal(batch.offsets, np.arange(6) * 2)
    np.testing.assert_array_equal(batch.of(3), [3, 3])
    assert batch.num_simplices == 5 and len(batch.split()) == 5 and batch.errors == ()


def test_one_call_or_a_stream():
    """relation() asks in one GetRelationBatch call what fits in a message and may fail as a
    whole; the rest goes over StreamRelations."""
    values = _requests.simplex_array(range(10))
    assert _batches.in_one_call(values, raise_errors=True, max_batch=10)
    assert not _batches.in_one_call(values, raise_errors=True, max_batch=9)
    assert not _batches.in_one_call(values, raise_errors=False, max_batch=10)


def test_stream_items_keep_or_raise_their_error():
    ok = _messages.decode_stream_relations(pb.StreamRelationsResponse(request_id=3, ids=[7, 8]),
                                           raise_errors=True)
    assert ok.index == 3 and ok.ids.tolist() == [7, 8] and ok.error is None
    failed = pb.StreamRelationsResponse(
        request_id=4, error=pb.ItemError(code=grpc.StatusCode.OUT_OF_RANGE.value[0],
                                         message="simplex.id: 9 is outside [0, 5)"))
    item = _messages.decode_stream_relations(failed, raise_errors=False)
    assert isinstance(item.error, actopo.OutOfRangeError) and item.ids.tolist() == []
    with pytest.raises(actopo.OutOfRangeError, match="outside"):
        _messages.decode_stream_relations(failed, raise_errors=True)


def test_assembler_joins_pieces_in_any_order():
    values = np.arange(10, dtype=np.int32)
    data = values.tobytes()
    a = Assembler("morse-smale")
    responses = [
        pb.RunJobResponse(accepted=pb.JobAccepted(job_id="j1")),
        pb.RunJobResponse(progress=pb.JobProgress(fraction=0.5)),
        pb.RunJobResponse(chunk=pb.ResultChunk(
            array=pb.Array(name="segmentation/AscendingManifold", dtype=pb.DATA_TYPE_INT32,
                           shape=[10], data=data[20:]), offset=20, total_bytes=40)),
        pb.RunJobResponse(chunk=pb.ResultChunk(
            array=pb.Array(name="segmentation/AscendingManifold", dtype=pb.DATA_TYPE_INT32,
                           shape=[10], data=data[:20]), offset=0, total_bytes=40)),
    ]
    summary = pb.RunJobResponse()
    summary.summary.result.update({"critical_cells": [1, 2, 0, 0], "digest": "ab"})
    responses.append(summary)
    reports = [a.feed(r) for r in responses]
    assert reports == [None, JobProgress("run", 0.5, 0.0), None, None, None]
    result = a.result()
    assert result.job_id == "j1" and result.groups == ["segmentation"]
    np.testing.assert_array_equal(result.segmentation["AscendingManifold"], values)
    assert result.summary == {"critical_cells": [1, 2, 0, 0], "digest": "ab"}
    assert isinstance(result.summary["critical_cells"][0], int)


def test_load_stream_reports_progress_and_keeps_the_mesh():
    reports = []
    stream = _messages.LoadStream(reports.append)
    stream.feed(pb.LoadMeshWithProgressResponse(
        progress=pb.LoadProgress(phase="read", fraction=0.5, elapsed_seconds=0.25)))
    with pytest.raises(actopo.ActopoError, match="ended without the mesh"):
        stream.mesh()
    stream.feed(pb.LoadMeshWithProgressResponse(mesh=pb.MeshInfo(mesh_id="m1", tetrahedra=2)))
    assert reports == [actopo.LoadProgress(phase="read", fraction=0.5, elapsed_seconds=0.25)]
    assert stream.mesh().mesh_id == "m1" and stream.mesh().tetrahedra == 2


def _download_stream(mesh: _mesh.MeshArrays, chunk_bytes: int) -> list[pb.DownloadMeshResponse]:
    """DownloadMesh's answer for `mesh` as a server could send it, in chunks of `chunk_bytes`
    (the upload's byte stream, so chunks end inside values and straddle arrays)."""
    mesh = _mesh.mesh_arrays(mesh)
    header = _upload.header(mesh, pb.PartitionOptions())
    header.ClearField("sha256")
    header.ClearField("partition")
    for f in header.fields:
        if f.name in mesh.times:
            f.time = mesh.times[f.name]
    buffers = [a.data.cast("B") for a in (mesh.points, mesh.tetrahedra,
                                          *mesh.point_data.values())]
    return [pb.DownloadMeshResponse(header=header),
            *(pb.DownloadMeshResponse(chunk=c) for c in _upload.chunks(buffers, chunk_bytes))]


@pytest.mark.parametrize("chunk_bytes", [1, 7, 1000])
def test_a_download_stream_decodes_into_the_arrays_it_announced(chunk_bytes):
    sent = _mesh.MeshArrays(
        "two", POINTS, TETS[:, ::-1].astype(np.int32),
        {"h": POINTS[:, 2].astype(np.float32), "label": np.arange(5, dtype=np.int64),
         "i": np.arange(5, dtype=np.int32), "x": POINTS[:, 0]}, {"x": 2.5})
    reports: list[float] = []
    stream = MeshStream(reports.append)
    for response in _download_stream(sent, chunk_bytes):
        stream.feed(response)
    mesh = stream.mesh()
    assert (mesh.name, mesh.times, list(mesh.point_data)) == ("two", {"x": 2.5},
                                                              ["h", "label", "i", "x"])
    np.testing.assert_array_equal(mesh.points, POINTS)
    np.testing.assert_array_equal(mesh.tetrahedra, TETS[:, ::-1])
    assert mesh.tetrahedra.dtype == np.int32
    for name, values in sent.point_data.items():
        assert mesh.point_data[name].dtype == values.dtype
        np.testing.assert_array_equal(mesh.point_data[name], values)
    total = 5 * 24 + 2 * 16 + 5 * (4 + 8 + 4 + 8)
    assert len(reports) == -(-total // chunk_bytes) and reports[-1] == 1.0
    assert reports == sorted(reports)
    assert repr(mesh) == "MeshArrays('two', 5 vertices, 2 tetrahedra, fields ['h', 'label', " \
        "'i', 'x'])"


def test_a_broken_download_stream_is_an_error():
    sent = _mesh.MeshArrays("two", POINTS, TETS.astype(np.int32), {"h": POINTS[:, 2]})
    header, *chunks = _download_stream(sent, 64)
    stream = MeshStream(lambda fraction: None)
    with pytest.raises(actopo.ActopoError, match="a chunk before the header"):
        stream.feed(chunks[0])
    with pytest.raises(actopo.ActopoError, match="ended without its header"):
        stream.mesh()
    stream.feed(header)
    with pytest.raises(actopo.ActopoError, match="a second header"):
        stream.feed(header)
    for chunk in chunks[:-1]:
        stream.feed(chunk)
    with pytest.raises(actopo.ActopoError, match=r"ended after 128 of the 192 bytes"):
        stream.mesh()
    stream.feed(chunks[-1])
    with pytest.raises(actopo.ActopoError, match="more than the 192 bytes the header announced"):
        stream.feed(pb.DownloadMeshResponse(chunk=b"\0"))
    for field, value, message in (("points_dtype", pb.DATA_TYPE_INT32, "points of dtype int32"),
                                  ("tetrahedra_dtype", pb.DATA_TYPE_FLOAT64,
                                   "tetrahedra of dtype float64"),
                                  ("num_vertices", -1, "-1 vertices")):
        bad = pb.DownloadMeshResponse()
        bad.CopyFrom(header)
        setattr(bad.header, field, value)
        with pytest.raises(actopo.ActopoError, match=message):
            MeshStream(lambda fraction: None).feed(bad)
    twice = pb.DownloadMeshResponse()
    twice.CopyFrom(header)
    twice.header.fields.append(twice.header.fields[0])
    with pytest.raises(actopo.ActopoError, match="a field named twice"):
        MeshStream(lambda fraction: None).feed(twice)


def test_a_download_request_names_its_fields():
    assert _messages.build_download_mesh("m1", None) == pb.DownloadMeshRequest(mesh_id="m1")
    assert _messages.build_download_mesh("m1", []) == pb.DownloadMeshRequest(mesh_id="m1")
    assert _messages.build_download_mesh("m1", "all") == \
        pb.DownloadMeshRequest(mesh_id="m1", all_fields=True)
    assert list(_messages.build_download_mesh("m1", ("b", "a")).fields) == ["b", "a"]
    with pytest.raises(actopo.InvalidArgumentError, match=r"for that field alone: \['h'\]"):
        _messages.build_download_mesh("m1", "h")
    with pytest.raises(actopo.InvalidArgumentError, match="is not a field name"):
        _messages.build_download_mesh("m1", ["h", 3])  # type: ignore[list-item]
    assert _messages.download_description("m1") == "download m1"


def test_mesh_arrays_are_checked_as_a_tuple_is():
    """A MeshArrays made by hand uploads as the same arrays as a tuple would: made contiguous
    and little-endian, its ids checked; its times kept."""
    made = _mesh.MeshArrays("two", POINTS.astype(">f8"), TETS, {"x": POINTS[:, 0]}, {"x": 1.0})
    mesh = _mesh.mesh_arrays(made)
    assert mesh.points.dtype == np.dtype("<f8") and mesh.tetrahedra.dtype == np.dtype("<i4")
    assert mesh.point_data["x"].flags.c_contiguous and mesh.times == {"x": 1.0}
    with pytest.raises(actopo.InvalidMeshError, match=r"two: tetrahedra reference vertex 9"):
        _mesh.mesh_arrays(_mesh.MeshArrays("two", POINTS, TETS + 5))


def test_mesh_arrays_as_pyvista_and_meshio(monkeypatch):
    mesh = _mesh.MeshArrays("two", POINTS, TETS, {"h": POINTS[:, 2]})
    grid = mesh.to_pyvista()
    np.testing.assert_array_equal(grid.points, POINTS)
    np.testing.assert_array_equal(grid.cells_dict[pv.CellType.TETRA], TETS)
    np.testing.assert_array_equal(grid.point_data["h"], POINTS[:, 2])
    converted = mesh.to_meshio()
    np.testing.assert_array_equal(converted.cells_dict["tetra"], TETS)
    np.testing.assert_array_equal(converted.point_data["h"], POINTS[:, 2])
    for module, method in (("pyvista", mesh.to_pyvista), ("meshio", mesh.to_meshio)):
        monkeypatch.setitem(sys.modules, module, None)  # as if it were not installed
        with pytest.raises(ImportError, match=f"pip install 'actopo\\[{module}\\]'"):
            method()


def test_a_load_request_of_a_path_a_sample_or_a_list_of_files():
    request = _messages.build_load_mesh("a.vtu", block_size=10)
    assert request.WhichOneof("source") == "path" and request.partition.block_size == 10
    assert _messages.load_description(request) == "load a.vtu"
    request = _messages.build_load_mesh("sample:jittered:4")
    assert request.sample == "jittered:4"
    assert _messages.load_description(request) == "load sample:jittered:4"
    for paths, times in ((["a.vtu", "b.vtu"], None), (("a.vtu", "b.vtu"), np.array([2, 3.5]))):
        request = _messages.build_load_mesh(paths, times=times)
        assert request.WhichOneof("source") == "files"
        assert list(request.files.paths) == ["a.vtu", "b.vtu"]
        assert list(request.files.times) == ([] if times is None else [2.0, 3.5])
        assert _messages.load_description(request) == "load a.vtu +1 file"
    request = _messages.build_load_mesh([])
    assert request.HasField("files") and not request.files.paths  # the server says: empty
    assert _messages.load_description(request) == "load no files"


def test_load_progress_choices(monkeypatch, capsys):
    reports = []
    for progress in (None, False, reports.append):
        sink = make_load_progress(progress, "load x")
        sink.update(actopo.LoadProgress("read", 1.0, 0.5))
        sink.close()
    assert reports == [actopo.LoadProgress("read", 1.0, 0.5)]
    assert capsys.readouterr().err == ""
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)  # neither tqdm nor rich: plain lines
    monkeypatch.setitem(sys.modules, "rich.progress", None)
    bars = make_load_progress(True, "load x")
    for phase, fraction in [("read", 0.0), ("read", 1.0), ("partition", 0.5), ("encode", 0.25),
                            ("stitch", 1.0)]:
        bars.update(actopo.LoadProgress(phase, fraction, 0.0))
    bars.close()
    err = capsys.readouterr().err
    for line in ("load x (read 1/3): 100%", "load x (partition 2/3):  50%",
                 "load x (encode 3/3):  25%", "load x (stitch): 100%"):
        assert f"\r{line}" in err
    assert err.endswith(" \r")  # a bar clears its line when the next one starts, and at the end


def test_job_progress_choices(monkeypatch, capsys):
    """A callable gets the run's fractions; bars show each phase, the faces named for what they
    are."""
    fractions: list[float] = []
    reports = [JobProgress("faces", 0.0, 0.1), JobProgress("faces", 1.0, 0.9),
               JobProgress("run", 0.5, 1.0), JobProgress("run", 1.0, 1.5)]
    for progress in (None, False, fractions.append):
        sink = make_progress(progress, "discrete-gradient")
        for report in reports:
            sink.update(report)
        sink.close()
    assert fractions == [0.5, 1.0]
    assert capsys.readouterr().err == ""
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)  # neither tqdm nor rich: plain lines
    monkeypatch.setitem(sys.modules, "rich.progress", None)
    bars = make_progress(True, "discrete-gradient")
    for report in reports:
        bars.update(report)
    bars.close()
    err = capsys.readouterr().err
    for line in ("discrete-gradient (the mesh's edges and triangles, once per mesh): 100%",
                 "discrete-gradient:  50%", "discrete-gradient: 100%"):
        assert f"\r{line}" in err


def test_client_needs_a_target(monkeypatch):
    """As every failure of the package: an ActopoError (InvalidArgumentError, a ValueError)."""
    monkeypatch.delenv("ACTOPO_SERVER", raising=False)
    for client in (actopo.Client, actopo.AsyncClient):
        with pytest.raises(actopo.InvalidArgumentError, match="ACTOPO_SERVER") as error:
            client()
        assert isinstance(error.value, ValueError) and error.value.code is None


def test_unreachable_server_is_unavailable():
    with actopo.Client("127.0.0.1:1", timeout=10) as client:  # > ~3 s of retries
        with pytest.raises(actopo.UnavailableError):
            client.server_info()


def test_affinity_key_travels_as_metadata(monkeypatch):
    from actopo._channel import metadata

    assert metadata(None) == ()
    assert metadata("t", "tenant-7") == (("authorization", "Bearer t"),
                                         ("x-actopo-session", "tenant-7"))
    monkeypatch.setenv("ACTOPO_AFFINITY_KEY", "from-env")
    client = actopo.Client("127.0.0.1:9")
    try:
        assert ("x-actopo-session", "from-env") in client._metadata
    finally:
        client.close()
