"""The ParaView plugin (paraview/actopo_plugin.py) for real, headless: pvbatch loads it with
paraview/load_actopo.py, reads shared meshes with ParaView's reader, applies each filter against a
running actopo-server (tests/paraview_driver.py), and writes what the outputs hold. Every array
must equal what the Python client returns for the same mesh, scalar, structure and options: same
TTK names, dtypes and values, points, polylines, the segmentation on the input grid, TTK's
persistence diagram as lines with its diagonal, the simplified field in place of the input's with
its order beside it (whose digests also equal upstream TTK's), the summary in the field data
beside the session's statistics. The merge trees (join and split) and contour trees, on the field
and on the field simplified first, must be TTK's three outputs with TTK's array names and types:
as many nodes and arcs as the job's summary counts, the segmentation a SegmentationId per vertex
of the input grid; every array equals upstream TTK's byte for byte
(tests/ttk_reference/trees-ttk.json), or row for row where TTK's order follows its scheduling,
and the tree the client reads from the filter's outputs has TTK's digests. Tree Type switches
from the join tree to the split tree, and a threshold leaves fewer nodes. The filters over
several fields run on the Isabel series (12 fields on one mesh): the distance matrix's table
must hold, row by row and column by column under TTK's column names, the very distances
Session.distance_matrix() returns, and the tracking's lines the client's tracking arrays, a line
per link between consecutive steps. Failures (an unknown scalar, an unreachable server, a wrong
token, triangles, a relative threshold above 1, a single field, an integer field, an unknown
field, a Wasserstein order below 1, a tree's threshold out of range) must print the server's or
client's message and leave pvbatch running.

The plugin finds the client on its own (the repository's .venv and client-py/, after ParaView's
numpy); the test checks it runs on ParaView's numpy with the client's protobuf and gRPC, that a
copy of the plugin elsewhere finds the client through $ACTOPO_PYTHONPATH, and says what is
missing without it.

Skipped, saying why, without pvbatch (Debian package paraview; scripts/install-deps.sh), without
a built server ($ACTOPO_BUILD) or without the shared meshes ($ACTOPO_DATA_DIR).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.append(str(ROOT / "client-py" / "tests"))
from harness import DATA_DIR, free_port, running_server  # noqa: E402

# ParaView's Python modules: Debian's python3-paraview, or the copy scripts/install-deps.sh
# unpacks where that package cannot be installed (it conflicts with the build's python3-vtk9).
PARAVIEW_PYTHON = ROOT / ".tools" / "paraview-python" / "usr" / "lib" / "python3" / "dist-packages"
DEBIAN_PARAVIEW_PYTHON = Path("/usr/lib/python3/dist-packages/paraview")
TOKEN = "paraview-test-token"
FERTILITY = "fertility_tet.vtu"
FINGERS = "viscousFingers001_s2_tet.vtu"
SERIES = "isabel_series_s2_tet.vtu"  # 12 fields velocityMag_02 ... velocityMag_48, time order
SERIES_MEMBERS = ["velocityMag_48", "velocityMag_02", "velocityMag_30", "velocityMag_45"]
SERIES_STEPS = ["velocityMag_02", "velocityMag_03", "velocityMag_04", "velocityMag_05"]
PVBATCH_SECONDS = 120

# name, filter, mesh, properties (as pvbatch sets them), how the client runs the same
CASES: list[dict[str, Any]] = [
    {"name": "critical_points", "filter": "ACTOPOCriticalPoints", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "eigenfunction4"], "Structure": "explicit"},
     "client": {"algorithm": "critical-points", "scalar": "eigenfunction4",
                "session": {"structure": "explicit"}}},
    {"name": "critical_points_server_path", "filter": "ACTOPOCriticalPoints", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "compact",
                    "ServerPath": FERTILITY, "BoundaryRule": "none"},
     "client": {"algorithm": "critical-points", "scalar": "height", "load": FERTILITY,
                "session": {"structure": "compact"},
                "parameters": {"boundary_rule": "none"}}},
    {"name": "discrete_gradient", "filter": "ACTOPODiscreteGradient", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "eigenfunction4"], "Structure": "compact",
                    "BlockSize": 500},
     "client": {"algorithm": "discrete-gradient", "scalar": "eigenfunction4", "block_size": 500,
                "session": {"structure": "compact"}}},
    {"name": "morse_smale", "filter": "ACTOPOMorseSmaleComplex", "mesh": FINGERS,
     "properties": {"ScalarField": ["POINTS", "density"], "Structure": "actopo",
                    "Consumers": 2, "Producers": 2, "BufferRatio": 0.3, "Prefetch": "spatial",
                    "Precompute": "declared"},
     "client": {"algorithm": "morse-smale", "scalar": "density",
                "session": {"structure": "actopo", "consumers": 2, "producers": 2,
                            "buffer_ratio": 0.3, "prefetch": "spatial",
                            "precompute": "declared"}}},
    {"name": "persistence_diagram", "filter": "ACTOPOPersistenceDiagram", "mesh": FINGERS,
     "properties": {"ScalarField": ["POINTS", "density"], "Structure": "compact"},
     "client": {"algorithm": "persistence-diagram", "scalar": "density",
                "session": {"structure": "compact"},
                "parameters": {"embedding": "diagram"}}},
    {"name": "persistence_diagram_domain", "filter": "ACTOPOPersistenceDiagram",
     "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "eigenfunction4"], "Structure": "explicit",
                    "Embedding": "domain"},
     "client": {"algorithm": "persistence-diagram", "scalar": "eigenfunction4",
                "session": {"structure": "explicit"},
                "parameters": {"embedding": "domain"}}},
    # The defaults: 1% of the range.
    {"name": "topological_simplification", "filter": "ACTOPOTopologicalSimplification",
     "mesh": FINGERS,
     "properties": {"ScalarField": ["POINTS", "density"], "Structure": "compact"},
     "client": {"algorithm": "topological-simplification", "scalar": "density",
                "session": {"structure": "compact"},
                "parameters": {"relative_threshold": "0.01"}},
     "ttk": "0.01"},
    {"name": "topological_simplification_absolute", "filter": "ACTOPOTopologicalSimplification",
     "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "explicit",
                    "PersistenceThreshold": 3.6677284240722656, "ThresholdIsRelative": 0},
     "client": {"algorithm": "topological-simplification", "scalar": "height",
                "session": {"structure": "explicit"},
                "parameters": {"persistence_threshold": "3.6677284240722656"}},
     "ttk": "0.05"},  # 5% of the range, given absolutely
    {"name": "morse_smale_simplified", "filter": "ACTOPOMorseSmaleComplex", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "actopo",
                    "PersistenceThreshold": 0.05},
     "client": {"algorithm": "morse-smale", "scalar": "height",
                "session": {"structure": "actopo"},
                "parameters": {"relative_threshold": "0.05"}},
     "ttk": "0.05"},
    # The trees, TTK's MergeTree (join by default, split) and ContourTree; "tree": the entry of
    # trees-ttk.json they must equal, TTK's tree on the field (None) or on the field simplified
    # at a fraction of its range; "report": the properties whose default pvbatch reports.
    {"name": "merge_tree", "filter": "ACTOPOMergeTree", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "explicit"},
     "report": ["TreeType", "PersistenceThreshold", "ThresholdIsRelative"],
     "client": {"algorithm": "merge-tree", "scalar": "height",
                "session": {"structure": "explicit"}, "parameters": {"tree": "join"}},
     "tree": ["join_tree", None]},
    {"name": "merge_tree_split", "filter": "ACTOPOMergeTree", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "compact",
                    "TreeType": "Split Tree"},
     "client": {"algorithm": "merge-tree", "scalar": "height",
                "session": {"structure": "compact"}, "parameters": {"tree": "split"}},
     "tree": ["split_tree", None]},
    {"name": "merge_tree_simplified", "filter": "ACTOPOMergeTree", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "actopo",
                    "PersistenceThreshold": 0.05},
     "client": {"algorithm": "merge-tree", "scalar": "height",
                "session": {"structure": "actopo"},
                "parameters": {"tree": "join", "relative_threshold": "0.05"}},
     "tree": ["join_tree", "0.05"], "ttk": "0.05"},
    {"name": "contour_tree", "filter": "ACTOPOContourTree", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "actopo",
                    "Consumers": 2},
     "report": ["PersistenceThreshold"],
     "client": {"algorithm": "contour-tree", "scalar": "height",
                "session": {"structure": "actopo", "consumers": 2}},
     "tree": ["contour_tree", None]},
    {"name": "contour_tree_simplified", "filter": "ACTOPOContourTree", "mesh": FERTILITY,
     "properties": {"ScalarField": ["POINTS", "height"], "Structure": "explicit",
                    "PersistenceThreshold": 3.6677284240722656, "ThresholdIsRelative": 0},
     "client": {"algorithm": "contour-tree", "scalar": "height",
                "session": {"structure": "explicit"},
                "parameters": {"persistence_threshold": "3.6677284240722656"}},
     "tree": ["contour_tree", "0.05"], "ttk": "0.05"},  # 5% of the range, given absolutely
    # On the server's copy of the mesh: the segmentation still lands on the input grid.
    {"name": "contour_tree_server_path", "filter": "ACTOPOContourTree", "mesh": FINGERS,
     "properties": {"ScalarField": ["POINTS", "density"], "Structure": "compact",
                    "ServerPath": FINGERS},
     "client": {"algorithm": "contour-tree", "scalar": "density", "load": FINGERS,
                "session": {"structure": "compact"}},
     "tree": ["contour_tree", None]},
]
# The filters over several fields: name, filter, mesh, properties, the properties whose value
# pvbatch reports (the defaults the domain chose), how the client computes the same.
SERIES_CASES: list[dict[str, Any]] = [
    # The defaults: every field of the input, uploaded with it; p = 2; every pair.
    {"name": "distance_matrix", "filter": "ACTOPOPersistenceDiagramDistanceMatrix",
     "mesh": SERIES, "properties": {}, "report": ["ScalarFields"],
     "client": {"kind": "distance_matrix", "fields": "all", "options": {},
                "session": {"structure": "actopo"}}},
    # Four members in an order of their own, on the server's copy of the mesh.
    {"name": "distance_matrix_server_path", "filter": "ACTOPOPersistenceDiagramDistanceMatrix",
     "mesh": SERIES,
     "properties": {"ScalarFields": SERIES_MEMBERS, "ServerPath": SERIES, "Structure": "compact",
                    "WassersteinOrder": 1.0, "PersistenceThreshold": 0.01},
     "client": {"kind": "distance_matrix", "fields": SERIES_MEMBERS, "load": SERIES,
                "options": {"p": 1, "relative_threshold": 0.01},
                "session": {"structure": "compact"}}},
    {"name": "tracking", "filter": "ACTOPOTrackingFromFields", "mesh": SERIES,
     "properties": {}, "report": ["ScalarFields"],
     "client": {"kind": "tracking", "fields": "all", "session": {"structure": "actopo"}}},
    {"name": "tracking_absolute", "filter": "ACTOPOTrackingFromFields", "mesh": SERIES,
     "properties": {"ScalarFields": SERIES_STEPS, "Structure": "explicit",
                    "WassersteinOrder": 1.5, "PersistenceThreshold": 2.0,
                    "ThresholdIsRelative": 0},
     "client": {"kind": "tracking", "fields": SERIES_STEPS,
                "parameters": {"p": "1.5", "persistence_threshold": "2.0"},
                "session": {"structure": "explicit"}}},
]
TRACKING_POINT_ARRAYS = ["TimeStep", "CriticalType", "Scalar", "VertexId"]
TRACKING_CELL_ARRAYS = ["ConnectedComponentId", "MatchingIdentifier", "Cost", "ComponentLength"]
# Failing runs: name, filter, properties, what pvbatch's output must say (mesh: fertility;
# "before": ParaView filters applied to it first).
ERRORS: list[dict[str, Any]] = [
    {"name": "error_unknown_scalar_uploaded", "filter": "ACTOPOCriticalPoints",
     "properties": {"ScalarField": ["POINTS", "nope"]},
     "message": "the input has no numeric point array 'nope'; point arrays: 'eigenfunction4', "
                "'height'"},
    {"name": "error_unknown_scalar", "filter": "ACTOPOCriticalPoints",
     "properties": {"ScalarField": ["POINTS", "nope"], "ServerPath": FERTILITY},
     "message": "scalar field 'nope' not found; point fields: 'eigenfunction4', 'height' "
                "[NOT_FOUND]"},
    {"name": "error_unreachable", "filter": "ACTOPODiscreteGradient",
     "properties": {"ScalarField": ["POINTS", "height"]},
     "message": "failed to connect to all addresses"},
    {"name": "error_token", "filter": "ACTOPOMorseSmaleComplex",
     "properties": {"ScalarField": ["POINTS", "height"], "Token": "wrong"},
     "message": "[UNAUTHENTICATED]"},
    {"name": "error_not_tetrahedral", "filter": "ACTOPOMorseSmaleComplex",
     "mesh": "happi_tas_tri.vtu", "properties": {"ScalarField": ["POINTS", "tas"]},
     "message": "only tetrahedral meshes are supported, found cell types: 36290 vtkTriangle"},
    {"name": "error_threshold", "filter": "ACTOPOTopologicalSimplification",
     "properties": {"ScalarField": ["POINTS", "height"], "PersistenceThreshold": 1.5},
     "message": "parameters.relative_threshold: threshold: 1.5 is not a fraction of the scalar "
                "range in [0, 1] [INVALID_ARGUMENT]"},
    {"name": "error_one_field", "filter": "ACTOPOPersistenceDiagramDistanceMatrix",
     "properties": {"ScalarFields": ["height"]},
     "message": "the distance matrix needs at least two point fields (Scalar Fields), got 1: "
                "'height'"},
    {"name": "error_integer_field", "filter": "ACTOPOTrackingFromFields",
     "before": [["Calculator", {"ResultArrayName": "ids", "Function": "floor(height)",
                                "ResultArrayType": "Int"}]],
     "properties": {"ScalarFields": ["height", "ids"]},
     "message": "point array 'ids' holds int values; tracking takes floating-point fields "
                "(float or double)"},
    {"name": "error_unknown_field", "filter": "ACTOPOTrackingFromFields",
     "properties": {"ScalarFields": ["height", "nope"], "ServerPath": FERTILITY},
     "message": "fields[1]: scalar field 'nope' not found; point fields: 'eigenfunction4', "
                "'height' [NOT_FOUND]"},
    {"name": "error_wasserstein_order", "filter": "ACTOPOPersistenceDiagramDistanceMatrix",
     "properties": {"WassersteinOrder": 0.5},
     "message": "parameters.p: 0.5 is not a Wasserstein order; give a finite number of at least "
                "1 (the bottleneck distance comes with every result) [INVALID_ARGUMENT]"},
    {"name": "error_tree_threshold", "filter": "ACTOPOMergeTree",
     "properties": {"ScalarField": ["POINTS", "height"], "TreeType": "Split Tree",
                    "PersistenceThreshold": 1.5},
     "message": "parameters.relative_threshold: threshold: 1.5 is not a fraction of the scalar "
                "range in [0, 1] [INVALID_ARGUMENT]"},
    {"name": "error_tree_persistence", "filter": "ACTOPOContourTree",
     "properties": {"ScalarField": ["POINTS", "height"], "PersistenceThreshold": -1.0,
                    "ThresholdIsRelative": 0},
     "message": "parameters.persistence_threshold: threshold: -1 is not a finite, non-negative "
                "persistence [INVALID_ARGUMENT]"},
]
GROUP_OF_PORT = {"critical-points": ["critical_points"], "discrete-gradient": ["critical_cells"],
                 "morse-smale": ["critical_points", "separatrices", "segmentation"],
                 "persistence-diagram": ["diagram"], "topological-simplification": ["simplified"],
                 "merge-tree": ["tree_nodes", "tree_arcs", "segmentation"],
                 "contour-tree": ["tree_nodes", "tree_arcs", "segmentation"]}
SIMPLIFICATION_REFERENCE = ROOT / "tests" / "ttk_reference" / "simplification-ttk.json"
TREES_REFERENCE = ROOT / "tests" / "ttk_reference" / "trees-ttk.json"
# TTK's tree outputs: the nodes' point data, the arcs' point and cell data, the segmentation's
# point data (trees_reference.py), in TTK's order.
TREE_NODE_ARRAYS = ["NodeId", "Scalar", "VertexId", "CriticalType", "RegionSize", "RegionSpan"]
TREE_ARC_POINT_ARRAYS = ["Scalar", "ttkMaskScalarField"]
TREE_ARC_CELL_ARRAYS = ["SegmentationId", "upNodeId", "downNodeId", "RegionSize", "RegionSpan"]
TREE_SEGMENTATION_ARRAYS = ["SegmentationId", "RegionSize", "RegionSpan", "RegionType"]
VTK_VERTEX = 1
VTK_LINE = 3
STATISTICS = ["ActopoEngineWaitSeconds", "ActopoEngineRequests", "ActopoEngineHits",
              "ActopoEngineMisses", "ActopoEngineEvictions", "ActopoEngineHitRate",
              "ActopoEngineBufferPeakBytes", "ActopoMemoryStaticBytes",
              "ActopoMemoryRelationPeakBytes", "ActopoMemoryProcessRssBytes",
              "ActopoPreprocessSeconds", "ActopoRunSeconds", "ActopoJobs"]


def pvbatch() -> str:
    path = shutil.which("pvbatch")
    if path is None:
        pytest.skip("pvbatch not installed (Debian package paraview; scripts/install-deps.sh)")
    if not (PARAVIEW_PYTHON.is_dir() or DEBIAN_PARAVIEW_PYTHON.is_dir()):
        pytest.skip("ParaView's Python modules not found (Debian package python3-paraview; "
                    f"scripts/install-deps.sh unpacks them into {PARAVIEW_PYTHON})")
    return path


def pvbatch_environment() -> dict[str, str]:
    """pvbatch with ParaView's Python modules and nothing of ours on its path: the plugin must
    find the client by itself, and the properties, not the variables, name server and token."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "ACTOPO_PYTHONPATH",
                        "ACTOPO_SERVER", "ACTOPO_TOKEN", "ACTOPO_PARAVIEW_PLUGIN")}
    if PARAVIEW_PYTHON.is_dir():
        env["PYTHONPATH"] = str(PARAVIEW_PYTHON)
    return env


