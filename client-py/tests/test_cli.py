"""The `actopo` command line: every command, --json outputs parsed, results equal upstream TTK's
(and, for `run --json`, actopo-bench's, as the README promises); fields added and deleted, and
`run` over several fields and diagram-distance's matrices."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path

import grpc
import matplotlib.image
import meshio
import numpy as np
import pytest
import pyvista  # noqa: F401 (the CLI writes its .vtp files with it: a dependency of these tests)
from harness import start_cli, wait_until
from meshes import lattice
from references import ENTRY, check_summary, ttk, ttk_simplification

import actopo
from actopo._cli import COMMANDS, main
from actopo._cli_parser import parser


def _json(cli, *args):
    status, out, err = cli(*args, "--json")
    assert status == 0, err
    return json.loads(out)


@pytest.mark.parametrize("algorithm", ["critical-points", "discrete-gradient", "morse-smale",
                                       "persistence-diagram", "topological-simplification"])
def test_acceptance_run_json(server, data_dir, bench, algorithm):
    """The issue's acceptance command, run as a user would: its result is upstream TTK's, and,
    as the README promises of `run --json`, actopo-bench's; digests included when asked."""
    out = subprocess.run(
        [sys.executable, "-m", "actopo", "--server", server, "run", "--mesh",
         "fertility_tet.vtu", "--algorithm", algorithm, "--structure", "actopo", "--json",
         "--digests"],
        capture_output=True, text=True, timeout=120, check=True)
    report = json.loads(out.stdout)
    if algorithm == "topological-simplification":  # by default, 1% of the field's range
        expected = ttk_simplification("fertility_tet.vtu", "eigenfunction4", "0.01")
    else:
        expected = ttk("fertility_tet.vtu", "eigenfunction4")[ENTRY[algorithm]]
    check_summary(algorithm, report["result"], expected, digests=True)
    assert report["result"] == bench(data_dir / "fertility_tet.vtu", algorithm, "--scalar",
                                     "eigenfunction4", "--digests")
    assert report["algorithm"] == algorithm and report["structure"] == "actopo"
    assert report["mesh"]["tetrahedra"] == 60948
    # Built by the job when it read them, as in actopo-bench's report.
    assert (report["mesh"]["edges"] is None) == (algorithm == "critical-points")
    assert set(report) >= {"mesh", "structure", "algorithm", "config", "times_s", "engine",
                           "memory", "result"}


def test_every_command_of_the_parser_runs_something():
    [commands] = [a for a in parser()._actions if isinstance(a, argparse._SubParsersAction)]
    assert list(commands.choices) == list(COMMANDS)


def test_console_script_is_installed(server):
    script = Path(sys.executable).with_name("actopo")
    if not script.exists():
        pytest.skip("the actopo script is not beside this Python")
    out = subprocess.run([str(script), "info"], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "ACTOPO_SERVER": server}, check=True)
    assert "critical-points" in out.stdout


def test_info_meshes_sessions(cli):
    info = _json(cli, "info")
    assert "morse-smale" in info["algorithms"] and info["limits"]["max_batch_size"] > 0
    status, out, _ = cli("info")
    assert status == 0 and "relations:" in out
    mesh = _json(cli, "load", "manifoldCheck0_tet.vtu", "--block-size", "10")
    assert mesh["tetrahedra"] == 24 and mesh["block_size"] == 10
    assert mesh["mesh_id"] in [m["mesh_id"] for m in _json(cli, "meshes")]
    status, out, _ = cli("meshes")
    assert mesh["mesh_id"] in out
    session = _json(cli, "open", mesh["mesh_id"], "--structure", "compact")
    assert session["structure"] == "compact" and session["scalar_field"] == "height"
    assert session["session_id"] in [s["session_id"] for s in _json(cli, "sessions")]
    status, out, _ = cli("sessions")
    assert session["session_id"] in out

    relation = _json(cli, "relation", "vertex_star", "0", "3", "--session", session["session_id"])
    assert [r["simplex"] for r in relation] == [0, 3] and relation[0]["ids"]
    edges = _json(cli, "relation", "edge_triangles", "0,1", "--vertices", "--session",
                  session["session_id"])
    assert all(0 in v and 1 in v for v in edges[0]["vertices"])
    status, out, _ = cli("relation", "vertex_edges", "0", "--session", session["session_id"])
    assert out.startswith("vertex_edges(0): ")
    stats = _json(cli, "stats", "--session", session["session_id"])
    assert stats[session["session_id"]]["relation_queries"]["count"] == 4
    assert session["session_id"] in _json(cli, "stats")
    status, out, _ = cli("stats")
    assert status == 0 and session["session_id"] in out

    assert cli("close", session["session_id"])[0] == 0
    assert cli("delete", mesh["mesh_id"])[0] == 0
    assert mesh["mesh_id"] not in [m["mesh_id"] for m in _json(cli, "meshes")]


