"""Gudhi's distances between the persistence diagrams of a series, beside ours.

Writes every field's diagram with actopo-bench (persistence-diagram over --scalars all,
--output), computes the n x n Wasserstein-2 (gudhi.wasserstein, internal_p=inf: POT's exact
network simplex) and bottleneck (gudhi.bottleneck_distance, e=0) matrices per pair type and
combined as SEMANTICS.md defines them, times them, and compares them with actopo-bench's
diagram-distance result:

    .venv/bin/python bench/series_gudhi.py --mesh ../shared/data/isabel_series_s2_tet.vtu
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import tempfile
import time
from pathlib import Path

import gudhi
import gudhi.wasserstein
import meshio
import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def diagram(path: Path) -> dict[int, np.ndarray]:
    """Per pair type, the finite pairs of a written diagram as (birth, death) rows."""
    grid = meshio.read(path)
    cells = {name: np.concatenate(values) for name, values in grid.cell_data.items()}
    kind, finite = cells["PairType"], cells["IsFinite"]
    birth, death = cells["Birth"], cells["Birth"] + cells["Persistence"]
    return {k: np.stack([birth[(kind == k) & (finite == 1)], death[(kind == k) & (finite == 1)]],
                        axis=1) for k in range(3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True)
    parser.add_argument("--bench", default=str(ROOT / "build/server/cmd/actopo-bench"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        subprocess.run([args.bench, "--mesh", args.mesh, "--scalars", "all", "--algorithm",
                        "persistence-diagram", "--structure", "explicit", "--output",
                        f"{scratch}/d", "--json"], check=True, capture_output=True)
        ours = json.loads(subprocess.run(
            [args.bench, "--mesh", args.mesh, "--scalars", "all", "--algorithm",
             "diagram-distance", "--json"], check=True, capture_output=True, text=True).stdout)
        fields = ours["result"]["fields"]
        diagrams = [diagram(Path(scratch) / f"d_{f}_diagram.vtu") for f in fields]
    n = len(fields)
    w, b = np.zeros((n, n)), np.zeros((n, n))
    start = time.perf_counter()
    for i in range(n):
        for j in range(i + 1, n):
            w[i, j] = w[j, i] = math.sqrt(sum(
                gudhi.wasserstein.wasserstein_distance(diagrams[i][k], diagrams[j][k], order=2,
                                                       internal_p=math.inf) ** 2
                for k in range(3)))
    wasserstein_s = time.perf_counter() - start
    start = time.perf_counter()
    for i in range(n):
        for j in range(i + 1, n):
            b[i, j] = b[j, i] = max(gudhi.bottleneck_distance(diagrams[i][k], diagrams[j][k], 0)
                                    for k in range(3))
    bottleneck_s = time.perf_counter() - start
    relative = lambda x, y: float(np.max(np.abs(x - y) / np.maximum(x, 1e-300)))  # noqa: E731
    print(json.dumps({
        "fields": n, "gudhi_wasserstein_s": wasserstein_s, "gudhi_bottleneck_s": bottleneck_s,
        "ours_distance_s": ours["times_s"]["distances"], "ours_total_s": ours["times_s"]["total"],
        "max_relative_difference_wasserstein": relative(w, np.array(ours["result"]["wasserstein"])),
        "max_relative_difference_bottleneck": relative(b, np.array(ours["result"]["bottleneck"])),
    }, indent=1))


if __name__ == "__main__":
    main()