class Run:
    """One pvbatch run of the driver: its outputs, arrays, console text and duration."""

    def __init__(self, outputs: dict[str, Any], arrays: dict[str, np.ndarray], console: str,
                 seconds: float, target: str) -> None:
        self.outputs = outputs
        self.arrays = arrays
        self.console = console
        self.seconds = seconds
        self.target = target

    def port(self, case: str, port: int) -> dict[str, Any]:
        return self.outputs["cases"][case][port]

    def array(self, case: str, port: int, kind: str, name: str) -> np.ndarray:
        return self.arrays[f"{case}/{port}/{kind}/{name}"]


def run_pvbatch(cases: list[dict[str, Any]], tmp: Path, target: str,
                plugin_dir: Path = ROOT / "paraview", **env: str) -> Run:
    """Runs tests/paraview_driver.py on `cases` in pvbatch (with `env` added)."""
    binary = pvbatch()
    (tmp / "cases.json").write_text(json.dumps({"cases": cases}))
    start = time.monotonic()
    done = subprocess.run([binary, str(ROOT / "tests" / "paraview_driver.py"),
                           str(tmp / "cases.json"), str(tmp), str(plugin_dir)],
                          env={**pvbatch_environment(), **env}, capture_output=True, text=True,
                          timeout=PVBATCH_SECONDS)
    seconds = time.monotonic() - start
    console = done.stdout + done.stderr
    assert done.returncode == 0, f"pvbatch exited {done.returncode}:\n{console}"
    outputs = json.loads((tmp / "outputs.json").read_text())
    with np.load(tmp / "arrays.npz") as npz:
        arrays = {k: npz[k] for k in npz.files}
    return Run(outputs, arrays, console, seconds, target)