def test_load_progress_goes_to_stderr(cli):
    """--progress: a bar per phase on stderr, the mesh alone on stdout; by default only on a
    terminal (stderr is not one here)."""
    status, out, err = cli("load", "sample:jittered:20", "--progress")
    assert status == 0, err
    for step in ("read 1/3", "partition 2/3", "encode 3/3"):
        assert f"load sample:jittered:20 ({step})" in err
    header, row = out.splitlines()
    assert header.split()[:2] == ["MESH", "NAME"] and row.split()[1] == "jittered:20"
    status, out, err = cli("load", "sample:jittered:20", "--progress", "--json")
    assert status == 0 and "encode 3/3" in err
    mesh = json.loads(out)
    assert mesh["name"] == "jittered:20" and mesh["tetrahedra"] == 41154
    for flags in ((), ("--no-progress",)):
        status, out, err = cli("load", "sample:jittered:4", "--json", *flags)
        assert status == 0 and err == "" and json.loads(out)["tetrahedra"] == 162
    assert cli("delete", row.split()[0], mesh["mesh_id"])[0] == 0


def test_a_series_loads_from_several_paths(cli):
    """`load A B ... --times T1,T2,...` and the loading commands' `--mesh A --mesh B ...`: the
    files of a series as one mesh, a field <field>_<k> per file; --times only with several
    paths, one per path."""
    steps = [f"isabel_series_s2/isabel_0{t}_s2_tet.vtu" for t in (2, 3, 4)]
    mesh = _json(cli, "load", *steps, "--times", "2,3,4.5")
    assert [(f["name"], f["time"]) for f in mesh["fields"]] == [
        ("velocityMag_0", 2.0), ("velocityMag_1", 3.0), ("velocityMag_2", 4.5)]
    assert mesh["name"] == "isabel_02_s2_tet.vtu +2 files"
    assert cli("delete", mesh["mesh_id"])[0] == 0
    report = _json(cli, "run", "critical-points", "--mesh", steps[0], "--mesh", steps[1],
                   "--scalars", "all", "--structure", "compact")
    assert report["mesh"]["name"] == "isabel_02_s2_tet.vtu +1 file"
    assert report["config"]["scalars"] == ["velocityMag_0", "velocityMag_1"]
    one = _json(cli, "run", "critical-points", "--mesh", steps[1], "--structure", "compact")
    assert one["mesh"]["name"] == "isabel_03_s2_tet.vtu"  # one --mesh: the file, as before
    assert report["fields"][1]["result"] == one["result"]
    for paths, times in ((steps[:1], "2"), (steps, "2,3")):
        status, _, err = cli("load", *paths, "--times", times)
        assert status == 2 and "actopo: error: --times:" in err
    status, _, err = cli("load", steps[0], "isabel_series_s2/nope.vtu")
    assert status == 1 and "files.paths[1]" in err and "NOT_FOUND" in err


def test_commands_show_the_load_of_their_mesh(cli):
    report = _json(cli, "run", "--sample", "jittered:6", "--algorithm", "critical-points")
    status, out, err = cli("run", "--sample", "jittered:6", "--algorithm", "critical-points",
                           "--progress", "--json")
    assert status == 0 and json.loads(out)["result"] == report["result"]
    assert "load sample:jittered:6 (encode 3/3)" in err
    status, out, err = cli("relation", "vertex_star", "0", "--sample", "jittered:4",
                           "--progress")
    assert status == 0 and out.startswith("vertex_star(0): ")
    assert "load sample:jittered:4 (read 1/3)" in err


def test_relation_on_a_temporary_mesh(cli):
    before = _json(cli, "meshes")
    answer = _json(cli, "relation", "tetrahedron_vertices", "0", "--mesh", "sample:jittered:3")
    assert sorted(answer[0]["ids"]) == answer[0]["ids"] and len(answer[0]["ids"]) == 4
    assert _json(cli, "meshes") == before  # loaded for the command, deleted after


