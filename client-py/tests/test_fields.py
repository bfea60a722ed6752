"""Fields added to and deleted from loaded meshes, and jobs over many fields, against a real
server: an added field gives the jobs of the same values uploaded with the mesh (and of TTK on
the series' members), every rejection of AddFields with its code and the field named, a series
loaded from a list of files as from the .pvd of them and field by field as each file alone (its
rejections naming the file), a deleted field left to the sessions that read it, a job over
fields equal to single-field jobs field by field on every structure, run_fields in order and
cancelled when closed early, and both clients alike. The distances between diagrams are in
test_distances.py."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import hashlib
import json
from collections import Counter

import grpc
import meshio
import numpy as np
import pytest
from harness import running_server, wait_until, wait_until_async
from meshes import lattice

import actopo
from actopo._errors import translated
from actopo._proto import pb

STRUCTURES = ["explicit", "compact", "actopo"]
ALGORITHMS = ["critical-points", "discrete-gradient", "morse-smale", "persistence-diagram",
              "topological-simplification"]


def _values(points: np.ndarray) -> dict[str, np.ndarray]:
    """Fields of the lattice besides its own "f" (float64) and "z" (float32): tie-free, one of
    each float dtype."""
    x, y, z = points.T
    index = np.arange(len(points))
    return {"g": np.cos(3 * x) * np.sin(4 * z) + 0.2 * y + 1e-7 * index,
            "h": (np.sin(2 * y) * x + 0.5 * z * z + 1e-6 * index).astype(np.float32)}


@pytest.fixture(scope="module")
def uploaded(client):
    """The lattice uploaded with all four fields, and uploaded with "f" alone, the other three
    added after: the same values, two ways."""
    points, tets, fields = lattice(8)
    extra = _values(points)
    whole = client.upload_mesh((points, tets, {**fields, **extra}), name="whole", block_size=64)
    part = client.upload_mesh((points, tets, {"f": fields["f"]}), name="part", block_size=64)
    part = client.add_fields(part, {"z": fields["z"], **extra})
    yield whole, part, {**fields, **extra}
    client.delete_mesh(whole)
    client.delete_mesh(part)


def _summary(client, mesh, field, algorithm, structure="compact"):
    with client.open_session(mesh, scalar=field, structure=structure) as session:
        return session.run(algorithm, include_arrays=False, digests=True).summary


def test_added_fields_are_described_as_uploaded_ones(uploaded):
    whole, part, values = uploaded
    assert [f.name for f in part.fields] == ["f", "z", "g", "h"]
    assert [dataclasses.replace(f, time=None) for f in part.fields] == whole.fields
    assert [(f.name, f.dtype) for f in part.fields] == [
        ("f", "float64"), ("z", "float32"), ("g", "float64"), ("h", "float32")]
    for info in part.fields:
        assert (info.min, info.max) == (float(values[info.name].min()),
                                        float(values[info.name].max()))
        assert info.time is None
    assert part.vertices == whole.vertices and part.bytes > 0


@pytest.mark.parametrize("field", ["z", "g", "h"])
@pytest.mark.parametrize("algorithm", ["critical-points", "persistence-diagram", "morse-smale"])
def test_a_job_on_an_added_field_is_the_job_on_the_uploaded_one(client, uploaded, field,
                                                                algorithm):
    """float32 and float64 fields, added or uploaded with the mesh: the same results, digests
    included."""
    whole, part, _ = uploaded
    assert _summary(client, part, field, algorithm) == _summary(client, whole, field, algorithm)


def test_series_members_added_from_their_files_give_ttks_diagrams(client, data_dir):
    """Steps 3 to 5 of the Isabel series added to the mesh of step 2 (read here from their own
    files, with their time steps): the persistence diagrams of upstream TTK."""
    expected = json.loads((data_dir / "expected-ttk-series.json").read_text())
    expected = expected["isabel_series_s2_tet.vtu"]
    folder = data_dir / "isabel_series_s2"
    steps = {f"velocityMag_0{t}": meshio.read(folder / f"isabel_0{t}_s2_tet.vtu")
             .point_data["velocityMag"] for t in (3, 4, 5)}
    mesh = client.load_mesh("isabel_series_s2/isabel_02_s2_tet.vtu")
    try:
        mesh = client.add_fields(mesh.mesh_id, steps, times={"velocityMag_05": 5,
                                                            "velocityMag_03": 3.0})
        assert [(f.name, f.time) for f in mesh.fields] == [
            ("velocityMag", None), ("velocityMag_03", 3.0), ("velocityMag_04", None),
            ("velocityMag_05", 5.0)]
        assert client.get_mesh(mesh).fields == mesh.fields
        for name in steps:
            ttk = expected[name]["upstream"]["persistence_diagram"]
            summary = _summary(client, mesh, name, "persistence-diagram")
            assert (summary["pairs_sha256"], summary["counts_by_type"]) == \
                (ttk["pairs_sha256"], ttk["counts_by_type"]), name
    finally:
        client.delete_mesh(mesh)


# A series given as a list of files (LoadMeshRequest.files).

ISABEL = "isabel_series_s2"
STEPS = [f"{ISABEL}/isabel_0{t}_s2_tet.vtu" for t in (2, 3, 4, 5)]


def test_a_list_of_files_loads_as_the_pvd_of_them(server, client, data_dir):
    """The four Isabel files with the .pvd's time steps: the fields of the .pvd (names, times,
    dtypes, ranges), by both clients, with the load's progress as for a path; without times,
    each file's index."""
    pvd = client.load_mesh(f"{ISABEL}/isabel_series.pvd")
    reports: list[actopo.LoadProgress] = []
    listed = client.load_mesh(STEPS, times=[2, 3, 4, 5], progress=reports.append)
    plain = client.load_mesh(STEPS[:2])

    async def load_async():
        async with actopo.AsyncClient(server) as aclient:
            return await aclient.load_mesh(STEPS, times=np.arange(2.0, 6.0))

    awaited = asyncio.run(load_async())
    try:
        assert [(f.name, f.time) for f in pvd.fields] == [
            ("velocityMag_0", 2.0), ("velocityMag_1", 3.0), ("velocityMag_2", 4.0),
            ("velocityMag_3", 5.0)]
        assert listed.fields == pvd.fields and awaited.fields == pvd.fields
        assert (listed.vertices, listed.tetrahedra) == (pvd.vertices, pvd.tetrahedra)
        assert listed.name == "isabel_02_s2_tet.vtu +3 files"
        assert listed.source == "files:" + ",".join(STEPS)
        assert [(f.name, f.time) for f in plain.fields] == [("velocityMag_0", 0.0),
                                                            ("velocityMag_1", 1.0)]
        assert list(dict.fromkeys(r.phase for r in reports)) == ["read", "partition", "encode"]
        read = [r.fraction for r in reports if r.phase == "read"]
        assert read == sorted(read) and read[-1] == pytest.approx(1.0)
    finally:
        for mesh in (pvd, listed, plain, awaited):
            client.delete_mesh(mesh)