def driver_case(name: str, filter_name: str, mesh: str, target: str,
                properties: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """A case for the driver; `extra`: its "before" filters and the properties to "report"."""
    return {"name": name, "filter": filter_name, "mesh": str(DATA_DIR / mesh),
            "properties": {"ServerAddress": target, "Token": TOKEN, **properties}, **extra}


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Run]:
    """Every case and every failure in one pvbatch run, against a server requiring a token."""
    pvbatch()
    with running_server("--token", TOKEN) as target:
        unreachable = f"127.0.0.1:{free_port()}"
        cases = [driver_case(c["name"], c["filter"], c["mesh"], target, c["properties"],
                             report=c.get("report", [])) for c in CASES]
        cases += [driver_case(c["name"], c["filter"], c["mesh"], target, c["properties"],
                              report=c.get("report", [])) for c in SERIES_CASES]
        cases += [driver_case(e["name"], e["filter"], e.get("mesh", FERTILITY),
                              unreachable if e["name"] == "error_unreachable" else target,
                              e["properties"], before=e.get("before", []))
                  for e in ERRORS]
        yield run_pvbatch(cases, tmp_path_factory.mktemp("paraview"), target)


@pytest.fixture(scope="module")
def expected(run: Run) -> dict[str, Any]:
    """What the Python client returns for each case, run directly on the same server."""
    import pyvista as pv

    import actopo

    results = {}
    with actopo.Client(run.target, token=TOKEN) as client:
        for case in CASES:
            how = case["client"]
            grid = pv.read(DATA_DIR / case["mesh"])
            if "load" in how:
                mesh = client.load_mesh(how["load"])
            else:
                mesh = client.upload_mesh(grid, block_size=how.get("block_size", 0))
            with client.open_session(mesh, scalar=how["scalar"], **how["session"]) as session:
                result = session.run(how["algorithm"], parameters=how.get("parameters"))
            client.delete_mesh(mesh)
            results[case["name"]] = (result, grid)
    return results