def test_upload_and_run_uploaded_file(cli, data_dir):
    path = str(data_dir / "manifoldCheck1_tet.vtu")
    expected = ttk("manifoldCheck1_tet.vtu", "height")
    mesh = _json(cli, "upload", path, "--name", "mc1")  # a .vtu keeps its extension
    assert mesh["name"] == "mc1.vtu" and mesh["source"] == "upload:mc1.vtu"
    report = _json(cli, "run", "--mesh-id", mesh["mesh_id"], "--algorithm", "morse-smale",
                   "--structure", "explicit")
    check_summary("morse-smale", report["result"], expected["morse_smale"], digests=False)
    report = _json(cli, "run", "--upload", path, "--algorithm", "discrete-gradient", "--digests")
    check_summary("discrete-gradient", report["result"], expected["discrete_gradient"],
                  digests=True)
    assert cli("delete", mesh["mesh_id"])[0] == 0


def test_run_writes_a_trace(cli, tmp_path):
    path = tmp_path / "job.json"
    report = _json(cli, "run", "--sample", "jittered:10", "--algorithm", "critical-points",
                   "--structure", "actopo", "--trace", str(path))
    assert report["trace"] == str(path)
    events = json.loads(path.read_text())["traceEvents"]
    assert [e["name"] for e in events if e.get("cat") == "phase"] == [
        "start engine", "critical-points", "results"]
    status, out, _ = cli("run", "--sample", "jittered:10", "--algorithm", "critical-points",
                         "--trace", str(tmp_path / "again.json"))
    assert status == 0 and f"wrote {tmp_path / 'again.json'} (open it in" in out


def test_run_writes_files_for_paraview(cli, data_dir, tmp_path, monkeypatch):
    prefix = str(tmp_path / "mc0")
    report = _json(cli, "run", "--mesh", "manifoldCheck0_tet.vtu", "--algorithm", "morse-smale",
                   "--output", prefix, "--geometry", str(data_dir / "manifoldCheck0_tet.vtu"))
    assert [Path(f).name for f in report["files"]] == [
        "mc0_critical_points.vtp", "mc0_separatrices.vtp", "mc0_segmentation.vtu"]
    for f in report["files"]:
        assert b"VTKFile" in Path(f).read_bytes()[:200]
    status, out, _ = cli("run", "--mesh", "manifoldCheck0_tet.vtu", "--algorithm",
                         "critical-points", "--output", str(tmp_path / "cp"))
    assert status == 0 and "wrote" in out and (tmp_path / "cp_critical_points.vtp").exists()
    # Without a local copy of the mesh: its geometry comes from the server.
    monkeypatch.delenv("ACTOPO_DATA_DIR", raising=False)  # else the CLI finds the file there
    monkeypatch.chdir(tmp_path)
    downloaded = _json(cli, "run", "--mesh", "manifoldCheck0_tet.vtu", "--algorithm",
                       "morse-smale", "--output", str(tmp_path / "server"))
    assert [Path(f).name for f in downloaded["files"]] == [
        "server_critical_points.vtp", "server_separatrices.vtp", "server_segmentation.vtu"]
    local = meshio.read(data_dir / "manifoldCheck0_tet.vtu")
    ours, theirs = (meshio.read(tmp_path / f"{p}_segmentation.vtu") for p in ("server", "mc0"))
    for written in (ours, theirs):
        np.testing.assert_array_equal(written.points, local.points)
        np.testing.assert_array_equal(written.cells_dict["tetra"], local.cells_dict["tetra"])
    # The job's arrays alike; the local file's own field comes only with the file.
    assert set(theirs.point_data) - set(ours.point_data) == {"height"}
    for name, values in ours.point_data.items():
        np.testing.assert_array_equal(values, theirs.point_data[name], err_msg=name)


