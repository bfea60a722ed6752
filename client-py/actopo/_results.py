"""Job results: the RunJob stream assembled into numpy arrays, the summary and statistics; in
a job over several fields, a FieldResult per field as its FieldResult message arrives."""

from __future__ import annotations

import os
from collections import deque
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from actopo import _convert, _diagram, _distances, _simplified, _tracking, _tree, _vtk
from actopo._arrays import dtype_of
from actopo._diagram import PersistenceDiagram
from actopo._distances import DistanceMatrix
from actopo._errors import ActopoError
from actopo._literals import Algorithm
from actopo._proto import pb
from actopo._simplified import SimplifiedField
from actopo._tracking import Trajectories
from actopo._tree import Tree
from actopo._types import JobProgress, JobStats


@dataclass
class JobResult:
    """The outcome of Session.run().

    Attributes:
        algorithm: e.g. "morse-smale".
        job_id: the server's id of the job.
        summary: the same object as actopo-bench's JSON ``result`` (counts and digests).
        arrays: result arrays by "<group>/<TTK name>", e.g. "critical_points/CriticalType".
        stats: timings, engine statistics and memory of the job.
        trace: the job's Chrome trace-event JSON when run with ``trace=True``, else None.

    Groups (see the proto's ResultChunk): ``critical_points`` (critical-points, morse-smale),
    ``critical_cells`` (discrete-gradient), ``separatrices`` and ``segmentation``
    (morse-smale), ``diagram`` and ``persistence_curve`` (persistence-diagram), ``simplified``
    (topological-simplification, and morse-smale run with a threshold), ``tree_nodes``,
    ``tree_arcs`` and ``segmentation`` (merge-tree, contour-tree). Each group is a dict of TTK
    array names::

        result.critical_points["CriticalType"]        # int8, one per critical vertex
        result.segmentation["MorseSmaleManifold"]     # int32, one per vertex

    A persistence diagram also comes typed, one entry per pair: ``result.diagram``; a
    simplified field, one value per vertex: ``result.simplified``; a merge or contour tree,
    its nodes, arcs and segmentation: ``result.tree``.

    A job over several fields (``Session.run(..., fields=[...])``) has one FieldResult per
    field in ``fields``, in the job's order, each with the summary, arrays and typed views a
    job on that field alone gives; its own summary is ``{"fields": [names]}``, or for
    diagram-distance the matrices (typed: ``result.distance_matrix``), and its ``stats`` the
    whole job's.
    """

    algorithm: Algorithm
    job_id: str
    summary: dict[str, Any]
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    stats: JobStats | None = None
    trace: bytes | None = None
    fields: list[FieldResult] = field(default_factory=list)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    @property
    def groups(self) -> list[str]:
        """The groups present, in arrival order."""
        return list(dict.fromkeys(k.split("/", 1)[0] for k in self.arrays))

    def group(self, name: str) -> dict[str, np.ndarray]:
        """The arrays of one group by TTK name ({} when absent)."""
        prefix = name + "/"
        return {k[len(prefix):]: v for k, v in self.arrays.items() if k.startswith(prefix)}

    def _groups(self) -> dict[str, dict[str, np.ndarray]]:
        return {name: self.group(name) for name in self.groups}

    @property
    def critical_points(self) -> dict[str, np.ndarray]:
        return self.group("critical_points")

    @property
    def critical_cells(self) -> dict[str, np.ndarray]:
        return self.group("critical_cells")

    @property
    def separatrices(self) -> dict[str, np.ndarray]:
        return self.group("separatrices")

    @property
    def segmentation(self) -> dict[str, np.ndarray]:
        return self.group("segmentation")

    @cached_property
    def diagram(self) -> PersistenceDiagram | None:
        """The pairs of a persistence-diagram job as a PersistenceDiagram (TTK's diagonal set
        apart); None for the other algorithms and for a job run without its arrays."""
        group = self.group("diagram")
        return _diagram.from_arrays(group, self.group("persistence_curve")) if group else None

    @cached_property
    def simplified(self) -> SimplifiedField | None:
        """The simplified field of a topological-simplification job, or of a morse-smale job
        run with a threshold (the field its complex was computed on), as a SimplifiedField;
        None for the other jobs and for a job run without its arrays."""
        group = self.group("simplified")
        return _simplified.from_arrays(group) if group else None

    @cached_property
    def tree(self) -> Tree | None:
        """The tree of a merge-tree or contour-tree job (its ``tree_nodes``, ``tree_arcs`` and
        ``segmentation`` groups and its summary's "tree") as a Tree, the arcs' ends as global
        NodeIds; None for the other algorithms and for a job run without its arrays."""
        nodes = self.group("tree_nodes")
        if not nodes:
            return None
        return _tree.from_arrays(str(self.summary.get("tree", "")), nodes,
                                 self.group("tree_arcs"), self.segmentation)

    @cached_property
    def distance_matrix(self) -> DistanceMatrix | None:
        """The matrices of a diagram-distance job as a DistanceMatrix; None for the other
        jobs (and for each field's own result)."""
        if self.algorithm != "diagram-distance" or "wasserstein" not in self.summary:
            return None
        return _distances.from_summary(self.summary)

    @cached_property
    def tracking(self) -> Trajectories | None:
        """The trajectories of a tracking job (its summary and ``tracking`` arrays) as
        Trajectories; None for the other jobs and for a tracking job run without arrays."""
        group = self.group("tracking")
        if self.algorithm != "tracking" or not group or "trajectories" not in self.summary:
            return None
        return _tracking.from_result(self.summary, group)

    def save_trace(self, path: str | os.PathLike[str]) -> str:
        """Writes the job's trace (run with ``trace=True``) to `path`, for ui.perfetto.dev or
        chrome://tracing, and returns the path."""
        if self.trace is None:
            raise ValueError(f"job {self.job_id} was run without trace=True: it has no trace")
        Path(path).write_bytes(self.trace)
        return str(path)

    def to_pyvista(self, mesh: Any = None) -> dict[str, Any]:
        """The result as pyvista datasets, by group (needs the ``pyvista`` extra).

        Critical points and cells and a tree's nodes become PolyData vertices with their
        arrays as point data, separatrices and a tree's arcs PolyData polylines with per-line
        cell data. The per-vertex groups need the
        mesh's geometry, which stays on the server: pass the mesh you uploaded (any form
        upload_mesh() takes) to get them as UnstructuredGrids, else they are left out: the
        segmentation (the mesh with its arrays added) and the simplified field (the mesh with
        the scalar field replaced by the simplified one and ``<field>_Order`` added, as TTK's
        TopologicalSimplification outputs it). A persistence diagram becomes TTK's diagram, an
        UnstructuredGrid of lines (PersistenceDiagram.to_pyvista()).
        """
        datasets = _vtk.to_pyvista(self._groups(), mesh)
        if self.diagram is not None:
            datasets["diagram"] = self.diagram.to_pyvista()
        return datasets

    def write(self, prefix: str, mesh: Any = None) -> list[str]:
        """Writes files for ParaView as actopo-bench does (PREFIX_critical_points.vtp, ...).

        Uses pyvista if installed, else meshio (then every file is a .vtu). A tree's nodes and
        arcs go to PREFIX_tree_nodes.vtp and PREFIX_tree_arcs.vtp. The simplified field
        (PREFIX_simplified.vtu) and the segmentation are written only when `mesh` gives the
        geometry; a persistence diagram as PREFIX_diagram.vtu and
        PREFIX_persistence_curve.csv. Returns the paths written.
        """
        written = _vtk.write_files(self._groups(), prefix, mesh)
        if self.diagram is not None:
            written += self.diagram.write(prefix)
        return written