def assert_same_array(actual: np.ndarray, wanted: np.ndarray, what: str) -> None:
    assert actual.dtype == wanted.dtype, f"{what}: dtype {actual.dtype}, client {wanted.dtype}"
    assert actual.shape == wanted.shape, f"{what}: shape {actual.shape}, client {wanted.shape}"
    assert np.array_equal(actual, wanted), f"{what}: values differ from the client's"


def assert_same_diagram(run: Run, name: str, port: int, result: Any, where: str) -> None:
    """TTK's diagram grid: a VTK_LINE per pair, and in the birth-death plane TTK's diagonal from
    the first point to the last pair's birth point; its points and every point and cell array
    equal what the server streamed, the diagonal's cell values included."""
    output = run.port(name, port)
    group = result.group("diagram")
    diagram = result.diagram
    n = len(diagram)
    with_diagonal = diagram.embedding == "diagram"
    assert output["type"] == "vtkUnstructuredGrid"
    assert output["points"] == 2 * n and output["cells"] == n + with_diagonal
    cell_types = run.array(name, port, "geometry", "CellTypes")
    assert cell_types.tolist() == [VTK_LINE] * output["cells"]
    lines = run.array(name, port, "geometry", "Connectivity").reshape(-1, 2)
    np.testing.assert_array_equal(lines[:n], np.arange(2 * n).reshape(-1, 2))
    assert lines[n:].tolist() == ([[0, 2 * (n - 1)]] if with_diagonal else [])
    assert_same_array(run.array(name, port, "geometry", "CellOffsets"),
                      np.arange(0, 2 * output["cells"] + 1, 2), f"{where} cell offsets")
    assert_same_array(run.array(name, port, "geometry", "Points"), group["Points"],
                      f"{where} Points")
    point_arrays = ["ttkVertexScalarField", "CriticalType", "Coordinates"]
    cell_arrays = ["PairIdentifier", "PairType", "Persistence", "Birth", "IsFinite"]
    assert sorted(output["point_arrays"]) == sorted(point_arrays)
    assert sorted(output["cell_arrays"]) == sorted(cell_arrays)
    for kind, names in (("point", point_arrays), ("cell", cell_arrays)):
        for key in names:
            assert_same_array(run.array(name, port, kind, key), group[key], f"{where} {key}")