def test_each_field_of_a_list_is_its_file_loaded_alone(client, data_dir):
    """Field k of the list is file k's velocityMag: described alike, the same persistence
    diagram and simplification (one job over the list's fields, a job on each file alone), and
    the simplified field differs from the file's values exactly where the simplification
    changed them."""
    listed = client.load_mesh(STEPS)
    alone = [client.load_mesh(path) for path in STEPS]
    simplify = {"persistence_threshold": "0.5"}
    try:
        with client.open_session(listed, structure="compact") as session:
            diagrams = session.run("persistence-diagram", fields="all", digests=True)
            simplified = session.run("topological-simplification", fields="all",
                                     parameters=simplify, digests=True)
        assert [r.field for r in simplified.fields] == [f.name for f in listed.fields]
        for k, (path, mesh) in enumerate(zip(STEPS, alone, strict=True)):
            field = listed.fields[k]
            assert field.name == f"velocityMag_{k}" and field.time == float(k)
            assert dataclasses.replace(field, name="velocityMag", time=None) == mesh.fields[0]
            with client.open_session(mesh, structure="compact") as session:
                diagram = session.run("persistence-diagram", digests=True)
                single = session.run("topological-simplification", parameters=simplify,
                                     digests=True)
            assert diagrams.fields[k].summary == diagram.summary, path
            assert simplified.fields[k].summary == single.summary, path
            ours, theirs = simplified.fields[k].simplified, single.simplified
            assert ours is not None and theirs is not None
            np.testing.assert_array_equal(ours.values, theirs.values, err_msg=path)
            np.testing.assert_array_equal(ours.order, theirs.order, err_msg=path)
            values = meshio.read(data_dir / path).point_data["velocityMag"]
            assert np.count_nonzero(ours.values != values) == single.summary["changed_values"]
    finally:
        for mesh in (listed, *alone):
            client.delete_mesh(mesh)


