"""topological-simplification through the client: the simplified field and its order, read from
the streamed arrays as result.simplified and digested here, equal upstream TTK's
(tests/ttk_reference/simplification-ttk.json) on every structure at relative thresholds 0.01 and
0.05, and so do the pairs kept and the values changed, counted against the mesh file; morse-smale
with a threshold equals TTK's complex of the simplified field; the absolute and default
thresholds, the bad parameters, both clients, files equal actopo-bench's, and the CLI. The first
tests need no server."""

from __future__ import annotations

import asyncio
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
import pyvista as pv
from harness import BENCH_BIN
from references import SIMPLIFICATION_TTK, check_summary, segmentation_sha256

import actopo
from actopo import _simplified
from actopo._mesh import mesh_arrays
from actopo._simplified import from_arrays
from actopo.types import SimplifiedField

SIMPLIFICATION = "topological-simplification"
STRUCTURES = ["explicit", "compact", "actopo"]
REFERENCE = SIMPLIFICATION_TTK
# The (file, field) and thresholds of simplification-ttk.json, listed here so that the tests
# exist without reading it first; test_every_reference_case_is_tested keeps the two equal.
CASES = [
    ("manifoldCheck0_tet.vtu", "height"),
    ("fertility_tet.vtu", "eigenfunction4"),
    ("fertility_tet.vtu", "height"),
    ("viscousFingers001_s2_tet.vtu", "density"),
    ("isabel02_s2_tet.vtu", "velocityMag"),
]
THRESHOLDS = ["0.01", "0.05"]
CASE_IDS = [f"{f[:-8]}-{v}" for f, v in CASES]
FINGERS = "viscousFingers001_s2_tet.vtu"
ISABEL = "isabel02_s2_tet.vtu"


def _sha256(lines: list[str]) -> str:
    return hashlib.sha256("".join(lines).encode()).hexdigest()


def test_digests_are_of_one_line_per_vertex():
    """"<vertex> <value as %.17g>" and "<vertex> <order>", in ascending vertex id, as
    simplification_reference.py writes TTK's: 17 significant digits, C's exponents."""
    field = from_arrays({"f_Order": np.array([2, 0, 3, 1], dtype=np.int32),
                         "f": np.array([0.1, -0.5, 1e-05, 1 / 3])})
    assert field.name == "f" and field.order_name == "f_Order" and len(field) == 4
    assert field.values.dtype == np.float64 and field.order.dtype == np.int32
    text = "0 0.10000000000000001\n1 -0.5\n2 1.0000000000000001e-05\n3 0.33333333333333331\n"
    assert field.scalars_sha256() == hashlib.sha256(text.encode()).hexdigest()
    assert field.order_sha256() == _sha256(["0 2\n", "1 0\n", "2 3\n", "3 1\n"])
    assert field.changed_vertices([0.1, 0.0, 1e-05, 0.0]).tolist() == [1, 3]
    assert field.changed_vertices(np.float32([0.1, -0.5, 1e-05, 1 / 3])).tolist() == [0, 2, 3]
    assert list(field.point_data()) == ["f", "f_Order"]
    with pytest.raises(ValueError, match="original: 3 values, the simplified field 'f' has 4"):
        field.changed_vertices([0.0, 0.0, 0.0])


def test_digests_fed_in_pieces_equal_the_whole_text(monkeypatch):
    values = np.linspace(-1, 1, 10)
    field = SimplifiedField("f", values, np.arange(10, dtype=np.int32))
    whole = _sha256([f"{v} {x:.17g}\n" for v, x in enumerate(values.tolist())])
    assert field.scalars_sha256() == whole
    monkeypatch.setattr(_simplified, "_LINES_PER_UPDATE", 3)
    assert field.scalars_sha256() == whole
    assert field.order_sha256() == _sha256([f"{v} {v}\n" for v in range(10)])


def test_a_layout_the_client_cannot_read_is_named():
    with pytest.raises(actopo.ActopoError, match="simplified/: expected a field and its _Order "
                       "array, got f"):
        from_arrays({"f": np.zeros(3)})
    with pytest.raises(actopo.ActopoError, match="got f, f_Order, g"):
        from_arrays({"f": np.zeros(3), "f_Order": np.zeros(3), "g": np.zeros(3)})
    with pytest.raises(actopo.ActopoError, match="simplified/f_Order: 2 values, expected 3"):
        from_arrays({"f": np.zeros(3), "f_Order": np.zeros(2)})