def assert_same_tree_port(run: Run, name: str, port: int, group: dict[str, np.ndarray],
                          where: str) -> None:
    """A tree's nodes or arcs as TTK outputs them, a vtkUnstructuredGrid: a VTK_VERTEX cell per
    node, or a VTK_LINE cell per arc through the points Offsets and Connectivity name; the
    points and every array the client's, per point or per arc where TTK puts them."""
    output = run.port(name, port)
    assert output["type"] == "vtkUnstructuredGrid"
    points = np.asarray(group["Points"], dtype=np.float64).reshape(-1, 3)
    assert_same_array(run.array(name, port, "geometry", "Points"), points, f"{where} Points")
    cell_types = run.array(name, port, "geometry", "CellTypes")
    offsets = run.array(name, port, "geometry", "CellOffsets")
    connectivity = run.array(name, port, "geometry", "Connectivity")
    if "Offsets" not in group:  # the nodes
        assert output["cells"] == output["points"] == len(points)
        assert cell_types.tolist() == [VTK_VERTEX] * len(points)
        np.testing.assert_array_equal(offsets, np.arange(len(points) + 1))
        np.testing.assert_array_equal(connectivity, np.arange(len(points)))
        point_arrays = {k: v for k, v in group.items() if k != "Points"}
        cell_arrays: dict[str, np.ndarray] = {}
    else:
        arcs = len(group["Offsets"]) - 1
        assert output["cells"] == arcs
        assert cell_types.tolist() == [VTK_LINE] * arcs
        assert_same_array(offsets, group["Offsets"], f"{where} Offsets")
        assert_same_array(connectivity,
                          group.get("Connectivity", np.arange(2 * arcs, dtype=np.int64)),
                          f"{where} Connectivity")
        point_arrays = {k: group[k] for k in TREE_ARC_POINT_ARRAYS}
        cell_arrays = {k: v for k, v in group.items()
                       if k not in (*TREE_ARC_POINT_ARRAYS, "Points", "Offsets", "Connectivity")}
    assert sorted(output["point_arrays"]) == sorted(point_arrays)
    assert sorted(output["cell_arrays"]) == sorted(cell_arrays)
    for kind, arrays in (("point", point_arrays), ("cell", cell_arrays)):
        for key, values in arrays.items():
            assert_same_array(run.array(name, port, kind, key), values, f"{where} {key}")


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_outputs_equal_the_python_clients_results(run: Run, expected: dict[str, Any],
                                                  case: dict[str, Any]) -> None:
    name = case["name"]
    result, grid = expected[name]
    groups = GROUP_OF_PORT[case["client"]["algorithm"]]
    assert len(run.outputs["cases"][name]) == len(groups)
    for port, group_name in enumerate(groups):
        group = result.group(group_name)
        output = run.port(name, port)
        where = f"{name} port {port} ({group_name})"
        if group_name in ("segmentation", "simplified"):
            # The input grid, its own arrays kept, the group's added; downstream of a
            # simplification (TTK's chain) the simplified field replaces the input's, and its
            # order is added.
            added = {**result.group("simplified"), **group}
            assert output["type"] == "vtkUnstructuredGrid"
            assert output["cells"] == grid.n_cells
            assert_same_array(run.array(name, port, "geometry", "Points"),
                              np.asarray(grid.points), f"{where} Points")
            assert sorted(output["point_arrays"]) == sorted({*grid.point_data.keys(), *added})
            for key in grid.point_data.keys():  # noqa: SIM118 (pyvista)
                if key not in added:
                    assert_same_array(run.array(name, port, "point", key),
                                      np.asarray(grid.point_data[key]), f"{where} {key}")
            for key, values in added.items():
                assert_same_array(run.array(name, port, "point", key), values, f"{where} {key}")
            continue
        if group_name == "diagram":
            assert_same_diagram(run, name, port, result, where)
            continue
        if group_name in ("tree_nodes", "tree_arcs"):
            assert_same_tree_port(run, name, port, group, where)
            continue
        assert output["type"] == "vtkPolyData"
        assert_same_array(run.array(name, port, "geometry", "Points"),
                          np.asarray(group["Points"], dtype=np.float64).reshape(-1, 3),
                          f"{where} Points")
        if group_name == "separatrices":
            # One polyline per separatrix through its points; the per-separatrix arrays.
            assert output["lines"] == len(group["Offsets"]) - 1 == output["cells"]
            assert_same_array(run.array(name, port, "geometry", "LineOffsets"),
                              group["Offsets"], f"{where} Offsets")
            arrays = {k: v for k, v in group.items() if k not in ("Points", "Offsets")}
            assert sorted(output["cell_arrays"]) == sorted(arrays)
            assert output["point_arrays"] == []
            kind = "cell"
        else:
            # One vertex per critical point or cell, the arrays as point data.
            assert output["verts"] == output["points"] == len(group["Points"])
            arrays = {k: v for k, v in group.items() if k != "Points"}
            assert sorted(output["point_arrays"]) == sorted(arrays)
            kind = "point"
        for key, values in arrays.items():
            assert_same_array(run.array(name, port, kind, key), values, f"{where} {key}")
    assert result.summary  # the run found something to compare
    assert sum(run.port(name, p)["points"] for p in range(len(groups))) > 0


SIMPLIFIED = [c for c in CASES if "ttk" in c]


@pytest.mark.parametrize("case", SIMPLIFIED, ids=[c["name"] for c in SIMPLIFIED])
def test_simplified_fields_equal_ttks(run: Run, expected: dict[str, Any],
                                      case: dict[str, Any]) -> None:
    """The simplified field and its order that the filter outputs, digested as
    simplification-ttk.json digests TTK's, equal upstream TTK's at the same threshold; the
    field replaced the input's under its name, as in TTK's output."""
    from actopo.types import SimplifiedField

    result, _ = expected[case["name"]]
    field = case["client"]["scalar"]
    ttk = json.loads(SIMPLIFICATION_REFERENCE.read_text())["results"][case["mesh"]][field][
        case["ttk"]]
    port = len(GROUP_OF_PORT[case["client"]["algorithm"]]) - 1  # the grid
    values = run.array(case["name"], port, "point", field)
    order = run.array(case["name"], port, "point", f"{field}_Order")
    assert values.dtype == np.float64 and order.dtype == np.int32
    simplified = SimplifiedField(field, values, order)
    assert simplified.scalars_sha256() == ttk["scalars_sha256"]
    assert simplified.order_sha256() == ttk["order_sha256"]
    summary = result.summary.get("simplification", result.summary)
    assert summary["kept_pairs"] == ttk["kept_pairs"]
    assert summary["threshold"] == ttk["threshold"]


def assert_statistics(run: Run, data: dict[str, Any], algorithm: str, structure: str,
                      where: str) -> None:
    """The job's identity and the session's statistics in an output's field data."""
    assert data["ActopoAlgorithm"] == algorithm
    assert data["ActopoStructure"] == structure
    assert data["ActopoServer"] == run.target
    missing = [k for k in STATISTICS if k not in data]
    assert not missing, f"{where}: no {missing} in {sorted(data)}"
    assert data["ActopoJobs"] == 1
    assert data["ActopoEngineHits"] + data["ActopoEngineMisses"] == \
        data["ActopoEngineRequests"]
    if data["ActopoStructure"] != "explicit":  # explicit reads stored relations: no requests
        assert data["ActopoEngineRequests"] > 0
    assert data["ActopoMemoryStaticBytes"] > 0
    assert data["ActopoRunSeconds"] > 0
    assert data["ActopoEngineWaitSeconds"] >= 0
    assert 0 <= data["ActopoEngineHitRate"] <= 1


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_every_output_carries_the_summary_and_the_sessions_statistics(
        run: Run, expected: dict[str, Any], case: dict[str, Any]) -> None:
    result, _ = expected[case["name"]]
    for port, output in enumerate(run.outputs["cases"][case["name"]]):
        data = output["field_data"]
        where = f"{case['name']} port {port}"
        assert json.loads(data["ActopoSummary"]) == result.summary, where
        assert_statistics(run, data, case["client"]["algorithm"],
                          case["client"]["session"]["structure"], where)


