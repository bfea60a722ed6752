"""persistence-diagram through the client: the pairs rebuilt from the streamed arrays equal
upstream TTK's (expected-ttk.json) on every structure; TTK's diagonal, the domain embedding, the
curves, above(), files equal actopo-bench's, the bad parameter, both clients, and the CLI's
--plot. The first tests need no server."""

from __future__ import annotations

import asyncio
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import matplotlib.image
import meshio
import numpy as np
import pytest
import pyvista as pv
from harness import BENCH_BIN
from references import CASE_IDS, CASES, check_summary, ttk

import actopo
from actopo._diagram import from_arrays, persistence_curve
from actopo.types import PersistenceDiagram

DIAGRAM = "persistence-diagram"
STRUCTURES = ["explicit", "compact", "actopo"]
FINGERS = "viscousFingers001_s2_tet.vtu"
VTK_LINE = 3


def _wire(pairs: list[tuple[int, int, int, bool, float, float]]) -> dict[str, np.ndarray]:
    """The diagram/ group the server would stream for these (type, birth vertex, death vertex,
    finite, birth, death) pairs, TTK's diagonal included."""
    n = len(pairs)
    kinds = np.array([p[0] for p in pairs], dtype=np.int32)
    finite = np.array([p[3] for p in pairs])
    birth = np.array([p[4] for p in pairs])
    death = np.array([p[5] for p in pairs])
    points = np.zeros((2 * n, 3))
    points[0::2, :2] = birth[:, None]
    points[1::2, 0], points[1::2, 1] = birth, death
    return {
        "Points": points,
        "Offsets": np.arange(0, 2 * n + 3, 2, dtype=np.int64),
        "ttkVertexScalarField": np.array([v for p in pairs for v in p[1:3]], dtype=np.int32),
        "CriticalType": np.array([t for k, f in zip(kinds, finite, strict=True)
                                  for t in (k, k + 1 if f else 3)], dtype=np.int32),
        "Coordinates": np.zeros((2 * n, 3), dtype=np.float32),
        "PairIdentifier": np.append(np.arange(n), -1).astype(np.int32),
        "PairType": np.append(kinds, -1).astype(np.int32),
        "Persistence": np.append(death - birth, 2 * (death[0] - birth[0])),
        "Birth": np.append(birth, 0.0),
        "IsFinite": np.append(finite, False).astype(np.int8),
    }


PAIRS = [(0, 10, 40, False, 0.0, 9.0), (0, 9, 12, True, 1.0, 2.5), (1, 12, 30, True, 2.5, 6.0),
         (2, 30, 40, True, 6.0, 9.0)]


def test_digest_sorts_pairs_as_integer_tuples():
    """Vertex 9 before vertex 10 (not as text), type first; the digest is over those lines."""
    diagram = from_arrays(_wire(PAIRS))
    assert diagram.sorted_pairs().tolist() == [[0, 9, 12, 1], [0, 10, 40, 0], [1, 12, 30, 1],
                                               [2, 30, 40, 1]]
    text = "0 9 12 1\n0 10 40 0\n1 12 30 1\n2 30 40 1\n"
    assert diagram.pairs_sha256() == hashlib.sha256(text.encode()).hexdigest()
    assert diagram.counts_by_type() == {"0": 1, "0_infinite": 1, "1": 1, "2": 1}
    assert len(diagram) == 4 and diagram.embedding == "diagram"
    np.testing.assert_array_equal(diagram.death, [9.0, 2.5, 6.0, 9.0])
    assert diagram.is_finite.dtype == bool and diagram.birth_vertex.tolist() == [10, 9, 12, 30]