def test_run_output_geometry_of_another_mesh_is_refused_before_the_job(cli, server, data_dir,
                                                                      tmp_path, shared_server):
    """--geometry FILE whose counts differ from the mesh's: an error naming --geometry and both
    counts, and no job."""
    jobs = sum(shared_server.requests("RunJob").values())
    other = str(data_dir / "manifoldCheck1_tet.vtu")
    status, out, err = cli("run", "morse-smale", "--mesh", "manifoldCheck0_tet.vtu", "--output",
                           str(tmp_path / "x"), "--geometry", other)
    assert status == 1 and out == ""
    assert err == (f"actopo: error: --geometry {other}: 24 vertices, but the mesh "
                   "manifoldCheck0_tet.vtu on the server has 29; give the same mesh's file, or "
                   "leave --geometry out to download the geometry from the server\n")
    status, _, err = cli("run", "topological-simplification", "--mesh", "manifoldCheck0_tet.vtu",
                         "--output", str(tmp_path / "x"), "--geometry", str(tmp_path / "no.vtu"))
    assert status == 1 and f"--geometry: no such mesh file: {tmp_path / 'no.vtu'}" in err
    status, _, err = cli("run", "morse-smale", "--mesh", "manifoldCheck0_tet.vtu", "--output",
                         str(tmp_path / "x"), "--geometry", str(data_dir / "happi_tas_tri.vtu"))
    assert status == 1 and "--geometry: happi_tas_tri.vtu: only tetrahedral meshes" in err
    assert sum(shared_server.requests("RunJob").values()) == jobs
    assert not list(tmp_path.iterdir())
    # Algorithms that write no per-vertex file do not read it.
    status, _, err = cli("run", "critical-points", "--mesh", "manifoldCheck0_tet.vtu",
                         "--output", str(tmp_path / "cp"), "--geometry", other)
    assert status == 0, err


def test_run_output_warns_only_when_the_download_fails(cli, tmp_path, monkeypatch):
    """A local file of the same name but another mesh is passed over for the server's
    geometry; when downloading that fails, the files that need it are left out, with a
    warning, and the others written."""
    monkeypatch.delenv("ACTOPO_DATA_DIR", raising=False)
    monkeypatch.chdir(tmp_path)
    points, tets, fields = lattice(3)  # 27 vertices; the server's file has 29
    meshio.Mesh(points, [("tetra", tets)], point_data=fields).write("manifoldCheck0_tet.vtu")
    status, out, err = cli("run", "morse-smale", "--mesh", "manifoldCheck0_tet.vtu",
                           "--output", "a")
    assert status == 0 and err == "" and "wrote a_segmentation.vtu" in out
    assert len(meshio.read("a_segmentation.vtu").points) == 29

    def unavailable(*args, **kwargs):
        raise actopo.UnavailableError("the server went away", grpc.StatusCode.UNAVAILABLE)

    monkeypatch.setattr(actopo.Client, "download_mesh", unavailable)
    status, out, err = cli("run", "morse-smale", "--mesh", "manifoldCheck0_tet.vtu", "--param",
                           "persistence_threshold=0.1", "--output", "b")
    assert status == 0 and "wrote b_critical_points.vtp" in out and "b_segm" not in out
    assert err == ("actopo: simplified field and segmentation not written: downloading the "
                   "mesh's geometry failed (the server went away [UNAVAILABLE]); pass "
                   "--geometry FILE (the same mesh, local)\n")


def test_compare_structures(cli):
    report = _json(cli, "compare", "--mesh", "sample:jittered:8", "--algorithm",
                   "discrete-gradient", "--structures", "explicit,compact,actopo")
    rows = report["structures"]
    assert [r["structure"] for r in rows] == ["explicit", "compact", "actopo"]
    assert all(r["same_result"] and r["run_s"] > 0 for r in rows)
    assert all(r["job_s"] == r["preprocess_s"] + r["run_s"] for r in rows)
    assert rows[0]["result"] == rows[1]["result"] == rows[2]["result"]
    status, out, _ = cli("compare", "--sample", "jittered:6", "--algorithm", "critical-points",
                         "--structures", "compact,actopo", "--repeat", "2")
    assert status == 0 and "STRUCTURE" in out and "actopo" in out and "DIFFERENT" not in out
    # The comparison's former name still works when called as before.
    status, out, err = cli("bench", "--mesh", "sample:jittered:6", "--algorithm",
                           "critical-points", "--structures", "compact", "--no-progress")
    assert status == 0 and "SAME_RESULT" in out and "actopo compare" in err


