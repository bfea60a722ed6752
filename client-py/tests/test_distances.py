"""diagram-distance through the client, on the 12 members of the Isabel series
(isabel_series_s2_tet.vtu, loaded from the server's data directory): the matrix is symmetric
with a zero diagonal, equals actopo-bench's, and its average-linkage groups are ttk-data's three
clusters (series.json); each member's diagram is upstream TTK's; the parameters, their
rejections and the progress phases."""

from __future__ import annotations

import json

import numpy as np
import pytest

import actopo
import actopo._progress

SERIES = "isabel_series_s2_tet.vtu"
SOME = ["velocityMag_02", "velocityMag_05", "velocityMag_31", "velocityMag_47"]


@pytest.fixture(scope="module")
def series(data_dir):
    return json.loads((data_dir / "series.json").read_text())


@pytest.fixture(scope="module")
def isabel(client):
    mesh = client.load_mesh(SERIES)
    yield mesh
    client.delete_mesh(mesh)


@pytest.fixture(scope="module")
def expected_diagrams(data_dir):
    expected = json.loads((data_dir / "expected-ttk-series.json").read_text())
    return {name: entry["upstream"]["persistence_diagram"]
            for name, entry in expected[SERIES].items()}


def test_the_matrix_of_the_series_is_actopo_benchs(client, isabel, bench, data_dir, series):
    with client.open_session(isabel, structure="compact") as session:
        matrix = session.distance_matrix()
    expected = bench(data_dir / SERIES, "diagram-distance", "--scalars", "all")
    assert matrix.fields == expected["fields"] == list(series["fields"])
    assert len(matrix) == 12 and matrix.p == 2.0 and not matrix.essential
    for values, key in ((matrix.wasserstein, "wasserstein"), (matrix.bottleneck, "bottleneck")):
        assert values.dtype == np.float64 and values.shape == (12, 12)
        np.testing.assert_array_equal(values, values.T)
        assert (np.diag(values) == 0).all() and (values[~np.eye(12, dtype=bool)] > 0).all()
        np.testing.assert_allclose(values, expected[key], rtol=0, atol=1e-12, err_msg=key)
    assert (matrix.bottleneck <= matrix.wasserstein).all()
    assert matrix.pairs == expected["pairs"] and matrix.thresholds == expected["thresholds"]
    clusters = [series["fields"][name]["cluster"] for name in matrix.fields]
    assert matrix.groups(3).tolist() == clusters == [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2]