def test_above_keeps_the_persistent_pairs_and_their_curves():
    diagram = from_arrays(_wire(PAIRS))  # persistences 9, 1.5, 3.5, 3
    strong = diagram.above(3.0)
    assert strong.pair_identifier.tolist() == [0, 2, 3]
    assert strong.persistence.tolist() == [9.0, 3.5, 3.0]
    assert strong.birth_point.shape == (3, 3) and strong.embedding == "diagram"
    assert strong.curves[-1].persistence.tolist() == [3.0, 3.5, 9.0]
    assert strong.curves[-1].number_of_pairs.tolist() == [3, 2, 1]
    assert strong.curves[0].number_of_pairs.tolist() == [1]
    assert len(diagram.above(100.0)) == 0 and len(diagram.above(0.0)) == 4
    assert persistence_curve(np.array([2.0, 1.0, 2.0])).number_of_pairs.tolist() == [3, 2]


def test_a_layout_the_client_cannot_read_is_named():
    wire = _wire(PAIRS)
    wire["Offsets"] = np.array([0, 3, 4, 6, 8, 10])
    with pytest.raises(actopo.ActopoError, match="diagram/Offsets: the pairs' lines are not "
                       "two consecutive points"):
        from_arrays(wire)
    wire = _wire(PAIRS)
    del wire["CriticalType"]
    with pytest.raises(actopo.ActopoError, match="diagram/CriticalType: missing"):
        from_arrays(wire)
    wire = _wire(PAIRS)
    wire["Birth"] = wire["Birth"][:-1]
    with pytest.raises(actopo.ActopoError, match="diagram/Birth: 4 values, expected 5"):
        from_arrays(wire)


def test_every_expected_diagram_is_tested(data_dir):
    """Every case of expected-ttk.json (references.CASES) has a diagram, and no other does."""
    expected = json.loads((data_dir / "expected-ttk.json").read_text())
    listed = [(f, field) for f, fields in expected.items() for field, entry in fields.items()
              if "persistence_diagram" in entry["upstream"]]
    assert sorted(listed) == sorted(CASES)


@pytest.fixture(scope="module")
def expected(data_dir):
    return json.loads((data_dir / "expected-ttk.json").read_text())


def _run(client, mesh, field, structure="compact", **options) -> actopo.JobResult:
    with client.open_session(mesh, scalar=field, structure=structure) as session:
        return session.run(DIAGRAM, digests=True, **options)


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("file,field", CASES, ids=CASE_IDS)
def test_pairs_from_the_arrays_equal_ttks(client, meshes, expected, file, field, structure):
    """The digest computed here from the streamed arrays, the counts per type and the largest
    persistence equal upstream TTK's; so does the summary, which the server computed."""
    ttk = expected[file][field]["upstream"]["persistence_diagram"]
    result = _run(client, meshes(file), field, structure)
    diagram = result.diagram
    assert diagram is not None
    assert diagram.pairs_sha256() == ttk["pairs_sha256"]
    assert diagram.counts_by_type() == ttk["counts_by_type"]
    assert len(diagram) == ttk["pairs"]
    # Both are the difference of the same two field values in double precision.
    assert diagram.persistence.max() == ttk["max_persistence"]
    if "lines" in ttk:
        assert diagram.sorted_pairs().tolist() == ttk["lines"]
    summary = result.summary
    assert (summary["pairs_sha256"], summary["counts_by_type"], summary["pairs"],
            summary["max_persistence"]) == (ttk["pairs_sha256"], ttk["counts_by_type"],
                                            ttk["pairs"], ttk["max_persistence"])
    # Every critical cell of the gradient is in exactly one pair (SEMANTICS.md).
    finite = [int(((diagram.pair_type == k) & diagram.is_finite).sum()) for k in range(3)]
    infinite = [int(((diagram.pair_type == k) & ~diagram.is_finite).sum()) for k in range(3)]
    assert summary["critical_cells"] == [finite[0] + infinite[0],
                                         finite[0] + finite[1] + infinite[1],
                                         finite[1] + finite[2] + infinite[2], finite[2]]


@pytest.fixture(scope="module")
def fingers(client, meshes):
    """The density diagram of viscousFingers in both embeddings (253 pairs, all three types)."""
    mesh = meshes(FINGERS)
    return (_run(client, mesh, "density"),
            _run(client, mesh, "density", parameters={"embedding": "domain"}))


