"""Many fields on one mesh through actopo-bench: --scalars runs any algorithm over a list of
fields with one structure, each field's result equal to its own run and to TTK's; diagram-distance
compares the fields' diagrams, checked against Gudhi's exact distances on the real Isabel
series (SEMANTICS.md "Distances between persistence diagrams")."""
import json
import math

import gudhi
import gudhi.wasserstein
import meshio
import numpy as np
import pytest
import pyvista
from test_bench_cli import DATA, bench, run_json

SERIES = DATA / "isabel_series_s2_tet.vtu"
MEMBERS = json.loads((DATA / "series.json").read_text())["fields"]
EXPECTED = json.loads((DATA / "expected-ttk-series.json").read_text())[SERIES.name]


def group(field):
    return MEMBERS[field]["cluster"]


@pytest.mark.parametrize("structure", ["explicit", "compact", "actopo"])
def test_every_members_diagram_equals_ttks(structure):
    r = run_json("--mesh", str(SERIES), "--scalars", "all", "--algorithm", "persistence-diagram",
                 "--structure", structure, "--digests")
    assert [f["scalar"] for f in r["fields"]] == list(EXPECTED)
    assert r["config"]["scalars"] == list(EXPECTED)
    assert "result" not in r
    for entry in r["fields"]:
        expected = EXPECTED[entry["scalar"]]["upstream"]["persistence_diagram"]
        assert entry["result"]["pairs_sha256"] == expected["pairs_sha256"], entry["scalar"]
        assert entry["result"]["pairs"] == expected["pairs"]
        assert entry["times_s"]["run"] > 0


@pytest.mark.parametrize("algorithm", ["critical-points", "morse-smale",
                                       "topological-simplification"])
def test_a_field_in_a_list_gives_what_it_gives_alone(algorithm):
    fields = ["velocityMag_30", "velocityMag_02"]
    many = run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
                    algorithm, "--structure", "actopo", "--consumers", "2", "--digests")
    for field, entry in zip(fields, many["fields"], strict=True):
        alone = run_json("--mesh", str(SERIES), "--scalar", field, "--algorithm", algorithm,
                         "--structure", "compact", "--digests")
        assert entry["scalar"] == field
        assert entry["result"] == alone["result"], field


def diagram_points(path):
    """Per pair type, the finite pairs of a written diagram as (birth, death) rows."""
    grid = meshio.read(path)
    cells = {name: np.concatenate(values) for name, values in grid.cell_data.items()}
    kind, finite = cells["PairType"], cells["IsFinite"]
    birth, persistence = cells["Birth"], cells["Persistence"]
    return {k: np.stack([birth[(kind == k) & (finite == 1)],
                         (birth + persistence)[(kind == k) & (finite == 1)]], axis=1)
            for k in range(3)}


def gudhi_distances(a, b):
    wasserstein = math.sqrt(sum(
        gudhi.wasserstein.wasserstein_distance(a[k], b[k], order=2, internal_p=math.inf) ** 2
        for k in range(3)))
    bottleneck = max(gudhi.bottleneck_distance(a[k], b[k], 0) for k in range(3))
    return wasserstein, bottleneck


def test_distances_equal_gudhis_on_the_isabel_members(tmp_path):
    # One member of each group and a neighbour in time: small and large diagrams (655 to 3,167
    # pairs), near and far.
    fields = ["velocityMag_02", "velocityMag_03", "velocityMag_32", "velocityMag_46"]
    r = run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
                 "diagram-distance", "--structure", "actopo")
    result = r["result"]
    assert result["fields"] == fields and result["p"] == 2
    assert set(r["times_s"]) >= {"run", "distances", "total"}
    written = run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
                       "persistence-diagram", "--structure", "explicit",
                       "--output", str(tmp_path / "d"))
    diagrams = {f: diagram_points(tmp_path / f"d_{f}_diagram.vtu") for f in fields}
    assert [e["result"]["pairs"] for e in written["fields"]] == result["pairs"]
    for i, first in enumerate(fields):
        assert result["wasserstein"][i][i] == 0 and result["bottleneck"][i][i] == 0
        for j in range(i + 1, len(fields)):
            wasserstein, bottleneck = gudhi_distances(diagrams[first], diagrams[fields[j]])
            assert result["wasserstein"][i][j] == pytest.approx(wasserstein, rel=1e-9)
            assert result["bottleneck"][i][j] == pytest.approx(bottleneck, rel=1e-9)
            assert result["wasserstein"][j][i] == result["wasserstein"][i][j]