def test_every_reference_case_is_tested():
    results = json.loads(REFERENCE.read_text())["results"]
    listed = [(f, field) for f, fields in results.items() for field in fields]
    assert sorted(listed) == sorted(CASES)
    assert all(sorted(entry) == THRESHOLDS for fields in results.values()
               for entry in fields.values())


@pytest.fixture(scope="module")
def reference():
    """reference(file, field, threshold) -> TTK's entry of simplification-ttk.json."""
    results = json.loads(REFERENCE.read_text())["results"]
    return lambda file, field, threshold: results[file][field][threshold]


@pytest.fixture(scope="module")
def original(data_dir):
    """original(file, field) -> the field's values as the mesh file holds them."""
    read: dict[str, dict[str, np.ndarray]] = {}

    def values(file: str, field: str) -> np.ndarray:
        if file not in read:
            read[file] = mesh_arrays(data_dir / file).point_data
        return read[file][field]

    return values


def _run(client, mesh, field, structure="compact", algorithm=SIMPLIFICATION,
         **options) -> actopo.JobResult:
    with client.open_session(mesh, scalar=field, structure=structure) as session:
        return session.run(algorithm, digests=True, **options)


def _relative(threshold: str) -> dict[str, dict[str, str]]:
    return {"parameters": {"relative_threshold": threshold}}


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("threshold", THRESHOLDS)
@pytest.mark.parametrize("file,field", CASES, ids=CASE_IDS)
def test_simplified_field_equals_ttks(client, meshes, reference, original, file, field,
                                      threshold, structure):
    """The digests computed here from the streamed field and order, the pairs kept and the
    values changed (against the file's field) equal upstream TTK's; so does the summary."""
    ttk = reference(file, field, threshold)
    mesh = meshes(file)
    result = _run(client, mesh, field, structure, **_relative(threshold))
    simplified = result.simplified
    assert simplified is not None and simplified.name == field
    assert len(simplified) == mesh.vertices
    assert simplified.scalars_sha256() == ttk["scalars_sha256"]
    assert simplified.order_sha256() == ttk["order_sha256"]
    changed = simplified.changed_vertices(original(file, field))
    assert len(changed) == ttk["changed_values"]
    if "changes" in ttk:  # small edits are listed whole
        assert [[int(v), simplified.values[v]] for v in changed] == ttk["changes"]
    summary = result.summary
    assert summary["kept_pairs"] == ttk["kept_pairs"]
    assert summary["threshold"] == ttk["threshold"]  # the same product in double precision
    assert (summary["changed_values"], summary["scalars_sha256"], summary["order_sha256"]) == \
        (ttk["changed_values"], ttk["scalars_sha256"], ttk["order_sha256"])
    assert summary["kept_pairs"] + summary["removed_pairs"] == summary["pairs"]
    # The order ranks the vertices: a permutation of 0..n-1 along which the field never falls.
    assert np.array_equal(np.sort(simplified.order), np.arange(mesh.vertices))
    assert (np.diff(simplified.values[np.argsort(simplified.order)]) >= 0).all()


