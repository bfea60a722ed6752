"""A small tetrahedral lattice made in numpy, and a brute-force relation oracle for it."""

from __future__ import annotations

import itertools
from collections import defaultdict

import numpy as np


def lattice(n: int = 4) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The unit cube as an n^3 lattice, 6 tetrahedra per cell (Freudenthal split), with a
    tie-free scalar field "f" and a float32 field "z"."""
    grid = np.stack(np.meshgrid(*[np.linspace(0, 1, n)] * 3, indexing="ij"), axis=-1)
    points = grid.reshape(-1, 3)

    def index(i: int, j: int, k: int) -> int:
        return (i * n + j) * n + k

    tets = []
    for i, j, k in itertools.product(range(n - 1), repeat=3):
        for order in itertools.permutations(range(3)):
            corner = [i, j, k]
            path = [index(*corner)]
            for axis in order:
                corner[axis] += 1
                path.append(index(*corner))
            tets.append(path)
    x, y, z = points.T
    f = np.sin(5 * x) * np.cos(4 * y) + 0.3 * z + 1e-6 * np.arange(len(points))
    return points, np.array(tets, dtype=np.int64), {"f": f, "z": z.astype(np.float32)}


class Oracle:
    """Relations computed from the tetrahedra with sets."""

    def __init__(self, tets: np.ndarray) -> None:
        self.tets = [tuple(sorted(map(int, t))) for t in tets]
        self.vertex_star: dict[int, list[int]] = defaultdict(list)
        for t, tet in enumerate(self.tets):
            for v in tet:
                self.vertex_star[v].append(t)
        self.edges = sorted({e for t in self.tets for e in itertools.combinations(t, 2)})
        triangles: dict[tuple[int, ...], int] = defaultdict(int)
        for t in self.tets:
            for f in itertools.combinations(t, 3):
                triangles[f] += 1
        self.triangles = sorted(triangles)
        self.boundary_vertices = {v for f, c in triangles.items() if c == 1 for v in f}

    def star(self, simplex: tuple[int, ...]) -> list[int]:
        return [t for t, tet in enumerate(self.tets) if set(simplex) <= set(tet)]

    def neighbors(self, v: int) -> list[int]:
        return sorted({w for t in self.vertex_star[v] for w in self.tets[t]} - {v})

    def tetrahedron_neighbors(self, t: int) -> list[int]:
        return [u for u in range(len(self.tets))
                if u != t and len(set(self.tets[u]) & set(self.tets[t])) == 3]
