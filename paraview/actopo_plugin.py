"""ParaView plugin: TTK's topological filters computed by a running actopo-server.

Nine filters take a tetrahedral vtkUnstructuredGrid and a point scalar field (the last two:
several), send them to the server with the Python client (``actopo``), and return what TTK's
filter of the same name returns, with TTK's array names:

- ACTOPO Critical Points (ScalarFieldCriticalPoints): the critical vertices as vtkPolyData with
  CriticalType, IsOnBoundary, ttkVertexScalarField and the scalar;
- ACTOPO Discrete Gradient (DiscreteGradient): the critical cells, one point per cell, with
  CellDimension, CellId, ttkVertexScalarField, IsOnBoundary and the scalar;
- ACTOPO Morse-Smale Complex (MorseSmaleComplex 3D): port 0 the critical points (+ ManifoldSize),
  port 1 the 1-separatrices as polylines (SourceId, DestinationId, SeparatrixId, SeparatrixType),
  port 2 the input grid with DescendingManifold, AscendingManifold and MorseSmaleManifold; with a
  Persistence Threshold, the complex of the simplified field (as TopologicalSimplification
  followed by MorseSmaleComplex), port 2 then carrying the simplified field and its order;
- ACTOPO Persistence Diagram (PersistenceDiagram): TTK's diagram, a vtkUnstructuredGrid of
  VTK_LINE cells, a line per pair and the diagonal, with ttkVertexScalarField, CriticalType and
  Coordinates per point and PairIdentifier, PairType, Persistence, Birth and IsFinite per line;
  Embedding "domain" puts the points at the pairs' vertices (no diagonal);
- ACTOPO Topological Simplification (TopologicalSimplification, LTS, constrained by the
  persistence pairs above a threshold): the input grid with the scalar field replaced by the
  simplified one and ``<field>_Order``, its vertex order, added;
- ACTOPO Merge Tree (MergeTree, Tree Type Join Tree or Split Tree) and ACTOPO Contour Tree
  (ContourTree): TTK's three outputs, port 0 the nodes ("Skeleton Nodes", a VTK_VERTEX cell each,
  with NodeId, Scalar, VertexId, CriticalType, RegionSize, RegionSpan), port 1 the arcs ("Skeleton
  Arcs", a VTK_LINE each, with Scalar and ttkMaskScalarField per point and SegmentationId,
  upNodeId, downNodeId, RegionSize, RegionSpan per arc), port 2 the input grid with SegmentationId,
  RegionSize, RegionSpan and RegionType per vertex; with a Persistence Threshold, the tree of the
  simplified field, port 2 then carrying the simplified field and its order, as the Morse-Smale
  complex's;
- ACTOPO Persistence Diagram Distance Matrix (PersistenceDiagramDistanceMatrix, from the fields
  rather than their diagrams): a vtkTable, a row per field, TTK's columns Diagram00, Diagram01,
  ... (Wasserstein-p), then Bottleneck00, ... and FieldName;
- ACTOPO Tracking From Fields (TrackingFromFields): the persistence pairs tracked through the
  fields taken as time steps, as vtkPolyData lines (a line per link between two consecutive
  steps) with TimeStep, CriticalType, Scalar, VertexId per point and ConnectedComponentId,
  MatchingIdentifier, Cost, ComponentLength per line.

Every output carries the session's statistics as field data (ActopoEngineWaitSeconds,
ActopoEngineHits, ActopoEngineMisses, ActopoMemoryStaticBytes, ..., ActopoSummary as JSON).
Failures (server unreachable, unknown field, a mesh that is not tetrahedral, fewer than two fields
for the last two filters, ...) are reported in ParaView's Output Messages with the server's or the
client's message, and the filter fails.

Load it with Tools > Manage Plugins > Load New (paraview/README.md: the Python path, and the
one-line fix ParaView 5.11.0 needs under Python 3.11), or ``paraview.simple.LoadPlugin(path)``.
"""

from __future__ import annotations

import inspect
import json
import os
import sys
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import fields
from pathlib import Path
from typing import Any

# ParaView 5.11.0's decorators call inspect.getargspec, which Python 3.11 removed (ParaView
# 5.11.1 uses getfullargspec); its .args is all they read. Harmless on versions that have it.
if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec  # type: ignore[attr-defined]

# ParaView's own numpy, imported before the client's directories are added (see below).
import numpy as np
from paraview.util.vtkAlgorithm import (
    VTKPythonAlgorithmBase,
    smdomain,
    smhint,
    smproperty,
    smproxy,
)
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkConstants import (
    VTK_DOUBLE,
    VTK_FLOAT,
    VTK_LINE,
    VTK_SIGNED_CHAR,
    VTK_TETRA,
    VTK_VERTEX,
)
from vtkmodules.vtkCommonCore import (
    vtkAbstractArray,
    vtkDoubleArray,
    vtkOutputWindow,
    vtkPoints,
    vtkStringArray,
    vtkTypeInt64Array,
)
from vtkmodules.vtkCommonDataModel import (
    vtkCellArray,
    vtkCellTypes,
    vtkDataObject,
    vtkFieldData,
    vtkPolyData,
    vtkTable,
    vtkUnstructuredGrid,
)
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

paraview_plugin_name = "ACTOPO"
paraview_plugin_version = "0.1.0"

PYTHONPATH_VARIABLE = "ACTOPO_PYTHONPATH"
"""Directories (os.pathsep-separated) holding the ``actopo`` client and its gRPC stack."""

DEFAULT_SERVER = "127.0.0.1:50051"
STRUCTURES = ("explicit", "compact", "actopo")
PREFETCH = ("auto", "linear", "spatial", "adaptive")
PRECOMPUTE = ("auto", "requested", "declared")
BOUNDARY_RULES = ("ttk", "none")
EMBEDDINGS = ("diagram", "domain")
TREE_TYPES = ("Join Tree", "Split Tree")
"""ACTOPO Merge Tree's Tree Type, TTK's entries (a TTK state's TreeType = 'Split Tree' applies)."""
TREES = ("join", "split")
"""The server's merge-tree parameter "tree" for each of TREE_TYPES."""
DEFAULT_SIMPLIFICATION_THRESHOLD = 0.01
"""ACTOPO Topological Simplification's default: 1% of the scalar field's range, the server's."""
DEFAULT_WASSERSTEIN_ORDER = 2.0
"""The distance matrix's and the tracking's p, the server's default (TTK's "p parameter")."""