def test_bench_load_json(cli):
    """A short load run: every mode, two clients, a few requests each; the server's breakdown
    counts exactly the simplices the clients were answered."""
    report = _json(cli, "bench", "--sample", "jittered:6", "--structure", "compact",
                   "--clients", "2", "--requests", "3", "--batch-size", "50",
                   "--stream-size", "300", "--chunk-size", "128", "--query-readers", "2")
    assert report["mesh"]["source"] == "sample:jittered:6"
    assert report["config"]["relation"] == "vertex_star"
    runs = {r["mode"]: r for r in report["runs"]}
    assert list(runs) == ["unary", "batch", "stream", "job"]
    for r in runs.values():
        assert r["structure"] == "compact" and r["clients"] == 2
        assert r["requests"] == 6 and r["errors"] == 0 and r["first_error"] is None, r
        assert r["requests_per_s"] > 0 and r["seconds"] > 0
        assert set(r["latency_ms"]) == {"p50", "p90", "p99", "p99.9", "mean", "max"}
        assert 0 < r["latency_ms"]["p50"] <= r["latency_ms"]["p99.9"] <= r["latency_ms"]["max"]
    sent = {"unary": 6, "batch": 6 * 50, "stream": 6 * 300}
    for mode, simplices in sent.items():
        r = runs[mode]
        assert r["simplices"] == simplices and r["simplices_per_s"] > 0
        server = r["server"]
        assert server["query_breakdown"]["simplices"] == simplices, mode
        assert server["relation_queries"]["count"] >= r["requests"]
        assert server["per_simplex_ns"]["compute"] > 0
        assert set(server["per_call_us"]) == {"queue", "compute", "serialize"}
    assert runs["batch"]["server"]["relation_queries"]["count"] == 6
    assert runs["stream"]["server"]["relation_queries"]["count"] == 6 * 3  # 3 messages each
    job = runs["job"]
    assert job["simplices"] is None and job["server"]["jobs"]["count"] == 6
    assert job["server"]["run_s"]["p50"] > 0


def test_bench_table_and_errors(cli, server, capsys):
    status, out, err = cli("bench", "--target", server, "--sample", "jittered:5",
                           "--structure", "explicit,actopo", "--modes", "batch,stream",
                           "--clients", "1,2", "--duration", "0.2", "--no-progress")
    assert status == 0, err
    lines = out.splitlines()
    assert "SIMPLICES/S" in lines[1] and "P99.9_MS" in lines[1] and "SERIALIZE_NS" in lines[1]
    assert len([line for line in lines if line.startswith(("explicit", "actopo"))]) == 8
    with pytest.raises(SystemExit) as usage:
        cli("bench", "--modes", "unary,warp")
    assert usage.value.code == 2 and "warp" in capsys.readouterr().err
    status, _, err = cli("bench", "--sample", "jittered:4", "--batch-size", "100000000")
    assert status == 1 and "max_batch_size" in err
    status, _, err = cli("bench", "--mesh-id", "mesh-nope", "--duration", "0.1")
    assert status == 1 and "NOT_FOUND" in err


def test_errors_exit_with_a_message(cli, data_dir, monkeypatch, capsys):
    status, _, err = cli("load", "no_such_file.vtu")
    assert status == 1 and "actopo: error:" in err and "NOT_FOUND" in err
    status, _, err = cli("run", "--upload", str(data_dir / "happi_tas_tri.vtu"),
                         "--algorithm", "critical-points")  # the server reads it and says
    assert status == 1 and "happi_tas_tri.vtu" in err and "36290 triangle" in err
    assert "TetGen" in err and "INVALID_ARGUMENT" in err
    monkeypatch.delenv("ACTOPO_SERVER", raising=False)
    assert main(["info"]) == 2
    assert "ACTOPO_SERVER" in capsys.readouterr().err


def test_ctrl_c_cancels_the_cli_job(shared_server, client):
    """SIGINT while `actopo run` waits for its job, held on the server: the job stops, the
    session and mesh go."""
    before = {m.mesh_id for m in client.list_meshes()}
    sessions = {s.session_id for s in client.list_sessions()}
    cancelled = grpc.StatusCode.CANCELLED.value[0]
    jobs = Counter(shared_server.requests("RunJob"))
    with shared_server.hold("RunJob") as hold:
        process = start_cli("--server", shared_server.target, "run", "--mesh",
                            "sample:jittered:20", "--algorithm", "morse-smale", "--structure",
                            "compact")
        try:
            # The job is held, or the command ended early. The bound only stops a hang: the CLI
            # generates and partitions its mesh first, which under ASan, beside other tests, has
            # taken more than 30 s.
            wait_until(lambda: process.poll() is not None or hold.is_held,
                       "the command's job held on the server", timeout=120)
            assert process.poll() is None, process.stderr.read()
            process.send_signal(signal.SIGINT)
            _, err = process.communicate(timeout=30)
        finally:
            if process.poll() is None:
                process.kill()
    assert process.returncode == 130 and "actopo: cancelled" in err
    assert {s.session_id for s in client.list_sessions()} == sessions
    assert {m.mesh_id for m in client.list_meshes()} == before
    # Let go, the job sees that it was cancelled (by its call's end, and by the session's).
    wait_until(lambda: Counter(shared_server.requests("RunJob"))[cancelled] > jobs[cancelled],
               "the server to end the command's job CANCELLED")


