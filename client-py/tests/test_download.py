"""Meshes downloaded from a real server (DownloadMesh): a loaded file comes back as read locally
(its points, its tetrahedra with their vertices as given, its fields with their dtypes), an
upload comes back as sent (integer and float32 fields, added fields with their times) and
uploads again as the same mesh, progress, pyvista and meshio, every rejection with its code,
and the asyncio client alike. The decoding of the stream alone is in test_offline.py."""

from __future__ import annotations

import asyncio

import grpc
import meshio
import numpy as np
import pytest
import pyvista as pv
from meshes import lattice

import actopo
from actopo._errors import translated
from actopo._proto import pb


def _same(mesh: actopo.types.MeshArrays, points: np.ndarray, tets: np.ndarray,
          fields: dict[str, np.ndarray]) -> None:
    """The downloaded `mesh` holds these arrays, values and dtypes alike, fields in order."""
    assert mesh.points.dtype == np.float64 and mesh.tetrahedra.dtype == np.int32
    np.testing.assert_array_equal(mesh.points, points)
    np.testing.assert_array_equal(mesh.tetrahedra, tets)
    assert list(mesh.point_data) == list(fields)
    for name, values in fields.items():
        assert mesh.point_data[name].dtype == values.dtype, name
        np.testing.assert_array_equal(mesh.point_data[name], values, err_msg=name)


@pytest.mark.parametrize("file", ["fertility_tet.vtu", "viscousFingers001_s2_tet.vtu",
                                  "isabel_series_s2_tet.vtu"])
def test_a_loaded_file_comes_back_as_read_locally(client, meshes, data_dir, file):
    """Points in input order, each tetrahedron's vertices in the file's order (most are not
    sorted), each field with the file's dtype (viscousFingers' density is float32)."""
    local = meshio.read(data_dir / file)
    tets = local.cells_dict["tetra"]
    assert (np.diff(tets, axis=1) < 0).any()  # the order as given is what is compared
    info = meshes(file)
    fields = {k: np.asarray(v) for k, v in local.point_data.items()}
    everything = client.download_mesh(info, "all")
    assert everything.name == file and everything.times == {}
    _same(everything, local.points, tets, fields)
    bare = client.download_mesh(info.mesh_id)  # by id; no fields
    _same(bare, local.points, tets, {})
    last = list(fields)[-1]
    _same(client.download_mesh(info, [last]), local.points, tets, {last: fields[last]})
    _same(client.download_mesh(info, []), local.points, tets, {})


def test_an_upload_comes_back_as_sent_and_uploads_again_as_itself(client):
    """Integer and float fields keep their dtypes, tetrahedra their vertex order, added fields
    their time values; what download_mesh() gives, upload_mesh() takes as it is."""
    points, tets, fields = lattice(5)
    rng = np.random.default_rng(7)
    tets = rng.permuted(tets, axis=1)  # each tetrahedron's vertices in a random order
    n = len(points)
    fields |= {"label": (np.arange(n) % 7).astype(np.int32),
               "big": np.arange(n, dtype=np.int64) * 2**40}
    info = client.upload_mesh((points, tets, fields), name="lattice")
    again = None
    try:
        added = {"w": np.linspace(0, 1, n), "w32": np.linspace(1, 2, n).astype(np.float32)}
        info = client.add_fields(info, added, times=[0.5, 1.5])
        mesh = client.download_mesh(info, "all")
        assert mesh.name == "lattice" and mesh.times == {"w": 0.5, "w32": 1.5}
        _same(mesh, points, tets, {**fields, **added})
        picked = client.download_mesh(info, ["w32", "label"])
        _same(picked, points, tets, {"w32": added["w32"], "label": fields["label"]})
        assert picked.times == {"w32": 1.5}

        again = client.upload_mesh(mesh)
        assert again.name == "lattice" and (again.vertices, again.tetrahedra) == (n, len(tets))
        assert [(f.name, f.dtype) for f in again.fields] == \
            [(f.name, f.dtype) for f in info.fields]
        assert [f.time for f in again.fields] == [None] * len(info.fields)  # uploads: no times
        _same(client.download_mesh(again, "all"), points, tets, {**fields, **added})
    finally:
        client.delete_mesh(info)
        if again is not None:
            client.delete_mesh(again)