def test_ttks_diagonal_is_set_apart(fingers, data_dir):
    result, _ = fingers
    wire = result.group("diagram")
    diagram = result.diagram
    n = len(diagram)
    assert n == result.summary["pairs"] == 253
    # On the wire: a line per pair, then the diagonal (the last Offsets entry counts its two
    # point ids, which only TTK's rule gives: the first point and the last pair's birth point).
    assert wire["Points"].shape == (2 * n, 3) and len(wire["Offsets"]) == n + 2
    for name, value in (("PairIdentifier", -1), ("PairType", -1), ("IsFinite", 0),
                        ("Birth", 0.0), ("Persistence", 2 * wire["Persistence"][0])):
        assert len(wire[name]) == n + 1 and wire[name][-1] == value, name
    # In the diagram: the pairs only, in the order of their birth.
    assert diagram.pair_identifier.tolist() == list(range(n))
    assert (diagram.pair_type >= 0).all() and (np.diff(diagram.birth) >= 0).all()
    np.testing.assert_array_equal(diagram.birth_point,
                                  np.stack([diagram.birth, diagram.birth, 0 * diagram.birth], 1))
    np.testing.assert_array_equal(diagram.death_point[:, :2],
                                  np.stack([diagram.birth, diagram.death], 1))
    np.testing.assert_allclose(diagram.death - diagram.birth, diagram.persistence, rtol=1e-12)
    assert (diagram.birth_type == diagram.pair_type).all()
    assert (diagram.death_type == np.where(diagram.is_finite, diagram.pair_type + 1, 3)).all()
    mesh = meshio.read(data_dir / FINGERS)
    np.testing.assert_array_equal(diagram.birth_coordinates,
                                  mesh.points[diagram.birth_vertex].astype(np.float32))
    # Rebuilt: TTK's grid, equal to the streamed arrays, the diagonal from 0 to 2(n - 1).
    grid = diagram.ttk_grid()
    assert grid.lines.tolist()[-1] == [0, 2 * (n - 1)] and len(grid.lines) == n + 1
    np.testing.assert_array_equal(grid.points, wire["Points"])
    for name, values in {**grid.point_data, **grid.cell_data}.items():
        assert values.dtype == wire[name].dtype, name
        np.testing.assert_array_equal(values, wire[name], err_msg=name)


def test_domain_embedding_puts_the_points_at_the_vertices(fingers, data_dir):
    plane, domain = fingers
    wire = domain.group("diagram")
    diagram = domain.diagram
    n = len(diagram)
    assert diagram.embedding == "domain" and plane.diagram.embedding == "diagram"
    assert len(wire["Offsets"]) == n + 1 and -1 not in wire["PairIdentifier"]  # no diagonal
    assert diagram.pairs_sha256() == plane.diagram.pairs_sha256() == domain.summary["pairs_sha256"]
    mesh = meshio.read(data_dir / FINGERS)
    np.testing.assert_array_equal(diagram.birth_point, mesh.points[diagram.birth_vertex])
    np.testing.assert_array_equal(diagram.death_point, mesh.points[diagram.death_vertex])
    np.testing.assert_allclose(diagram.death, plane.diagram.death, rtol=1e-12)
    grid = diagram.ttk_grid()
    assert len(grid.lines) == n
    np.testing.assert_array_equal(grid.points, wire["Points"])
    for name, values in {**grid.point_data, **grid.cell_data}.items():
        np.testing.assert_array_equal(values, wire[name], err_msg=name)


def test_curves_count_the_pairs_above_each_persistence(fingers):
    diagram = fingers[0].diagram
    for kind in (0, 1, 2, -1):
        of_kind = diagram.persistence if kind == -1 else \
            diagram.persistence[diagram.pair_type == kind]
        curve = diagram.curves[kind]
        computed = persistence_curve(of_kind)
        np.testing.assert_array_equal(curve.persistence, computed.persistence)
        np.testing.assert_array_equal(curve.number_of_pairs, computed.number_of_pairs)
    every = diagram.curves[-1]
    assert every.number_of_pairs[0] == len(diagram)
    for persistence, alive in zip(every.persistence[::20], every.number_of_pairs[::20],
                                  strict=True):
        assert len(diagram.above(persistence)) == alive


