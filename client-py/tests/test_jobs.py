"""Jobs: results equal upstream TTK's (computed here from the streamed arrays), topo-relations
and the boundary rules equal what the mesh file gives, arrays, pyvista and files, progress,
cancellation. Persistence diagrams and simplifications are checked against TTK in
test_persistence.py and test_simplification.py."""

from __future__ import annotations

import json
import os
import sys
import threading
from pathlib import Path

import meshio
import numpy as np
import pytest
import pyvista as pv
import references
from harness import wait_until
from references import CASE_IDS, CASES

import actopo
import actopo._progress
from actopo._mesh import MeshArrays, mesh_arrays

STRUCTURES = ["explicit", "compact", "actopo"]
DEADLINE_SECONDS = 1.0
"""A job's deadline in the tests of deadlines: the job is held on the server until it passed."""


@pytest.fixture(scope="module")
def fertility(client):
    mesh = client.load_mesh("fertility_tet.vtu")
    yield mesh
    client.delete_mesh(mesh)


@pytest.fixture(scope="module")
def fertility_session(client, fertility):
    with client.open_session(fertility, scalar="eigenfunction4", structure="actopo") as s:
        yield s


@pytest.fixture(scope="module")
def big(client):
    """A sample whose Morse-Smale complex runs for a few tenths of a second. The tests that
    cancel hold the job on the server until the client has cancelled it; a cancelled stream
    reaches the server as a message of its own, which is in long before such a job, let go,
    could end."""
    mesh = client.sample("jittered:50")
    yield mesh
    client.delete_mesh(mesh)


def _stopped(session: actopo.Session, finished_before: int) -> bool:
    """Whether the session's job was stopped on the server: waits until the session runs no
    job, then checks that the job did not finish (the session counts finished jobs only)."""
    wait_until(lambda: session.describe().running_job_id is None, "the session to run no job")
    return session.stats().jobs.count == finished_before


@pytest.fixture(scope="module")
def mesh_file(data_dir):
    """mesh_file(file) -> the mesh file's arrays, read here (not by the server)."""
    read: dict[str, MeshArrays] = {}

    def arrays(file: str) -> MeshArrays:
        if file not in read:
            read[file] = mesh_arrays(data_dir / file)
        return read[file]

    return arrays


def test_every_expected_case_is_tested():
    assert sorted(references.expected_cases()) == sorted(CASES)


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("file,field", CASES, ids=CASE_IDS)
def test_results_equal_ttks(client, meshes, file, field, structure):
    """Critical points, the gradient's critical cells and the Morse-Smale complex, digested
    here from the streamed arrays, and the summaries, equal upstream TTK's; the summaries'
    digests too, where the job asked for them."""
    ttk = references.ttk(file, field)
    with client.open_session(meshes(file), scalar=field, structure=structure) as session:
        cp = session.run("critical-points", digests=True)
        references.check_critical_points(cp, ttk["critical_points"], digests=True)
        dg = session.run("discrete-gradient", digests=True)
        references.check_discrete_gradient(dg, session, ttk["discrete_gradient"])
        ms = session.run("morse-smale")
        references.check_morse_smale(ms, session, ttk["morse_smale"], ttk["discrete_gradient"])
    for result, algorithm in ((cp, "critical-points"), (dg, "discrete-gradient"),
                              (ms, "morse-smale")):
        assert result.algorithm == algorithm and result.job_id
        assert result.stats.run_seconds > 0


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("file", ["manifoldCheck1_tet.vtu", "fertility_tet.vtu"])
def test_topo_relations_count_what_the_mesh_holds(client, meshes, mesh_file, file, structure):
    """Every relation's total over all its simplices, as counted from the file's tetrahedra:
    TTK's 20 relations by default, with the edge and triangle neighbours when asked."""
    with client.open_session(meshes(file), structure=structure) as session:
        ttk = session.run("topo_relations").summary
        every = session.run("topo_relations", parameters={"relations": "all"}).summary
    expected = references.relation_totals(mesh_file(file).tetrahedra)
    assert (every["relations"], every["relation_totals"]) == ("all", expected)
    del expected["edge_neighbors"], expected["triangle_neighbors"]
    assert (ttk["relations"], ttk["relation_totals"]) == ("ttk", expected)