_HERE = Path(__file__).resolve().parent


class PluginError(Exception):
    """A failure found by the plugin itself (bad input, missing client); shown as it is."""


# --- Finding the actopo client ---------------------------------------------------------------
#
# ParaView runs its own Python (Debian: the system python3.11, with Debian's numpy and, when
# installed, Debian's protobuf 4.x). The client and grpcio/protobuf live in a virtual environment
# (the repository's .venv: numpy 2.x, protobuf 7.x). Appending that environment to sys.path is
# not enough: the stubs need the environment's protobuf, and Debian's older one would be found
# first. So numpy stays ParaView's (imported above, before anything is added), the client's
# directories are searched first only while `actopo` is imported (bringing grpc and protobuf
# with it), and stay at the end of sys.path afterwards.


def client_directories() -> list[str]:
    """Where the client is looked for: $ACTOPO_PYTHONPATH when set, else this repository's
    .venv (for this Python version) and client-py/ (the editable install's sources)."""
    configured = os.environ.get(PYTHONPATH_VARIABLE)
    if configured is not None:
        return [d for d in configured.split(os.pathsep) if d]
    repo = _HERE.parent
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    candidates = [repo / ".venv" / "lib" / version / "site-packages", repo / "client-py"]
    return [str(p) for p in candidates if p.is_dir()]


@contextmanager
def _searched_first(directories: Sequence[str]) -> Iterator[None]:
    saved = list(sys.path)
    sys.path[:0] = directories
    try:
        yield
    finally:
        sys.path[:] = saved + [d for d in directories if d not in saved]


_client: Any = None


def actopo_client() -> Any:
    """The ``actopo`` module, imported on first use (so the plugin loads without it and a
    filter reports what is missing)."""
    global _client
    if _client is None:
        directories = client_directories()
        try:
            with _searched_first(directories):
                import actopo
        except Exception as e:  # ImportError, or a stub refusing its protobuf/grpcio version
            searched = ", ".join(directories) or "(nothing)"
            raise PluginError(
                f"cannot import the actopo Python client ({type(e).__name__}: {e}). Searched "
                f"first: {searched}. Set {PYTHONPATH_VARIABLE} to the site-packages of an "
                "environment where 'pip install ./client-py' was run for Python "
                f"{sys.version_info.major}.{sys.version_info.minor} (paraview/README.md)"
            ) from e
        _client = actopo
    return _client


# --- Settings --------------------------------------------------------------------------------


class Settings:
    """What the filter's properties set; 0 and "auto" mean the server's defaults.

    (Not a dataclass: ParaView runs the plugin before registering it in sys.modules, where
    dataclasses look up string annotations.)
    """

    def __init__(self) -> None:
        self.server = ""
        self.token = ""
        self.server_path = ""
        self.structure = "actopo"
        self.consumers = 0
        self.producers = 0
        self.buffer_ratio = 0.0
        self.prefetch = "auto"
        self.precompute = "auto"
        self.block_size = 0
        self.boundary_rule = "ttk"
        self.embedding = "diagram"
        self.tree = "join"
        self.persistence_threshold = 0.0
        self.threshold_is_relative = True
        self.fields: list[str] = []
        self.p = DEFAULT_WASSERSTEIN_ORDER

    def target(self) -> str:
        return self.server.strip() or os.environ.get("ACTOPO_SERVER") or DEFAULT_SERVER

    def threshold_parameters(self) -> dict[str, str]:
        """The simplification's parameter as the server takes it: a fraction of the scalar
        field's range, or a persistence."""
        name = "relative_threshold" if self.threshold_is_relative else "persistence_threshold"
        return {name: repr(float(self.persistence_threshold))}

    def optional_threshold_parameters(self) -> dict[str, str]:
        """threshold_parameters(), or none when the threshold is 0 (no simplification); a
        negative value goes to the server, which names it."""
        if self.persistence_threshold == 0:
            return {}
        return self.threshold_parameters()


def _default_server() -> str:
    return os.environ.get("ACTOPO_SERVER") or DEFAULT_SERVER


def _doc(text: str) -> Callable[[Any], Any]:
    """A property's documentation (tooltip). The decorators have no element for it; a nested
    element is added like a domain."""
    escaped = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return smdomain.xml(f"<Documentation>{escaped}</Documentation>")


def _enumeration(values: Sequence[str]) -> Callable[[Any], Any]:
    entries = "".join(f'<Entry value="{i}" text="{v}"/>' for i, v in enumerate(values))
    return smdomain.xml(f'<EnumerationDomain name="enum">{entries}</EnumerationDomain>')


def _threshold_properties(default: float, meaning: str,
                          scale: str = "the scalar field's range") -> Callable[[type], type]:
    """Adds Persistence Threshold (default `default`; `meaning` says what it does; a relative
    threshold is a fraction of `scale`) and Threshold Is Relative to a filter class, as
    _connection_properties adds its properties."""

    def decorate(cls: type) -> type:
        @smproperty.doublevector(name="PersistenceThreshold", label="Persistence Threshold",
                                 default_values=default)
        @smdomain.doublerange(min=0.0)
        @_doc(f"{meaning} With Threshold Is Relative, a fraction of {scale} (0.01: 1%, at "
              "most 1); otherwise a persistence, in the field's units.")
        def SetPersistenceThreshold(self: ActopoFilter, value: float) -> None:
            self.set_option("persistence_threshold", float(value))

        @smproperty.intvector(name="ThresholdIsRelative", label="Threshold Is Relative",
                              default_values=1)
        @smdomain.xml('<BooleanDomain name="bool"/>')
        @_doc(f"Persistence Threshold is a fraction of {scale} (checked), or an absolute "
              "persistence (unchecked).")
        def SetThresholdIsRelative(self: ActopoFilter, value: int) -> None:
            self.set_option("threshold_is_relative", bool(value))

        for setter in (SetPersistenceThreshold, SetThresholdIsRelative):
            setattr(cls, setter.__name__, setter)
        return cls

    return decorate