@pytest.mark.parametrize("threshold", THRESHOLDS)
@pytest.mark.parametrize("file,field", CASES, ids=CASE_IDS)
def test_morse_smale_of_the_simplified_field_equals_ttks(client, meshes, reference, file, field,
                                                         threshold):
    """morse-smale with a threshold simplifies first: its counts, regions and segmentation
    digests (computed here too) equal TTK's complex of TTK's simplified field, its summary's
    "simplification" the simplification's, and it streams the simplified field as well."""
    ttk = reference(file, field, threshold)
    result = _run(client, meshes(file), field, "actopo", "morse-smale", **_relative(threshold))
    summary = result.summary
    complex_ = ttk["morse_smale"]
    for key in ("critical_cells", "separatrices", "regions", "segmentation_sha256"):
        assert summary[key] == complex_[key], key
    for key, name in (("descending", "DescendingManifold"), ("ascending", "AscendingManifold"),
                      ("morse_smale", "MorseSmaleManifold")):
        labels = result.segmentation[name]
        assert segmentation_sha256(labels) == complex_["segmentation_sha256"][key], name
        assert len(np.unique(labels)) == complex_["regions"][key], name
    assert np.bincount(result.critical_points["CellDimension"], minlength=4).tolist() == \
        complex_["critical_cells"]
    simplification = summary["simplification"]
    assert (simplification["threshold"], simplification["kept_pairs"],
            simplification["changed_values"], simplification["scalars_sha256"],
            simplification["order_sha256"]) == (ttk["threshold"], ttk["kept_pairs"],
                                                ttk["changed_values"], ttk["scalars_sha256"],
                                                ttk["order_sha256"])
    assert result.groups == ["critical_points", "separatrices", "simplified", "segmentation"]
    simplified = result.simplified
    assert simplified is not None and simplified.scalars_sha256() == ttk["scalars_sha256"]
    assert simplified.order_sha256() == ttk["order_sha256"]
    # The critical cells report the simplified field at their highest vertex, as TTK's complex
    # of TTK's simplified field does.
    points = result.critical_points
    assert np.array_equal(points[field], simplified.values[points["ttkVertexScalarField"]])


def test_absolute_and_default_thresholds(client, meshes, reference):
    """persistence_threshold is the same cut given absolutely; without a parameter the cut is
    1% of the range; morse-smale without one does not simplify."""
    mesh = meshes(FINGERS)
    ttk = reference(FINGERS, "density", "0.05")
    with client.open_session(mesh, scalar="density", structure="compact") as session:
        absolute = session.run(SIMPLIFICATION,
                               parameters={"persistence_threshold": repr(ttk["threshold"])})
        default = session.run(SIMPLIFICATION)
        plain = session.run("morse-smale")
    assert absolute.summary["threshold"] == ttk["threshold"]
    assert absolute.simplified.scalars_sha256() == ttk["scalars_sha256"]
    assert absolute.simplified.order_sha256() == ttk["order_sha256"]
    one_percent = reference(FINGERS, "density", "0.01")
    assert default.summary["threshold"] == one_percent["threshold"]
    assert default.simplified.scalars_sha256() == one_percent["scalars_sha256"]
    assert "simplification" not in plain.summary and plain.simplified is None
    assert plain.groups == ["critical_points", "separatrices", "segmentation"]


def test_simplified_is_none_without_a_simplification(client, meshes):
    with client.open_session(meshes("manifoldCheck0_tet.vtu")) as session:
        assert session.run("critical-points").simplified is None
        summary_only = session.run(SIMPLIFICATION, include_arrays=False)
        assert summary_only.simplified is None and summary_only.arrays == {}
        assert summary_only.summary["kept_pairs"] == 2


# Every bad threshold, with the message the server gives, for both algorithms.
BAD_THRESHOLDS = [
    ({"relative_threshold": "0.01", "persistence_threshold": "1"},
     "parameters: give persistence_threshold or relative_threshold, not both"),
    ({"relative_threshold": "x"}, "parameters.relative_threshold: 'x' is not a number"),
    ({"persistence_threshold": "nan"}, "parameters.persistence_threshold: 'nan' is not a number"),
    ({"relative_threshold": "-0.5"},
     "parameters.relative_threshold: threshold: -0.5 is not a fraction of the scalar range in "
     "[0, 1]"),
    ({"relative_threshold": "1.5"},
     "parameters.relative_threshold: threshold: 1.5 is not a fraction of the scalar range in "
     "[0, 1]"),
    ({"persistence_threshold": "-2"},
     "parameters.persistence_threshold: threshold: -2 is not a finite, non-negative "
     "persistence"),
]


@pytest.mark.parametrize("algorithm", [SIMPLIFICATION, "morse-smale"])
def test_bad_thresholds_are_named(client, meshes, algorithm):
    with client.open_session(meshes("manifoldCheck0_tet.vtu")) as session:
        for parameters, message in BAD_THRESHOLDS:
            with pytest.raises(actopo.InvalidArgumentError) as error:
                session.run(algorithm, parameters=parameters)
            assert error.value.details == message, parameters
        with pytest.raises(actopo.InvalidArgumentError, match="unknown parameter 'threshold'"):
            session.run(algorithm, parameters={"threshold": "0.1"})
        # The session goes on; 1 is the whole range, 0 nothing.
        for parameters in ({"relative_threshold": "1"}, {"persistence_threshold": "0"}):
            assert session.run(algorithm, parameters=parameters).simplified is not None


