"""What the client decides alone about fields, many-field jobs and distance matrices: the
checks of add_fields() before anything is sent, the AddFields byte stream and its digest, the
job's field list, a many-field RunJob stream assembled per field, and DistanceMatrix (linkage,
groups, plot) on matrices given here."""

from __future__ import annotations

import hashlib
import itertools
import sys

import grpc
import matplotlib.image
import meshio
import numpy as np
import pytest
import pyvista as pv
from scipy.cluster.hierarchy import dendrogram, linkage
from scipy.spatial.distance import squareform

import actopo
from actopo import _fields, _messages, _requests, _upload
from actopo._convert import struct_to_dict
from actopo._distances import average_linkage, from_summary
from actopo._errors import translate
from actopo._proto import pb
from actopo._results import Assembler
from actopo.types import DistanceMatrix, FieldResult

N = 5


def _arrays(fields, vertices=N, times=None):
    return _fields.field_arrays(fields, vertices, times)


def test_dtypes_are_kept_or_become_float64():
    arrays = _arrays({"f32": np.arange(N, dtype=np.float32), "f64": np.arange(N) / 2,
                      "i8": np.arange(N, dtype=np.int8), "u64": np.arange(N, dtype=np.uint64),
                      "big": np.arange(N, dtype=">f8"), "column": np.ones((N, 1)),
                      "list": [0, 1, 2, 3, 4.5]})
    assert [(a.name, a.values.dtype.str) for a in arrays] == [
        ("f32", "<f4"), ("f64", "<f8"), ("i8", "<f8"), ("u64", "<f8"), ("big", "<f8"),
        ("column", "<f8"), ("list", "<f8")]
    assert all(a.values.flags.c_contiguous and a.time is None for a in arrays)
    np.testing.assert_array_equal(arrays[4].values, np.arange(N))
    strided = _arrays({"x": np.arange(2 * N, dtype=np.float64)[::2]})[0].values
    assert strided.flags.c_contiguous and strided.tolist() == [0, 2, 4, 6, 8]


@pytest.mark.parametrize("values,message", [
    (np.zeros(N, dtype=np.float16), "field 'bad': values must be float32, float64 or "
                                    "integers, got dtype float16"),
    (np.zeros(N, dtype=bool), "got dtype bool"),
    (np.zeros(N, dtype=np.complex128), "got dtype complex128"),
    (np.array(["a"] * N), "got dtype <U1"),
    (np.zeros((N, 3)), "field 'bad': values must be one per vertex, shape (5,), got shape (5, 3)"),
    (np.float64(1.0), "got shape ()"),
    (np.zeros(N + 1), "field 'bad': 6 values, but the mesh has 5 vertices"),
])
def test_bad_values_are_rejected_naming_the_field(values, message):
    with pytest.raises(actopo.InvalidArgumentError) as e:
        _arrays({"good": np.zeros(N), "bad": values})
    assert message in str(e.value) and e.value.code is None
    assert isinstance(e.value, ValueError)


def test_times_by_name_or_in_order():
    fields = {"a": np.zeros(N), "b": np.ones(N)}
    assert [a.time for a in _arrays(fields, times={"b": 2})] == [None, 2.0]
    assert [a.time for a in _arrays(fields, times=[1, 2.5])] == [1.0, 2.5]
    for times, message in [({"c": 1.0}, "times: 'c' is not one of the fields added (a, b)"),
                           ([1.0], "times: 1 values for 2 fields"),
                           ({"a": float("nan")}, "times['a']: nan is not finite"),
                           ({"a": "soon"}, "times['a']: 'soon' is not a number")]:
        with pytest.raises(actopo.InvalidArgumentError, match=None) as e:
            _arrays(fields, times=times)
        assert message in str(e.value)


def test_fields_of_pyvista_and_meshio_datasets():
    grid = pv.ImageData(dimensions=(N, 1, 1)).cast_to_unstructured_grid()
    grid.point_data["s"] = np.arange(N, dtype=np.float32)
    grid.point_data["v"] = np.zeros((N, 3))  # a vector field: left out, as uploads leave it
    grid.point_data["k"] = np.arange(N, dtype=np.int32)
    assert [(a.name, a.values.dtype.str) for a in _arrays(grid)] == [("s", "<f4"), ("k", "<f8")]
    mesh = meshio.Mesh(np.zeros((N, 3)), [("vertex", np.arange(N).reshape(-1, 1))],
                       point_data={"h": np.arange(N) * 1.5, "label": np.array(["x"] * N)})
    assert [a.name for a in _arrays(mesh)] == ["h"]
    with pytest.raises(actopo.InvalidArgumentError, match="no field to add"):
        _arrays({})
    with pytest.raises(actopo.InvalidArgumentError, match="cannot take point fields from a list"):
        _arrays([np.zeros(N)])
    with pytest.raises(actopo.InvalidArgumentError, match="a field's name must be a string"):
        _arrays({3: np.zeros(N)})