def _connection_properties(cls: type) -> type:
    """Adds the properties every filter has. ParaView reads a proxy's properties from its
    class's own dictionary, so each filter class gets its own decorated setters."""

    @smproperty.stringvector(name="ServerAddress", label="Server Address",
                             default_values=_default_server())
    @_doc("HOST:PORT of the actopo-server (default $ACTOPO_SERVER, else 127.0.0.1:50051).")
    def SetServerAddress(self: ActopoFilter, value: str) -> None:
        self.set_option("server", value)

    @smproperty.stringvector(name="ServerPath", label="Server Path", default_values="")
    @_doc("Optional: a mesh file under the server's data directory to load instead of "
          "uploading the input (it must be the same mesh for the segmentation).")
    def SetServerPath(self: ActopoFilter, value: str) -> None:
        self.set_option("server_path", value)

    @smproperty.stringvector(name="Token", default_values="", panel_visibility="advanced")
    @_doc("Optional bearer token, for a server started with --token (default $ACTOPO_TOKEN).")
    def SetToken(self: ActopoFilter, value: str) -> None:
        self.set_option("token", value)

    @smproperty.intvector(name="Structure", default_values=STRUCTURES.index("actopo"))
    @_enumeration(STRUCTURES)
    @_doc("Topological data structure: explicit (all relations up front), compact (on-demand "
          "cache) or actopo (task-parallel engine). The results are identical.")
    def SetStructure(self: ActopoFilter, value: int) -> None:
        self.set_option("structure", STRUCTURES[value])

    @smproperty.intvector(name="Consumers", default_values=0, panel_visibility="advanced")
    @smdomain.intrange(min=0, max=64)
    @_doc("Algorithm threads (0: one per server core).")
    def SetConsumers(self: ActopoFilter, value: int) -> None:
        self.set_option("consumers", value)

    @smproperty.intvector(name="Producers", default_values=0, panel_visibility="advanced")
    @smdomain.intrange(min=0, max=64)
    @_doc("actopo: producer threads per consumer (0: the server's default).")
    def SetProducers(self: ActopoFilter, value: int) -> None:
        self.set_option("producers", value)

    @smproperty.doublevector(name="BufferRatio", default_values=0.0,
                             panel_visibility="advanced")
    @smdomain.doublerange(min=0.0, max=1.0)
    @_doc("compact cache / actopo buffer size as a fraction of the blocks (0: 0.2).")
    def SetBufferRatio(self: ActopoFilter, value: float) -> None:
        self.set_option("buffer_ratio", value)

    @smproperty.intvector(name="Prefetch", default_values=0, panel_visibility="advanced")
    @_enumeration(PREFETCH)
    @_doc("actopo: which blocks the producers compute ahead.")
    def SetPrefetch(self: ActopoFilter, value: int) -> None:
        self.set_option("prefetch", PREFETCH[value])

    @smproperty.intvector(name="Precompute", default_values=0, panel_visibility="advanced")
    @_enumeration(PRECOMPUTE)
    @_doc("actopo: the relation asked for, or the algorithm's whole declared set.")
    def SetPrecompute(self: ActopoFilter, value: int) -> None:
        self.set_option("precompute", PRECOMPUTE[value])

    @smproperty.intvector(name="BlockSize", default_values=0, panel_visibility="advanced")
    @smdomain.intrange(min=0, max=100000)
    @_doc("Octree bucket capacity, vertices per block (0: the server's 1000).")
    def SetBlockSize(self: ActopoFilter, value: int) -> None:
        self.set_option("block_size", value)

    for setter in (SetServerAddress, SetServerPath, SetToken, SetStructure, SetConsumers,
                   SetProducers, SetBufferRatio, SetPrefetch, SetPrecompute, SetBlockSize):
        setattr(cls, setter.__name__, setter)
    return cls


# The input: a vtkUnstructuredGrid with at least one scalar point array to pick from.
_INPUT_ARRAYS = '<InputArrayDomain name="input_scalars" attribute_type="point" ' \
                'number_of_components="1"/>'

_SCALAR_PROPERTY = """
<StringVectorProperty name="ScalarField" label="Scalar Field" command="SetInputArrayToProcess"
    number_of_elements="5" element_types="0 0 0 0 2" animateable="0">
  <ArrayListDomain name="array_list" attribute_type="Scalars" input_domain_name="input_scalars">
    <RequiredProperties><Property name="Input" function="Input"/></RequiredProperties>
  </ArrayListDomain>
  <Documentation>The point scalar field (one component) the algorithm runs on.</Documentation>
</StringVectorProperty>
"""


# The fields of a job over several: every one-component floating-point point array of the input
# is listed, all checked by default (ParaView lists them once the input has been updated); the
# proxy calls ClearScalarFields, then AddScalarField once per checked name, in the list's order.
_FIELDS_PROPERTY = """
<StringVectorProperty name="ScalarFields" label="Scalar Fields" command="AddScalarField"
    clean_command="ClearScalarFields" repeat_command="1" number_of_elements_per_command="1"
    animateable="0">
  <ArrayListDomain name="array_list" input_domain_name="input_scalars"
      data_type="VTK_FLOAT VTK_DOUBLE">
    <RequiredProperties><Property name="Input" function="Input"/></RequiredProperties>
  </ArrayListDomain>
  <Hints><ArraySelectionWidget icon_type="point"/></Hints>
  <Documentation>The point scalar fields (one component, float or double) the job runs over, in
this order (for tracking, the time steps); at least two. None checked: all of them.</Documentation>
</StringVectorProperty>
"""


_MENU = '<ShowInMenu category="ACTOPO"/>'


# --- Input and outputs -----------------------------------------------------------------------


def _scalar_name(algorithm: VTKPythonAlgorithmBase, grid: vtkUnstructuredGrid) -> str:
    """The selected point array, else the first one-component floating-point point array."""
    info = algorithm.GetInputArrayInformation(0)
    if info is not None and info.Has(vtkDataObject.FIELD_NAME()):
        name = info.Get(vtkDataObject.FIELD_NAME())
        if name:
            return str(name)
    names = _float_scalars(grid)
    if names:
        return names[0]
    raise PluginError("the input has no one-component floating-point point array to use as "
                      "the scalar field")


def _is_float_scalar(array: Any) -> bool:
    return array is not None and array.GetNumberOfComponents() == 1 \
        and array.GetDataType() in (VTK_FLOAT, VTK_DOUBLE)


def _float_scalars(grid: vtkUnstructuredGrid) -> list[str]:
    """The input's one-component float and double point arrays, in its order."""
    data = grid.GetPointData()
    return [str(data.GetArrayName(i)) for i in range(data.GetNumberOfArrays())
            if _is_float_scalar(data.GetArray(i))]


def _point_array_names(grid: vtkUnstructuredGrid) -> str:
    data = grid.GetPointData()
    names = [data.GetArrayName(i) for i in range(data.GetNumberOfArrays())]
    return ", ".join(repr(n) for n in names) or "none"


