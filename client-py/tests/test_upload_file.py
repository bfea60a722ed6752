"""Mesh files uploaded as their bytes (upload_file: CreateUpload, WriteUpload, GetUpload,
DeleteUpload, then LoadMesh of the upload): the same mesh and results as the server's own load
of the file, a .pvd with its files, resumption after a cut connection or a half-written upload,
every bad input named with the upload gone, the server's upload budget, upload count and
timeout, constant client memory, both clients, and the CLI."""

from __future__ import annotations

import asyncio
import hashlib
import json
import shutil
import subprocess
import sys
import threading
from collections import Counter
from pathlib import Path
from typing import Any

import grpc
import pytest
import pyvista as pv
from harness import run_cli, server_process, wait_until
from proxy import cutting_proxy
from references import ENTRY, check_summary, ttk

import actopo
from actopo import _file_upload, _mesh
from actopo._file_upload import Sender, upload_plan
from actopo._proto import pb
from actopo._stub import sync_stub
from actopo._types import UPLOAD_PHASES

SHAPE = ("vertices", "edges", "triangles", "tetrahedra", "blocks", "block_size")
LARGE_N = 70
"""The wavelet of the large file: 70^3 points, 1,642,545 tetrahedra, about 73 MB uncompressed."""
_WRITE_LARGE = """
import sys, vtk
n = int(sys.argv[1])
source = vtk.vtkRTAnalyticSource()
source.SetWholeExtent(-n // 2, n // 2 - 1, -n // 2, n // 2 - 1, -n // 2, n // 2 - 1)
tetrahedralize = vtk.vtkDataSetTriangleFilter()
tetrahedralize.SetInputConnection(source.GetOutputPort())
writer = vtk.vtkXMLUnstructuredGridWriter()
writer.SetInputConnection(tetrahedralize.GetOutputPort())
writer.SetFileName(sys.argv[2])
writer.SetDataModeToAppended()
writer.EncodeAppendedDataOff()
writer.SetCompressorTypeToNone()
sys.exit(0 if writer.Write() else 1)
"""
# A client in a process of its own: its peak resident size before and after uploading a file.
_MEASURE_MEMORY = """
import json, resource, sys
import actopo
with actopo.Client(sys.argv[1]) as client:
    client.server_info()
    baseline = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    mesh = client.upload_file(sys.argv[2])
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    client.delete_mesh(mesh)
print(json.dumps({"baseline_kib": baseline, "peak_kib": peak, "tetrahedra": mesh.tetrahedra}))
"""


@pytest.fixture(scope="module")
def large_vtu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """ParaView's Wavelet on 70^3 points as an uncompressed .vtu of about 73 MB (VTK writes it
    in a process of its own, in a fraction of a second)."""
    path = tmp_path_factory.mktemp("large") / "wavelet70.vtu"
    subprocess.run([sys.executable, "-c", _WRITE_LARGE, str(LARGE_N), str(path)], check=True,
                   timeout=300)
    assert path.stat().st_size > 60 << 20
    return path


def _upload_file(kind: str, target: str, path: Path | str, **kwargs: Any) -> actopo.MeshInfo:
    """upload_file() with a new blocking ("sync") or asyncio ("async") client on `target`."""
    if kind == "sync":
        with actopo.Client(target) as client:
            return client.upload_file(path, **kwargs)

    async def main() -> actopo.MeshInfo:
        async with actopo.AsyncClient(target) as client:
            return await client.upload_file(path, **kwargs)

    return asyncio.run(main())