def test_both_clients_decode_the_same_field(server, client, meshes):
    mesh = meshes(ISABEL)

    async def run() -> SimplifiedField | None:
        async with actopo.AsyncClient(server) as aclient:
            async with aclient.open_session(mesh, scalar="velocityMag",
                                            structure="actopo") as session:
                return (await session.run(SIMPLIFICATION, **_relative("0.05"))).simplified

    asynchronous = asyncio.run(run())
    synchronous = _run(client, mesh, "velocityMag", "explicit", **_relative("0.05")).simplified
    assert asynchronous is not None and synchronous is not None
    assert asynchronous.name == synchronous.name == "velocityMag"
    np.testing.assert_array_equal(asynchronous.values, synchronous.values)
    np.testing.assert_array_equal(asynchronous.order, synchronous.order)


def _bench_files(data_dir: Path, tmp_path: Path, file: str, field: str, algorithm: str,
                 threshold: str) -> str:
    """actopo-bench --output into tmp_path/bench_*; the prefix."""
    if not BENCH_BIN.is_file():
        pytest.skip(f"actopo-bench not built ({BENCH_BIN}); set ACTOPO_BENCH_BIN")
    prefix = str(tmp_path / "bench")
    subprocess.run([str(BENCH_BIN), "--mesh", str(data_dir / file), "--scalar", field,
                    "--algorithm", algorithm, "--relative-threshold", threshold, "--output",
                    prefix], capture_output=True, timeout=120, check=True)
    return prefix


def test_files_and_pyvista_equal_actopo_benchs(client, meshes, data_dir, tmp_path):
    """PREFIX_simplified.vtu: the mesh with the field (float32 in the file) replaced by the
    simplified one (float64) and <field>_Order added, as actopo-bench writes it; only with
    the mesh, whose geometry stays on the server."""
    result = _run(client, meshes(FINGERS), "density", "compact", **_relative("0.05"))
    assert result.write(str(tmp_path / "nomesh")) == [] and result.to_pyvista() == {}
    files = result.write(str(tmp_path / "client"), data_dir / FINGERS)
    assert [Path(f).name for f in files] == ["client_simplified.vtu"]
    bench = _bench_files(data_dir, tmp_path, FINGERS, "density", SIMPLIFICATION, "0.05")
    ours, theirs = pv.read(files[0]), pv.read(f"{bench}_simplified.vtu")
    assert ours.n_cells == theirs.n_cells and ours.n_points == theirs.n_points
    np.testing.assert_array_equal(ours.points, theirs.points)
    np.testing.assert_array_equal(ours.cell_connectivity, theirs.cell_connectivity)
    assert sorted(ours.point_data.keys()) == sorted(theirs.point_data.keys()) == \
        ["density", "density_Order"]
    for name in ("density", "density_Order"):
        assert ours.point_data[name].dtype == theirs.point_data[name].dtype, name
        np.testing.assert_array_equal(ours.point_data[name], theirs.point_data[name],
                                      err_msg=name)
    grid = result.to_pyvista(pv.read(data_dir / FINGERS))["simplified"]
    np.testing.assert_array_equal(grid.point_data["density"], result.simplified.values)
    np.testing.assert_array_equal(grid.point_data["density_Order"], result.simplified.order)