def test_a_bad_list_is_rejected_naming_the_file(client, shared_server):
    with _raises(actopo.NotFoundError, grpc.StatusCode.NOT_FOUND, "files.paths[1]",
                 "'isabel_series_s2/nope.vtu' not found"):
        client.load_mesh([STEPS[0], f"{ISABEL}/nope.vtu"])
    with _raises(actopo.InvalidMeshError, grpc.StatusCode.INVALID_ARGUMENT, "files.paths[1]",
                 "outside the server's data directory"):
        client.load_mesh([STEPS[0], "../x.vtu"])
    with _raises(actopo.InvalidMeshError, grpc.StatusCode.INVALID_ARGUMENT, "files.paths[0]",
                 "is a collection"):
        client.load_mesh([f"{ISABEL}/isabel_series.pvd"])
    with _raises(actopo.InvalidMeshError, grpc.StatusCode.INVALID_ARGUMENT,
                 "files: step 1: fertility_tet.vtu: has 14570 points, not 51597"):
        client.load_mesh([STEPS[0], "fertility_tet.vtu"], progress=lambda report: None)
    with _raises(actopo.InvalidMeshError, grpc.StatusCode.INVALID_ARGUMENT, "files.paths: empty"):
        client.load_mesh([])
    # What the client checks itself is not sent; the server checks it too.
    before = Counter(shared_server.requests("LoadMesh"))
    for kwargs, message in [({"times": [1.0]}, "times: 1 values for 2 paths"),
                            ({"times": [1.0, float("nan")]}, "times[1]: nan is not finite"),
                            ({"times": [1.0, "2"]}, "times[1]: '2' is not a number")]:
        with pytest.raises(actopo.InvalidArgumentError) as e:
            client.load_mesh(STEPS[:2], **kwargs)
        assert message in str(e.value) and e.value.code is None
    with pytest.raises(actopo.InvalidArgumentError, match="times: only with a list of paths"):
        client.load_mesh(STEPS[0], times=[2.0])
    with pytest.raises(actopo.InvalidArgumentError, match=r"path\[1\]: 3 is not a path"):
        client.load_mesh([STEPS[0], 3])
    assert Counter(shared_server.requests("LoadMesh")) == before
    request = pb.LoadMeshRequest(files=pb.FileSeries(paths=STEPS[:1], times=[1.0, 2.0]))
    with _raises(actopo.InvalidMeshError, grpc.StatusCode.INVALID_ARGUMENT,
                 "files.times: 2 values for 1 paths"):
        with translated(mesh=True):
            client._stub.LoadMesh(request, timeout=30, metadata=client._metadata)


@pytest.fixture
def small(client):
    points, tets, fields = lattice(4)
    mesh = client.upload_mesh((points, tets, fields), name="small")
    yield mesh
    with contextlib.suppress(actopo.NotFoundError):
        client.delete_mesh(mesh)


def _raw_add_fields(client, mesh_id: str, fields: list[tuple[str, int]], payload: bytes,
                    sha256: str | None = None) -> None:
    """AddFields with a header and bytes made here, as a client that does not check them
    would send them; `sha256` None: the payload's digest, "": unchecked."""
    digest = hashlib.sha256(payload).hexdigest() if sha256 is None else sha256
    header = pb.AddFieldsHeader(mesh_id=mesh_id, sha256=digest,
                                fields=[pb.UploadField(name=n, dtype=d) for n, d in fields])
    requests = [pb.AddFieldsRequest(header=header)]
    requests += [pb.AddFieldsRequest(chunk=payload[i:i + 1000])
                 for i in range(0, len(payload), 1000)]
    with translated():
        client._stub.AddFields(iter(requests), timeout=30, metadata=client._metadata)


def _raises(kind, code, *names):
    """pytest.raises of `kind`, then checks the gRPC code and that the message names each of
    `names`."""
    @contextlib.contextmanager
    def check():
        with pytest.raises(kind) as e:
            yield
        assert e.value.code == code, e.value
        for name in names:
            assert name in e.value.details, (name, e.value.details)
    return check()