@pytest.mark.parametrize("field", ["eigenfunction4", "height"])
def test_boundary_rules_follow_their_definition(client, meshes, mesh_file, field):
    """boundary_rule "ttk" (the default) and "none" give the critical points their definition
    gives on the file's field; the first is TTK's, and on fertility the two differ."""
    file = "fertility_tet.vtu"
    arrays = mesh_file(file)
    rules = {}
    with client.open_session(meshes(file), scalar=field, structure="compact") as session:
        for rule in ("ttk", "none"):
            points = session.run("critical-points", parameters={"boundary_rule": rule})
            rules[rule] = list(zip(points.critical_points["ttkVertexScalarField"].tolist(),
                                   points.critical_points["CriticalType"].tolist(), strict=True))
            assert rules[rule] == references.critical_points(
                arrays.tetrahedra, arrays.point_data[field], rule), rule
    expected = references.ttk(file, field)["critical_points"]["vertices"]
    assert [list(p) for p in rules["ttk"]] == expected
    assert rules["none"] != rules["ttk"]


def test_arrays_agree_with_the_summary(fertility_session, fertility):
    cp = fertility_session.run("critical-points")
    types = cp.critical_points["CriticalType"]
    counts = cp.summary["counts"]
    assert types.dtype == np.int8
    assert np.bincount(types, minlength=5).tolist() == [
        counts["minimum"], counts["saddle1"], counts["saddle2"], counts["maximum"],
        counts["degenerate"]]
    assert cp.critical_points["Points"].shape == (len(types), 3)
    assert cp["critical_points/ttkVertexScalarField"].dtype == np.int32
    assert "eigenfunction4" in cp.critical_points

    ms = fertility_session.run("morse-smale")
    assert ms.groups == ["critical_points", "separatrices", "segmentation"]
    cells = ms.critical_points["CellDimension"]
    assert np.bincount(cells, minlength=4).tolist() == ms.summary["critical_cells"]
    seg = ms.segmentation
    assert {k: v.shape for k, v in seg.items()} == {
        k: (fertility.vertices,) for k in ("DescendingManifold", "AscendingManifold",
                                           "MorseSmaleManifold")}
    assert len(np.unique(seg["DescendingManifold"])) == ms.summary["regions"]["descending"]
    sep = ms.separatrices
    offsets = sep["Offsets"]
    assert offsets[0] == 0 and offsets[-1] == len(sep["Points"])
    assert len(offsets) - 1 == len(sep["SeparatrixType"]) == len(sep["SourceId"])
    total = ms.summary["separatrices"]
    assert len(sep["SeparatrixType"]) == sum(total[k] for k in ("descending", "ascending",
                                                                 "saddle_connectors"))
    dg = fertility_session.run("discrete-gradient", include_arrays=False)
    assert dg.arrays == {} and dg.summary["critical_cells"] == ms.summary["critical_cells"]


def test_to_pyvista_and_files(fertility_session, data_dir, tmp_path):
    ms = fertility_session.run("morse-smale")
    datasets = ms.to_pyvista()
    assert set(datasets) == {"critical_points", "separatrices"}  # no geometry given
    assert datasets["critical_points"].n_points == sum(ms.summary["critical_cells"])
    assert datasets["separatrices"].n_cells == len(ms.separatrices["SeparatrixType"])
    assert "SeparatrixType" in datasets["separatrices"].cell_data
    with_mesh = ms.to_pyvista(pv.read(data_dir / "fertility_tet.vtu"))
    np.testing.assert_array_equal(with_mesh["segmentation"].point_data["MorseSmaleManifold"],
                                  ms.segmentation["MorseSmaleManifold"])
    files = ms.write(str(tmp_path / "ms"), data_dir / "fertility_tet.vtu")
    assert [os.path.basename(f) for f in files] == ["ms_critical_points.vtp",
                                                    "ms_separatrices.vtp", "ms_segmentation.vtu"]
    assert pv.read(files[2]).point_data["DescendingManifold"].shape == (14570,)


def test_progress_callback_and_bar(fertility_session, capsys):
    fractions = []
    fertility_session.run("critical-points", progress=fractions.append, include_arrays=False)
    assert fractions and fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)
    fertility_session.run("critical-points", progress=True, include_arrays=False)