# --- The trees -----------------------------------------------------------------------------------

TREES = [c for c in CASES if "tree" in c]


def ttk_tree(case: dict[str, Any]) -> dict[str, Any]:
    """The case's entry of trees-ttk.json: upstream TTK's tree of the same field, or of the
    field simplified first at the same fraction of its range."""
    kind, fraction = case["tree"]
    entry = json.loads(TREES_REFERENCE.read_text())["results"][case["mesh"]][
        case["client"]["scalar"]]
    return entry["trees"][kind] if fraction is None else entry["simplified"][fraction][kind]


def array_digest(values: np.ndarray) -> str:
    """"<dtype>:<count>:<SHA-256 of the little-endian bytes>", as trees_reference.py digests
    TTK's arrays."""
    data = np.ascontiguousarray(values).astype(values.dtype.newbyteorder("<")).tobytes()
    return f"{values.dtype.name}:{len(values)}:{hashlib.sha256(data).hexdigest()}"


def rows_digest(rows: Iterable[str]) -> str:
    """The SHA-256 of the rows sorted as strings: trees_reference.py's order-free digests."""
    return hashlib.sha256("".join(sorted(rows)).encode()).hexdigest()


def port_arrays(run: Run, name: str, port: int) -> dict[str, np.ndarray]:
    """Every point and cell array of an output port by name."""
    output = run.port(name, port)
    return {**{k: run.array(name, port, "point", k) for k in output["point_arrays"]},
            **{k: run.array(name, port, "cell", k) for k in output["cell_arrays"]}}


def tree_groups(run: Run, name: str) -> dict[str, dict[str, np.ndarray]]:
    """What the filter's three ports hold, as the server's groups by TTK name: tree_nodes,
    tree_arcs (the line cells as Offsets and Connectivity) and segmentation (with the input
    grid's own arrays)."""
    nodes = {"Points": run.array(name, 0, "geometry", "Points"), **port_arrays(run, name, 0)}
    arcs = {"Points": run.array(name, 1, "geometry", "Points"),
            "Offsets": run.array(name, 1, "geometry", "CellOffsets"),
            "Connectivity": run.array(name, 1, "geometry", "Connectivity"),
            **port_arrays(run, name, 1)}
    return {"tree_nodes": nodes, "tree_arcs": arcs, "segmentation": port_arrays(run, name, 2)}


def in_ttks_order(names: list[str], ttk_names: list[str]) -> bool:
    """Whether `names` hold TTK's arrays `ttk_names`, in TTK's order. Arrays of the server's
    own may come with them; test_outputs_equal_the_python_clients_results holds the port to
    the client's arrays."""
    return [n for n in names if n in ttk_names] == ttk_names


@pytest.mark.parametrize("case", TREES, ids=[c["name"] for c in TREES])
def test_trees_are_ttks(run: Run, expected: dict[str, Any], case: dict[str, Any]) -> None:
    """TTK's three outputs: the nodes (a VTK_VERTEX each) and the arcs (a VTK_LINE each) as
    vtkUnstructuredGrids with TTK's arrays, in TTK's order and with TTK's types, as many as the
    job's summary counts; the input grid with a SegmentationId, an arc's, per vertex. Every
    array equals upstream TTK's byte for byte (where FTM moved its join tree in as the contour
    tree, TTK's node and arc order follow its scheduling: their rows then, in any order), and
    the tree the client reads from these outputs has TTK's digests."""
    from actopo._tree import from_arrays

    name = case["name"]
    result, grid = expected[name]
    summary = result.summary
    ttk = ttk_tree(case)
    outputs = run.outputs["cases"][name]
    assert [o["type"] for o in outputs] == ["vtkUnstructuredGrid"] * 3
    nodes, arcs, segmentation = outputs
    assert in_ttks_order(nodes["point_arrays"], TREE_NODE_ARRAYS) and nodes["cell_arrays"] == []
    assert arcs["point_arrays"] == TREE_ARC_POINT_ARRAYS
    assert in_ttks_order(arcs["cell_arrays"], TREE_ARC_CELL_ARRAYS)
    assert in_ttks_order(segmentation["point_arrays"], TREE_SEGMENTATION_ARRAYS)
    assert nodes["points"] == nodes["cells"] == summary["nodes"] == ttk["nodes"]
    assert arcs["cells"] == summary["arcs"] == ttk["arcs"]
    assert summary["critical_types"] == ttk["critical_types"]
    assert (segmentation["points"], segmentation["cells"]) == (grid.n_points, grid.n_cells)
    groups = tree_groups(run, name)
    ids = groups["segmentation"]["SegmentationId"]
    assert len(ids) == grid.n_points
    assert np.isin(ids, groups["tree_arcs"]["SegmentationId"]).all()

    moved = ttk.get("moved_join_tree", False)
    assert len(ttk["arrays_sha256"]) == 17  # every array of the three outputs
    for key, want in ttk["arrays_sha256"].items():
        group, array = key.split("/")
        got = array_digest(groups[group][array])
        assert got.split(":")[:2] == want.split(":")[:2], f"{name} {key}: {got}, TTK's {want}"
        if not moved or group == "segmentation":
            assert got == want, f"{name} {key}: the bytes differ from TTK's"

    tree = from_arrays(summary["tree"], groups["tree_nodes"], groups["tree_arcs"],
                       groups["segmentation"])
    assert tree.counts_by_type() == ttk["critical_types"]
    assert tree.nodes_sha256() == ttk["nodes_sha256"]
    assert tree.arcs_sha256() == ttk["arcs_sha256"]
    assert tree.segmentation_sha256() == ttk["segmentation_sha256"]
    n, a = tree.nodes, tree.arcs
    assert rows_digest(
        f"{v} {t} {size} {span} {scalar:.9g}\n" for v, t, size, span, scalar in zip(
            n.vertex.tolist(), n.critical_type.tolist(), n.region_size.tolist(),
            n.region_span.tolist(), n.scalar.tolist(), strict=True)) == ttk["node_rows_sha256"]
    assert rows_digest(
        f"{sid} {down} {up} {size} {span:.9g}\n" for sid, down, up, size, span in zip(
            a.segmentation_id.tolist(), n.vertex[a.down].tolist(), n.vertex[a.up].tolist(),
            a.region_size.tolist(), a.region_span.tolist(), strict=True)) == \
        ttk["arc_rows_sha256"]


