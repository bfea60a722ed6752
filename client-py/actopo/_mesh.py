"""Meshes the client accepts, turned into the arrays an upload sends.

Accepted: a pyvista dataset (UnstructuredGrid, or anything castable to one), a meshio.Mesh, a
local file path (read with pyvista, else meshio), or a tuple (points, tetrahedra[, point_data])
of numpy arrays, or MeshArrays (what Client.download_mesh() gives). Anything that is not made only
of tetrahedra is rejected here, before a byte is sent, naming the cell types found.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from actopo._errors import InvalidMeshError

# VTK cell type numbers, as pyvista reports them.
VTK_TETRA = 10
_VTK_NAMES = {1: "vertex", 2: "poly_vertex", 3: "line", 4: "polyline", 5: "triangle",
              6: "triangle_strip", 7: "polygon", 8: "pixel", 9: "quad", 10: "tetra",
              11: "voxel", 12: "hexahedron", 13: "wedge", 14: "pyramid", 15: "pentagonal_prism",
              16: "hexagonal_prism", 21: "quadratic_edge", 22: "quadratic_triangle",
              23: "quadratic_quad", 24: "quadratic_tetra", 25: "quadratic_hexahedron",
              42: "polyhedron"}
_SURFACE = {"vertex", "poly_vertex", "line", "polyline", "triangle", "triangle_strip", "polygon",
            "pixel", "quad", "quadratic_edge", "quadratic_triangle", "quadratic_quad"}
_FIELD_DTYPES = {"f": np.float64, "i": np.int64, "u": np.int64, "b": np.int32}

ACCEPTED_FILES = ("give a tetrahedral mesh in a file VTK writes (.vtu, a legacy .vtk unstructured "
                  "grid) or one meshio reads (e.g. .msh, .mesh, .inp, .xdmf)")
"""The files an upload takes, as its errors say."""

MeshLike = Any
"""pyvista dataset | meshio.Mesh | str | os.PathLike | (points, tetrahedra[, point_data]) |
MeshArrays."""


@dataclass(eq=False)
class MeshArrays:
    """A tetrahedral mesh as little-endian numpy arrays: what an upload sends, and what
    Client.download_mesh() gives back (which upload_mesh() takes as it is).

    Attributes:
        name: the mesh's name.
        points: (n, 3) float32 or float64, in input order.
        tetrahedra: (t, 4) int32 or int64 vertex ids, each tetrahedron's vertices in the order
            they were given.
        point_data: scalar point fields by name, (n,) each: float32, float64, int32 or int64.
        times: the time value of each field that has one (a series member); an upload does not
            send them (the server takes times from AddFields only).
    """

    name: str
    points: np.ndarray
    tetrahedra: np.ndarray
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    times: dict[str, float] = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"MeshArrays({self.name!r}, {len(self.points)} vertices, "
                f"{len(self.tetrahedra)} tetrahedra, fields {list(self.point_data)})")

    def to_pyvista(self) -> Any:
        """A pyvista.UnstructuredGrid of the tetrahedra with the point fields (needs the
        ``pyvista`` extra)."""
        try:
            import pyvista as pv
        except ImportError:
            raise ImportError("to_pyvista() needs pyvista: pip install 'actopo[pyvista]'") \
                from None
        grid = pv.UnstructuredGrid({pv.CellType.TETRA: self.tetrahedra}, self.points)
        for key, values in self.point_data.items():
            grid.point_data[key] = values
        return grid

    def to_meshio(self) -> Any:
        """A meshio.Mesh of one "tetra" block with the point fields (needs the ``meshio``
        extra)."""
        try:
            import meshio
        except ImportError:
            raise ImportError("to_meshio() needs meshio: pip install 'actopo[meshio]'") from None
        return meshio.Mesh(self.points, [("tetra", self.tetrahedra)],
                           point_data=dict(self.point_data))


def _hint(cells: Mapping[str, int]) -> str:
    found = ", ".join(f"{count} {name}" for name, count in sorted(cells.items()))
    names = set(cells)
    if names <= _SURFACE:
        hint = ("this is a surface or line mesh; the service works on tetrahedral volume meshes: "
                "fill the surface with tetrahedra first (e.g. TetGen, or pyvista's "
                "mesh.delaunay_3d())")
    else:
        hint = ("split the cells into tetrahedra first: ParaView's Tetrahedralize filter, or "
                "pyvista's mesh.triangulate() (vtkDataSetTriangleFilter)")
    return f"only tetrahedral meshes are supported, found cell types: {found}; hint: {hint}"


def _reject(cells: Mapping[str, int], source: str) -> InvalidMeshError:
    return InvalidMeshError(f"{source}: {_hint(cells)}")


def _from_pyvista(mesh: Any, name: str) -> MeshArrays:
    import pyvista as pv

    grid: Any = mesh if isinstance(mesh, pv.UnstructuredGrid) \
        else mesh.cast_to_unstructured_grid()
    types = np.asarray(grid.celltypes)
    if types.size == 0:
        raise InvalidMeshError(f"{name}: the mesh has no cells")
    if not np.all(types == VTK_TETRA):
        found = Counter(_VTK_NAMES.get(int(t), f"vtk_type_{int(t)}") for t in types)
        raise _reject(found, name)
    tets = np.asarray(grid.cells_dict[VTK_TETRA])
    data = {k: np.asarray(grid.point_data[k]) for k in grid.point_data.keys()}  # noqa: SIM118 (pyvista)
    return _checked(name, np.asarray(grid.points), tets, data)


def _from_meshio(mesh: Any, name: str) -> MeshArrays:
    found: Counter[str] = Counter()
    for block in mesh.cells:
        found[block.type] += len(block.data)
    if not found:
        raise InvalidMeshError(f"{name}: the mesh has no cells")
    if set(found) != {"tetra"}:
        raise _reject(found, name)
    tets = np.concatenate([np.asarray(b.data) for b in mesh.cells])
    return _checked(name, np.asarray(mesh.points), tets,
                    {k: np.asarray(v) for k, v in mesh.point_data.items()})


def read_file(path: Path) -> Any:
    """A local mesh file as pyvista reads it, else as meshio does (whichever is installed)."""
    if not path.is_file():
        raise FileNotFoundError(f"no such mesh file: {path}")
    try:
        import pyvista as pv
    except ImportError:
        try:
            import meshio
        except ImportError:
            raise ImportError("reading a mesh file needs pyvista or meshio: "
                              "pip install 'actopo[pyvista]' or 'actopo[meshio]'") from None
        try:
            return meshio.read(path)
        except meshio.ReadError as e:
            raise _unreadable(path, f" ({e})") from None
    try:
        return pv.read(path)
    except OSError as e:
        if e.errno is not None:  # the file's own trouble: permissions, ...
            raise
        # "This file was not able to be automatically read by pyvista.", after meshio tried too
        raise _unreadable(path) from None


def _unreadable(path: Path, reason: str = "") -> InvalidMeshError:
    return InvalidMeshError(f"{path}: not a mesh file that pyvista or meshio reads{reason}; "
                            f"{ACCEPTED_FILES}")


def _from_file(path: Path) -> MeshArrays:
    return mesh_arrays(read_file(path), path.name)


def _from_tuple(arrays: Sequence[Any], name: str) -> MeshArrays:
    if len(arrays) not in (2, 3):
        raise InvalidMeshError("a mesh tuple is (points, tetrahedra) or (points, tetrahedra, "
                               f"point_data), got {len(arrays)} items")
    data = dict(arrays[2] or {}) if len(arrays) == 3 else {}
    tets = np.asarray(arrays[1])
    if tets.ndim == 2 and tets.shape[1] != 4:
        kind = {3: "triangle", 2: "line", 8: "hexahedron", 6: "wedge", 5: "pyramid"}.get(
            tets.shape[1], f"{tets.shape[1]}-vertex cell")
        raise _reject({kind: tets.shape[0]}, name)
    return _checked(name, np.asarray(arrays[0]), tets, data)


def _checked(name: str, points: np.ndarray, tets: np.ndarray,
             data: Mapping[str, np.ndarray]) -> MeshArrays:
    if points.ndim != 2 or points.shape[1] != 3:
        raise InvalidMeshError(f"{name}: points must have shape (n, 3), got {points.shape}")
    if points.dtype.kind not in "fiu":
        raise InvalidMeshError(f"{name}: points must be numbers, got dtype {points.dtype}")
    points = np.ascontiguousarray(points, dtype="<f4" if points.dtype == np.float32 else "<f8")
    if tets.ndim != 2 or tets.shape[1] != 4:
        raise InvalidMeshError(f"{name}: tetrahedra must have shape (t, 4), got {tets.shape}")
    if tets.dtype.kind not in "iu":
        raise InvalidMeshError(f"{name}: tetrahedra must be integers, got dtype {tets.dtype}")
    if len(tets) == 0:
        raise InvalidMeshError(f"{name}: the mesh has no tetrahedra")
    low, high = int(tets.min()), int(tets.max())
    if low < 0 or high >= len(points):
        raise InvalidMeshError(f"{name}: tetrahedra reference vertex {low if low < 0 else high}, "
                               f"outside [0, {len(points)})")
    tets = np.ascontiguousarray(tets, dtype="<i4" if high < 2**31 else "<i8")
    fields: dict[str, np.ndarray] = {}
    for key, values in data.items():
        values = np.asarray(values)
        if values.ndim == 2 and values.shape[1] == 1:
            values = values[:, 0]
        if values.ndim != 1 or len(values) != len(points) or values.dtype.kind not in "fiub":
            continue  # vectors, tensors, strings: the service keeps scalar point fields only
        if values.dtype in (np.float32, np.float64, np.int32, np.int64):
            dtype = values.dtype.newbyteorder("<")
        else:
            dtype = np.dtype(_FIELD_DTYPES[values.dtype.kind]).newbyteorder("<")
        fields[str(key)] = np.ascontiguousarray(values, dtype=dtype)
    return MeshArrays(name, points, tets, fields)


def mesh_arrays(mesh: MeshLike, name: str | None = None) -> MeshArrays:
    """Any accepted mesh as MeshArrays; raises InvalidMeshError for what the service rejects."""
    if isinstance(mesh, MeshArrays):  # checked too: it may have been made by hand
        arrays = _checked(mesh.name, mesh.points, mesh.tetrahedra, mesh.point_data)
        arrays.times = dict(mesh.times)
    elif isinstance(mesh, (str, os.PathLike)):
        arrays = _from_file(Path(mesh))
    elif isinstance(mesh, (tuple, list)):
        arrays = _from_tuple(mesh, name or "arrays")
    elif hasattr(mesh, "cells") and hasattr(mesh, "point_data") and hasattr(mesh, "points") \
            and isinstance(mesh.cells, list):
        arrays = _from_meshio(mesh, name or "meshio")
    elif hasattr(mesh, "cast_to_unstructured_grid") or hasattr(mesh, "celltypes"):
        arrays = _from_pyvista(mesh, name or "pyvista")
    else:
        raise InvalidMeshError(
            f"cannot upload a {type(mesh).__name__}: pass a pyvista.UnstructuredGrid, a "
            "meshio.Mesh, a file path, or (points, tetrahedra[, point_data]) numpy arrays")
    if name:
        arrays.name = name
    return arrays