def test_parameters_and_each_fields_diagram(client, isabel, bench, data_dir,
                                            expected_diagrams):
    """p, a relative threshold and the essential pairs, as actopo-bench takes them; each
    field's result is its persistence diagram, upstream TTK's, and with its arrays."""
    with client.open_session(isabel, structure="actopo") as session:
        result = session.run("diagram-distance", fields=SOME, digests=True, parameters={
            "p": "1", "relative_threshold": "0.01", "essential": "true"})
    expected = bench(data_dir / SERIES, "diagram-distance", "--scalars", ",".join(SOME), "--p",
                     "1", "--relative-threshold", "0.01", "--essential")
    matrix = result.distance_matrix
    assert matrix is not None and matrix.fields == SOME and matrix.p == 1.0 and matrix.essential
    np.testing.assert_allclose(matrix.wasserstein, expected["wasserstein"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(matrix.bottleneck, expected["bottleneck"], rtol=0, atol=1e-12)
    assert set(result.summary) == {"fields", "p", "essential", "wasserstein", "bottleneck",
                                   "pairs", "thresholds", "distance_seconds"}
    assert matrix.pairs == expected["pairs"] and matrix.thresholds == expected["thresholds"]
    ranges = {f.name: f.max - f.min for f in isabel.fields}
    for name, threshold in zip(SOME, matrix.thresholds, strict=True):  # 1% of each range
        assert threshold == pytest.approx(0.01 * ranges[name], rel=1e-12)
    assert [(r.field, r.index) for r in result.fields] == [(n, i) for i, n in enumerate(SOME)]
    for field in result.fields:
        ttk = expected_diagrams[field.field]
        assert field.algorithm == "diagram-distance" and field.distance_matrix is None
        assert (field.summary["pairs_sha256"], field.summary["counts_by_type"],
                field.summary["pairs"]) == (ttk["pairs_sha256"], ttk["counts_by_type"],
                                            ttk["pairs"])
        assert field.diagram is not None and field.diagram.pairs_sha256() == ttk["pairs_sha256"]


def test_a_second_structure_and_field_order_give_the_same_distances(client, isabel):
    reverse = SOME[::-1]
    with client.open_session(isabel, structure="explicit") as session:
        forward = session.distance_matrix(SOME, p=1.5, persistence_threshold=0.5)
        backward = session.distance_matrix(reverse, p=1.5, persistence_threshold=0.5)
    assert backward.fields == reverse and forward.thresholds == [0.5] * 4
    # The same matchings; the sums of their costs may be made in another order.
    np.testing.assert_allclose(backward.wasserstein, forward.wasserstein[::-1, ::-1],
                               rtol=1e-12, atol=0)
    np.testing.assert_array_equal(backward.bottleneck, forward.bottleneck[::-1, ::-1])


def test_bad_distance_jobs_are_rejected_naming_the_parameter(client, isabel):
    with client.open_session(isabel, structure="compact") as session:
        with pytest.raises(actopo.InvalidArgumentError, match="persistence_threshold or "
                           "relative_threshold, not both"):
            session.distance_matrix(SOME[:2], persistence_threshold=1, relative_threshold=0.1)
        with pytest.raises(actopo.InvalidArgumentError, match=r"parameters\.p: .*0\.5"):
            session.distance_matrix(SOME[:2], p=0.5)
        with pytest.raises(actopo.InvalidArgumentError, match=r"parameters\.essential"):
            session.run("diagram-distance", fields=SOME[:2], parameters={"essential": "maybe"})
        with pytest.raises(actopo.InvalidArgumentError) as e:
            session.distance_matrix(SOME[:1])
        assert "2" in e.value.details or "two" in e.value.details
        with pytest.raises(actopo.InvalidArgumentError):  # and not on the session's field alone
            session.run("diagram-distance")
        assert session.describe().running_job_id is None


def test_progress_of_the_diagrams_then_of_the_distances(client, isabel, monkeypatch):
    """A bar for the diagrams' run over the whole list, then one for the distances (a "faces"
    bar first when this is the mesh's first job on its faces); a callable gets the run's
    fractions only, up to 1. (They go back within each field's persistence diagram, as a
    persistence-diagram job's own do: reported, not checked here.)"""
    bars: list[str] = []

    class Recorder:
        def __init__(self, description: str) -> None:
            bars.append(description)

        def update(self, fraction: float) -> None:
            pass

        def close(self) -> None:
            pass

    monkeypatch.setattr(actopo._progress, "_bar", Recorder)
    fractions: list[float] = []
    with client.open_session(isabel, structure="compact") as session:
        session.distance_matrix(SOME[:3], progress=True)
        session.distance_matrix(SOME[:3], progress=fractions.append)
    assert [b for b in bars if "edges and triangles" not in b] == [
        "diagram-distance", "diagram-distance (distances)"]
    assert fractions and fractions[-1] == pytest.approx(1.0) and max(fractions) <= 1.0


def test_tracking_over_fields_comes_whole(client, isabel, expected_diagrams):
    """tracking, the other algorithm over several fields: TTK's tracking output as the job's
    `tracking` group, the links' costs beside the summary's counts, each field's diagram
    upstream TTK's."""
    steps = SOME[:2]
    with client.open_session(isabel, structure="compact") as session:
        result = session.run("tracking", fields=steps, parameters={"relative_threshold": "0.05"})
        with pytest.raises(actopo.InvalidArgumentError, match="at least two fields"):
            session.run("tracking", fields=steps[:1])
    tracking = result.group("tracking")
    assert result.groups == ["tracking"] and result.summary["fields"] == steps
    assert len(tracking["Cost"]) == result.summary["links"] == len(tracking["Offsets"]) - 1
    assert set(tracking["TimeStep"].tolist()) <= {0, 1}
    for field in result.fields:
        assert field.diagram.pairs_sha256() == \
            expected_diagrams[field.field]["pairs_sha256"]


def test_trajectories_as_arrays_polydata_and_a_plot(client, isabel, tmp_path):
    """result.tracking: the trajectories as numpy arrays, consistent with the summary; a
    pyvista PolyData with TTK's names; a plot of the trajectories over time."""
    steps = SOME[:3]
    with client.open_session(isabel, structure="actopo") as session:
        result = session.run("tracking", fields=steps)
        assert session.run("diagram-distance", fields=steps[:2]).tracking is None
    tracks = result.tracking
    assert tracks is not None and tracks.fields == steps and tracks.p == 2.0
    assert len(tracks) == result.summary["trajectories"]
    assert len(tracks.lines) == len(tracks.cost) == result.summary["links"]
    np.testing.assert_allclose(tracks.step_wasserstein, result.summary["step_wasserstein"])
    # A link joins consecutive steps, at least the change of the extremum's value apart.
    first, second = tracks.lines[:, 0], tracks.lines[:, 1]
    assert (tracks.time_step[second] == tracks.time_step[first] + 1).all()
    assert (tracks.cost >= np.abs(tracks.scalar[second] - tracks.scalar[first]) - 1e-12).all()
    longest = int(np.argmax(tracks.component_length))
    path = tracks.trajectory(int(tracks.component[longest]))
    assert len(path) == tracks.component_length[longest] + 1
    assert tracks.time_step[path].tolist() == list(range(tracks.time_step[path][0],
                                                         tracks.time_step[path][0] + len(path)))
    poly = tracks.to_pyvista()
    assert poly.n_cells == len(tracks.lines) and poly.n_points == len(tracks.points)
    assert set(poly.point_data.keys()) == {"TimeStep", "CriticalType", "Scalar", "VertexId"}
    assert set(poly.cell_data.keys()) == {"ConnectedComponentId", "MatchingIdentifier", "Cost",
                                          "ComponentLength"}
    written = tracks.plot(tmp_path / "tracks.png", min_length=2)
    assert (tmp_path / "tracks.png").stat().st_size > 10_000 and written.endswith("tracks.png")