# Fields: add-fields, delete-field, and run over several fields.

SERIES = "isabel_series_s2_tet.vtu"
SOME = ["velocityMag_02", "velocityMag_30", "velocityMag_45", "velocityMag_46"]


@pytest.fixture(scope="module")
def isabel(client):
    mesh = client.load_mesh(SERIES)
    yield mesh
    client.delete_mesh(mesh)


def test_run_over_fields_prints_a_line_per_field(cli, client, isabel):
    status, out, err = cli("run", "persistence-diagram", "--mesh-id", isabel.mesh_id,
                           "--scalars", "velocityMag_02,velocityMag_30", "--structure",
                           "compact")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith(f"persistence-diagram on {SERIES} (230640 tetrahedra")
    assert lines[1].startswith("  velocityMag_02: ") and '"pairs": 655' in lines[1]
    assert lines[2].startswith("  velocityMag_30: ") and '"pairs": 3109' in lines[2]
    assert lines[3].startswith("  run ") and "over 2 fields" in lines[3] and len(lines) == 4
    report = _json(cli, "run", "critical-points", "--mesh-id", isabel.mesh_id, "--scalars",
                   "all", "--digests", "--structure", "explicit")
    names = [f.name for f in isabel.fields]
    assert [f["field"] for f in report["fields"]] == names
    assert [f["index"] for f in report["fields"]] == list(range(12))
    assert report["result"] == {"fields": names} and report["config"]["scalars"] == names
    assert report["algorithm"] == "critical-points" and report["structure"] == "explicit"
    with client.open_session(isabel, scalar="velocityMag_48", structure="compact") as session:
        alone = session.run("critical-points", digests=True, include_arrays=False)
    assert report["fields"][-1]["result"] == alone.summary
    assert all(f["run_s"] > 0 for f in report["fields"])


def test_run_diagram_distance_prints_the_matrices(cli, isabel, bench, data_dir, tmp_path):
    plot = tmp_path / "distances.png"
    status, out, err = cli("run", "diagram-distance", "--mesh-id", isabel.mesh_id, "--scalars",
                           ",".join(SOME), "--param", "p=1", "--plot", str(plot))
    assert status == 0, err
    assert "distances between 4 persistence diagrams (p = 1, infinite pairs left out)" in out
    header = out.splitlines()[out.splitlines().index("Wasserstein-1:") + 1]
    assert header.split() == SOME and "bottleneck:" in out
    assert f"wrote {plot}" in out
    assert matplotlib.image.imread(plot).shape[0] > 500
    report = _json(cli, "run", "diagram-distance", "--mesh-id", isabel.mesh_id, "--scalars",
                   ",".join(SOME), "--param", "p=1")
    expected = bench(data_dir / SERIES, "diagram-distance", "--scalars", ",".join(SOME), "--p",
                     "1")
    result = report["result"]
    assert (result["fields"], result["pairs"], result["thresholds"], result["p"]) == (
        expected["fields"], expected["pairs"], expected["thresholds"], expected["p"])
    for key in ("wasserstein", "bottleneck"):
        np.testing.assert_allclose(result[key], expected[key], rtol=0, atol=1e-12)
    assert [f["result"]["pairs"] for f in report["fields"]] == [655, 3109, 2819, 2920]