def _at_least_two(names: Sequence[str], job: str) -> None:
    if len(names) < 2:
        listed = ", ".join(repr(n) for n in names) or "none"
        raise PluginError(f"{job} needs at least two point fields (Scalar Fields), got "
                          f"{len(names)}: {listed}")


def _checked_fields(grid: vtkUnstructuredGrid, selected: Sequence[str], job: str) -> list[str]:
    """The fields a job over several fields uploads and runs over: those selected, else all the
    input's floating-point scalars; at least two, each a one-component float or double point
    array of the input."""
    names = list(selected) or _float_scalars(grid)
    _at_least_two(names, job)
    data = grid.GetPointData()
    for name in names:
        array = data.GetAbstractArray(name)
        if array is None:
            raise PluginError(f"the input has no point array '{name}'; point arrays: "
                              f"{_point_array_names(grid)}")
        if array.GetNumberOfComponents() != 1:
            raise PluginError(f"point array '{name}' has {array.GetNumberOfComponents()} "
                              f"components; {job} takes scalar fields (one component)")
        if not _is_float_scalar(array):
            kind = array.GetDataTypeAsString() if array.IsA("vtkDataArray") \
                else array.GetClassName()
            raise PluginError(f"point array '{name}' holds {kind} values; {job} takes "
                              "floating-point fields (float or double)")
    return names


def _tetrahedra(grid: vtkUnstructuredGrid) -> np.ndarray:
    if grid.GetNumberOfCells() == 0:
        raise PluginError("the input has no cells; the service takes tetrahedral meshes")
    types = numpy_support.vtk_to_numpy(grid.GetCellTypesArray())
    if not np.all(types == VTK_TETRA):
        kinds, counts = np.unique(types, return_counts=True)
        found = ", ".join(f"{count} {vtkCellTypes.GetClassNameFromTypeId(int(kind))}"
                          for kind, count in zip(kinds, counts, strict=True))
        raise PluginError(f"only tetrahedral meshes are supported, found cell types: {found}; "
                          "apply ParaView's Tetrahedralize filter first")
    connectivity = numpy_support.vtk_to_numpy(grid.GetCells().GetConnectivityArray())
    return connectivity.reshape(-1, 4)