def test_each_bad_input_is_rejected_with_its_code_naming_the_field(client, small):
    n = small.vertices
    ok = np.linspace(0, 1, n)
    nan = ok.copy()
    nan[5] = np.nan
    with _raises(actopo.NotFoundError, grpc.StatusCode.NOT_FOUND, "mesh-nope"):
        client.add_fields(dataclasses.replace(small, mesh_id="mesh-nope"), {"a": ok})
    with _raises(actopo.NotFoundError, grpc.StatusCode.NOT_FOUND, "mesh-nope"):
        client.add_field("mesh-nope", "a", ok)  # the client asks for the vertex count first
    with _raises(actopo.InvalidArgumentError, grpc.StatusCode.INVALID_ARGUMENT, "fields[1]"):
        client.add_fields(small, {"a": ok, "b": nan})
    with _raises(actopo.InvalidArgumentError, grpc.StatusCode.INVALID_ARGUMENT, "fields[0]"):
        client.add_fields(small, {"": ok})
    with _raises(actopo.AlreadyExistsError, grpc.StatusCode.ALREADY_EXISTS, "fields[1]", "'z'"):
        client.add_fields(small, {"a": ok, "z": ok})
    # What the client checks itself never reaches the server; a client that sends it anyway:
    raw = ok.astype("<f8").tobytes()
    with _raises(actopo.InvalidArgumentError, grpc.StatusCode.INVALID_ARGUMENT, "fields[1]"):
        _raw_add_fields(client, small.mesh_id, [("a", pb.DATA_TYPE_FLOAT64),
                                                ("b", pb.DATA_TYPE_INT32)], raw + raw[:4 * n])
    with _raises(actopo.InvalidArgumentError, grpc.StatusCode.INVALID_ARGUMENT, "fields[1]"):
        _raw_add_fields(client, small.mesh_id, [("a", pb.DATA_TYPE_FLOAT64),
                                                ("a", pb.DATA_TYPE_FLOAT64)], raw + raw)
    with _raises(actopo.InvalidArgumentError, grpc.StatusCode.INVALID_ARGUMENT):
        _raw_add_fields(client, small.mesh_id, [("a", pb.DATA_TYPE_FLOAT64)], raw[:-8], "")
    with _raises(actopo.InvalidArgumentError, grpc.StatusCode.INVALID_ARGUMENT):
        _raw_add_fields(client, small.mesh_id, [("a", pb.DATA_TYPE_FLOAT64)], raw + raw[:8], "")
    with _raises(actopo.ActopoError, grpc.StatusCode.DATA_LOSS):
        _raw_add_fields(client, small.mesh_id, [("a", pb.DATA_TYPE_FLOAT64)], raw,
                        hashlib.sha256(b"other bytes").hexdigest())
    # All or nothing: none of the fields above was added.
    assert [f.name for f in client.get_mesh(small).fields] == ["f", "z"]
    # The same field with its digest unchecked, then the right one: both taken.
    _raw_add_fields(client, small.mesh_id, [("a", pb.DATA_TYPE_FLOAT64)], raw, "")
    _raw_add_fields(client, small.mesh_id, [("b", pb.DATA_TYPE_FLOAT64)], raw)
    assert [f.name for f in client.get_mesh(small).fields] == ["f", "z", "a", "b"]


def test_the_client_rejects_before_sending(client, small, shared_server):
    before = Counter(shared_server.requests("AddFields"))
    for fields, message in [({"a": np.zeros(small.vertices + 1)}, "field 'a': 65 values"),
                            ({"a": np.zeros(small.vertices, np.float16)}, "dtype float16"),
                            ({"a": np.zeros((small.vertices, 2))}, "shape (64, 2)")]:
        with pytest.raises(actopo.InvalidArgumentError, match=None) as e:
            client.add_fields(small, fields)
        assert message in str(e.value) and e.value.code is None
    assert Counter(shared_server.requests("AddFields")) == before


def test_the_memory_budget_holds_added_fields():
    with running_server("--memory-budget-mib", "8") as target, actopo.Client(target) as client:
        points, tets, fields = lattice(20)  # 8000 vertices: 64 KB per float64 field
        mesh = client.upload_mesh((points, tets, fields))
        many = {f"m{i:03d}": np.full(mesh.vertices, float(i)) for i in range(160)}  # 10 MiB
        with _raises(actopo.ResourceExhaustedError, grpc.StatusCode.RESOURCE_EXHAUSTED):
            client.add_fields(mesh, many)
        assert [f.name for f in client.get_mesh(mesh).fields] == ["f", "z"]
        mesh = client.add_fields(mesh, dict(list(many.items())[:4]))  # 256 KB fit
        assert len(mesh.fields) == 6