def test_the_matrix_separates_the_three_groups_of_the_series():
    r = run_json("--mesh", str(SERIES), "--scalars", "all", "--algorithm", "diagram-distance",
                 "--structure", "explicit", "--consumers", "2")
    result = r["result"]
    fields = result["fields"]
    assert fields == list(MEMBERS)
    for key in ["wasserstein", "bottleneck"]:
        m = result[key]
        within = max(m[i][j] for i, a in enumerate(fields) for j, b in enumerate(fields)
                     if group(a) == group(b))
        between = min(m[i][j] for i, a in enumerate(fields) for j, b in enumerate(fields)
                      if group(a) != group(b))
        # Any linkage then recovers ttk-data's three groups.
        assert within < between, key


def test_a_threshold_and_another_order():
    fields = "velocityMag_02,velocityMag_45"
    full = run_json("--mesh", str(SERIES), "--scalars", fields, "--algorithm",
                    "diagram-distance", "--structure", "compact")["result"]
    kept = run_json("--mesh", str(SERIES), "--scalars", fields, "--algorithm",
                    "diagram-distance", "--structure", "compact",
                    "--relative-threshold", "0.05")["result"]
    # 5% of each member's own range.
    ranges = [MEMBERS[f]["range"][1] - MEMBERS[f]["range"][0] for f in fields.split(",")]
    assert kept["thresholds"] == pytest.approx([0.05 * x for x in ranges])
    assert all(k < f for k, f in zip(kept["pairs"], full["pairs"], strict=True))
    # Leaving out the small pairs only removes cost: they cost at most half their persistence.
    assert kept["wasserstein"][0][1] < full["wasserstein"][0][1]
    w1 = run_json("--mesh", str(SERIES), "--scalars", fields, "--algorithm",
                  "diagram-distance", "--structure", "compact", "--p", "1")["result"]
    assert w1["p"] == 1
    assert w1["wasserstein"][0][1] > full["wasserstein"][0][1]  # W1 >= W2 >= bottleneck
    assert full["wasserstein"][0][1] >= full["bottleneck"][0][1]


@pytest.mark.parametrize(("flags", "message"), [
    (["--algorithm", "diagram-distance"], "--scalars: diagram-distance compares fields"),
    (["--algorithm", "diagram-distance", "--scalars", "velocityMag_02"],
     "compares at least two fields; 'velocityMag_02' gives 1"),
    (["--algorithm", "persistence-diagram", "--scalars", "velocityMag_02,nope"],
     "--scalars: "),
    (["--algorithm", "persistence-diagram", "--scalars", "velocityMag_02,velocityMag_02"],
     "--scalars: field 'velocityMag_02' is listed twice"),
    (["--algorithm", "persistence-diagram", "--scalars", "velocityMag_02,,velocityMag_03"],
     "has an empty field name"),
    (["--algorithm", "persistence-diagram", "--scalars", "all", "--scalar", "velocityMag_02"],
     "give --scalar NAME or --scalars LIST, not both"),
    (["--algorithm", "topo-relations", "--scalars", "all"], "reads no scalar field"),
    (["--algorithm", "diagram-distance", "--scalars", "all", "--p", "0.5"],
     "--p: 0.5 is not a Wasserstein order"),
    (["--algorithm", "diagram-distance", "--scalars", "all", "--relative-threshold", "2"],
     "--relative-threshold: 2 is outside [0, 1]"),
])
def test_bad_field_lists_and_parameters_are_named(flags, message):
    proc = bench("--mesh", str(SERIES), *flags, check=False)
    assert proc.returncode == 1
    assert message in proc.stderr, proc.stderr


