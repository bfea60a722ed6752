"""actopo-bench as users call it: the JSON contract of DESIGN.md, identical results across
structures, output files, and clear errors for bad flags."""
import collections
import itertools
import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = Path(os.environ.get("ACTOPO_BUILD", ROOT / "build")) / "server/cmd/actopo-bench"
ALGORITHMS = ["topo-relations", "critical-points", "discrete-gradient", "morse-smale",
              "persistence-diagram", "topological-simplification", "merge-tree", "contour-tree"]
DATA = Path(os.environ.get("ACTOPO_DATA_DIR", ROOT.parent / "shared/data"))


def bench(*args, check=True):
    proc = subprocess.run([str(BENCH), *args], capture_output=True, text=True, timeout=300)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def run_json(*args):
    return json.loads(bench(*args, "--json").stdout)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_same_result_on_every_structure(algorithm):
    sample = ["--sample", "jittered:12", "--algorithm", algorithm, "--block-size", "100"]
    results = [run_json(*sample, "--structure", "explicit")]
    results.append(run_json(*sample, "--structure", "compact", "--consumers", "2"))
    for prefetch in ["linear", "spatial", "adaptive"]:
        results.append(run_json(*sample, "--structure", "actopo", "--producers", "2",
                                "--prefetch", prefetch, "--consumers", "2"))
    for r in results[1:]:
        assert r["result"] == results[0]["result"]
    first = results[0]
    assert set(first) >= {"mesh", "structure", "algorithm", "config", "times_s", "engine",
                          "memory", "result"}
    assert first["mesh"]["tetrahedra"] == 6 * 11 ** 3
    times = first["times_s"]
    assert set(times) == {"load", "partition", "preprocess", "run", "results", "total"}
    # total runs from process start to result ready: it covers every phase.
    assert times["total"] >= sum(v for k, v in times.items() if k != "total")
    assert set(first["engine"]) >= {"wait_s", "requests", "hits", "misses", "evictions",
                                    "blocks_computed"}
    assert set(first["memory"]) >= {"peak_rss_bytes", "structure_bytes", "buffer_peak_bytes"}
    actopo = results[-1]["engine"]
    assert actopo["requests"] == actopo["hits"] + actopo["misses"]
    assert len(actopo["consumers"]) == 2


def test_result_keys_per_algorithm():
    r = run_json("--sample", "wavelet:8", "--algorithm", "morse-smale", "--structure", "explicit",
                 "--digests")
    assert set(r["result"]) >= {"critical_cells", "separatrices", "regions", "segmentation_sha256"}
    assert set(r["result"]["separatrices"]) >= {"descending", "ascending", "saddle_connectors"}
    r = run_json("--sample", "wavelet:8", "--algorithm", "critical-points", "--digests")
    assert set(r["result"]["counts"]) == {"minimum", "saddle1", "saddle2", "degenerate", "maximum"}
    assert len(r["result"]["vertices_sha256"]) == 64
    r = run_json("--sample", "wavelet:8", "--algorithm", "discrete-gradient")
    c = r["result"]["critical_cells"]
    assert c[0] - c[1] + c[2] - c[3] == 1  # a ball


def test_persistence_diagram_equals_ttk_and_writes_the_diagram(tmp_path):
    expected = json.loads((DATA / "expected-ttk.json").read_text())
    want = expected["fertility_tet.vtu"]["height"]["upstream"]["persistence_diagram"]
    prefix = tmp_path / "pd"
    r = run_json("--mesh", str(DATA / "fertility_tet.vtu"), "--scalar", "height",
                 "--algorithm", "persistence-diagram", "--structure", "actopo",
                 "--output", str(prefix), "--digests")
    assert r["result"]["pairs_sha256"] == want["pairs_sha256"]
    assert r["result"]["counts_by_type"] == want["counts_by_type"]
    assert [Path(f).name for f in r["files"]] == ["pd_diagram.vtu", "pd_persistence_curve.csv"]
    assert b"UnstructuredGrid" in (tmp_path / "pd_diagram.vtu").read_bytes()[:300]