def test_a_point_field_file_is_read_with_pyvista_or_meshio(data_dir, monkeypatch):
    path = data_dir / "isabel_series_s2" / "isabel_03_s2_tet.vtu"
    read = _fields.read_point_fields(path)
    monkeypatch.setitem(sys.modules, "pyvista", None)  # as if pyvista were not installed
    again = _fields.read_point_fields(path)
    assert list(read) == list(again) == ["velocityMag"]
    np.testing.assert_array_equal(read["velocityMag"], again["velocityMag"])
    with pytest.raises(FileNotFoundError, match="no such mesh file"):
        _fields.read_point_fields(data_dir / "nothing_here.vtu")


def test_add_fields_stream_chunks_and_digest():
    a = np.arange(40, dtype=np.float32)
    b = np.linspace(0, 1, 40)
    messages = list(_upload.add_fields_requests(
        "mesh-1", _arrays({"a": a, "b": b}, 40, times=[None, 7.5]), chunk_bytes=64))
    header = messages[0].header
    payload = b"".join(m.chunk for m in messages[1:-1])
    assert payload == a.tobytes() + b.tobytes()
    assert [len(m.chunk) for m in messages[1:-1]] == [64] * 7 + [32]  # 160 + 320 bytes, straddled
    # The digest comes last, hashed as the chunks went.
    assert header.sha256_last and not header.sha256
    assert messages[-1].WhichOneof("payload") == "sha256"
    assert messages[-1].sha256 == hashlib.sha256(payload).hexdigest()
    assert header.mesh_id == "mesh-1"
    assert [(f.name, f.dtype, f.HasField("time")) for f in header.fields] == [
        ("a", pb.DATA_TYPE_FLOAT32, False), ("b", pb.DATA_TYPE_FLOAT64, True)]
    assert header.fields[1].time == 7.5
    # The message builder checks the fields before the first message is taken.
    with pytest.raises(actopo.InvalidArgumentError, match="field 'a': 40 values"):
        _messages.build_add_fields("mesh-1", {"a": a}, 41)
    # The chunk size is the upload's.
    sizes = [len(m.chunk) for m in _messages.build_add_fields(
        "m", {"x": np.zeros(300_000)}, 300_000) if m.WhichOneof("payload") == "chunk"]
    assert sizes == [_upload.CHUNK_BYTES, _upload.CHUNK_BYTES, 2_400_000 - 2 * _upload.CHUNK_BYTES]


def test_already_exists_and_data_loss_codes():
    class FakeError(grpc.RpcError):
        def __init__(self, code):
            self._code = code

        def code(self):
            return self._code

        def details(self):
            return "fields[0].name: 'h' exists"

    taken = translate(FakeError(grpc.StatusCode.ALREADY_EXISTS))
    assert type(taken) is actopo.AlreadyExistsError
    assert taken.code == grpc.StatusCode.ALREADY_EXISTS
    lost = translate(FakeError(grpc.StatusCode.DATA_LOSS))
    assert type(lost) is actopo.DataLossError and lost.code == grpc.StatusCode.DATA_LOSS


def test_a_job_names_its_fields():
    request, name = _messages.build_run_job("s", "diagram_distance", None, False,
                                            fields=["a", "b"])
    assert name == "diagram-distance" and request.algorithm == pb.ALGORITHM_DIAGRAM_DISTANCE
    assert list(request.fields) == ["a", "b"] and not request.all_fields
    request, _ = _messages.build_run_job("s", "critical-points", None, False, fields="all")
    assert request.all_fields and not request.fields
    request, _ = _messages.build_run_job("s", "critical-points", None, False)
    assert not request.all_fields and not request.fields
    for fields, message in [("velocity", "fields: 'velocity' is neither a list of field names "
                                         "nor 'all' (for that field alone: ['velocity'])"),
                            ([], "fields: an empty list"), (["a", 3], "fields: 3 is not")]:
        with pytest.raises(actopo.InvalidArgumentError) as e:
            _requests.job_fields(fields)
        assert message in str(e.value)