def tree_summary(run: Run, name: str) -> dict[str, Any]:
    return json.loads(run.port(name, 0)["field_data"]["ActopoSummary"])


def test_tree_type_switches_from_the_join_tree_to_the_split_tree(run: Run) -> None:
    """Tree Type has TTK's entries, Join Tree by default (the server's default); Split Tree
    gives another tree of the same field, whose leaves are the maxima instead of the minima."""
    # The driver reports an enumeration as the list of its one entry.
    assert run.outputs["properties"]["merge_tree"] == {
        "TreeType": ["Join Tree"], "PersistenceThreshold": 0.0, "ThresholdIsRelative": 1}
    assert tree_summary(run, "merge_tree")["tree"] == "join"
    assert tree_summary(run, "merge_tree_split")["tree"] == "split"
    join = run.array("merge_tree", 0, "point", "CriticalType")
    split = run.array("merge_tree_split", 0, "point", "CriticalType")
    assert len(join) != len(split)  # fertility's height: 20 nodes, 26
    # A join tree's leaves are minima and its root the maximum; a split tree's the reverse.
    assert np.count_nonzero(join == 3) == 1 and np.count_nonzero(join == 0) > 1
    assert np.count_nonzero(split == 0) == 1 and np.count_nonzero(split == 3) > 1


SIMPLIFIED_TREES = [("merge_tree", "merge_tree_simplified"),
                    ("contour_tree", "contour_tree_simplified")]


@pytest.mark.parametrize("pair", SIMPLIFIED_TREES, ids=[p[1] for p in SIMPLIFIED_TREES])
def test_a_threshold_leaves_fewer_nodes(run: Run, pair: tuple[str, str]) -> None:
    """Persistence Threshold, 0 by default (the field as it is), simplifies the field first:
    the tree of the same field has fewer nodes and arcs, and the Segmentation port carries
    the simplified field and its order, as downstream of TTK's TopologicalSimplification."""
    whole, simplified = pair
    assert run.outputs["properties"][whole]["PersistenceThreshold"] == 0
    for port in (0, 1):
        assert 0 < run.port(simplified, port)["cells"] < run.port(whole, port)["cells"]
    assert tree_summary(run, simplified)["nodes"] < tree_summary(run, whole)["nodes"]
    assert tree_summary(run, simplified)["tree"] == tree_summary(run, whole)["tree"]
    assert "simplification" in tree_summary(run, simplified)
    assert "simplification" not in tree_summary(run, whole)
    assert "height_Order" in run.port(simplified, 2)["point_arrays"]
    assert "height_Order" not in run.port(whole, 2)["point_arrays"]


# --- The filters over several fields -------------------------------------------------------------


def series_fields() -> list[str]:
    """The Isabel series' fields in the file's order (series.json lists them so)."""
    return list(json.loads((DATA_DIR / "series.json").read_text())["fields"])


def case_fields(case: dict[str, Any]) -> list[str]:
    fields = case["client"]["fields"]
    return series_fields() if fields == "all" else list(fields)


def ttk_columns(prefix: str, count: int) -> list[str]:
    """TTK PersistenceDiagramDistanceMatrix's column names: the index zero-padded to the width
    of the last one (ttkPersistenceDiagramDistanceMatrix.cpp)."""
    width = len(str(count - 1))
    return [prefix + str(i).zfill(width) for i in range(count)]