@pytest.mark.parametrize("structure", ["explicit", "compact", "actopo"])
def test_critical_points_build_no_faces_and_equal_ttk(structure):
    """critical points reads VT and VB, computed from the vertices' stars: the encoding
    builds no edges or triangles, and the result is still TTK's (fertility has a boundary)."""
    upstream = json.loads((DATA / "expected-ttk.json").read_text())["fertility_tet.vtu"]
    upstream = upstream["height"]["upstream"]
    want = upstream["critical_points"]
    r = run_json("--mesh", str(DATA / "fertility_tet.vtu"), "--scalar", "height",
                 "--algorithm", "critical-points", "--structure", structure, "--digests")
    assert r["mesh"]["edges"] is None and r["mesh"]["triangles"] is None
    assert r["memory"]["static_breakdown_bytes"]["edges"] == 0
    assert r["result"]["vertices_sha256"] == want["vertices_sha256"]
    assert r["result"]["counts"] == want["counts"]
    # Every other algorithm reads edges or triangles: they are built and counted.
    r = run_json("--mesh", str(DATA / "fertility_tet.vtu"), "--scalar", "height",
                 "--algorithm", "discrete-gradient", "--structure", structure)
    assert r["mesh"]["edges"] == upstream["mesh"]["edges"]


@pytest.mark.parametrize("structure", ["explicit", "compact", "actopo"])
def test_simplified_morse_smale_on_every_structure(structure, tmp_path):
    """morse-smale with a threshold reads the simplification's relations too (VV): the explicit
    structure must have stored them."""
    r = run_json("--sample", "jittered:12", "--algorithm", "morse-smale", "--structure", structure,
                 "--relative-threshold", "0.05", "--output", str(tmp_path / "ms"))
    s = r["result"]["simplification"]
    assert s["kept_pairs"] + s["removed_pairs"] == s["pairs"]
    assert s["removed_maxima"] + s["removed_minima"] > 0
    assert r["result"]["critical_cells"][0] < s["pairs"]
    assert (tmp_path / "ms_simplified.vtu").stat().st_size > 0
    plain = run_json("--sample", "jittered:12", "--algorithm", "morse-smale", "--structure",
                     structure)
    assert plain["result"]["critical_cells"][0] > r["result"]["critical_cells"][0]


def test_legacy_backend_keeps_the_same_extrema():
    sample = ["--sample", "jittered:12", "--algorithm", "topological-simplification",
              "--relative-threshold", "0.1"]
    lts = run_json(*sample)["result"]
    legacy = run_json(*sample, "--backend", "legacy")["result"]
    assert (lts["backend"], legacy["backend"]) == ("lts", "legacy")
    assert legacy["sweeps"] >= 1
    for key in ("kept_pairs", "constraints", "minima", "maxima"):
        assert legacy[key] == lts[key], key


def test_bad_thresholds_are_named():
    proc = bench("--sample", "jittered:4", "--algorithm", "topological-simplification",
                 "--relative-threshold", "2", check=False)
    assert proc.returncode == 1
    assert "--relative-threshold: " in proc.stderr and "[0, 1]" in proc.stderr
    proc = bench("--sample", "jittered:4", "--algorithm", "morse-smale",
                 "--relative-threshold", "0.1", "--persistence-threshold", "3", check=False)
    assert "not both" in proc.stderr


def test_output_files(tmp_path):
    prefix = tmp_path / "ms"
    r = run_json("--sample", "jittered:10", "--algorithm", "morse-smale", "--output", str(prefix))
    files = [Path(f) for f in r["files"]]
    assert [f.name for f in files] == ["ms_critical_points.vtp", "ms_separatrices.vtp",
                                      "ms_segmentation.vtu"]
    for f in files:
        assert f.stat().st_size > 0
        assert b"VTKFile" in f.read_bytes()[:200]
    text = (tmp_path / "ms_segmentation.vtu").read_bytes()
    for name in [b"DescendingManifold", b"AscendingManifold", b"MorseSmaleManifold"]:
        assert name in text