def test_a_callable_gets_the_run_a_bar_shows_the_faces_first(client, monkeypatch):
    """The first job on a mesh that reads faces reports their build (phase "faces") before its
    run: a bar per phase shows it, a callable(fraction) sees only the run, so its fractions
    still rise once from 0 to 1."""
    bars: list[str] = []

    class Recorder:
        def __init__(self, description: str) -> None:
            bars.append(description)

        def update(self, fraction: float) -> None:
            pass

        def close(self) -> None:
            pass

    monkeypatch.setattr(actopo._progress, "_bar", Recorder)
    for progress_of in ("bar", "callable"):
        mesh = client.sample("jittered:10", block_size=50)  # blocks enough for several reports
        assert mesh.edges is None
        try:
            with client.open_session(mesh, structure="compact") as session:
                fractions: list[float] = []
                result = session.run("discrete-gradient", include_arrays=False,
                                     progress=True if progress_of == "bar" else fractions.append)
                assert result.stats is not None and result.stats.faces_seconds > 0
                again = session.run("discrete-gradient", include_arrays=False)
                assert again.stats is not None and again.stats.faces_seconds == 0
                if progress_of == "bar":
                    assert bars == ["discrete-gradient (the mesh's edges and triangles, once "
                                    "per mesh)", "discrete-gradient"]
                else:
                    assert fractions and fractions == sorted(fractions)
                    assert fractions[0] < 1.0 and fractions[-1] == pytest.approx(1.0)
        finally:
            client.delete_mesh(mesh)


def test_cancel_from_another_thread(shared_server, client, big):
    """cancel() from another thread while result() waits for the job, held on the server."""
    with client.open_session(big, structure="compact") as session:
        with shared_server.hold("RunJob") as hold:
            job = session.submit("morse-smale")
            assert job.job_id and session.describe().running_job_id == job.job_id
            hold.wait_held()
            failed: list[BaseException] = []

            def cancel_once_waiting() -> None:
                try:
                    # result() holds the job's lock while it reads the job's stream.
                    wait_until(job._lock.locked, "result() to wait for the job")
                    job.cancel()
                except BaseException as e:
                    failed.append(e)
                finally:
                    hold.release()  # the job sees its cancel, or ends and fails the test

            canceller = threading.Thread(target=cancel_once_waiting)
            canceller.start()
            try:
                with pytest.raises(actopo.CancelledError):
                    job.result()
            finally:
                canceller.join()
                if failed:
                    raise failed[0]
        assert _stopped(session, 0)


def test_ctrl_c_cancels_the_job(shared_server, client, big):
    with client.open_session(big, structure="compact") as session:
        with shared_server.hold("RunJob") as hold:
            sent = threading.Event()
            interrupter = threading.Thread(target=hold.interrupt_when_held, args=(sent,))
            interrupter.start()
            try:
                with pytest.raises(KeyboardInterrupt):
                    session.run("morse-smale")
            finally:
                interrupter.join()
            assert sent.is_set() and hold.is_held
        assert _stopped(session, 0), "the job ran on on the server after Ctrl-C"
        assert session.run("critical-points", include_arrays=False).summary["counts"]


def test_ctrl_c_right_after_submit_cancels_the_job(shared_server, client, big, monkeypatch):
    """Python raises Ctrl-C between any two steps of run(): here right after submit() returned,
    before run() holds the job, where only the session knows which job is running. The job's
    stream is kept open, as a loaded machine may deliver its cancellation after the job ended:
    the job must be cancelled by CancelJob."""
    submit = actopo.Session.submit
    kept: list[actopo.Job] = []

    def submit_then_interrupt(self, *args, **kwargs):
        kept.append(submit(self, *args, **kwargs))
        raise KeyboardInterrupt

    with client.open_session(big, structure="compact") as session:
        with shared_server.hold("RunJob") as hold:
            monkeypatch.setattr(actopo.Session, "submit", submit_then_interrupt)
            with pytest.raises(KeyboardInterrupt):
                session.run("morse-smale")
            monkeypatch.undo()
            assert hold.is_held and len(kept) == 1
        try:
            assert _stopped(session, 0), "the job ran on on the server after Ctrl-C"
        finally:
            kept[0]._call.cancel()
        assert session.run("critical-points", include_arrays=False).summary["counts"]


