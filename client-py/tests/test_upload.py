"""Uploads from pyvista, meshio, files and numpy arrive whole: the jobs on them give upstream
TTK's results on the files they came from. (A .vtu, .vtk, .vti or .pvd path goes as its bytes:
test_upload_file.py.)"""

from __future__ import annotations

import meshio
import numpy as np
import pytest
import pyvista as pv
from meshes import lattice
from references import ENTRY, check_summary, ttk

import actopo


def _run(client, mesh, algorithm, scalar):
    try:
        with client.open_session(mesh, scalar=scalar, structure="actopo") as s:
            return s.run(algorithm, include_arrays=False, digests=True).summary
    finally:
        client.delete_mesh(mesh)


def _is_ttks(summary, algorithm, file, field):
    check_summary(algorithm, summary, ttk(file, field)[ENTRY[algorithm]], digests=True)


def test_upload_pyvista_grid(client, data_dir):
    grid = pv.read(data_dir / "fertility_tet.vtu")
    mesh = client.upload_mesh(grid, name="fertility from pyvista")
    assert (mesh.vertices, mesh.tetrahedra, mesh.source) == (14570, 60948, "upload")
    assert {f.name for f in mesh.fields} == {"eigenfunction4", "height"}
    _is_ttks(_run(client, mesh, "discrete-gradient", "eigenfunction4"), "discrete-gradient",
             "fertility_tet.vtu", "eigenfunction4")


def test_upload_meshio_mesh(client, data_dir):
    mesh = client.upload_mesh(meshio.read(data_dir / "manifoldCheck2_tet.vtu"))
    assert mesh.name == "meshio" and mesh.tetrahedra == 24
    _is_ttks(_run(client, mesh, "morse-smale", "height"), "morse-smale",
             "manifoldCheck2_tet.vtu", "height")


def test_upload_file_path_and_numpy_arrays(client, data_dir):
    path = data_dir / "manifoldCheck0_tet.vtu"
    mesh = client.upload_mesh(str(path), block_size=10)  # as its bytes
    assert mesh.name == "manifoldCheck0_tet.vtu" and mesh.block_size == 10
    assert mesh.source == "upload:manifoldCheck0_tet.vtu"
    file = _run(client, mesh, "critical-points", None)  # the first floating-point field
    _is_ttks(file, "critical-points", "manifoldCheck0_tet.vtu", "height")
    m = meshio.read(path)
    arrays = (m.points, m.cells_dict["tetra"].astype(np.int64), {"height": m.point_data["height"]})
    assert _run(client, client.upload_mesh(arrays), "critical-points", "height") == file


def test_upload_over_many_chunks(client):
    points, tets, fields = lattice(40)  # 64000 vertices, ~2.5 MB of arrays
    mesh = client.upload_mesh((points.astype(np.float32), tets, fields), name="lattice40")
    assert (mesh.vertices, mesh.tetrahedra) == (64000, 6 * 39**3)
    client.delete_mesh(mesh)


def test_triangle_meshes_are_rejected_on_the_client(client, data_dir):
    grid = pv.read(data_dir / "happi_tas_tri.vtu")
    before = len(client.list_meshes())
    with pytest.raises(actopo.InvalidMeshError) as e:
        client.upload_mesh(grid)
    assert e.value.code is None
    assert "36290 triangle" in str(e.value) and "hint:" in str(e.value)
    assert len(client.list_meshes()) == before


def test_bad_uploads_are_rejected_by_the_server(client):
    points, tets, fields = lattice(3)
    nan = fields["f"].copy()
    nan[3] = np.nan
    mesh = client.upload_mesh((points, tets, {"f": nan}))
    try:
        with pytest.raises(actopo.InvalidArgumentError, match="f"):
            client.open_session(mesh, scalar="f")
    finally:
        client.delete_mesh(mesh)
    repeated = np.vstack([tets, [[0, 0, 1, 2]]])
    with pytest.raises(actopo.InvalidMeshError, match="repeats vertex 0") as e:
        client.upload_mesh((points, repeated))
    assert e.value.code is not None
    with pytest.raises(actopo.InvalidMeshError, match="non-finite"):
        client.upload_mesh((np.where(points == points[2], np.nan, points), tets))