def test_distance_parameters():
    assert _requests.distance_parameters(2, None, None, False) == {"p": "2.0",
                                                                   "essential": "false"}
    assert _requests.distance_parameters(1, 0.5, None, True) == {
        "p": "1.0", "essential": "true", "persistence_threshold": "0.5"}
    assert _requests.distance_parameters(2.5, None, 0.01, False)["relative_threshold"] == "0.01"
    with pytest.raises(actopo.InvalidArgumentError, match="relative_threshold: 'x'"):
        _requests.distance_parameters(2, None, "x", False)
    with pytest.raises(actopo.InvalidArgumentError, match="p: True is not a number"):
        _requests.distance_parameters(True, None, None, False)


def _chunk(field: str, name: str, values: np.ndarray, offset: int = 0,
           piece: slice = slice(None)) -> pb.RunJobResponse:
    data = values.tobytes()
    return pb.RunJobResponse(chunk=pb.ResultChunk(
        array=pb.Array(name=name, dtype=pb.DATA_TYPE_INT32, shape=list(values.shape),
                       data=data[piece]), offset=offset, total_bytes=len(data), field=field))


def _field(name: str, index: int, summary: dict, seconds: float) -> pb.RunJobResponse:
    response = pb.RunJobResponse(field=pb.FieldResult(field=name, index=index,
                                                      run_seconds=seconds))
    response.field.result.update(summary)
    return response


def _summary(summary: dict) -> pb.RunJobResponse:
    response = pb.RunJobResponse()
    response.summary.result.update(summary)
    return response


def test_a_job_over_fields_is_assembled_per_field():
    """Each field's arrays (ResultChunk.field) and summary (FieldResult) become its
    FieldResult as its FieldResult message arrives; the job's own summary and statistics are
    the job's; take_fields() hands each field out once."""
    a, b = np.arange(6, dtype=np.int32), np.arange(4, dtype=np.int32) * 7
    assembler = Assembler("critical-points")
    taken = []
    responses = [
        pb.RunJobResponse(accepted=pb.JobAccepted(job_id="j2")),
        pb.RunJobResponse(progress=pb.JobProgress(fraction=0.25, phase="run")),
        _chunk("a", "critical_points/CriticalType", a, 12, slice(12, None)),
        _chunk("a", "critical_points/CriticalType", a, 0, slice(0, 12)),
        _field("a", 0, {"counts": {"maximum": 2}}, 0.5),
        _chunk("b", "critical_points/CriticalType", b),
        _field("b", 1, {"counts": {"maximum": 3}}, 0.25),
        _summary({"fields": ["a", "b"]}),
        pb.RunJobResponse(stats=pb.JobStats(run_seconds=0.75)),
    ]
    for response in responses:
        assembler.feed(response)
        taken.append([f.field for f in assembler.take_fields()])
    assert taken == [[], [], [], [], ["a"], [], ["b"], [], []]
    result = assembler.result()
    assert result.summary == {"fields": ["a", "b"]} and result.arrays == {}
    assert result.stats.run_seconds == 0.75 and result.distance_matrix is None
    first, second = result.fields
    assert isinstance(first, FieldResult) and isinstance(first, actopo.JobResult)
    assert (first.field, first.index, first.run_seconds, first.job_id) == ("a", 0, 0.5, "j2")
    assert first.summary == {"counts": {"maximum": 2}} and first.stats is None
    np.testing.assert_array_equal(first.critical_points["CriticalType"], a)
    np.testing.assert_array_equal(second.critical_points["CriticalType"], b)
    assert second.algorithm == "critical-points" and repr(second).startswith("FieldResult('b'")
    streaming = Assembler("critical-points", keep_fields=False)
    for response in responses:
        streaming.feed(response)
    assert [f.field for f in streaming.take_fields()] == ["a", "b"]
    assert streaming.result().fields == []


def test_summaries_keep_infinite_numbers():
    struct = pb.JobSummary().result
    struct.update({"bottleneck": [[0.0, float("inf")], [float("inf"), 0.0]], "pairs": [3, 4]})
    summary = struct_to_dict(struct)
    assert summary["bottleneck"] == [[0, float("inf")], [float("inf"), 0]]
    assert isinstance(summary["pairs"][0], int)


# Three groups of fields, far apart, and a field between two of them.
POINTS = np.array([0.0, 0.4, 0.5, 10.0, 10.2, 10.9, 30.0, 30.5, 20.0])
NAMES = [f"f{i}" for i in range(len(POINTS))]
DISTANCES = np.abs(POINTS[:, None] - POINTS[None, :])


def _matrix(values: np.ndarray = DISTANCES, names=NAMES) -> DistanceMatrix:
    return from_summary({"fields": names, "wasserstein": values.tolist(),
                         "bottleneck": (values / 2).tolist(), "pairs": [1] * len(names),
                         "thresholds": [0.0] * len(names), "p": 2, "essential": False,
                         "distance_seconds": 0.1})