def _created_ids(client: actopo.Client | actopo.AsyncClient,
                 monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The ids of the uploads the client creates from now on (its CreateUpload answers)."""
    ids: list[str] = []
    create = client._stub.CreateUpload
    if isinstance(client, actopo.AsyncClient):
        async def spy_async(request: Any, **kwargs: Any) -> Any:
            response = await create(request, **kwargs)
            ids.append(response.upload.upload_id)
            return response
        monkeypatch.setattr(client._stub, "CreateUpload", spy_async)
    else:
        def spy(request: Any, **kwargs: Any) -> Any:
            response = create(request, **kwargs)
            ids.append(response.upload.upload_id)
            return response
        monkeypatch.setattr(client._stub, "CreateUpload", spy)
    return ids


def _gone(target: str, upload_id: str) -> bool:
    """Whether the server no longer has the upload (GetUpload answers NOT_FOUND)."""
    with grpc.insecure_channel(target) as channel:
        try:
            sync_stub(channel).GetUpload(pb.GetUploadRequest(upload_id=upload_id), timeout=30)
        except grpc.RpcError as e:
            assert e.code() == grpc.StatusCode.NOT_FOUND, e
            assert f"no upload '{upload_id}'" in (e.details() or "")
            return True
    return False


def _create(stub: Any, files: list[tuple[str, bytes]], sha256: str | None = None) -> str:
    """A raw CreateUpload of files given as (path, bytes); `sha256` in place of the first's."""
    infos = [pb.UploadFileInfo(path=p, size=len(data), sha256=hashlib.sha256(data).hexdigest())
             for p, data in files]
    if sha256 is not None:
        infos[0].sha256 = sha256
    return str(stub.CreateUpload(pb.CreateUploadRequest(files=infos), timeout=30)
               .upload.upload_id)


def _write(upload_id: str, data: bytes, offset: int = 0,
           file: int = 0) -> list[pb.WriteUploadRequest]:
    return [pb.WriteUploadRequest(start=pb.WriteUploadStart(upload_id=upload_id, file=file,
                                                            offset=offset)),
            *(pb.WriteUploadRequest(chunk=data[k:k + (1 << 20)])
              for k in range(0, len(data), 1 << 20))]


@pytest.fixture
def stub(server: str) -> Any:
    with grpc.insecure_channel(server) as channel:
        yield sync_stub(channel)


# The same mesh as the server's own load.


def test_an_uploaded_file_is_the_servers_own_load_of_it(client, data_dir):
    """fertility_tet.vtu uploaded and loaded from the data directory: the same counts, fields
    and discrete gradient (digests); progress sends, then loads."""
    reports: list[actopo.LoadProgress] = []
    uploaded = client.upload_file(data_dir / "fertility_tet.vtu", block_size=500,
                                  progress=reports.append)
    loaded = client.load_mesh("fertility_tet.vtu", block_size=500)
    try:
        assert (uploaded.name, uploaded.source) == ("fertility_tet.vtu",
                                                    "upload:fertility_tet.vtu")
        a, b = (client.get_mesh(m, count_faces=True) for m in (uploaded, loaded))
        assert [getattr(a, k) for k in SHAPE] == [getattr(b, k) for k in SHAPE]
        assert a.fields == b.fields
        summaries = []
        for mesh in (uploaded, loaded):
            with client.open_session(mesh, scalar="eigenfunction4") as session:
                summaries.append(session.run("discrete-gradient", include_arrays=False,
                                             digests=True).summary)
        assert summaries[0] == summaries[1]
        check_summary("discrete-gradient", summaries[0],
                      ttk("fertility_tet.vtu", "eigenfunction4")["discrete_gradient"],
                      digests=True)
    finally:
        client.delete_mesh(uploaded)
        client.delete_mesh(loaded)
    phases = [r.phase for r in reports]
    assert list(dict.fromkeys(phases)) == list(UPLOAD_PHASES)
    sent = [r for r in reports if r.phase == "send"]
    size = (data_dir / "fertility_tet.vtu").stat().st_size
    assert sent[-1].sent_bytes == sent[-1].total_bytes == size and sent[-1].fraction == 1.0
    assert [r.sent_bytes for r in sent] == sorted(r.sent_bytes or 0 for r in sent)
    assert all(r.sent_bytes is None for r in reports if r.phase != "send")


def test_an_image_file_uploads_as_the_server_loads_it(client, data_dir):
    """A .vti: split into tetrahedra by the server as when it loads it from its folder."""
    name = "001_density_001_064_2.0.vti"
    uploaded = client.upload_file(data_dir / name)
    loaded = client.load_mesh(name)
    try:
        assert [getattr(uploaded, k) for k in SHAPE] == [getattr(loaded, k) for k in SHAPE]
        assert uploaded.fields == loaded.fields and uploaded.tetrahedra > 0
    finally:
        client.delete_mesh(uploaded)
        client.delete_mesh(loaded)


def test_upload_mesh_sends_a_mesh_file_as_its_bytes_and_arrays_as_arrays(client, data_dir):
    """upload_mesh() of a .vtu path takes the file path (source upload:NAME, its name kept with
    the extension); arrays go as int32 tetrahedra, gzip-compressed on request."""
    path = data_dir / "manifoldCheck1_tet.vtu"
    mesh = client.upload_mesh(str(path), name="mc1")
    assert (mesh.name, mesh.source, mesh.tetrahedra) == ("mc1.vtu", "upload:mc1.vtu", 24)
    client.delete_mesh(mesh)
    arrays = _mesh.mesh_arrays(path)
    assert arrays.tetrahedra.dtype == "int32"
    mesh = client.upload_mesh(arrays, compression=grpc.Compression.Gzip)
    assert (mesh.source, mesh.vertices, mesh.tetrahedra) == ("upload", 24, 24)
    client.delete_mesh(mesh)


def test_a_pvd_goes_with_the_files_it_names(client, data_dir, tmp_path):
    """A .pvd naming two files in a subfolder (one as ./series/...): the same series as the
    files loaded as a list with the same times."""
    series = tmp_path / "series"
    series.mkdir()
    names = ["isabel_series_s2/isabel_02_s2_tet.vtu", "isabel_series_s2/isabel_03_s2_tet.vtu"]
    for k, name in enumerate(names):
        shutil.copy(data_dir / name, series / f"a_{k}.vtu")
    (tmp_path / "steps.pvd").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n'
        '    <DataSet timestep="2" part="0" file="series/a_0.vtu"/>\n'
        '    <DataSet timestep="3" part="0" file="./series/a_1.vtu"/>\n'
        "  </Collection>\n</VTKFile>\n")
    files = upload_plan(tmp_path / "steps.pvd")
    assert [f.name for f in files] == ["steps.pvd", "series/a_0.vtu", "series/a_1.vtu"]
    uploaded = client.upload_file(tmp_path / "steps.pvd")
    loaded = client.load_mesh(names, times=[2, 3])
    try:
        assert (uploaded.name, uploaded.source) == ("steps.pvd", "upload:steps.pvd")
        assert [(f.name, f.time) for f in uploaded.fields] == [("velocityMag_0", 2.0),
                                                              ("velocityMag_1", 3.0)]
        assert uploaded.fields == loaded.fields
        assert (uploaded.vertices, uploaded.tetrahedra) == (loaded.vertices, loaded.tetrahedra)
    finally:
        client.delete_mesh(uploaded)
        client.delete_mesh(loaded)