def test_a_deleted_field_is_gone_and_its_sessions_keep_it(client, small):
    points, _, _ = lattice(4)
    values = _values(points)["g"]
    mesh = client.add_field(small, "w", values, time=1.5)
    assert (mesh.fields[-1].name, mesh.fields[-1].time) == ("w", 1.5)
    with client.open_session(mesh, scalar="w", structure="actopo") as session:
        before = session.run("persistence-diagram", digests=True)
        after_delete = client.delete_field(mesh, "w")
        assert [f.name for f in after_delete.fields] == ["f", "z"]
        assert [f.name for f in client.get_mesh(mesh).fields] == ["f", "z"]
        again = session.run("persistence-diagram", digests=True)
        assert again.summary == before.summary
        np.testing.assert_array_equal(again.diagram.sorted_pairs(), before.diagram.sorted_pairs())
        assert session.run("critical-points").summary["counts"]
    with pytest.raises(actopo.ActopoError, match="w"):
        client.open_session(mesh, scalar="w")
    with pytest.raises(actopo.ActopoError):  # nor can a job name it
        with client.open_session(mesh, scalar="f") as session:
            session.run("critical-points", fields=["f", "w"])
    with _raises(actopo.NotFoundError, grpc.StatusCode.NOT_FOUND, "w"):
        client.delete_field(mesh, "w")
    with _raises(actopo.NotFoundError, grpc.StatusCode.NOT_FOUND):
        client.delete_field("mesh-nope", "f")
    mesh = client.add_field(mesh, "w", values.astype(np.float32))  # the name is free again
    assert mesh.fields[-1].dtype == "float32" and mesh.fields[-1].time is None


def _same_result(field_result: actopo.types.FieldResult, single: actopo.JobResult) -> None:
    """A field's result in a job over fields is the job on that field alone: summary and every
    array."""
    where = field_result.field
    assert field_result.summary == single.summary, where
    assert list(field_result.arrays) == list(single.arrays), where
    for name, values in single.arrays.items():
        got = field_result.arrays[name]
        assert got.dtype == values.dtype, (where, name)
        np.testing.assert_array_equal(got, values, err_msg=f"{where} {name}")


@pytest.mark.parametrize("structure", STRUCTURES)
def test_a_job_over_fields_is_the_jobs_field_by_field(client, uploaded, structure):
    """Every algorithm over the four fields, in one job, on each structure: each field's
    summary (digests included) and arrays equal a job on that field alone."""
    mesh = uploaded[1]
    names = [f.name for f in mesh.fields]
    parameters = {"topological-simplification": {"relative_threshold": "0.05"}}
    with client.open_session(mesh, scalar="f", structure=structure) as session:
        for algorithm in ALGORITHMS:
            options = {"parameters": parameters.get(algorithm), "digests": True}
            many = session.run(algorithm, fields=["h", "f", "g"], **options)
            assert [(r.field, r.index) for r in many.fields] == [("h", 0), ("f", 1), ("g", 2)]
            assert many.summary == {"fields": ["h", "f", "g"]} and many.arrays == {}
            assert many.stats is not None and many.stats.run_seconds == pytest.approx(
                sum(r.run_seconds for r in many.fields), rel=1e-6, abs=1e-9)
            every = session.run(algorithm, fields="all", include_arrays=False, **options)
            assert [r.field for r in every.fields] == names
            for result in many.fields:
                with client.open_session(mesh, scalar=result.field,
                                         structure=structure) as alone:
                    single = alone.run(algorithm, **options)
                _same_result(result, single)
                assert result.run_seconds > 0 and result.algorithm == algorithm
                assert every.fields[names.index(result.field)].summary == single.summary
            if algorithm == "persistence-diagram":
                assert all(r.diagram is not None for r in many.fields)
            if algorithm == "topological-simplification":
                assert [r.simplified.name for r in many.fields] == ["h", "f", "g"]


def test_a_job_over_fields_rejects_what_it_cannot_run(client, small):
    with client.open_session(small, structure="compact") as session:
        with pytest.raises(actopo.ActopoError) as e:
            session.run("critical-points", fields=["f", "nope"])
        assert e.value.code in (grpc.StatusCode.NOT_FOUND, grpc.StatusCode.INVALID_ARGUMENT)
        assert "nope" in e.value.details
        with pytest.raises(actopo.InvalidArgumentError, match="fields: an empty list"):
            session.run("critical-points", fields=[])
        assert session.run("critical-points", fields=["z"]).fields[0].field == "z"