@pytest.mark.parametrize("args,message", [
    (["run", "diagram-distance"], "diagram-distance compares fields: give --scalars"),
    (["run", "critical-points", "--scalar", "a", "--scalars", "a,b"], "--scalar and --scalars"),
    (["run", "morse-smale", "--scalars", "a,b", "--output", "out/x"],
     "--output writes one field's result"),
    (["run", "persistence-diagram", "--scalars", "a,b", "--plot", "x.png"],
     "--plot draws one field's persistence diagram"),
    (["run", "diagram-distance", "--scalars", "all", "--plot", "x.png", "--threshold", "1%"],
     "--threshold draws on a persistence diagram"),
])
def test_usage_errors_of_run_over_fields(cli, args, message):
    status, out, err = cli(*args, "--mesh-id", "mesh-never-asked")
    assert status == 2 and out == "" and message in err


@pytest.mark.parametrize("args", [["add-fields", "mesh-1"], ["delete-field", "mesh-1"],
                                  ["add-fields", "mesh-1", "f.vtu", "--times", "soon"],
                                  ["run", "critical-points", "--scalars", ",", "--sample", "x"]])
def test_usage_errors_of_the_field_commands(cli, args, capsys):
    with pytest.raises(SystemExit) as usage:
        cli(*args)
    assert usage.value.code == 2 and "usage:" in capsys.readouterr().err


def test_add_fields_and_delete_field(cli, client, tmp_path):
    points, tets, fields = lattice(4)
    mesh = client.upload_mesh((points, tets, {"f": fields["f"]}), name="cli fields")
    path = tmp_path / "more.vtu"
    meshio.write(path, meshio.Mesh(points, [("tetra", tets)], point_data={
        "p": points[:, 0] * 2.0, "q": fields["z"], "normals": points}))
    try:
        status, out, err = cli("add-fields", mesh.mesh_id, str(path), "--fields", "q",
                               "--times", "1.5")
        assert status == 0, err
        rows = [line.split() for line in out.splitlines()]
        assert rows[0] == ["FIELD", "DTYPE", "MIN", "MAX", "TIME"]
        assert rows[1][::4] == ["f", "-"] and rows[2] == ["q", "float32", "0.000", "1.000", "1.5"]
        status, _, err = cli("add-fields", mesh.mesh_id, str(path))  # p and q: q is taken
        assert status == 1 and "ALREADY_EXISTS" in err and "'q'" in err
        assert [f.name for f in client.get_mesh(mesh).fields] == ["f", "q"]  # p was not added
        added = _json(cli, "add-fields", mesh.mesh_id, str(path), "--fields", "p")
        assert [(f["name"], f["time"]) for f in added["fields"]] == [
            ("f", None), ("q", 1.5), ("p", None)]
        status, _, err = cli("add-fields", mesh.mesh_id, str(path), "--fields", "normals")
        assert status == 1 and "has no scalar point field 'normals' (it has: p, q)" in err
        status, _, err = cli("add-fields", mesh.mesh_id, str(tmp_path / "none.vtu"))
        assert status == 1 and "no such mesh file" in err
        status, out, err = cli("delete-field", mesh.mesh_id, "q")
        assert status == 0 and [line.split()[0] for line in out.splitlines()] == [
            "FIELD", "f", "p"]
        status, _, err = cli("delete-field", mesh.mesh_id, "q")
        assert status == 1 and "NOT_FOUND" in err
        assert [f["name"] for f in _json(cli, "delete-field", mesh.mesh_id, "p")["fields"]] \
            == ["f"]
    finally:
        client.delete_mesh(mesh)


def test_run_tracking_prints_its_summary_after_the_fields(cli, isabel):
    status, out, err = cli("run", "tracking", "--mesh-id", isabel.mesh_id, "--scalars",
                           ",".join(SOME[:2]), "--param", "relative_threshold=0.05")
    assert status == 0, err
    lines = out.splitlines()
    assert [line.split(":")[0] for line in lines[1:3]] == [f"  {f}" for f in SOME[:2]]
    summary = json.loads(out[out.index("result: ") + len("result: "):])
    assert summary["fields"] == SOME[:2] and summary["links"] > 0
    status, _, err = cli("run", "tracking", "--mesh-id", isabel.mesh_id)
    assert status == 2 and "tracking compares fields: give --scalars" in err


def test_run_tracking_plots_the_trajectories(cli, isabel, tmp_path):
    path = tmp_path / "tracks.png"
    status, out, err = cli("run", "tracking", "--mesh-id", isabel.mesh_id, "--scalars",
                           ",".join(SOME[:3]), "--plot", str(path))
    assert status == 0, err
    assert f"wrote {path}" in out and path.stat().st_size > 10_000