@pytest.mark.parametrize("entry,error", [
    ("../outside.vtu", actopo.InvalidArgumentError), ("/abs/a.vtu", actopo.InvalidArgumentError),
    ("series/missing.vtu", FileNotFoundError)])
def test_a_pvd_naming_files_outside_its_folder_or_missing_is_refused(client, tmp_path, entry,
                                                                    error):
    """Before anything is sent: the error names the .pvd and its entry."""
    pvd = tmp_path / "bad.pvd"
    pvd.write_text(f'<VTKFile type="Collection"><Collection><DataSet file="{entry}"/>'
                   "</Collection></VTKFile>")
    with pytest.raises(error) as e:
        client.upload_file(pvd)
    assert str(pvd) in str(e.value) and entry.lstrip("/") in str(e.value)
    if isinstance(e.value, actopo.ActopoError):
        assert e.value.code is None


# Resuming.


@pytest.mark.parametrize("kind", ["sync", "async"])
def test_a_cut_connection_resumes_and_sends_the_file_about_once(server, large_vtu, kind):
    """The connection reset half way through the file (a proxy in front of the server): the
    client asks what the server holds and goes on; all it sent, every call and the resent
    chunk included, is under 1.1 times the file."""
    size = large_vtu.stat().st_size
    with cutting_proxy(server, cut_after=size // 2) as proxy:
        mesh = _upload_file(kind, proxy.target, large_vtu)
        assert proxy.cuts == 1
        assert size <= proxy.sent <= 1.1 * size, proxy.sent / size
    assert mesh.tetrahedra == 5 * (LARGE_N - 1) ** 3 and mesh.vertices == LARGE_N ** 3
    with actopo.Client(server) as client:
        client.delete_mesh(mesh)


def test_a_half_written_upload_goes_on_from_what_the_server_holds(client, stub, data_dir):
    """A raw WriteUpload that sends half the chunks and is cancelled; GetUpload says how much
    the server holds; the client's writer sends the rest only, and the upload loads."""
    path = data_dir / "isabel_series_s2_tet.vtu"
    files = upload_plan(path)
    data = path.read_bytes()
    upload_id = str(stub.CreateUpload(_file_upload.create_request(files), timeout=30)
                    .upload.upload_id)
    messages = _write(upload_id, data)
    half = messages[:1 + (len(messages) - 1) // 2]
    half_bytes = sum(len(m.chunk) for m in half)
    cancelled = threading.Event()

    def requests() -> Any:
        yield from half
        cancelled.wait(60)

    def held() -> int:
        status = stub.GetUpload(pb.GetUploadRequest(upload_id=upload_id), timeout=30).upload
        return int(status.received_bytes[0])

    call = stub.WriteUpload.future(requests(), timeout=60)
    wait_until(lambda: held() == half_bytes, "the first half to be held")
    call.cancel()
    cancelled.set()
    status = stub.GetUpload(pb.GetUploadRequest(upload_id=upload_id), timeout=30).upload
    assert status.received_bytes[0] == half_bytes and not status.complete
    sender = Sender(files)
    reports: list[actopo.LoadProgress] = []
    client._send(sender, status, _Reports(reports))
    assert sender.sent_bytes == len(data) - half_bytes
    assert reports[0].sent_bytes == half_bytes and reports[-1].sent_bytes == len(data)
    request = _file_upload.build_load_upload(upload_id, pb.PartitionOptions())
    mesh = client._load_reporting(request, _Reports([]))
    assert (mesh.vertices, mesh.tetrahedra) == (51597, 230640)
    client.delete_mesh(mesh)
    assert _gone(client.target, upload_id)  # loading takes it


class _Reports:
    """A progress sink that keeps the reports."""

    def __init__(self, reports: list[actopo.LoadProgress]) -> None:
        self.reports = reports

    def update(self, report: actopo.LoadProgress) -> None:
        self.reports.append(report)

    def close(self) -> None:
        pass


def test_a_server_out_of_reach_for_a_moment_is_waited_for(server, large_vtu):
    """After the cut the proxy refuses connections for a second: GetUpload's own retries and
    the resumption's backoff carry the upload over the gap."""
    size = large_vtu.stat().st_size
    with cutting_proxy(server, cut_after=size // 3, down_after_cut=1.0) as proxy:
        mesh = _upload_file("sync", proxy.target, large_vtu)
        assert proxy.cuts == 1 and proxy.refused >= 1 and proxy.sent <= 1.1 * size
    with actopo.Client(server) as client:
        client.delete_mesh(mesh)


def test_without_retries_a_cut_connection_fails_and_deletes_the_upload(server, large_vtu,
                                                                       monkeypatch):
    size = large_vtu.stat().st_size
    with cutting_proxy(server, cut_after=size // 2) as proxy:
        with actopo.Client(proxy.target, retries=False) as client:
            ids = _created_ids(client, monkeypatch)
            with pytest.raises(actopo.UnavailableError):
                client.upload_file(large_vtu)
    assert len(ids) == 1 and _gone(server, ids[0])


# Bad input: each named, the upload gone.


def test_a_wrong_sha256_is_data_loss_and_drops_the_upload(stub, server, client, data_dir,
                                                          monkeypatch):
    data = b"0123456789" * 1000
    upload_id = _create(stub, [("a.vtu", data)], sha256="0" * 64)
    with pytest.raises(grpc.RpcError) as e:
        stub.WriteUpload(iter(_write(upload_id, data)), timeout=30)
    assert e.value.code() == grpc.StatusCode.DATA_LOSS
    assert "files[0] 'a.vtu'" in e.value.details() and "0" * 64 in e.value.details()
    assert _gone(server, upload_id)
    # The client's own: a file that changed after it was hashed.
    plan = upload_plan

    def wrong_digest(path: Any, name: Any = None) -> list[_file_upload.LocalFile]:
        return [_file_upload.LocalFile(f.path, f.name, f.size, "f" * 64)
                for f in plan(path, name)]

    monkeypatch.setattr(_file_upload, "upload_plan", wrong_digest)
    ids = _created_ids(client, monkeypatch)
    with pytest.raises(actopo.DataLossError, match=r"manifoldCheck2_tet\.vtu"):
        client.upload_file(data_dir / "manifoldCheck2_tet.vtu")
    assert len(ids) == 1 and _gone(server, ids[0])


def test_a_file_that_is_not_a_mesh_is_named_and_dropped(client, server, tmp_path, monkeypatch):
    notes = tmp_path / "notes.vtu"
    notes.write_text("not a mesh\n" * 100)
    ids = _created_ids(client, monkeypatch)
    with pytest.raises(actopo.InvalidMeshError, match=r"notes\.vtu") as e:
        client.upload_file(notes)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert len(ids) == 1 and _gone(server, ids[0])
    (tmp_path / "notes.txt").write_text("not a mesh\n")
    with pytest.raises(actopo.InvalidArgumentError, match="upload_mesh"):
        client.upload_file(tmp_path / "notes.txt")
    with pytest.raises(FileNotFoundError, match=r"nosuch\.vtu"):
        client.upload_file(tmp_path / "nosuch.vtu")


def test_a_triangle_mesh_is_refused_by_the_server_naming_it(client, server, data_dir,
                                                            monkeypatch):
    ids = _created_ids(client, monkeypatch)
    with pytest.raises(actopo.InvalidMeshError, match="36290 triangle") as e:
        client.upload_mesh(data_dir / "happi_tas_tri.vtu")
    assert "happi_tas_tri.vtu" in str(e.value)
    assert len(ids) == 1 and _gone(server, ids[0])


def test_more_bytes_than_announced_drop_the_upload(stub, server):
    data = b"x" * 100
    upload_id = _create(stub, [("a.vtu", data)])
    with pytest.raises(grpc.RpcError) as e:
        stub.WriteUpload(iter(_write(upload_id, data + b"y")), timeout=30)
    assert e.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert "files[0] 'a.vtu': more than the 100 bytes announced" in e.value.details()
    assert _gone(server, upload_id)


def test_an_incomplete_upload_does_not_load(stub, server):
    """LoadMesh of an upload missing bytes: FAILED_PRECONDITION saying what is held; the
    upload stays, to be finished (or deleted)."""
    data = b"x" * 100
    upload_id = _create(stub, [("a.vtu", data)])
    stub.WriteUpload(iter(_write(upload_id, data[:40])), timeout=30)
    with pytest.raises(grpc.RpcError) as e:
        stub.LoadMesh(pb.LoadMeshRequest(upload=upload_id), timeout=30)
    assert e.value.code() == grpc.StatusCode.FAILED_PRECONDITION
    assert "holds 40 of the 100 bytes" in e.value.details()
    stub.DeleteUpload(pb.DeleteUploadRequest(upload_id=upload_id), timeout=30)
    assert _gone(server, upload_id)


@pytest.mark.parametrize("kind", ["sync", "async"])
@pytest.mark.parametrize("stop", [KeyboardInterrupt, RuntimeError])
def test_ctrl_c_or_a_raising_callback_mid_send_deletes_the_upload(server, data_dir, kind,
                                                                  stop, monkeypatch):
    """The progress callable raises (as Ctrl-C would arrive) while the bytes go, over a slow
    link: the call stops, the upload is deleted, the exception propagates. The link carries
    200 kB/s: the DeleteUpload would wait behind the megabytes the stopped write left in the
    client's connection for longer than its deadline; it goes on a connection of its own."""
    path = data_dir / "isabel_series_s2_tet.vtu"

    # The first report of bytes handed to gRPC (it may take the whole file into its buffers
    # before the slow link has carried much: the proxy's count says what went).
    def callback(report: actopo.LoadProgress) -> None:
        if report.phase == "send" and (report.sent_bytes or 0) > 0:
            raise stop("stop")

    async def run_async(target: str) -> list[str]:
        async with actopo.AsyncClient(target) as client:
            ids = _created_ids(client, monkeypatch)
            with pytest.raises(stop):
                await client.upload_file(path, progress=callback)
        return ids

    with cutting_proxy(server, rate=2e5) as proxy:
        if kind == "async":
            ids = asyncio.run(run_async(proxy.target))
        else:
            with actopo.Client(proxy.target) as client:
                ids = _created_ids(client, monkeypatch)
                with pytest.raises(stop):
                    client.upload_file(path, progress=callback)
        assert proxy.sent < path.stat().st_size
    assert len(ids) == 1 and _gone(server, ids[0])


# The server's limits: its upload budget, upload count and timeout.


def test_the_limits_are_reported_and_enforced(data_dir):
    """A server with a 1 MiB upload budget and at most 2 uploads."""
    with server_process("--upload-budget-mib", "1", "--max-uploads", "2") as process, \
            actopo.Client(process.target) as client:
        limits = client.server_info().limits
        assert (limits.upload_budget_bytes, limits.max_uploads,
                limits.upload_timeout_seconds) == (1 << 20, 2, 900)
        with pytest.raises(actopo.ResourceExhaustedError, match="upload"):
            client.upload_file(data_dir / "fertility_tet.vtu")  # 1.1 MB
        mesh = client.upload_file(data_dir / "manifoldCheck0_tet.vtu")
        assert mesh.tetrahedra == 24
        stub = sync_stub(client._channel)
        held = [_create(stub, [(f"{k}.vtu", b"x")]) for k in range(2)]
        with pytest.raises(actopo.ResourceExhaustedError, match="2 uploads"):
            client.upload_file(data_dir / "manifoldCheck0_tet.vtu")
        for upload_id in held:
            stub.DeleteUpload(pb.DeleteUploadRequest(upload_id=upload_id), timeout=30)


def test_an_abandoned_upload_is_dropped_after_the_timeout(tmp_path):
    """A server that drops an upload left alone for 1 s, with a 1 MiB budget and an upload
    folder of the test's: an upload left half written goes, its folder with it, and its
    bytes leave the budget: an upload of the whole budget fits again."""
    folder = tmp_path / "spool"
    with server_process("--upload-budget-mib", "1", "--upload-timeout-s", "1", "--upload-dir",
                        str(folder)) as process, \
            grpc.insecure_channel(process.target) as channel:
        stub = sync_stub(channel)
        data = b"x" * (900 << 10)
        upload_id = _create(stub, [("big.vtu", data)])
        stub.WriteUpload(iter(_write(upload_id, data[:1000])), timeout=30)
        assert (folder / upload_id / "big.vtu").stat().st_size == 1000
        with pytest.raises(grpc.RpcError) as e:
            _create(stub, [("again.vtu", data)])
        assert e.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED
        wait_until(lambda: _gone(process.target, upload_id), "the abandoned upload to go")
        assert not (folder / upload_id).exists()
        again = _create(stub, [("again.vtu", data)])
        stub.DeleteUpload(pb.DeleteUploadRequest(upload_id=again), timeout=30)


# Memory.


def test_the_clients_memory_stays_constant_whatever_the_files_size(server, large_vtu):
    """A 73 MB file uploaded by a client in a process of its own: its peak resident size
    grows by less than 100 MB over what it had once connected (a decoded upload of it holds
    the arrays, some 60 MB of int64 tetrahedra alone)."""
    done = subprocess.run([sys.executable, "-c", _MEASURE_MEMORY, server, str(large_vtu)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    figures = json.loads(done.stdout)
    assert figures["tetrahedra"] == 5 * (LARGE_N - 1) ** 3
    grown = (figures["peak_kib"] - figures["baseline_kib"]) * 1024
    assert grown < 100e6, f"the client grew by {grown / 1e6:.0f} MB"


# The command line.


def test_cli_run_upload_and_mesh_of_a_local_file(server, data_dir, tmp_path):
    """`run --upload FILE` and `run --mesh FILE` of a file the server's data directory does not
    have (--mesh says it uploads it), `load FILE`, `upload FILE --name`: TTK's results, the
    meshes gone after `run`, the file's bytes sent."""
    mine = tmp_path / "mine.vtu"
    shutil.copy(data_dir / "manifoldCheck1_tet.vtu", mine)
    expected = ttk("manifoldCheck1_tet.vtu", "height")[ENTRY["critical-points"]]
    with actopo.Client(server) as client:
        before = {m.mesh_id for m in client.list_meshes()}
        for args in (["--upload", str(mine)], ["--mesh", "mine.vtu"]):
            done = run_cli(server, "run", "critical-points", *args, "--json", "--digests",
                           cwd=tmp_path)
            assert done.returncode == 0, done.stderr
            report = json.loads(done.stdout)
            assert report["mesh"]["source"] == "upload:mine.vtu"
            check_summary("critical-points", report["result"], expected, digests=True)
            if args[0] == "--mesh":
                assert done.stderr == ("actopo: mine.vtu is not in the server's data directory: "
                                       "uploading the local file\n")
        assert {m.mesh_id for m in client.list_meshes()} == before
        done = run_cli(server, "load", str(mine), "--json")
        assert done.returncode == 0, done.stderr
        loaded = json.loads(done.stdout)
        assert loaded["source"] == f"upload:{mine.name}"
        done = run_cli(server, "upload", str(mine), "--name", "mc1", "--json")
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout)["name"] == "mc1.vtu"
        for mesh in (loaded, json.loads(done.stdout)):
            client.delete_mesh(mesh["mesh_id"])
    done = run_cli(server, "run", "critical-points", "--mesh", "nosuch.vtu", cwd=tmp_path)
    assert done.returncode == 1 and "'nosuch.vtu' not found in the data directory" in done.stderr


def test_cli_output_writes_the_segmentation_on_the_uploaded_file(server, data_dir, tmp_path):
    mine = tmp_path / "mine.vtu"
    shutil.copy(data_dir / "manifoldCheck0_tet.vtu", mine)
    done = run_cli(server, "run", "morse-smale", "--upload", str(mine), "--output",
                   str(tmp_path / "out" / "m"), env={"ACTOPO_DATA_DIR": ""})
    assert done.returncode == 0, done.stderr
    assert "not written" not in done.stderr
    # On the file's geometry, which brings its own point field along (a download would not).
    assert "height" in pv.read(tmp_path / "out" / "m_segmentation.vtu").point_data


# The decisions, offline.


def test_what_a_failed_write_means():
    def error(code: grpc.StatusCode, details: str = "") -> grpc.RpcError:
        failure = grpc.RpcError()
        failure.code = lambda: code  # type: ignore[attr-defined]
        failure.details = lambda: details  # type: ignore[attr-defined]
        return failure

    resumable = _file_upload.resumable
    for code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.CANCELLED,
                 grpc.StatusCode.DEADLINE_EXCEEDED, grpc.StatusCode.INTERNAL,
                 grpc.StatusCode.UNKNOWN):
        assert resumable(error(code)), code
    for code in (grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.DATA_LOSS,
                 grpc.StatusCode.NOT_FOUND, grpc.StatusCode.RESOURCE_EXHAUSTED,
                 grpc.StatusCode.UNAUTHENTICATED):
        assert not resumable(error(code)), code
    precondition = grpc.StatusCode.FAILED_PRECONDITION
    assert resumable(error(precondition, "offset: 0, but the server holds 1048576 bytes of "
                                         "files[0] 'a.vtu'; go on from there"))
    assert resumable(error(grpc.StatusCode.ABORTED, "upload 'u' was taken over by a newer "
                                                    "WriteUpload call"))
    assert not resumable(error(precondition, "something else"))
    # Five calls in a row that move nothing forward, each after a longer wait; then the error.
    files = [_file_upload.LocalFile(Path("a.vtu"), "a.vtu", 10, "0" * 64)]
    sender = Sender(files)
    status = pb.UploadStatus(upload_id="u", received_bytes=[0])
    assert sender.next_write(status) == (0, 0)
    delays = [sender.failed(error(grpc.StatusCode.UNAVAILABLE)) for _ in range(4)]
    assert all(0.8 * 0.2 * 2**k <= d <= 1.2 * 0.2 * 2**k for k, d in enumerate(delays))
    with pytest.raises(actopo.UnavailableError, match="after 5 attempts"):
        sender.failed(error(grpc.StatusCode.UNAVAILABLE, "reset"))
    # Progress starts the count afresh.
    sender = Sender(files)
    sender.next_write(status)
    for held in range(1, 8):
        sender.failed(error(grpc.StatusCode.UNAVAILABLE))
        assert sender.next_write(pb.UploadStatus(upload_id="u", received_bytes=[held])) == \
            (0, held)
    assert sender.next_write(pb.UploadStatus(upload_id="u", received_bytes=[10])) is None
    with pytest.raises(actopo.InvalidArgumentError):
        Sender(files, retries=False).failed(error(grpc.StatusCode.INVALID_ARGUMENT))
    with pytest.raises(actopo.UnavailableError) as e:
        Sender(files, retries=False).failed(error(grpc.StatusCode.UNAVAILABLE))
    assert "attempts" not in str(e.value)


def test_a_server_without_file_uploads_gets_the_files_arrays(data_dir):
    """upload_mesh() of a .vtu on a server that answers CreateUpload UNIMPLEMENTED (a stand-in:
    grpc's Python server with UploadMesh alone) falls back to the decoded upload."""
    from concurrent.futures import ThreadPoolExecutor

    received: list[pb.UploadMeshRequest] = []

    def upload_mesh(requests: Any, context: Any) -> pb.UploadMeshResponse:
        received.extend(requests)
        header = received[0].header
        return pb.UploadMeshResponse(mesh=pb.MeshInfo(
            mesh_id="mesh-1", name=header.name, source="upload",
            vertices=header.num_vertices, tetrahedra=header.num_tetrahedra))

    server = grpc.server(ThreadPoolExecutor(2))
    handler = grpc.stream_unary_rpc_method_handler(
        upload_mesh, request_deserializer=pb.UploadMeshRequest.FromString,
        response_serializer=lambda m: m.SerializeToString())
    server.add_generic_rpc_handlers([grpc.method_handlers_generic_handler(
        "actopo.v1.TopologyService", {"UploadMesh": handler})])
    target = f"127.0.0.1:{server.add_insecure_port('127.0.0.1:0')}"
    server.start()
    try:
        with actopo.Client(target) as client:
            mesh = client.upload_mesh(data_dir / "manifoldCheck0_tet.vtu")
            with pytest.raises(actopo.ActopoError) as e:
                client.upload_file(data_dir / "manifoldCheck0_tet.vtu")
        assert e.value.code == grpc.StatusCode.UNIMPLEMENTED
    finally:
        server.stop(None)
    assert (mesh.name, mesh.source, mesh.vertices, mesh.tetrahedra) == (
        "manifoldCheck0_tet.vtu", "upload", 29, 24)
    assert received[0].header.tetrahedra_dtype == pb.DATA_TYPE_INT32


def test_a_pvd_that_is_no_collection_is_refused_here(tmp_path):
    for text, said in (("<VTKFile><Collection></Collection></VTKFile>", "lists no DataSet"),
                       ("<VTKFile><Other/></VTKFile>", "not a ParaView collection"),
                       ("<VTKFile><Collection>", "not a ParaView collection")):
        pvd = tmp_path / "x.pvd"
        pvd.write_text(text)
        with pytest.raises(actopo.InvalidMeshError, match=said) as e:
            upload_plan(pvd)
        assert str(pvd) in str(e.value) and e.value.code is None


def test_names_in_an_upload():
    name = _file_upload.upload_name
    assert name(Path("d/wave.vtu"), None) == "wave.vtu"
    assert name(Path("d/wave.vtu"), "w") == "w.vtu"
    assert name(Path("d/wave.VTU"), "w.vtu") == "w.vtu"
    for bad in ("a/b", "..", "", "a\\b"):
        with pytest.raises(actopo.InvalidArgumentError, match="name"):
            name(Path("wave.vtu"), bad)
    assert _file_upload.is_mesh_file("a.PVD") and not _file_upload.is_mesh_file("a.msh")


def test_ctrl_c_while_the_load_waits_deletes_the_upload(shared_server, data_dir, monkeypatch):
    """SIGINT while the upload's load is held at its start on the server, before it takes the
    upload: the client deletes the upload, the load goes nowhere."""
    def loads() -> Counter[int]:
        return Counter(shared_server.requests("LoadMeshWithProgress"))

    with actopo.Client(shared_server.target) as client:
        ids = _created_ids(client, monkeypatch)
        before, loads_before = {m.mesh_id for m in client.list_meshes()}, loads()
        with shared_server.hold("LoadMeshWithProgress") as hold:
            sent = threading.Event()

            interrupter = threading.Thread(target=hold.interrupt_when_held, args=(sent,))
            interrupter.start()
            try:
                with pytest.raises(KeyboardInterrupt) as interrupted:
                    client.upload_file(data_dir / "manifoldCheck0_tet.vtu")
            finally:
                interrupter.join()
            assert sent.is_set() and hold.is_held
            assert len(ids) == 1 and _gone(shared_server.target, ids[0])
        # Let go, the load finds no upload or its call cancelled: it ends without a mesh.
        wait_until(lambda: (loads() - loads_before).total() >= 1,
                   "the server to end the stopped load")
        assert (loads() - loads_before)[grpc.StatusCode.OK.value[0]] == 0
        assert {m.mesh_id for m in client.list_meshes()} == before
        del interrupted  # held until here: the garbage collector must not cancel the call