def test_a_series_downloads_with_its_times(client, data_dir):
    series = client.load_mesh(["isabel_series_s2/isabel_02_s2_tet.vtu",
                               "isabel_series_s2/isabel_03_s2_tet.vtu"], times=[2, 3])
    try:
        mesh = client.download_mesh(series, "all")
    finally:
        client.delete_mesh(series)
    assert list(mesh.point_data) == ["velocityMag_0", "velocityMag_1"]
    assert mesh.times == {"velocityMag_0": 2.0, "velocityMag_1": 3.0}
    step = meshio.read(data_dir / "isabel_series_s2/isabel_03_s2_tet.vtu")
    np.testing.assert_array_equal(mesh.point_data["velocityMag_1"],
                                  step.point_data["velocityMag"])


def test_progress_over_the_chunks_and_the_conversions(client, meshes, data_dir, tmp_path):
    """The Isabel series is about 10 MB: a report per chunk of about 1 MiB, rising to 1; the
    mesh as a pyvista grid and a meshio mesh, and as the geometry of a result's files."""
    info = meshes("isabel_series_s2_tet.vtu")
    reports: list[float] = []
    mesh = client.download_mesh(info, "all", progress=reports.append)
    assert len(reports) >= 8 and reports == sorted(reports) and reports[-1] == 1.0
    local = pv.read(data_dir / "isabel_series_s2_tet.vtu")
    grid = mesh.to_pyvista()
    assert isinstance(grid, pv.UnstructuredGrid)
    np.testing.assert_array_equal(grid.points, local.points)
    np.testing.assert_array_equal(grid.cell_connectivity, local.cell_connectivity)
    assert sorted(grid.point_data.keys()) == sorted(local.point_data.keys())
    converted = mesh.to_meshio()
    np.testing.assert_array_equal(converted.cells_dict["tetra"], local.cells_dict[10])
    np.testing.assert_array_equal(converted.point_data["velocityMag_48"],
                                  local.point_data["velocityMag_48"])

    with client.open_session(info, scalar="velocityMag_02", structure="compact") as session:
        result = session.run("morse-smale")
    files = result.write(str(tmp_path / "isabel"), client.download_mesh(info))
    segmentation = pv.read(files[-1])
    assert files[-1].endswith("_segmentation.vtu")
    np.testing.assert_array_equal(segmentation.points, local.points)
    np.testing.assert_array_equal(segmentation.point_data["MorseSmaleManifold"],
                                  result.segmentation["MorseSmaleManifold"])


def test_a_raising_progress_callable_stops_the_download(client, meshes):
    info = meshes("isabel_series_s2_tet.vtu")

    def stop(fraction: float) -> None:
        raise KeyError("stop")

    with pytest.raises(KeyError, match="stop"):
        client.download_mesh(info, "all", progress=stop)
    assert client.download_mesh(info).points.shape == (info.vertices, 3)  # the client goes on


def test_rejections_name_what_was_wrong(client, meshes):
    info = meshes("manifoldCheck0_tet.vtu")
    with pytest.raises(actopo.NotFoundError, match=r"^mesh_id: no mesh 'nope'") as e:
        client.download_mesh("nope")
    assert e.value.code == grpc.StatusCode.NOT_FOUND
    with pytest.raises(actopo.NotFoundError, match=r"^fields\[1\]: point field 'x' not found; "
                                                   r"point fields: 'height'"):
        client.download_mesh(info, ["height", "x"])
    with pytest.raises(actopo.InvalidArgumentError,
                       match=r"^fields\[1\]: 'height' is listed twice") as e:
        client.download_mesh(info, ["height", "height"])
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    # A string other than "all" is refused before anything is sent.
    with pytest.raises(actopo.InvalidArgumentError, match="for that field alone") as e:
        client.download_mesh(info, "height")
    assert e.value.code is None
    # The server's word on fields and all_fields together (the client never sends both).
    request = pb.DownloadMeshRequest(mesh_id=info.mesh_id, fields=["height"], all_fields=True)
    with pytest.raises(actopo.InvalidArgumentError,
                       match=r"^fields: give the fields or all_fields, not both"), translated():
        list(client._stub.DownloadMesh(request, timeout=30))


def test_the_async_client_downloads_the_same(server, client, meshes):
    info = meshes("viscousFingers001_s2_tet.vtu")
    expected = client.download_mesh(info, "all")

    async def download() -> tuple[actopo.types.MeshArrays, list[float]]:
        async with actopo.AsyncClient(server) as aclient:
            reports: list[float] = []
            mesh = await aclient.download_mesh(info, ["density"], progress=reports.append)
            with pytest.raises(actopo.NotFoundError, match="no mesh"):
                await aclient.download_mesh("nope")
            return mesh, reports

    mesh, reports = asyncio.run(download())
    _same(mesh, expected.points, expected.tetrahedra, expected.point_data)
    assert mesh.point_data["density"].dtype == np.float32 and reports[-1] == 1.0