def test_diagram_is_none_without_a_diagram(client, meshes):
    mesh = meshes("manifoldCheck0_tet.vtu")
    with client.open_session(mesh) as session:
        assert session.run("critical-points").diagram is None
        summary_only = session.run(DIAGRAM, include_arrays=False)
        assert summary_only.diagram is None and summary_only.summary["pairs"] == 2


def test_a_bad_embedding_is_named(client, meshes):
    with client.open_session(meshes("manifoldCheck0_tet.vtu")) as session:
        with pytest.raises(actopo.InvalidArgumentError) as error:
            session.run(DIAGRAM, parameters={"embedding": "x"})
        assert error.value.details == \
            "parameters.embedding: unknown value 'x'; available: diagram, domain"
        with pytest.raises(actopo.InvalidArgumentError, match="unknown parameter 'nope'"):
            session.run(DIAGRAM, parameters={"nope": "1"})
        assert session.run(DIAGRAM).diagram is not None  # the session goes on


def test_files_and_pyvista_equal_actopo_benchs(client, meshes, data_dir, tmp_path):
    if not BENCH_BIN.is_file():
        pytest.skip(f"actopo-bench not built ({BENCH_BIN}); set ACTOPO_BENCH_BIN")
    result = _run(client, meshes("fertility_tet.vtu"), "height", "explicit")
    files = result.write(str(tmp_path / "client"))
    assert [Path(f).name for f in files] == ["client_diagram.vtu",
                                             "client_persistence_curve.csv"]
    subprocess.run([str(BENCH_BIN), "--mesh", str(data_dir / "fertility_tet.vtu"), "--scalar",
                    "height", "--algorithm", DIAGRAM, "--output", str(tmp_path / "bench")],
                   capture_output=True, timeout=120, check=True)
    assert Path(files[1]).read_text() == (tmp_path / "bench_persistence_curve.csv").read_text()
    ours, theirs = pv.read(files[0]), pv.read(tmp_path / "bench_diagram.vtu")
    assert ours.n_cells == theirs.n_cells == len(result.diagram) + 1
    assert set(ours.celltypes) == set(theirs.celltypes) == {VTK_LINE}
    np.testing.assert_array_equal(ours.cell_connectivity, theirs.cell_connectivity)
    np.testing.assert_array_equal(ours.points, theirs.points)
    for data, other in ((ours.point_data, theirs.point_data), (ours.cell_data, theirs.cell_data)):
        assert sorted(data.keys()) == sorted(other.keys())
        for name in data.keys():  # noqa: SIM118 (pyvista)
            np.testing.assert_array_equal(data[name], other[name], err_msg=name)
    datasets = result.to_pyvista()
    assert list(datasets) == ["diagram"]
    assert datasets["diagram"].n_cells == ours.n_cells


def test_files_with_meshio_only(client, meshes, tmp_path, monkeypatch):
    result = _run(client, meshes("manifoldCheck0_tet.vtu"), "height")
    monkeypatch.setitem(sys.modules, "pyvista", None)  # as if pyvista were not installed
    written = meshio.read(result.write(str(tmp_path / "mc0"))[0])
    assert written.cells[0].type == "line" and written.cells[0].data.tolist() == [[0, 1], [2, 3],
                                                                                 [0, 2]]
    np.testing.assert_array_equal(written.cell_data["PairIdentifier"][0], [0, 1, -1])