@pytest.fixture(scope="module")
def noisy(client):
    """A mesh whose fields take a noticeable time each (random values: many critical cells),
    for closing run_fields while the job still has fields to do."""
    points, tets, _ = lattice(24)
    rng = np.random.default_rng(3)
    fields = {f"r{i}": rng.permutation(len(points)) / len(points) for i in range(24)}
    mesh = client.upload_mesh((points, tets, fields), name="noisy")
    yield mesh
    client.delete_mesh(mesh)


@pytest.mark.parametrize("algorithm", ["persistence-diagram", "morse-smale"])
def test_run_fields_yields_in_order_as_each_is_done(client, noisy, algorithm):
    names = [f.name for f in noisy.fields][:3]
    fractions: list[float] = []
    with client.open_session(noisy, structure="compact") as session:
        got = list(session.run_fields(algorithm, names, digests=True,
                                      progress=fractions.append))
        assert [(r.field, r.index) for r in got] == [(n, i) for i, n in enumerate(names)]
        whole = session.run(algorithm, fields=names, digests=True)
        for streamed, kept in zip(got, whole.fields, strict=True):
            _same_result(streamed, kept)
    # The progress covers the whole list, to 1. (A persistence diagram's own progress goes
    # back within its run, on one field as on several: reported, not checked here.)
    assert fractions and fractions[-1] == pytest.approx(1.0)
    if algorithm == "morse-smale":
        assert fractions == sorted(fractions)


def test_closing_run_fields_early_cancels_the_job(client, noisy, shared_server):
    names = [f.name for f in noisy.fields]
    with client.open_session(noisy, structure="compact") as session:
        jobs = Counter(shared_server.requests("RunJob"))
        finished = session.stats().jobs.count
        with contextlib.closing(session.run_fields("morse-smale", names)) as results:
            first = next(results)
        assert first.index == 0 and first.field == names[0]
        # The server ends the call CANCELLED, the session runs no job any more, and the job
        # stopped before its last fields (the server counts each field done as a job).
        cancelled = grpc.StatusCode.CANCELLED.value[0]
        wait_until(lambda: Counter(shared_server.requests("RunJob"))[cancelled] > jobs[cancelled],
                   "the server to end the job CANCELLED")
        wait_until(lambda: session.describe().running_job_id is None, "the session to run no job")
        assert session.stats().jobs.count - finished < len(names)
        assert session.run("critical-points", fields=names[:1]).fields[0].field == names[0]


def test_both_clients_add_delete_and_run_over_fields(server, client):
    points, tets, fields = lattice(5)
    extra = _values(points)

    async def scenario():
        async with actopo.AsyncClient(server) as aclient:
            mesh = await aclient.upload_mesh((points, tets, fields), name="async fields")
            mesh = await aclient.add_fields(mesh.mesh_id, {"g": extra["g"]}, times=[2.0])
            mesh = await aclient.add_field(mesh, "h", extra["h"])
            deleted = await aclient.delete_field(mesh, "z")
            async with aclient.open_session(mesh, structure="actopo") as session:
                many = await session.run("persistence-diagram", fields="all", digests=True)
                streamed = [r async for r in session.run_fields("critical-points", ["h", "g"])]
                matrix = await session.distance_matrix(["f", "g", "h"], p=1)
                agen = session.run_fields("morse-smale", ["f", "g", "h"])
                first = await anext(agen)
                await agen.aclose()

                async def idle() -> bool:
                    return (await session.describe()).running_job_id is None

                await wait_until_async(idle, "the session to run no job")  # the cancel is done
                after_close = await session.run("critical-points", fields=["f"])
            return mesh, deleted, many, streamed, matrix, first, after_close

    mesh, deleted, many, streamed, matrix, first, after_close = asyncio.run(scenario())
    try:
        assert [(f.name, f.time) for f in mesh.fields] == [
            ("f", None), ("z", None), ("g", 2.0), ("h", None)]
        assert [f.name for f in deleted.fields] == ["f", "g", "h"]
        assert [r.field for r in many.fields] == ["f", "g", "h"]
        assert [r.field for r in streamed] == ["h", "g"] and first.field == "f"
        assert after_close.fields[0].field == "f"
        with client.open_session(mesh, structure="actopo") as session:
            again = session.run("persistence-diagram", fields="all", digests=True)
            for a, b in zip(many.fields, again.fields, strict=True):
                _same_result(a, b)
            assert session.distance_matrix(["f", "g", "h"], p=1).wasserstein.tolist() == \
                matrix.wasserstein.tolist()
        assert matrix.fields == ["f", "g", "h"] and matrix.p == 1.0
    finally:
        client.delete_mesh(mesh)