@dataclass
class FieldResult(JobResult):
    """One field's result in a job over several fields: what a job on that field alone gives
    (summary, arrays, ``diagram``, ``simplified``, ...), its name, its position in the job's
    list and the seconds the algorithm ran on it. ``stats`` is None: the statistics are the
    whole job's (JobResult.stats)."""

    field: str = ""
    index: int = 0
    run_seconds: float = 0.0

    def __repr__(self) -> str:
        return (f"FieldResult({self.field!r}, index={self.index}, {self.algorithm!r}, "
                f"{len(self.arrays)} arrays)")


def distance_matrix_of(result: JobResult) -> DistanceMatrix:
    """The matrix of a diagram-distance job's result (Session.distance_matrix())."""
    matrix = result.distance_matrix
    if matrix is None:
        raise ActopoError(f"job {result.job_id}: its summary holds no distance matrix")
    return matrix


_Buffers = dict[str, tuple[bytearray, np.dtype[Any], tuple[int, ...]]]
"""Result arrays being assembled: name -> (bytes, dtype, shape)."""


class Assembler:
    """Feeds on RunJob responses and builds the JobResult (shared by both clients).

    In a job over several fields, the arrays of each field are kept apart (ResultChunk.field)
    until its FieldResult message makes them a FieldResult; take_fields() hands out those made
    since its last call. With `keep_fields` False they are not kept for the JobResult as well
    (Session.run_fields, which hands each out once)."""

    def __init__(self, algorithm: Algorithm, keep_fields: bool = True) -> None:
        self.algorithm = algorithm
        self.job_id = ""
        self.summary: dict[str, Any] | None = None
        self.stats: JobStats | None = None
        self._buffers: dict[str, _Buffers] = {}  # by field, "" for the job's own arrays
        self._trace: bytearray | None = None
        self._keep_fields = keep_fields
        self._fields: list[FieldResult] = []
        self._ready: deque[FieldResult] = deque()

    def feed(self, response: pb.RunJobResponse) -> JobProgress | None:
        """Takes one response; returns the progress report when it is a progress message."""
        event = response.WhichOneof("event")
        if event == "accepted":
            self.job_id = response.accepted.job_id
        elif event == "progress":
            p = response.progress
            return JobProgress(phase=p.phase or "run", fraction=p.fraction,
                               elapsed_seconds=p.elapsed_seconds)
        elif event == "chunk":
            self._chunk(response.chunk)
        elif event == "summary":
            self.summary = _convert.struct_to_dict(response.summary.result)
        elif event == "stats":
            self.stats = _convert.job_stats(response.stats)
        elif event == "trace":
            self._trace_piece(response.trace)
        elif event == "field":
            self._field(response.field)
        return None

    def take_fields(self) -> list[FieldResult]:
        """The fields' results completed since the last call, in order."""
        taken = list(self._ready)
        self._ready.clear()
        return taken

    def _field(self, message: pb.FieldResult) -> None:
        result = FieldResult(algorithm=self.algorithm, job_id=self.job_id,
                             summary=_convert.struct_to_dict(message.result),
                             arrays=self._arrays(self._buffers.pop(message.field, {})),
                             field=message.field, index=message.index,
                             run_seconds=message.run_seconds)
        self._ready.append(result)
        if self._keep_fields:
            self._fields.append(result)

    def _trace_piece(self, piece: pb.TraceChunk) -> None:
        if self._trace is None:
            self._trace = bytearray(piece.total_bytes or len(piece.data))
        end = piece.offset + len(piece.data)
        if piece.offset < 0 or end > len(self._trace):
            raise ActopoError(f"trace: piece [{piece.offset}, {end}) outside its "
                              f"{len(self._trace)} bytes")
        self._trace[piece.offset:end] = piece.data

    def _chunk(self, chunk: pb.ResultChunk) -> None:
        a = chunk.array
        buffers = self._buffers.setdefault(chunk.field, {})
        if a.name not in buffers:
            total = chunk.total_bytes or len(a.data)
            buffers[a.name] = (bytearray(total), dtype_of(a.dtype), tuple(a.shape))
        buffer = buffers[a.name][0]
        end = chunk.offset + len(a.data)
        if chunk.offset < 0 or end > len(buffer):
            of = f" of field '{chunk.field}'" if chunk.field else ""
            raise ActopoError(f"result array '{a.name}'{of}: piece [{chunk.offset}, {end}) "
                              f"outside its {len(buffer)} bytes")
        buffer[chunk.offset:end] = a.data

    @staticmethod
    def _arrays(buffers: _Buffers) -> dict[str, np.ndarray]:
        arrays = {}
        for name, (buffer, dtype, shape) in buffers.items():
            values = np.frombuffer(buffer, dtype=dtype)
            arrays[name] = values.reshape(shape) if len(shape) > 1 else values
        return arrays

    def result(self) -> JobResult:
        if self.summary is None:
            raise ActopoError(f"job {self.job_id or '?'}: the stream ended without a summary")
        return JobResult(algorithm=self.algorithm, job_id=self.job_id, summary=self.summary,
                         arrays=self._arrays(self._buffers.get("", {})), stats=self.stats,
                         trace=None if self._trace is None else bytes(self._trace),
                         fields=list(self._fields))