def test_both_clients_decode_the_same_diagram(server, client, meshes):
    mesh = meshes(FINGERS)

    async def run() -> PersistenceDiagram | None:
        async with actopo.AsyncClient(server) as aclient:
            async with aclient.open_session(mesh, scalar="density",
                                            structure="actopo") as session:
                return (await session.run(DIAGRAM)).diagram

    asynchronous = asyncio.run(run())
    synchronous = _run(client, mesh, "density", "explicit").diagram
    assert asynchronous is not None and synchronous is not None
    assert asynchronous.pairs_sha256() == synchronous.pairs_sha256()
    np.testing.assert_array_equal(asynchronous.death, synchronous.death)


def test_plot_draws_each_type_and_the_lines(fingers, tmp_path):
    diagram = fingers[0].diagram
    ax = diagram.plot(threshold=0.5, title="fingers")
    labels = ax.get_legend_handles_labels()[1]
    assert labels[:2] == ["diagonal", "death = birth + 0.5"]
    assert [label.split(":")[0] for label in labels[2:]] == [
        "type 0", "type 0, infinite (1)", "type 1", "type 2"]
    assert ax.get_title() == "fingers" and ax.get_xlabel() == "birth"
    path = diagram.save_plot(tmp_path / "fingers.svg")
    assert Path(path).read_text().startswith("<?xml")


# The command line.


def test_cli_plot_writes_a_png(cli, tmp_path):
    path = tmp_path / "fertility.png"
    status, out, err = cli("run", DIAGRAM, "--mesh", "fertility_tet.vtu", "--scalar", "height",
                           "--plot", str(path), "--threshold", "1%", "--json", "--digests")
    assert status == 0, err
    report = json.loads(out)
    assert report["plot"] == str(path) and report["algorithm"] == DIAGRAM
    check_summary(DIAGRAM, report["result"],
                  ttk("fertility_tet.vtu", "height")["persistence_diagram"], digests=True)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[:2] == (1050, 1050) and pixels[..., :3].std() > 0  # 7 in at 150 dpi
    status, out, err = cli("run", "--mesh", "manifoldCheck0_tet.vtu", "--algorithm", DIAGRAM,
                           "--plot", str(tmp_path / "mc0.png"), "--threshold", "0.5", "--digests")
    assert status == 0, err
    assert f"wrote {tmp_path / 'mc0.png'}" in out and '"0_infinite": 1' in out
    assert '"pairs_sha256": "96e8cf70' in out and (tmp_path / "mc0.png").stat().st_size > 0


def test_cli_parameters_and_usage(cli, capsys, tmp_path):
    mesh = ("--mesh", "manifoldCheck0_tet.vtu")
    status, out, err = cli("run", DIAGRAM, *mesh, "--param", "embedding=domain", "--json")
    assert status == 0, err
    report = json.loads(out)
    assert report["config"]["parameters"] == {"embedding": "domain"}
    assert "pairs_sha256" not in report["result"]  # digests only with --digests
    status, out, err = cli("run", DIAGRAM, *mesh, "--param", "embedding=domain", "--json",
                           "--digests")
    assert status == 0, err
    assert json.loads(out)["result"]["pairs_sha256"].startswith("96e8cf70")
    status, _, err = cli("run", DIAGRAM, *mesh, "--param", "embedding=x")
    assert status == 1
    assert "parameters.embedding: unknown value 'x'; available: diagram, domain" in err
    plot = ("--plot", str(tmp_path / "x.png"))
    status, _, err = cli("run", "critical-points", *mesh, *plot)
    assert status == 2 and "--plot draws a persistence diagram" in err
    status, _, err = cli("run", DIAGRAM, *mesh, "--threshold", "1%")
    assert status == 2 and "give --plot" in err
    assert not (tmp_path / "x.png").exists()
    for args in (("run", *mesh), ("run", DIAGRAM, "--algorithm", DIAGRAM, *mesh),
                 ("run", "diagram", *mesh), ("run", DIAGRAM, *mesh, *plot, "--threshold", "x")):
        with pytest.raises(SystemExit) as usage:
            cli(*args)
        assert usage.value.code == 2, args
    assert "not a number or a percentage: 'x'" in capsys.readouterr().err