def without_seconds(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary without its timings, which differ from one run to the next."""
    return {k: v for k, v in summary.items() if not k.endswith("_seconds")}


@pytest.fixture(scope="module")
def expected_series(run: Run) -> dict[str, Any]:
    """What the Python client returns for each case over several fields, on the same server:
    Session.distance_matrix() or the JobResult of a tracking job."""
    import actopo

    results: dict[str, Any] = {}
    with actopo.Client(run.target, token=TOKEN) as client:
        for case in SERIES_CASES:
            how = case["client"]
            mesh = client.load_mesh(how["load"]) if "load" in how \
                else client.upload_mesh(DATA_DIR / case["mesh"])
            with client.open_session(mesh, **how["session"]) as session:
                if how["kind"] == "distance_matrix":
                    results[case["name"]] = session.distance_matrix(how["fields"],
                                                                    **how["options"])
                else:
                    results[case["name"]] = session.run("tracking", fields=how["fields"],
                                                        parameters=how.get("parameters"))
            client.delete_mesh(mesh)
    return results


DISTANCE_CASES = [c for c in SERIES_CASES if c["client"]["kind"] == "distance_matrix"]
TRACKING_CASES = [c for c in SERIES_CASES if c["client"]["kind"] == "tracking"]


@pytest.mark.parametrize("case", DISTANCE_CASES, ids=[c["name"] for c in DISTANCE_CASES])
def test_distance_matrix_equals_the_clients(run: Run, expected_series: dict[str, Any],
                                            case: dict[str, Any]) -> None:
    """A row per field, named by FieldName in the fields' order; TTK's Diagram columns hold the
    Wasserstein-p distances and the Bottleneck columns the bottleneck ones, each exactly the
    client's; the field data carry the job's summary and the session's statistics."""
    name = case["name"]
    matrix = expected_series[name]
    fields = case_fields(case)
    count = len(fields)
    assert matrix.fields == fields
    assert len(run.outputs["cases"][name]) == 1
    output = run.port(name, 0)
    assert output["type"] == "vtkTable"
    assert output["rows"] == count
    diagrams, bottlenecks = ttk_columns("Diagram", count), ttk_columns("Bottleneck", count)
    assert output["columns"] == [*diagrams, *bottlenecks, "FieldName"]
    assert output["strings"]["FieldName"] == fields
    for j in range(count):
        assert_same_array(run.array(name, 0, "row", diagrams[j]), matrix.wasserstein[:, j],
                          f"{name} {diagrams[j]}")
        assert_same_array(run.array(name, 0, "row", bottlenecks[j]), matrix.bottleneck[:, j],
                          f"{name} {bottlenecks[j]}")
    assert np.all(matrix.wasserstein[~np.eye(count, dtype=bool)] > 0)  # distinct diagrams
    data = output["field_data"]
    summary = json.loads(data["ActopoSummary"])
    assert summary["fields"] == fields
    assert summary["p"] == matrix.p == case["client"]["options"].get("p", 2)
    assert summary["pairs"] == matrix.pairs and summary["thresholds"] == matrix.thresholds
    assert summary["wasserstein"] == matrix.wasserstein.tolist()
    assert summary["bottleneck"] == matrix.bottleneck.tolist()
    assert_statistics(run, data, "diagram-distance", case["client"]["session"]["structure"],
                      name)
    if "report" in case:  # by default every field of the input, in its order
        assert run.outputs["properties"][name]["ScalarFields"] == fields


@pytest.mark.parametrize("case", TRACKING_CASES, ids=[c["name"] for c in TRACKING_CASES])
def test_tracking_equals_the_clients(run: Run, expected_series: dict[str, Any],
                                     case: dict[str, Any]) -> None:
    """TTK's tracking output as vtkPolyData: the client's points, a VTK_LINE (two points) per
    link of the summary, from a step to the next; TimeStep, CriticalType, Scalar and VertexId
    per point, ConnectedComponentId, MatchingIdentifier, Cost and ComponentLength per line,
    with the server's types and values."""
    name = case["name"]
    result = expected_series[name]
    group = result.group("tracking")
    fields = case_fields(case)
    links = result.summary["links"]
    assert links > 0 and result.summary["fields"] == fields
    assert len(run.outputs["cases"][name]) == 1
    output = run.port(name, 0)
    assert output["type"] == "vtkPolyData"
    assert output["lines"] == output["cells"] == links
    assert output["verts"] == 0
    assert_same_array(run.array(name, 0, "geometry", "Points"), group["Points"],
                      f"{name} Points")
    offsets = run.array(name, 0, "geometry", "LineOffsets")
    np.testing.assert_array_equal(offsets, np.arange(0, 2 * links + 1, 2))  # two points each
    np.testing.assert_array_equal(offsets, group["Offsets"])
    connectivity = run.array(name, 0, "geometry", "LineConnectivity")
    np.testing.assert_array_equal(connectivity, group["Connectivity"])
    assert output["point_arrays"] == TRACKING_POINT_ARRAYS
    assert output["cell_arrays"] == TRACKING_CELL_ARRAYS
    for kind, names in (("point", TRACKING_POINT_ARRAYS), ("cell", TRACKING_CELL_ARRAYS)):
        for key in names:
            assert_same_array(run.array(name, 0, kind, key), group[key], f"{name} {key}")
    lines = connectivity.reshape(-1, 2)
    steps = run.array(name, 0, "point", "TimeStep")
    np.testing.assert_array_equal(steps[lines[:, 1]] - steps[lines[:, 0]], 1)
    assert steps.min() == 0 and steps.max() == len(fields) - 1
    data = output["field_data"]
    summary = json.loads(data["ActopoSummary"])
    assert without_seconds(summary) == without_seconds(result.summary)
    assert summary["p"] == float(case["client"].get("parameters", {}).get("p", 2))
    assert_statistics(run, data, "tracking", case["client"]["session"]["structure"], name)
    if "report" in case:
        assert run.outputs["properties"][name]["ScalarFields"] == fields


def test_the_plugin_uses_paraviews_numpy_and_the_clients_grpc_stack(run: Run) -> None:
    modules = run.outputs["modules"]
    venv = str(ROOT / ".venv")
    assert not modules["numpy"][1].startswith(venv), modules  # ParaView's own
    assert modules["google.protobuf"][1].startswith(venv), modules  # the stubs' protobuf
    assert modules["grpc"][1].startswith(venv), modules
    assert modules["actopo"][1].startswith(str(ROOT / "client-py")), modules
    print(f"PARAVIEW python {run.outputs['python']} numpy {modules['numpy'][0]} protobuf "
          f"{modules['google.protobuf'][0]} grpc {modules['grpc'][0]}; "
          f"pvbatch {run.seconds:.1f} s")


def plugin_elsewhere(tmp: Path) -> Path:
    """The plugin copied away from the repository, where it cannot find .venv by itself."""
    copy = tmp / "plugin"
    copy.mkdir()
    for name in ("actopo_plugin.py", "load_actopo.py"):
        shutil.copy(ROOT / "paraview" / name, copy / name)
    return copy


def test_actopo_pythonpath_names_the_clients_environment(run: Run, tmp_path: Path) -> None:
    case = driver_case("critical_points", "ACTOPOCriticalPoints", FERTILITY, run.target,
                       {"ScalarField": ["POINTS", "eigenfunction4"]})
    site = sysconfig.get_paths()["purelib"]  # this test's environment: .venv
    elsewhere = run_pvbatch([case], tmp_path, run.target, plugin_elsewhere(tmp_path),
                            ACTOPO_PYTHONPATH=os.pathsep.join([site, str(ROOT / "client-py")]))
    for kind, name in (("geometry", "Points"), ("point", "CriticalType")):
        assert_same_array(elsewhere.array("critical_points", 0, kind, name),
                          run.array("critical_points", 0, kind, name), name)
    assert not elsewhere.outputs["modules"]["numpy"][1].startswith(site)


def test_a_missing_client_is_reported(run: Run, tmp_path: Path) -> None:
    case = driver_case("no_client", "ACTOPOCriticalPoints", FERTILITY, run.target,
                       {"ScalarField": ["POINTS", "eigenfunction4"]})
    missing = run_pvbatch([case], tmp_path, run.target, plugin_elsewhere(tmp_path))
    assert missing.outputs["finished"]
    assert "cannot import the actopo Python client (ModuleNotFoundError: No module named " \
        "'actopo'). Searched first: (nothing). Set ACTOPO_PYTHONPATH" in missing.console, \
        missing.console
    assert missing.port("no_client", 0)["points"] == 0


@pytest.mark.parametrize("error", ERRORS, ids=[e["name"] for e in ERRORS])
def test_failures_show_the_message_and_pvbatch_goes_on(run: Run, error: dict[str, Any]) -> None:
    assert run.outputs["finished"]  # the cases after the failing ones ran too
    lines = run.console.splitlines()
    header = next((i for i, line in enumerate(lines)
                   if line.startswith(error["filter"].replace("ACTOPO", "Actopo"))
                   and error["message"] in line), None)
    assert header is not None, f"no '{error['message']}' in pvbatch's output:\n{run.console}"
    assert lines[header - 1].startswith("ERROR: In actopo_plugin.py")
    assert "Traceback" not in run.console  # the message, not a Python stack
    outputs = run.outputs["cases"][error["name"]]
    assert all(o.get("points", 0) == 0 and o.get("rows", 0) == 0 and not o["field_data"]
               for o in outputs)