def test_average_linkage_is_scipys():
    merges = average_linkage(DISTANCES)
    expected = linkage(squareform(DISTANCES), method="average")
    np.testing.assert_allclose(merges, expected, rtol=0, atol=1e-12)
    rng = np.random.default_rng(7)
    for _ in range(20):
        points = rng.normal(size=(12, 3))
        values = np.sqrt(((points[:, None] - points[None]) ** 2).sum(-1))
        np.testing.assert_allclose(average_linkage(values),
                                   linkage(squareform(values, checks=False), "average"),
                                   rtol=0, atol=1e-12)


def test_groups_by_average_linkage():
    matrix = _matrix()
    assert matrix.groups(3).tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 1]
    assert matrix.groups(1).tolist() == [0] * 9
    assert matrix.groups(9).tolist() == list(range(9))
    assert matrix.groups(4).tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 3]
    assert matrix.groups(3, "bottleneck").tolist() == matrix.groups(3).tolist()
    # Labels follow the fields' order, whatever the order of the merges.
    order = [8, 6, 0, 3, 1, 7, 4, 2, 5]
    shuffled = _matrix(DISTANCES[np.ix_(order, order)], [NAMES[i] for i in order])
    assert shuffled.groups(3).tolist() == [0, 1, 2, 0, 2, 1, 0, 2, 0]
    for k in (0, 10, 2.5, True):
        with pytest.raises(actopo.InvalidArgumentError, match=r"k: .* is not a number of groups"):
            matrix.groups(k)
    with pytest.raises(actopo.InvalidArgumentError, match="unknown metric 'euclid'"):
        matrix.groups(2, "euclid")


def test_a_matrix_from_a_summary():
    matrix = _matrix()
    assert len(matrix) == 9 and matrix.fields == NAMES and matrix.p == 2.0
    assert matrix.wasserstein.dtype == np.float64 and matrix.wasserstein.shape == (9, 9)
    np.testing.assert_array_equal(matrix.bottleneck, DISTANCES / 2)
    assert repr(matrix) == "DistanceMatrix(9 fields, p=2, essential=False)"
    infinite = from_summary({"fields": ["a", "b"], "wasserstein": [[0, None], [None, 0]],
                             "bottleneck": [[0, float("inf")], [float("inf"), 0]],
                             "pairs": [1, 2], "thresholds": [0, 0], "p": 1, "essential": True})
    assert np.isinf(infinite.wasserstein[0, 1]) and np.isinf(infinite.bottleneck[1, 0])
    assert infinite.groups(1).tolist() == [0, 0] and infinite.groups(2).tolist() == [0, 1]
    with pytest.raises(actopo.ActopoError, match="'bottleneck' is not a 2 x 2 matrix"):
        from_summary({"fields": ["a", "b"], "wasserstein": [[0, 1], [1, 0]], "bottleneck": [[0]]})


def test_plot_a_matrix(tmp_path, monkeypatch):
    matrix = _matrix()
    path = matrix.plot(tmp_path / "with_scipy.png")
    assert path == str(tmp_path / "with_scipy.png")
    with_scipy = matrix.plot()  # an Axes of a new figure: the heat map, the dendrogram above
    leaves = dendrogram(matrix.linkage(), no_plot=True)["leaves"]
    assert leaves != list(range(9))
    assert [t.get_text() for t in with_scipy.get_xticklabels()] == [NAMES[i] for i in leaves]
    assert len(with_scipy.child_axes) == 1
    monkeypatch.setitem(sys.modules, "scipy.cluster.hierarchy", None)  # scipy is optional
    plain = matrix.plot(metric="bottleneck", title="half")
    assert [t.get_text() for t in plain.get_yticklabels()] == NAMES and not plain.child_axes
    assert plain.get_title() == "half"
    written = matrix.plot(tmp_path / "without_scipy.png")
    for image in (path, written):
        pixels = matplotlib.image.imread(image)
        assert pixels.shape[0] > 500 and pixels.shape[1] > 500
    # On axes of the caller's own, beside something else.
    from matplotlib.figure import Figure

    axes = Figure().subplots(1, 2)
    assert matrix.plot(axes[1]) is axes[1]


def test_rows_of_a_matrix_are_what_groups_see():
    """groups() of every k nests: merging continues from k to k - 1 groups."""
    matrix = _matrix()
    for k in range(9, 1, -1):
        finer, coarser = matrix.groups(k), matrix.groups(k - 1)
        for i, j in itertools.combinations(range(9), 2):
            if finer[i] == finer[j]:
                assert coarser[i] == coarser[j]
