"""Results as pyvista datasets and as files for ParaView (pyvista, else meshio).

It takes a result's arrays by group ({"critical_points": {"Points": ..., ...}, ...}), or plain
arrays (line grids), not the JobResult or the PersistenceDiagram, so that _results and _diagram
depend on this module and not the other way round.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any, TypeAlias

import numpy as np

from actopo._mesh import mesh_arrays

Groups: TypeAlias = Mapping[str, Mapping[str, np.ndarray]]
"""A result's arrays: group name -> TTK array name -> values."""

POINT_GROUPS = ("critical_points", "critical_cells", "tree_nodes")
LINE_GROUPS = ("separatrices", "tree_arcs")
LINE_POINT_ARRAYS = {"tree_arcs": ("Scalar", "ttkMaskScalarField")}
"""The arrays of a line group that hold a value per point; the others hold one per line."""
VERTEX_GROUPS = ("simplified", "segmentation")
"""Groups of one value per vertex, put on the mesh's grid (so written only with the mesh):
the simplified field replaces the scalar field of the same name, as in TTK's output."""


def _group(groups: Groups, name: str) -> dict[str, np.ndarray]:
    """A copy of one group, {} when absent (the callers pop from it)."""
    return dict(groups.get(name, {}))


def _lines(name: str, group: Mapping[str, np.ndarray]
           ) -> tuple[np.ndarray, list[np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Points, each line's point ids (Connectivity[Offsets[i]:Offsets[i + 1]], or the points
    in order without Connectivity), and the per-point and per-line arrays."""
    points = np.asarray(group.get("Points", np.zeros((0, 3)))).reshape(-1, 3)
    offsets = np.asarray(group.get("Offsets", np.zeros(1, dtype=np.int64)), dtype=np.int64)
    ids = np.asarray(group.get("Connectivity", np.arange(offsets[-1] if len(offsets) else 0)),
                     dtype=np.int64)
    lines = [ids[start:end] for start, end in itertools.pairwise(offsets)]
    per_point = LINE_POINT_ARRAYS.get(name, ())
    arrays = {k: v for k, v in group.items() if k not in ("Points", "Offsets", "Connectivity")}
    return (points, lines, {k: v for k, v in arrays.items() if k in per_point},
            {k: v for k, v in arrays.items() if k not in per_point})


def _pyvista() -> Any:
    try:
        import pyvista as pv
    except ImportError:
        raise ImportError("to_pyvista() needs pyvista: pip install 'actopo[pyvista]'") from None
    return pv


def to_pyvista(groups: Groups, mesh: Any = None) -> dict[str, Any]:
    pv = _pyvista()
    out: dict[str, Any] = {}
    for name in POINT_GROUPS:
        group = _group(groups, name)
        if group:
            points = np.asarray(group.pop("Points"), dtype=np.float64).reshape(-1, 3)
            poly = pv.PolyData(points) if len(points) else pv.PolyData()
            for key, values in group.items():
                poly.point_data[key] = values
            out[name] = poly
    for name in LINE_GROUPS:
        group = _group(groups, name)
        if group:
            points, lines, point_arrays, line_arrays = _lines(name, group)
            cells = np.concatenate([np.concatenate([[len(line)], line]) for line in lines]) \
                if lines else np.zeros(0, dtype=np.int64)
            poly = pv.PolyData(points, lines=cells) if len(cells) else pv.PolyData()
            for key, values in point_arrays.items():
                poly.point_data[key] = values
            for key, values in line_arrays.items():
                poly.cell_data[key] = values
            out[name] = poly
    for name in VERTEX_GROUPS:
        group = _group(groups, name)
        if group and mesh is not None:
            grid = _mesh_grid(pv, mesh)
            for key, values in group.items():
                grid.point_data[key] = values
            out[name] = grid
    return out


def _mesh_grid(pv: Any, mesh: Any) -> Any:
    """A new UnstructuredGrid of the local mesh with its point fields, for one group."""
    if isinstance(mesh, pv.UnstructuredGrid):
        return mesh.copy()
    return mesh_arrays(mesh).to_pyvista()


def _write_meshio(groups: Groups, prefix: str, mesh: Any) -> list[str]:
    import meshio

    written = []
    for name in POINT_GROUPS:
        group = _group(groups, name)
        if group:
            points = np.asarray(group.pop("Points"), dtype=np.float64).reshape(-1, 3)
            cells = [("vertex", np.arange(len(points)).reshape(-1, 1))]
            path = f"{prefix}_{name}.vtu"
            meshio.Mesh(points, cells, point_data=group).write(path)
            written.append(path)
    for name in LINE_GROUPS:
        group = _group(groups, name)
        if not group:
            continue
        points, lines, point_arrays, line_arrays = _lines(name, group)
        segments, owner = [], []
        for i, ids in enumerate(lines):
            segments.append(np.stack([ids[:-1], ids[1:]], axis=1))
            owner.append(np.full(max(len(ids) - 1, 0), i))
        pieces = np.concatenate(segments) if segments else np.zeros((0, 2), dtype=np.int64)
        line_owner = np.concatenate(owner) if owner else np.zeros(0, dtype=np.int64)
        path = f"{prefix}_{name}.vtu"
        meshio.Mesh(points, [("line", pieces)], point_data=point_arrays,
                    cell_data={k: [np.asarray(v)[line_owner]] for k, v in line_arrays.items()}
                    ).write(path)
        written.append(path)
    local = None
    for name in VERTEX_GROUPS:
        group = _group(groups, name)
        if group and mesh is not None:
            local = local or mesh_arrays(mesh)
            path = f"{prefix}_{name}.vtu"
            meshio.Mesh(local.points, [("tetra", local.tetrahedra)],
                        point_data={**local.point_data, **group}).write(path)
            written.append(path)
    return written


def write_files(groups: Groups, prefix: str, mesh: Any = None) -> list[str]:
    try:
        import pyvista  # noqa: F401
    except ImportError:
        try:
            import meshio  # noqa: F401
        except ImportError:
            raise ImportError("writing result files needs pyvista (.vtp/.vtu) or meshio (.vtu): "
                              "pip install 'actopo[pyvista]'") from None
        return _write_meshio(groups, prefix, mesh)
    written = []
    for name, dataset in to_pyvista(groups, mesh).items():
        path = f"{prefix}_{name}.{'vtu' if name in VERTEX_GROUPS else 'vtp'}"
        dataset.save(path)
        written.append(path)
    return written


def line_grid(points: np.ndarray, lines: np.ndarray, point_data: Mapping[str, np.ndarray],
              cell_data: Mapping[str, np.ndarray]) -> Any:
    """An UnstructuredGrid of VTK_LINE cells, `lines` being (m, 2) point ids: the shape of TTK's
    persistence diagram, whose diagonal reuses two points of other lines (so no polylines)."""
    pv = _pyvista()
    if not len(lines):
        return pv.UnstructuredGrid()
    grid = pv.UnstructuredGrid({pv.CellType.LINE: np.asarray(lines, dtype=np.int64)},
                               np.asarray(points, dtype=np.float64).reshape(-1, 3))
    for key, values in point_data.items():
        grid.point_data[key] = values
    for key, values in cell_data.items():
        grid.cell_data[key] = values
    return grid


def write_line_grid(path: str, points: np.ndarray, lines: np.ndarray,
                    point_data: Mapping[str, np.ndarray],
                    cell_data: Mapping[str, np.ndarray]) -> str:
    """Writes line_grid()'s grid as a .vtu file with pyvista, else meshio; returns the path."""
    try:
        import pyvista  # noqa: F401
    except ImportError:
        try:
            import meshio
        except ImportError:
            raise ImportError("writing result files needs pyvista or meshio: "
                              "pip install 'actopo[pyvista]'") from None
        meshio.Mesh(np.asarray(points, dtype=np.float64).reshape(-1, 3), [("line", lines)],
                    point_data=dict(point_data),
                    cell_data={k: [v] for k, v in cell_data.items()}).write(path)
        return path
    line_grid(points, lines, point_data, cell_data).save(path)
    return path