def test_morse_smale_files_equal_actopo_benchs(client, meshes, data_dir, tmp_path):
    """A simplified complex writes what actopo-bench writes, in its order: the segmentation on
    the mesh as read, the simplified field beside it."""
    result = _run(client, meshes("fertility_tet.vtu"), "height", "explicit", "morse-smale",
                  **_relative("0.05"))
    files = result.write(str(tmp_path / "client"), data_dir / "fertility_tet.vtu")
    bench = _bench_files(data_dir, tmp_path, "fertility_tet.vtu", "height", "morse-smale",
                         "0.05")
    assert [Path(f).name.split("_", 1)[1] for f in files] == [
        "critical_points.vtp", "separatrices.vtp", "simplified.vtu", "segmentation.vtu"]
    for path in files:
        ours, theirs = pv.read(path), pv.read(path.replace(str(tmp_path / "client"), bench))
        np.testing.assert_array_equal(ours.points, theirs.points, err_msg=path)
        for data, other in ((ours.point_data, theirs.point_data),
                            (ours.cell_data, theirs.cell_data)):
            assert sorted(data.keys()) == sorted(other.keys()), path
            for name in data.keys():  # noqa: SIM118 (pyvista)
                np.testing.assert_array_equal(data[name], other[name], err_msg=f"{path} {name}")
    segmentation = pv.read(files[3])
    original = pv.read(data_dir / "fertility_tet.vtu")
    np.testing.assert_array_equal(segmentation.point_data["height"],
                                  original.point_data["height"])


def test_files_with_meshio_only(client, meshes, data_dir, tmp_path, monkeypatch):
    result = _run(client, meshes("manifoldCheck0_tet.vtu"), "height", **_relative("0.05"))
    monkeypatch.setitem(sys.modules, "pyvista", None)  # as if pyvista were not installed
    files = result.write(str(tmp_path / "mc0"), data_dir / "manifoldCheck0_tet.vtu")
    assert [Path(f).name for f in files] == ["mc0_simplified.vtu"]
    written = meshio.read(files[0])
    assert written.cells[0].type == "tetra"
    np.testing.assert_array_equal(written.point_data["height"], result.simplified.values)
    np.testing.assert_array_equal(written.point_data["height_Order"], result.simplified.order)


# The command line.


def test_cli_runs_a_simplification(cli, data_dir, reference, tmp_path, monkeypatch):
    prefix = str(tmp_path / "fertility")
    status, out, err = cli("run", SIMPLIFICATION, "--mesh", "fertility_tet.vtu", "--scalar",
                           "height", "--param", "relative_threshold=0.05", "--output", prefix,
                           "--geometry", str(data_dir / "fertility_tet.vtu"), "--json",
                           "--digests")
    assert status == 0, err
    report = json.loads(out)
    assert report["config"]["parameters"] == {"relative_threshold": "0.05"}
    check_summary(SIMPLIFICATION, report["result"],
                  reference("fertility_tet.vtu", "height", "0.05"), digests=True)
    assert report["files"] == [f"{prefix}_simplified.vtu"]
    # Without a local copy of the mesh: the simplified field on the server's geometry, the
    # same values as on the file's (which brings its other field along).
    monkeypatch.delenv("ACTOPO_DATA_DIR", raising=False)  # else the CLI finds the file there
    monkeypatch.chdir(tmp_path)
    status, out, err = cli("run", SIMPLIFICATION, "--mesh", "fertility_tet.vtu", "--scalar",
                           "height", "--param", "relative_threshold=0.05", "--output",
                           "out/server")
    assert status == 0 and err == "" and "wrote out/server_simplified.vtu" in out
    ours, theirs = pv.read("out/server_simplified.vtu"), pv.read(f"{prefix}_simplified.vtu")
    np.testing.assert_array_equal(ours.points, theirs.points)
    np.testing.assert_array_equal(ours.cell_connectivity, theirs.cell_connectivity)
    assert sorted(ours.point_data.keys()) == ["height", "height_Order"]
    assert sorted(theirs.point_data.keys()) == ["eigenfunction4", "height", "height_Order"]
    for name in ("height", "height_Order"):
        assert ours.point_data[name].dtype == theirs.point_data[name].dtype
        np.testing.assert_array_equal(ours.point_data[name], theirs.point_data[name])
    status, out, err = cli("run", "morse-smale", "--mesh", "manifoldCheck0_tet.vtu", "--param",
                           "persistence_threshold=0.1", "--output", str(tmp_path / "server"))
    assert status == 0 and err == "", err
    assert [line.rsplit("_", 1)[1] for line in out.splitlines() if "wrote" in line] == [
        "points.vtp", "separatrices.vtp", "simplified.vtu", "segmentation.vtu"]
    status, _, err = cli("run", SIMPLIFICATION, "--mesh", "manifoldCheck0_tet.vtu", "--param",
                         "relative_threshold=2")
    assert status == 1 and "parameters.relative_threshold: threshold: 2 is not a fraction" in err