def test_tracking_links_consecutive_members_at_their_optimal_cost(tmp_path):
    fields = ["velocityMag_02", "velocityMag_03", "velocityMag_04"]
    r = run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
                 "tracking", "--structure", "actopo", "--output", str(tmp_path / "t"))
    result = r["result"]
    assert result["fields"] == fields
    assert result["files"] == [str(tmp_path / "t_tracking.vtp")]
    run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
             "persistence-diagram", "--structure", "explicit", "--output", str(tmp_path / "d"))
    diagrams = [diagram_points(tmp_path / f"d_{f}_diagram.vtu") for f in fields]
    # Each step's matching is optimal: its cost is Gudhi's exact Wasserstein-2, type by type.
    for t in range(len(fields) - 1):
        for k in range(3):
            expected = gudhi.wasserstein.wasserstein_distance(
                diagrams[t][k], diagrams[t + 1][k], order=2, internal_p=math.inf)
            assert result["step_wasserstein_by_type"][t][k] == pytest.approx(expected, rel=1e-9)
    lines = pyvista.read(tmp_path / "t_tracking.vtp")
    assert lines.n_cells == result["links"]
    component = lines.cell_data["ConnectedComponentId"]
    assert len(set(component.tolist())) == result["trajectories"]
    assert np.bincount(component).max() + 1 == result["longest"]
    step, scalar = lines.point_data["TimeStep"], lines.point_data["Scalar"]
    cost, length = lines.cell_data["Cost"], lines.cell_data["ComponentLength"]
    ends = lines.lines.reshape(-1, 3)[:, 1:]
    assert (step[ends[:, 1]] == step[ends[:, 0]] + 1).all()
    # A link costs at least the change of its pair's extremum value (an L-infinity cost).
    assert (cost >= np.abs(scalar[ends[:, 1]] - scalar[ends[:, 0]]) - 1e-12).all()
    assert (length == np.bincount(component)[component]).all()
    assert set(np.unique(lines.point_data["CriticalType"]).tolist()) <= {0, 1, 3}


def test_the_matching_behind_an_entry_names_the_pairs_of_both_diagrams(tmp_path):
    fields = ["velocityMag_02", "velocityMag_03", "velocityMag_30"]
    r = run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
                 "diagram-distance", "--matching", "2,0")["result"]
    matching = r["matching"]
    assert matching["fields"] == [2, 0]
    run_json("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
             "persistence-diagram", "--structure", "explicit", "--output", str(tmp_path / "d"))

    def pairs(field):  # PairIdentifier -> (type, birth, death) of the finite pairs
        grid = meshio.read(tmp_path / f"d_{field}_diagram.vtu")
        cells = {name: np.concatenate(values) for name, values in grid.cell_data.items()}
        return {int(i): (int(t), b, b + p) for i, t, b, p, f in zip(
            cells["PairIdentifier"], cells["PairType"], cells["Birth"], cells["Persistence"],
            cells["IsFinite"], strict=True) if i >= 0 and f == 1}

    a, b = pairs(fields[2]), pairs(fields[0])
    assert sorted(i for i in matching["pair_a"] if i >= 0) == sorted(a)
    assert sorted(i for i in matching["pair_b"] if i >= 0) == sorted(b)
    for kind, i, j, cost in zip(matching["type"], matching["pair_a"], matching["pair_b"],
                                matching["cost"], strict=True):
        if i >= 0 and j >= 0:
            assert a[i][0] == b[j][0] == kind
            assert cost == pytest.approx(max(abs(a[i][1] - b[j][1]), abs(a[i][2] - b[j][2])))
        else:
            point = a[i] if i >= 0 else b[j]
            assert cost == pytest.approx((point[2] - point[1]) / 2)
    assert math.sqrt(sum(c * c for c in matching["cost"])) == pytest.approx(
        r["wasserstein"][2][0], rel=1e-9)
    proc = bench("--mesh", str(SERIES), "--scalars", ",".join(fields), "--algorithm",
                 "diagram-distance", "--matching", "0,3", check=False)
    assert proc.returncode == 1 and "--matching: 0,3 is outside the list of 3 fields" in proc.stderr