@pytest.mark.parametrize("structure", ["explicit", "compact", "actopo"])
def test_default_threads_use_every_core(structure):
    cores = os.cpu_count()
    r = run_json("--sample", "jittered:6", "--algorithm", "critical-points",
                 "--structure", structure)
    assert r["config"]["consumers"] == cores
    if structure == "actopo":
        assert r["config"]["producers"] == 1


@pytest.mark.parametrize("args,message", [
    (["--sample", "jittered:5", "--structure", "fancy"], "--structure: unknown structure 'fancy'"),
    (["--sample", "jittered:5", "--algorithm", "reeb-graph"], "unknown algorithm 'reeb-graph'"),
    (["--sample", "jittered:5", "--algorithm", "merge-tree", "--tree", "contour"],
     "--tree: unknown value 'contour'; available: join, split"),
    (["--sample", "jittered:5", "--consumers", "-1"], "--consumers: -1 is outside [1, 64]"),
    (["--sample", "jittered:5", "--buffer-ratio", "2"], "--buffer-ratio: 2 is outside [0, 1]"),
    (["--sample", "jittered:5", "--prefetch", "psychic"],
     "--prefetch: unknown prefetch mode 'psychic'"),
    (["--sample", "jittered:5", "--structure", "actopo", "--producers", "-1"],
     "--producers: -1 is outside [1, 64]"),
    (["--sample", "jittered:5", "--consumers", "65"], "--consumers: 65 is outside [1, 64]"),
    (["--sample", "nope:3"], "sample 'nope:3'"),
    (["--mesh", "/does/not/exist.vtu"], "/does/not/exist.vtu"),
    (["--sample", "jittered:5", "--scalar", "pressure"], "scalar field 'pressure' not found"),
    (["--sample", "jittered:5", "--block-size", "0"], "--block-size: 0 must be at least 1"),
    (["--sample", "jittered:5", "--colour", "red"], "unknown flag --colour"),
    (["--sample", "jittered:5", "--trace", "/does/not/exist/run.json"],
     "--trace: cannot write '/does/not/exist/run.json': No such file or directory"),
    ([], "give exactly one of --mesh PATH or --sample NAME"),
])
def test_errors_name_the_flag_and_value(args, message):
    proc = bench(*args, check=False)
    assert proc.returncode != 0
    assert message in proc.stderr


def test_block_labels_partition_with_or_without_output(tmp_path):
    """--block-labels reads its field whether or not --output keeps the fields; a float or
    unknown field is named by the flag."""
    meshio = pytest.importorskip("meshio")
    import numpy as np
    mesh = meshio.read(DATA / "fertility_tet.vtu")
    mesh.point_data["part"] = (mesh.points[:, 0] > np.median(mesh.points[:, 0])).astype(np.int32)
    mesh.point_data["wobble"] = mesh.points[:, 1] * 0.37
    path = tmp_path / "labelled.vtu"
    meshio.write(path, mesh)
    common = ["--mesh", str(path), "--algorithm", "critical-points", "--scalar", "height"]
    alone = run_json(*common, "--block-labels", "part")
    written = run_json(*common, "--block-labels", "part", "--output", str(tmp_path / "cp"))
    assert alone["mesh"]["blocks"] == written["mesh"]["blocks"] == 2
    assert alone["result"] == written["result"]
    proc = bench(*common, "--block-labels", "wobble", check=False)
    assert proc.returncode != 0
    assert "--block-labels: vertex 0 has label" in proc.stderr
    assert "not a 32-bit integer" in proc.stderr
    proc = bench(*common, "--block-labels", "nope", check=False)
    assert proc.returncode != 0
    assert "--block-labels: point field 'nope' not found; point fields: " in proc.stderr
    assert "'part'" in proc.stderr


def trace_events(path):
    """The trace's events and its thread names by tid (metadata events set them)."""
    trace = json.loads(Path(path).read_text())
    threads = {e["tid"]: e["args"]["name"] for e in trace["traceEvents"]
               if e["ph"] == "M" and e["name"] == "thread_name"}
    return [e for e in trace["traceEvents"] if e["ph"] != "M"], threads, trace["otherData"]