def test_deadline_and_busy_session(shared_server, client, big):
    with client.open_session(big, structure="compact") as session:
        with shared_server.hold("RunJob") as hold:
            job = session.submit("morse-smale")
            hold.wait_held()
            with pytest.raises(actopo.FailedPreconditionError, match=job.job_id):
                session.submit("critical-points")
            job.cancel()
            hold.release()
            with pytest.raises(actopo.CancelledError):
                job.result()
        assert _stopped(session, 0)
        with shared_server.hold("RunJob") as hold:
            with pytest.raises(actopo.DeadlineExceededError):
                session.run("morse-smale", timeout=DEADLINE_SECONDS)
            assert hold.is_held, "the deadline passed while the job was not held"
        assert _stopped(session, 0), "the job ran on past its deadline"
        assert session.run("critical-points", include_arrays=False).summary["counts"]


def test_cancel_unknown_job(client):
    with pytest.raises(actopo.NotFoundError):
        client.cancel_job("job-does-not-exist")


def test_files_with_meshio_only(fertility_session, data_dir, tmp_path, monkeypatch):
    ms = fertility_session.run("morse-smale")
    monkeypatch.setitem(sys.modules, "pyvista", None)  # as if pyvista were not installed
    files = ms.write(str(tmp_path / "ms"), data_dir / "fertility_tet.vtu")
    assert [os.path.basename(f) for f in files] == ["ms_critical_points.vtu",
                                                    "ms_separatrices.vtu", "ms_segmentation.vtu"]
    points = meshio.read(files[0])
    assert len(points.points) == sum(ms.summary["critical_cells"])
    np.testing.assert_array_equal(points.point_data["CellDimension"],
                                  ms.critical_points["CellDimension"])
    segmentation = meshio.read(files[2])
    np.testing.assert_array_equal(segmentation.point_data["AscendingManifold"],
                                  ms.segmentation["AscendingManifold"])
    with pytest.raises(ImportError, match="pyvista"):
        ms.to_pyvista()
    monkeypatch.setitem(sys.modules, "meshio", None)
    with pytest.raises(ImportError, match=r"actopo\[pyvista\]"):
        ms.write(str(tmp_path / "none"))


def test_trace_of_a_job(client, fertility, tmp_path):
    """trace=True: the job's threads, phases, computations and waits, in a file Perfetto
    opens; the waits are the job's misses. Without it there is none."""
    with client.open_session(fertility, scalar="eigenfunction4", structure="actopo",
                             consumers=2, producers=2, buffer_ratio=0.05) as session:
        result = session.run("morse-smale", trace=True, include_arrays=False)
        path = result.save_trace(tmp_path / "job.json")
        trace = json.loads(Path(path).read_text())
        threads = {e["tid"]: e["args"]["name"] for e in trace["traceEvents"]
                   if e["ph"] == "M" and e["name"] == "thread_name"}
        events = [e for e in trace["traceEvents"] if e["ph"] != "M"]
        assert trace["otherData"]["events"] == len(events)
        phases = {e["name"]: e for e in events if e["cat"] == "phase"}
        # The job's phases, and the algorithm's own steps inside its span.
        assert sorted(phases) == ["morse-smale", "results", "segmentations", "start engine"]
        run, step = phases["morse-smale"], phases["segmentations"]
        assert run["ts"] <= step["ts"] and step["ts"] + step["dur"] <= run["ts"] + run["dur"]
        assert {threads[e["tid"]] for e in events if e["cat"] == "phase"} == {"job"}
        assert {"consumer 0", "consumer 1"} <= set(threads.values())
        waits = [e for e in events if e["name"] == "wait"]
        assert len(waits) == result.stats.engine.misses > 0
        # How much the producers compute depends on the schedule (with a consumer per core they
        # run at idle priority and may compute nothing): each span is on its producer's row,
        # and the statistics count every span (a span after the run is not traced).
        computed = [e for e in events if e["cat"] in ("leader", "worker")]
        for e in computed:
            assert len(e["name"]) == 2 and threads[e["tid"]].split()[0] == e["cat"]
        engine = result.stats.engine
        assert sum(e["cat"] == "leader" for e in computed) <= engine.leader_relations
        assert sum(e["cat"] == "worker" for e in computed) <= engine.worker_relations

        plain = session.run("critical-points", include_arrays=False)
        assert plain.trace is None
        with pytest.raises(ValueError, match="without trace=True"):
            plain.save_trace(tmp_path / "none.json")