def _upload_arrays(grid: vtkUnstructuredGrid, scalars: Sequence[str]
                   ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(points, tetrahedra, {scalar: values} for each of `scalars`) as the client's
    upload_mesh() takes them."""
    values = {}
    for scalar in scalars:
        array = grid.GetPointData().GetArray(scalar)
        if array is None:
            raise PluginError(f"the input has no numeric point array '{scalar}'; point arrays: "
                              f"{_point_array_names(grid)}")
        if array.GetNumberOfComponents() != 1:
            raise PluginError(f"point array '{scalar}' has {array.GetNumberOfComponents()} "
                              "components; pick a scalar field (one component)")
        values[scalar] = numpy_support.vtk_to_numpy(array)
    if grid.GetPoints() is None:
        raise PluginError("the input has no points")
    points = numpy_support.vtk_to_numpy(grid.GetPoints().GetData())
    return points, _tetrahedra(grid), values


def _vtk_array(name: str, values: np.ndarray) -> vtkAbstractArray:
    values = np.ascontiguousarray(values)
    # int8 becomes vtkSignedCharArray as in TTK (numpy_support would make it a vtkCharArray).
    array_type = VTK_SIGNED_CHAR if values.dtype == np.int8 else None
    array = numpy_support.numpy_to_vtk(values, deep=True, array_type=array_type)
    array.SetName(name)
    return array


def _id_array(values: np.ndarray) -> Any:
    return numpy_support.numpy_to_vtkIdTypeArray(
        np.ascontiguousarray(values, dtype=numpy_support.ID_TYPE_CODE), deep=True)


def _points(values: np.ndarray) -> vtkPoints:
    points = vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(
        np.ascontiguousarray(np.reshape(values, (-1, 3)), dtype=np.float64), deep=True))
    return points


def _cells(offsets: np.ndarray) -> vtkCellArray:
    """Cells over consecutive points: cell i holds points offsets[i] to offsets[i + 1] - 1."""
    cells = vtkCellArray()
    cells.SetData(_id_array(offsets), _id_array(np.arange(offsets[-1] if len(offsets) else 0)))
    return cells


def point_group_polydata(group: Mapping[str, np.ndarray], output: vtkPolyData) -> None:
    """Critical points or cells: one vertex cell per point, the arrays as point data."""
    points = np.reshape(group.get("Points", np.zeros((0, 3))), (-1, 3))
    output.SetPoints(_points(points))
    output.SetVerts(_cells(np.arange(len(points) + 1)))
    for name, values in group.items():
        if name != "Points":
            output.GetPointData().AddArray(_vtk_array(name, values))


def separatrices_polydata(group: Mapping[str, np.ndarray], output: vtkPolyData) -> None:
    """1-separatrices: one polyline per separatrix through its points, the per-separatrix
    arrays as cell data."""
    output.SetPoints(_points(group.get("Points", np.zeros((0, 3)))))
    output.SetLines(_cells(np.asarray(group.get("Offsets", np.zeros(1)), dtype=np.int64)))
    for name, values in group.items():
        if name not in ("Points", "Offsets"):
            output.GetCellData().AddArray(_vtk_array(name, values))


def vertex_arrays_grid(source: vtkUnstructuredGrid, groups: Mapping[str, Mapping[str, np.ndarray]],
                       output: vtkUnstructuredGrid) -> None:
    """The input grid with the per-vertex arrays of `groups` (by group name) added; an array
    named as one of the input's replaces it, as TTK's TopologicalSimplification replaces the
    scalar field by the simplified one."""
    count = source.GetNumberOfPoints()
    for group, arrays in groups.items():
        for name, values in arrays.items():
            if len(values) != count:
                raise PluginError(f"{group} array {name} has {len(values)} values but the "
                                  f"input has {count} points: the server's mesh (Server Path) "
                                  "must be the input mesh")
    output.ShallowCopy(source)
    for arrays in groups.values():
        for name, values in arrays.items():
            output.GetPointData().AddArray(_vtk_array(name, values))


def diagram_grid(grid: Any, output: vtkUnstructuredGrid) -> None:
    """TTK's persistence diagram from the client's DiagramGrid (PersistenceDiagram.ttk_grid():
    the diagonal rebuilt, which the wire's offsets cannot carry): a VTK_LINE cell per row of
    `lines`, the point and cell arrays by TTK's names."""
    output.SetPoints(_points(grid.points))
    lines = np.asarray(grid.lines).reshape(-1, 2)
    cells = vtkCellArray()
    cells.SetData(_id_array(np.arange(0, 2 * len(lines) + 1, 2)), _id_array(lines.reshape(-1)))
    output.SetCells(VTK_LINE, cells)
    for name, values in grid.point_data.items():
        output.GetPointData().AddArray(_vtk_array(name, values))
    for name, values in grid.cell_data.items():
        output.GetCellData().AddArray(_vtk_array(name, values))


def matrix_column_names(prefix: str, count: int) -> list[str]:
    """The columns of a distance matrix as TTK's PersistenceDiagramDistanceMatrix names them:
    the prefix, then the column's index zero-padded to the width of the last index (12
    diagrams: Diagram00 ... Diagram11), so that the columns sort in order."""
    width = len(str(max(count - 1, 0)))
    return [f"{prefix}{i:0{width}d}" for i in range(count)]


def distance_table(matrix: Any, output: vtkTable) -> None:
    """The client's DistanceMatrix as TTK's distance-matrix table: a row per field; column
    DiagramJ holds the Wasserstein-p distances to field J, BottleneckJ the bottleneck ones
    (float64, inf where infinite); FieldName (a string column) names the row's field."""
    count = len(matrix.fields)
    for prefix, values in (("Diagram", matrix.wasserstein), ("Bottleneck", matrix.bottleneck)):
        values = np.asarray(values, dtype=np.float64).reshape(count, count)
        for j, name in enumerate(matrix_column_names(prefix, count)):
            output.AddColumn(_vtk_array(name, values[:, j]))
    names = vtkStringArray()
    names.SetName("FieldName")
    for field in matrix.fields:
        names.InsertNextValue(str(field))
    output.AddColumn(names)


TRACKING_POINT_ARRAYS = ("TimeStep", "CriticalType", "Scalar", "VertexId")
TRACKING_CELL_ARRAYS = ("ConnectedComponentId", "MatchingIdentifier", "Cost", "ComponentLength")


def tracking_polydata(group: Mapping[str, np.ndarray], output: vtkPolyData) -> None:
    """The tracking group (TTK's TrackingFromFields output): its points, a line per link
    (Offsets and Connectivity: two points each), the per-point and per-link arrays as point
    and cell data."""
    points = np.reshape(group.get("Points", np.zeros((0, 3))), (-1, 3))
    offsets = np.asarray(group.get("Offsets", np.zeros(1)), dtype=np.int64)
    connectivity = group.get("Connectivity")
    if connectivity is None:  # the points of each line in a row, as the separatrices'
        connectivity = np.arange(offsets[-1] if len(offsets) else 0)
    output.SetPoints(_points(points))
    lines = vtkCellArray()
    lines.SetData(_id_array(offsets), _id_array(np.asarray(connectivity)))
    output.SetLines(lines)
    links = max(len(offsets) - 1, 0)
    for name, values in group.items():
        if name in ("Points", "Offsets", "Connectivity"):
            continue
        on_points = name in TRACKING_POINT_ARRAYS or (
            name not in TRACKING_CELL_ARRAYS and len(values) == len(points))
        if len(values) != (len(points) if on_points else links):
            raise PluginError(f"tracking array {name} has {len(values)} values, for "
                              f"{len(points)} points and {links} lines")
        data = output.GetPointData() if on_points else output.GetCellData()
        data.AddArray(_vtk_array(name, values))


TREE_ARC_POINT_ARRAYS = ("Scalar", "ttkMaskScalarField")
"""The arrays of a tree's arcs that hold a value per point (TTK's point data); the others
(SegmentationId, upNodeId, downNodeId, RegionSize, RegionSpan) hold one per arc."""


def tree_nodes_grid(group: Mapping[str, np.ndarray], output: vtkUnstructuredGrid) -> None:
    """A tree's nodes as TTK's Skeleton Nodes: a VTK_VERTEX cell per node, in NodeId order,
    the node arrays (NodeId, Scalar, VertexId, CriticalType, RegionSize, RegionSpan) as point
    data."""
    points = np.reshape(group.get("Points", np.zeros((0, 3))), (-1, 3))
    count = len(points)
    output.SetPoints(_points(points))
    vertices = vtkCellArray()
    vertices.SetData(_id_array(np.arange(count + 1)), _id_array(np.arange(count)))
    output.SetCells(VTK_VERTEX, vertices)
    for name, values in group.items():
        if name == "Points":
            continue
        if len(values) != count:
            raise PluginError(f"tree node array {name} has {len(values)} values, for {count} "
                              "nodes")
        output.GetPointData().AddArray(_vtk_array(name, values))


def tree_arcs_grid(group: Mapping[str, np.ndarray], output: vtkUnstructuredGrid) -> None:
    """A tree's arcs as TTK's Skeleton Arcs: a VTK_LINE cell per arc, from its lower node's
    point to its upper node's (Offsets and Connectivity; without Connectivity the points follow
    on), Scalar and ttkMaskScalarField as point data, the per-arc arrays as cell data."""
    points = np.reshape(group.get("Points", np.zeros((0, 3))), (-1, 3))
    offsets = np.asarray(group.get("Offsets", np.zeros(1)), dtype=np.int64)
    if np.any(np.diff(offsets) != 2):
        raise PluginError("tree_arcs/Offsets: an arc is not a line of two points")
    connectivity = np.asarray(group.get("Connectivity", np.arange(offsets[-1])),
                              dtype=np.int64)
    if len(connectivity) != offsets[-1] or (len(connectivity) and (
            connectivity.min() < 0 or connectivity.max() >= len(points))):
        raise PluginError(f"tree_arcs/Connectivity: {len(connectivity)} point ids, for "
                          f"{len(offsets) - 1} arcs over {len(points)} points")
    output.SetPoints(_points(points))
    lines = vtkCellArray()
    lines.SetData(_id_array(offsets), _id_array(connectivity))
    output.SetCells(VTK_LINE, lines)
    arcs = len(offsets) - 1
    for name, values in group.items():
        if name in ("Points", "Offsets", "Connectivity"):
            continue
        on_points = name in TREE_ARC_POINT_ARRAYS
        if len(values) != (len(points) if on_points else arcs):
            raise PluginError(f"tree arc array {name} has {len(values)} values, for "
                              f"{len(points)} points and {arcs} arcs")
        data = output.GetPointData() if on_points else output.GetCellData()
        data.AddArray(_vtk_array(name, values))


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


def statistics(result: Any, session_stats: Any,
               settings: Settings) -> dict[str, str | float | int]:
    """The session's statistics and the job's identity, by field-data array name."""
    values: dict[str, str | float | int] = {
        "ActopoServer": settings.target(),
        "ActopoStructure": settings.structure,
        "ActopoAlgorithm": result.algorithm,
        "ActopoJobId": result.job_id,
        "ActopoSummary": json.dumps(result.summary, sort_keys=True),
        "ActopoPreprocessSeconds": float(session_stats.preprocess_seconds),
        "ActopoJobs": int(session_stats.jobs.count),
    }
    if result.stats is not None:
        values["ActopoRunSeconds"] = float(result.stats.run_seconds)
    for prefix, stats in (("Engine", session_stats.engine), ("Memory", session_stats.memory)):
        for item in fields(stats):
            number = getattr(stats, item.name)
            if item.name.endswith("_ns"):
                values[f"Actopo{prefix}{_camel(item.name[:-3])}Seconds"] = number / 1e9
            else:
                values[f"Actopo{prefix}{_camel(item.name)}"] = int(number)
    values["ActopoEngineHitRate"] = float(session_stats.engine.hit_rate)
    return values


def add_field_data(output: vtkDataObject, values: Mapping[str, str | float | int]) -> None:
    data: vtkFieldData = output.GetFieldData()
    for name, value in values.items():
        array: vtkAbstractArray
        if isinstance(value, str):
            array = vtkStringArray()
            array.InsertNextValue(value)
        elif isinstance(value, float):
            array = vtkDoubleArray()
            array.InsertNextValue(value)
        else:
            array = vtkTypeInt64Array()
            array.InsertNextValue(value)
        array.SetName(name)
        data.AddArray(array)


# --- The filters -----------------------------------------------------------------------------


class _Cancelled(Exception):
    pass


class ActopoFilter(VTKPythonAlgorithmBase):
    """Common part of the filters: settings, the round trip to the server, error reporting."""

    algorithm = ""
    label = ""
    output_types: tuple[str, ...] = ("vtkPolyData",)

    def __init__(self) -> None:
        VTKPythonAlgorithmBase.__init__(self, nInputPorts=1, inputType="vtkUnstructuredGrid",
                                        nOutputPorts=len(self.output_types),
                                        outputType=self.output_types[0])
        self.settings = Settings()

    def set_option(self, name: str, value: Any) -> None:
        if getattr(self.settings, name) != value:
            setattr(self.settings, name, value)
            self.Modified()

    def FillOutputPortInformation(self, port: int, info: Any) -> int:
        info.Set(vtkDataObject.DATA_TYPE_NAME(), self.output_types[port])
        return 1

    def FillInputPortInformation(self, port: int, info: Any) -> int:
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkUnstructuredGrid")
        return 1

    def parameters(self) -> dict[str, str]:
        return {}

    def RequestData(self, request: Any, inInfo: Any, outInfo: Any) -> int:
        try:
            grid = vtkUnstructuredGrid.GetData(inInfo[0])
            if grid is None:
                raise PluginError("the input is not a vtkUnstructuredGrid")
            result, session_stats = self.run(grid)
            outputs = [self.GetOutputData(outInfo, i) for i in range(len(self.output_types))]
            self.fill(grid, result, outputs)
            values = statistics(result, session_stats, self.settings)
            for output in outputs:
                add_field_data(output, values)
        except _Cancelled:
            return 0
        except Exception as e:  # every failure must reach ParaView's Output Messages
            self.report(e)
            return 0
        return 1

    def scalars(self, grid: vtkUnstructuredGrid) -> list[str]:
        """The point fields the job reads, uploaded with the mesh; the first is the session's
        scalar field (with Server Path, none means the server's first)."""
        return [_scalar_name(self, grid)]

    def job(self, session: Any, scalars: list[str]) -> Any:
        """Runs the algorithm on the session; its JobResult."""
        return session.run(self.algorithm, parameters=self.parameters(), progress=self._progress)

    def run(self, grid: vtkUnstructuredGrid) -> tuple[Any, Any]:
        """Uploads (or loads) the mesh, runs the algorithm on a session; (result, stats)."""
        actopo = actopo_client()
        s = self.settings
        scalars = self.scalars(grid)
        token = s.token or os.environ.get("ACTOPO_TOKEN") or None
        self.UpdateProgress(0.0)
        with actopo.Client(s.target(), token=token) as client:
            if s.server_path:
                mesh = client.load_mesh(s.server_path, block_size=s.block_size)
            else:
                name = scalars[0] if len(scalars) == 1 else f"{len(scalars)} fields"
                mesh = client.upload_mesh(_upload_arrays(grid, scalars), name=f"paraview:{name}",
                                          block_size=s.block_size)
            try:
                self.UpdateProgress(0.2)
                with client.open_session(mesh, scalar=scalars[0] if scalars else None,
                                         structure=s.structure, consumers=s.consumers,
                                         producers=s.producers, buffer_ratio=s.buffer_ratio,
                                         prefetch=s.prefetch,
                                         precompute=s.precompute) as session:
                    result = self.job(session, scalars)
                    return result, session.stats()
            finally:
                # A failure here must not hide the run's; the server frees the mesh with its
                # last session anyway.
                with suppress(actopo.ActopoError):
                    client.delete_mesh(mesh)

    def _progress(self, fraction: float) -> None:
        if self.GetAbortExecute():
            raise _Cancelled()  # leaving the session's block closes it, which cancels the job
        self.UpdateProgress(0.2 + 0.8 * fraction)

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        raise NotImplementedError

    def report(self, error: Exception) -> None:
        """Prints the error the way vtkErrorMacro does: ParaView shows it in Output Messages
        (pvbatch/pvpython on stderr)."""
        if isinstance(error, PluginError) or type(error).__module__.startswith("actopo"):
            message = str(error)
        else:  # a bug of the plugin: the traceback helps
            message = "".join(traceback.format_exception(error)).rstrip()
        target = self.settings.target()
        vtkOutputWindow.GetInstance().DisplayErrorText(
            f"ERROR: In {Path(__file__).name}\n{type(self).__name__} ({self.label}, server "
            f"{target}): {message}\n\n")


@smproxy.filter(name="ActopoCriticalPoints", label="ACTOPO Critical Points")
@smhint.xml(_MENU)
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
class ActopoCriticalPoints(ActopoFilter):
    """TTK ScalarFieldCriticalPoints on the server: the critical vertices."""

    algorithm = "critical-points"
    label = "ACTOPO Critical Points"

    @smproperty.intvector(name="BoundaryRule", label="Boundary Rule", default_values=0)
    @_enumeration(BOUNDARY_RULES)
    @_doc("ttk: boundary vertices may be saddles (TTK >= 1.1); none: the interior rule only.")
    def SetBoundaryRule(self, value: int) -> None:
        self.set_option("boundary_rule", BOUNDARY_RULES[value])

    def parameters(self) -> dict[str, str]:
        return {"boundary_rule": self.settings.boundary_rule}

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        point_group_polydata(result.group("critical_points"), outputs[0])


@smproxy.filter(name="ActopoDiscreteGradient", label="ACTOPO Discrete Gradient")
@smhint.xml(_MENU)
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
class ActopoDiscreteGradient(ActopoFilter):
    """TTK DiscreteGradient on the server: the critical cells, one point each."""

    algorithm = "discrete-gradient"
    label = "ACTOPO Discrete Gradient"

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        point_group_polydata(result.group("critical_cells"), outputs[0])


@smproxy.filter(name="ActopoMorseSmaleComplex", label="ACTOPO Morse-Smale Complex")
@smhint.xml(_MENU)
@smproperty.xml('<OutputPort name="Critical Points" index="0"/>'
                '<OutputPort name="1-Separatrices" index="1"/>'
                '<OutputPort name="Segmentation" index="2"/>')
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
@_threshold_properties(0.0, "0: no simplification. Above 0, the field is simplified first, "
                       "keeping the persistence pairs at least this persistent, and the "
                       "complex is that of the simplified field.")
class ActopoMorseSmaleComplex(ActopoFilter):
    """TTK MorseSmaleComplex (3D, default outputs) on the server; with a Persistence Threshold,
    of the field TopologicalSimplification leaves (the server chains the two)."""

    algorithm = "morse-smale"
    label = "ACTOPO Morse-Smale Complex"
    output_types = ("vtkPolyData", "vtkPolyData", "vtkUnstructuredGrid")

    def parameters(self) -> dict[str, str]:
        return self.settings.optional_threshold_parameters()

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        # Downstream of TTK's simplification the grid holds the simplified field and its order.
        vertex_arrays_grid(grid, {"simplified": result.group("simplified"),
                                  "segmentation": result.group("segmentation")}, outputs[2])
        point_group_polydata(result.group("critical_points"), outputs[0])
        separatrices_polydata(result.group("separatrices"), outputs[1])


@smproxy.filter(name="ActopoPersistenceDiagram", label="ACTOPO Persistence Diagram")
@smhint.xml(_MENU)
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
class ActopoPersistenceDiagram(ActopoFilter):
    """TTK PersistenceDiagram (DiscreteMorseSandwich) on the server: TTK's diagram grid."""

    algorithm = "persistence-diagram"
    label = "ACTOPO Persistence Diagram"
    output_types = ("vtkUnstructuredGrid",)

    @smproperty.intvector(name="Embedding", default_values=0)
    @_enumeration(EMBEDDINGS)
    @_doc("diagram: the points in the birth-death plane, (birth, birth) and (birth, death), "
          "with TTK's diagonal; domain: the points at the pairs' vertices, no diagonal.")
    def SetEmbedding(self, value: int) -> None:
        self.set_option("embedding", EMBEDDINGS[value])

    def parameters(self) -> dict[str, str]:
        return {"embedding": self.settings.embedding}

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        if result.diagram is None:
            raise PluginError(f"job {result.job_id}: the server sent no diagram")
        diagram_grid(result.diagram.ttk_grid(), outputs[0])


@smproxy.filter(name="ActopoTopologicalSimplification", label="ACTOPO Topological Simplification")
@smhint.xml(_MENU)
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
@_threshold_properties(DEFAULT_SIMPLIFICATION_THRESHOLD,
                       "The persistence pairs at least this persistent are kept (their extrema "
                       "are the constraints); the other extrema are removed.")
class ActopoTopologicalSimplification(ActopoFilter):
    """TTK TopologicalSimplification (LTS) on the server, constrained by the persistence pairs
    above the threshold: the input grid with the field simplified and its ``_Order`` added."""

    algorithm = "topological-simplification"
    label = "ACTOPO Topological Simplification"
    output_types = ("vtkUnstructuredGrid",)

    def __init__(self) -> None:
        super().__init__()
        self.settings.persistence_threshold = DEFAULT_SIMPLIFICATION_THRESHOLD

    def parameters(self) -> dict[str, str]:
        return self.settings.threshold_parameters()

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        if result.simplified is None:
            raise PluginError(f"job {result.job_id}: the server sent no simplified field")
        vertex_arrays_grid(grid, {"simplified": result.simplified.point_data()}, outputs[0])


# --- Merge and contour trees --------------------------------------------------------------------

# TTK's ports, by TTK's names.
_TREE_PORTS = ('<OutputPort name="Skeleton Nodes" index="0"/>'
               '<OutputPort name="Skeleton Arcs" index="1"/>'
               '<OutputPort name="Segmentation" index="2"/>')
_TREE_THRESHOLD = ("0: no simplification. Above 0, the field is simplified first, keeping the "
                   "persistence pairs at least this persistent, and the tree is that of the "
                   "simplified field.")


class ActopoTreeFilter(ActopoFilter):
    """Common part of the tree filters: TTK's three outputs, the nodes and the arcs as
    vtkUnstructuredGrids (VTK_VERTEX, VTK_LINE cells) and the input grid with the
    segmentation; with a Persistence Threshold, the tree of the simplified field."""

    output_types = ("vtkUnstructuredGrid", "vtkUnstructuredGrid", "vtkUnstructuredGrid")

    def parameters(self) -> dict[str, str]:
        return self.settings.optional_threshold_parameters()

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        nodes = result.group("tree_nodes")
        if not nodes:
            raise PluginError(f"job {result.job_id}: the server sent no tree")
        # Downstream of TTK's simplification the grid holds the simplified field and its order.
        vertex_arrays_grid(grid, {"simplified": result.group("simplified"),
                                  "segmentation": result.group("segmentation")}, outputs[2])
        tree_nodes_grid(nodes, outputs[0])
        tree_arcs_grid(result.group("tree_arcs"), outputs[1])


@smproxy.filter(name="ActopoMergeTree", label="ACTOPO Merge Tree")
@smhint.xml(_MENU)
@smproperty.xml(_TREE_PORTS)
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
@_threshold_properties(0.0, _TREE_THRESHOLD)
class ActopoMergeTree(ActopoTreeFilter):
    """TTK MergeTree (FTM) on the server: the join or the split tree (Tree Type), its nodes,
    arcs and segmentation; with a Persistence Threshold, of the field TopologicalSimplification
    leaves (the server chains the two)."""

    algorithm = "merge-tree"
    label = "ACTOPO Merge Tree"

    @smproperty.intvector(name="TreeType", label="Tree Type", default_values=0)
    @_enumeration(TREE_TYPES)
    @_doc("Join Tree: how the sublevel sets' components merge, from the minima (the leaves) "
          "up to the maximum (the root); Split Tree: the superlevel sets', from the maxima "
          "down to the minimum.")
    def SetTreeType(self, value: int) -> None:
        self.set_option("tree", TREES[value])

    def parameters(self) -> dict[str, str]:
        return {"tree": self.settings.tree, **super().parameters()}


@smproxy.filter(name="ActopoContourTree", label="ACTOPO Contour Tree")
@smhint.xml(_MENU)
@smproperty.xml(_TREE_PORTS)
@smproperty.xml(_SCALAR_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
@_threshold_properties(0.0, _TREE_THRESHOLD)
class ActopoContourTree(ActopoTreeFilter):
    """TTK ContourTree (FTM) on the server: the join and split trees combined, its nodes, arcs
    and segmentation; with a Persistence Threshold, of the simplified field."""

    algorithm = "contour-tree"
    label = "ACTOPO Contour Tree"


# --- Filters over several fields ---------------------------------------------------------------


def _wasserstein_order_property(cls: type) -> type:
    """Adds Wasserstein Order (p) to a filter over several fields, as _connection_properties
    adds its properties."""

    @smproperty.doublevector(name="WassersteinOrder", label="Wasserstein Order",
                             default_values=DEFAULT_WASSERSTEIN_ORDER)
    @smdomain.doublerange(min=1.0)
    @_doc("p of the Wasserstein-p distance between two persistence diagrams (TTK's \"p "
          "parameter\"): a finite number, at least 1. The bottleneck distance comes with it.")
    def SetWassersteinOrder(self: ActopoFilter, value: float) -> None:
        self.set_option("p", float(value))

    cls.SetWassersteinOrder = SetWassersteinOrder  # type: ignore[attr-defined]
    return cls


class ActopoFieldsFilter(ActopoFilter):
    """Common part of the filters over several point fields of the input (Scalar Fields): the
    fields go with the upload, and one job runs over them, in the order given."""

    job_name = ""
    """What the error messages call the job ("tracking")."""
    include_arrays = True

    def AddScalarField(self, name: str) -> None:
        self.settings.fields.append(str(name))
        self.Modified()

    def ClearScalarFields(self) -> None:
        if self.settings.fields:
            self.settings.fields = []
            self.Modified()

    def scalars(self, grid: vtkUnstructuredGrid) -> list[str]:
        if not self.settings.server_path:
            return _checked_fields(grid, self.settings.fields, self.job_name)
        # The server's mesh: the server checks the names; none selected is all of its fields.
        if self.settings.fields:
            _at_least_two(self.settings.fields, self.job_name)
        return list(self.settings.fields)

    def parameters(self) -> dict[str, str]:
        parameters = {"p": repr(float(self.settings.p))}
        if self.settings.persistence_threshold != 0:  # 0: every pair
            parameters.update(self.settings.threshold_parameters())
        return parameters

    def job(self, session: Any, scalars: list[str]) -> Any:
        return session.run(self.algorithm, fields=scalars or "all",
                           parameters=self.parameters(), include_arrays=self.include_arrays,
                           progress=self._progress)


_SERIES_THRESHOLD = ("0: every pair. Above 0, only the persistence pairs at least this "
                     "persistent are compared.")


@smproxy.filter(name="ActopoPersistenceDiagramDistanceMatrix",
                label="ACTOPO Persistence Diagram Distance Matrix")
@smhint.xml(_MENU)
@smproperty.xml(_FIELDS_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
@_wasserstein_order_property
@_threshold_properties(0.0, _SERIES_THRESHOLD, scale="each field's own range")
class ActopoPersistenceDiagramDistanceMatrix(ActopoFieldsFilter):
    """TTK PersistenceDiagramDistanceMatrix on the server, from the fields instead of their
    diagrams (the server computes each field's persistence diagram): a vtkTable with a row per
    field, TTK's Diagram columns (Wasserstein-p), Bottleneck columns and FieldName."""

    algorithm = "diagram-distance"
    label = "ACTOPO Persistence Diagram Distance Matrix"
    output_types = ("vtkTable",)
    job_name = "the distance matrix"
    include_arrays = False  # the matrices are in the summary; the diagrams are not needed

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        if result.distance_matrix is None:
            raise PluginError(f"job {result.job_id}: the server sent no distance matrix")
        distance_table(result.distance_matrix, outputs[0])


@smproxy.filter(name="ActopoTrackingFromFields", label="ACTOPO Tracking From Fields")
@smhint.xml(_MENU)
@smproperty.xml(_FIELDS_PROPERTY)
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkUnstructuredGrid"], composite_data_supported=False)
@smdomain.xml(_INPUT_ARRAYS)
@_connection_properties
@_wasserstein_order_property
@_threshold_properties(0.0, _SERIES_THRESHOLD, scale="each field's own range")
class ActopoTrackingFromFields(ActopoFieldsFilter):
    """TTK TrackingFromFields on the server: the persistence pairs of consecutive fields (the
    time steps, in the order given) matched and chained into trajectories, as vtkPolyData
    lines with TTK's tracking arrays."""

    algorithm = "tracking"
    label = "ACTOPO Tracking From Fields"
    output_types = ("vtkPolyData",)
    job_name = "tracking"

    def fill(self, grid: vtkUnstructuredGrid, result: Any, outputs: list[Any]) -> None:
        group = result.group("tracking")
        if not group and result.summary.get("links"):
            raise PluginError(f"job {result.job_id}: the server sent no tracking arrays")
        tracking_polydata(group, outputs[0])