@pytest.mark.parametrize("structure", ["actopo", "compact", "explicit"])
def test_trace_shows_phases_threads_computations_and_waits(tmp_path, structure):
    path = tmp_path / "run.json"
    report = run_json("--sample", "jittered:14", "--block-size", "60", "--algorithm",
                      "critical-points", "--structure", structure, "--consumers", "2",
                      "--producers", "2", "--buffer-ratio", "0.1", "--trace", str(path))
    events, threads, other = trace_events(path)
    assert report["trace"] == {"file": str(path), "events": len(events), "dropped": 0}
    assert other["events"] == len(events)

    main = [tid for tid, name in threads.items() if name == "main"]
    phases = [e["name"] for e in events if e["cat"] == "phase"]
    assert phases == ["load", "partition", "vertex order", *(
        ["preprocess"] if structure != "compact" else []), "critical-points", "results"]
    assert {e["tid"] for e in events if e["cat"] == "phase"} == set(main)
    # Phases follow each other on the main thread.
    spans = [e for e in events if e["cat"] == "phase"]
    for before, after in itertools.pairwise(spans):
        assert before["ts"] + before["dur"] <= after["ts"] + 1e-3
    assert {"consumer 0", "consumer 1"} <= set(threads.values())
    work = [e for e in events if e["name"] == "work"]
    assert {threads[e["tid"]] for e in work} == {"consumer 0", "consumer 1"}

    engine = report["engine"]
    waits = [e for e in events if e["name"] == "wait"]
    computed = [e for e in events if e["cat"] in ("leader", "worker", "consumer")
                and e["name"] not in ("wait", "work")]
    for e in computed:
        assert len(e["name"]) == 2 and e["args"]["block"] >= 0  # a relation's code, a block
    if structure == "actopo":
        assert len(waits) == engine["misses"] > 0
        for e in computed:  # each on its own row: consumer N, leader N or worker N.M
            assert threads[e["tid"]].split()[0] == e["cat"]
        # Which thread computes what depends on the schedule (at idle priority, the default
        # with a consumer per core, producers may compute nothing): what holds under any is
        # that the trace counts each role's computations as the statistics do. Producers may
        # finish a prefetch after the run; the trace stops at its end.
        by_role = collections.Counter(e["cat"] for e in computed)
        assert by_role["consumer"] == engine["consumer_relations"]
        assert by_role["leader"] <= engine["leader_relations"]
        assert by_role["worker"] <= engine["worker_relations"]
        assert 0 < len(computed) <= engine["blocks_computed"]
        for e in waits:
            assert len(e["args"]["relation"]) == 2 and e["args"]["block"] >= 0
    elif structure == "compact":
        assert not waits
        assert len(computed) == engine["blocks_computed"] > 0
        assert sum(e["args"]["count"] for e in events if e["name"] == "evict") == \
            engine["evictions"]
    else:
        assert not waits and not computed  # every relation was built before the run



def _without_digests(result):
    """`result` without its "*_sha256" keys, and the digests it had (64 hex digits each)."""
    kept, digests = {}, []
    for key, value in result.items():
        if key.endswith("_sha256"):
            digests.extend(value.values() if isinstance(value, dict) else [value])
        elif isinstance(value, dict):
            kept[key], inner = _without_digests(value)
            digests.extend(inner)
        else:
            kept[key] = value
    return kept, digests


@pytest.mark.parametrize("algorithm", ["critical-points", "discrete-gradient", "morse-smale",
                                       "persistence-diagram", "topological-simplification"])
def test_digests_only_when_asked(algorithm):
    """Without --digests the result has no "*_sha256" key; with it, the same result and the
    digests besides."""
    source = ("--sample", "jittered:6", "--algorithm", algorithm)
    plain, digested = run_json(*source)["result"], run_json(*source, "--digests")["result"]
    assert _without_digests(plain) == (plain, [])
    kept, digests = _without_digests(digested)
    assert kept == plain and digests
    assert all(len(d) == 64 and int(d, 16) >= 0 for d in digests)
