#!/usr/bin/env python3
"""What a TTK user runs to compare the persistence diagrams of a time series, as one process:
read the file once, ttkPersistenceDiagram of every point field (DiscreteMorseSandwich, the
standalone's `-B 2`), then ttkPersistenceDiagramDistanceMatrix of the diagrams (Wasserstein-p,
every pair type, the whole diagrams). Upstream TTK's public filters through its Python modules;
for timing beside `actopo-bench --scalars all --algorithm diagram-distance`.

    LD_LIBRARY_PATH=/tmp/ttk/build/lib PYTHONPATH=/tmp/ttk/build/lib/python3/dist-packages \\
        /usr/bin/python3 bench/ttk_series.py [--mesh F.vtu] [--fields all|F1,F2,...] \\
        [--threads 2] [--p 2] [--delta-lim 0.01] [--check-expected expected-ttk-series.json] \\
        [--exact-check] [--ours actopo-bench.json]

Prints one JSON object on stdout: the settings read back from the filter, the fields, the
n x n Wasserstein matrix (row i, column j), the pairs per field and the seconds of each phase
(import, read, diagrams, matrix, total). TTK's own messages and timers go to stderr; from Python
TTK prints none unless asked (its global debug level is 0): --debug-level 3 prints them as the
standalone programs do.

Settings (closest TTK allows to an exact Wasserstein-p over all pair types): WassersteinMetric p,
PairType -1 (all), Constraint 0 (full diagrams; the filter's default 4 keeps only the pairs above
10% of the largest persistence), AntiAlpha 0 (Alpha 1: birth-death plane only), Lambda 1,
DeltaLim as given (TTK's default 0.01); 2 threads for both filters, BackEnd 2 for the diagrams.

TTK's matrix (core/base/persistenceDiagramDistanceMatrix, read at 0a69faad): each diagram is
split into min (pairs with a minimum, but not the min-max pair), saddle-saddle and max (pairs
with a maximum, the infinite min-max pair included as a finite point (min, max)) diagrams; each
pair of diagrams is compared by an auction (PersistenceDiagramAuction) with ground cost
|db|^p + |dd|^p (an L_p ground metric), diagonal cost 2 |(d - b) / 2|^p, stopped when its relative
precision is below DeltaLim; the entry is (sum of the three costs)^(1/p). It is approximate: the
auction's result is within a factor (1 + DeltaLim) of the optimum by its own estimate.

Checks, outside the timed phases (all optional, never when timing):
  --check-expected  TTK's diagram of each field against expected-ttk-series.json (pairs_sha256).
  --exact-check     the exact optimum of TTK's own definition (scipy's linear_sum_assignment on
                    the same split diagrams), and the exact Wasserstein-p with the L-infinity
                    ground metric, the infinite pair left out (what actopo-bench computes);
                    about 6 CPU minutes for the 12 Isabel members.
  --ours FILE       actopo-bench's --json output: its "wasserstein" matrix beside both.
"""

import argparse
import ctypes
import hashlib
import json
import os
import sys
import time

T0 = time.perf_counter()

from topologytoolkit import (  # noqa: E402
    ttkPersistenceDiagram,
    ttkPersistenceDiagramDistanceMatrix,
)
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402
from vtkmodules.vtkCommonDataModel import (  # noqa: E402
    vtkDataObject,
    vtkMultiBlockDataSet,
    vtkUnstructuredGrid,
)
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader  # noqa: E402

T_IMPORT = time.perf_counter() - T0

POINTS = vtkDataObject.FIELD_ASSOCIATION_POINTS
DMS = 2  # PersistenceDiagram::BACKEND::DISCRETE_MORSE_SANDWICH, the standalone's -B 2
FULL_DIAGRAMS = 0  # ttkPersistenceDiagramDistanceMatrix's Constraint: no pair left out
ALL_PAIR_TYPES = -1
# TTK's CriticalType values, as in the diagram's CriticalType point array.
MINIMUM, SADDLE1, SADDLE2, MAXIMUM = 0, 1, 2, 3


class TtkOutputToStderr:
    """TTK and VTK print to the C++ std::cout: send file descriptor 1 to stderr while they run,
    so that stdout holds the JSON alone."""

    def __enter__(self):
        sys.stdout.flush()
        self.saved = os.dup(1)
        os.dup2(2, 1)

    def __exit__(self, *exc):
        ctypes.CDLL(None).fflush(None)
        os.dup2(self.saved, 1)
        os.close(self.saved)


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", default="/work/shared/data/isabel_series_s2_tet.vtu")
    parser.add_argument("--fields", default="all", help="all (every 1-component point field) "
                        "or F1,F2,...")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--p", default="2", help="Wasserstein order (TTK: an integer or inf)")
    parser.add_argument("--delta-lim", type=float, default=0.01,
                        help="the auction's relative precision (TTK's default 0.01)")
    parser.add_argument("--debug-level", type=int, default=None,
                        help="TTK's debug level (default: TTK's own)")
    parser.add_argument("--check-expected", metavar="JSON")
    parser.add_argument("--exact-check", action="store_true")
    parser.add_argument("--ours", metavar="JSON")
    return parser.parse_args()


def configure(algorithm, args):
    algorithm.SetUseAllCores(False)
    algorithm.SetThreadNumber(args.threads)
    if args.debug_level is not None:
        algorithm.SetDebugLevel(args.debug_level)


def read_mesh(path):
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput()


def field_names(mesh, spec):
    data = mesh.GetPointData()
    if spec != "all":
        return spec.split(",")
    names = []
    for i in range(data.GetNumberOfArrays()):
        array = data.GetArray(i)
        if array is not None and array.GetNumberOfComponents() == 1:
            names.append(array.GetName())
    return names


def persistence_diagram(mesh, field, args):
    """TTK's diagram of one field, as a vtkUnstructuredGrid of its own (the filter is freed)."""
    algorithm = ttkPersistenceDiagram()
    configure(algorithm, args)
    algorithm.SetBackEnd(DMS)
    algorithm.SetInputDataObject(0, mesh)
    algorithm.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    algorithm.Update()
    diagram = vtkUnstructuredGrid()
    diagram.ShallowCopy(algorithm.GetOutput())
    return diagram


def distance_matrix(diagrams, args):
    blocks = vtkMultiBlockDataSet()
    blocks.SetNumberOfBlocks(len(diagrams))
    for i, diagram in enumerate(diagrams):
        blocks.SetBlock(i, diagram)
    algorithm = ttkPersistenceDiagramDistanceMatrix()
    configure(algorithm, args)
    algorithm.SetWassersteinMetric(args.p)
    algorithm.SetPairType(ALL_PAIR_TYPES)
    algorithm.SetConstraint(FULL_DIAGRAMS)
    algorithm.SetAntiAlpha(0.0)  # Alpha = 1: the (birth, death) plane only, no geometry
    algorithm.SetLambda(1.0)  # ParaView's default (only used with geometry)
    algorithm.SetDeltaLim(args.delta_lim)
    algorithm.SetInputDataObject(0, blocks)
    algorithm.Update()
    table = algorithm.GetOutputDataObject(0)  # a vtkTable (GetOutput() is for data sets)
    n = len(diagrams)
    # Column j holds entry (i, j) in row i; the columns are named Diagram00, Diagram01, ...
    matrix = [[table.GetColumn(j).GetValue(i) for j in range(n)] for i in range(n)]
    settings = {
        "filter": "ttkPersistenceDiagramDistanceMatrix",
        "WassersteinMetric": algorithm.GetWassersteinMetric(),
        "PairType": algorithm.GetPairType(),
        "Constraint": algorithm.GetConstraint(),
        "Alpha": algorithm.GetAlpha(),
        "Lambda": algorithm.GetLambda(),
        "DeltaLim": algorithm.GetDeltaLim(),
        "threads": args.threads,
        "algorithm": "auction (PersistenceDiagramAuction, kd-tree), per pair type "
                     "(min, saddle-saddle, max), stopped at relative precision < DeltaLim",
        "ground_cost": "|db|^p + |dd|^p; diagonal 2 |(d - b) / 2|^p; the infinite min-max pair "
                       "is a finite point of the max diagram",
    }
    return matrix, settings


def diagram_pairs(diagram):
    """(type, birth vertex, death vertex, finite, birth value, death value, birth critical type,
    death critical type) of every pair of a TTK diagram, the diagonal cell left out."""
    cells = diagram.GetCellData()
    pair_id = vtk_to_numpy(cells.GetArray("PairIdentifier"))
    pair_type = vtk_to_numpy(cells.GetArray("PairType"))
    finite = vtk_to_numpy(cells.GetArray("IsFinite"))
    birth = vtk_to_numpy(cells.GetArray("Birth"))
    persistence = vtk_to_numpy(cells.GetArray("Persistence"))
    vertex = vtk_to_numpy(diagram.GetPointData().GetArray("ttkVertexScalarField"))
    critical = vtk_to_numpy(diagram.GetPointData().GetArray("CriticalType"))
    pairs = []
    for c in range(diagram.GetNumberOfCells()):
        if pair_id[c] < 0:
            continue
        ids = diagram.GetCell(c).GetPointIds()
        b, d = ids.GetId(0), ids.GetId(1)  # the birth's point first, as TTK reads them back
        # The values as TTK reads them back (VTUToDiagram): Birth and Birth + Persistence.
        pairs.append((int(pair_type[c]), int(vertex[b]), int(vertex[d]), int(finite[c]),
                      float(birth[c]), float(birth[c] + persistence[c]), int(critical[b]),
                      int(critical[d])))
    return pairs


def load_json(path):
    with open(path) as f:
        return json.load(f)


def check_expected(path, fields, all_pairs):
    expected = load_json(path)
    expected = next(iter(expected.values())) if len(expected) == 1 else expected
    out = {}
    for field, pairs in zip(fields, all_pairs, strict=True):
        lines = sorted((t, b, d, f) for t, b, d, f, *_ in pairs)
        text = "".join(f"{t} {b} {d} {f}\n" for t, b, d, f in lines)
        digest = hashlib.sha256(text.encode()).hexdigest()
        want = expected.get(field, {}).get("upstream", {}).get("persistence_diagram", {})
        out[field] = {"pairs": len(pairs), "pairs_sha256": digest,
                      "matches_expected": digest == want.get("pairs_sha256")}
    return out


def split_like_ttk(pairs):
    """TTK's three diagrams of one diagram (PersistenceDiagramDistanceMatrix::execute)."""
    split = ([], [], [])
    for *_, birth, death, cb, cd in pairs:
        if death - birth <= 0:
            continue
        point = (birth, death)
        if cb == MINIMUM and cd == MAXIMUM:
            split[2].append(point)
            continue
        if MAXIMUM in (cb, cd):
            split[2].append(point)
        if MINIMUM in (cb, cd):
            split[0].append(point)
        if {cb, cd} == {SADDLE1, SADDLE2}:
            split[1].append(point)
    return split


def split_finite(pairs):
    """The finite pairs by type, the infinite ones left out (actopo's default)."""
    split = ([], [], [])
    for t, _, _, finite, birth, death, *_ in pairs:
        if finite and 0 <= t <= 2:
            split[t].append((birth, death))
    return split


def exact_power_cost(a, b, p, internal):
    """The optimal sum of cost^p matching a and b (lists of (birth, death)), every point to one of
    the other list or to the diagonal; internal 'p' (TTK's cost) or 'inf' (L-infinity)."""
    import numpy as np
    from scipy.optimize import linear_sum_assignment

    n, m = len(a), len(b)
    if n + m == 0:
        return 0.0
    pa = np.array(a, dtype=float).reshape(n, 2)
    pb = np.array(b, dtype=float).reshape(m, 2)
    if internal == "inf":
        pair = np.maximum(np.abs(pa[:, None, 0] - pb[None, :, 0]),
                          np.abs(pa[:, None, 1] - pb[None, :, 1])) ** p
        diag_a = ((pa[:, 1] - pa[:, 0]) / 2) ** p
        diag_b = ((pb[:, 1] - pb[:, 0]) / 2) ** p
    else:
        pair = (np.abs(pa[:, None, 0] - pb[None, :, 0]) ** p
                + np.abs(pa[:, None, 1] - pb[None, :, 1]) ** p)
        diag_a = 2 * ((pa[:, 1] - pa[:, 0]) / 2) ** p
        diag_b = 2 * ((pb[:, 1] - pb[:, 0]) / 2) ** p
    big = 1e6 * (1 + float(pair.max(initial=0)) + float(diag_a.max(initial=0))
                 + float(diag_b.max(initial=0)))
    cost = np.zeros((n + m, m + n))
    cost[:n, :m] = pair
    cost[:n, m:] = big
    cost[:n, m:][np.arange(n), np.arange(n)] = diag_a
    cost[n:, :m] = big
    cost[n:, :m][np.arange(m), np.arange(m)] = diag_b
    rows, cols = linear_sum_assignment(cost)
    return float(cost[rows, cols].sum())


def exact_matrices(all_pairs, p):
    n = len(all_pairs)
    ttk_split = [split_like_ttk(pairs) for pairs in all_pairs]
    finite_split = [split_finite(pairs) for pairs in all_pairs]
    ttk_definition = [[0.0] * n for _ in range(n)]
    linf = [[0.0] * n for _ in range(n)]
    for i in range(n):
        for j in range(i + 1, n):
            w = sum(exact_power_cost(x, y, p, "p")
                    for x, y in zip(ttk_split[i], ttk_split[j], strict=True))
            ttk_definition[i][j] = ttk_definition[j][i] = w ** (1 / p)
            w = sum(exact_power_cost(x, y, p, "inf")
                    for x, y in zip(finite_split[i], finite_split[j], strict=True))
            linf[i][j] = linf[j][i] = w ** (1 / p)
    return ttk_definition, linf


def largest_relative_difference(a, b):
    worst = (0.0, None)
    for i, row in enumerate(a):
        for j, x in enumerate(row):
            y = b[i][j]
            if i != j and max(abs(x), abs(y)) > 0:
                r = abs(x - y) / max(abs(x), abs(y))
                if r > worst[0]:
                    worst = (r, [i, j, x, y])
    return {"relative": worst[0], "at": worst[1]}


def main():
    args = parse_args()
    phases = {"import_s": T_IMPORT}
    with TtkOutputToStderr():
        t = time.perf_counter()
        mesh = read_mesh(args.mesh)
        phases["read_s"] = time.perf_counter() - t
        fields = field_names(mesh, args.fields)

        t = time.perf_counter()
        diagrams, per_field = [], []
        for field in fields:
            t_field = time.perf_counter()
            diagrams.append(persistence_diagram(mesh, field, args))
            per_field.append(time.perf_counter() - t_field)
        phases["diagrams_s"] = time.perf_counter() - t
        phases["diagram_s_per_field"] = per_field

        t = time.perf_counter()
        matrix, settings = distance_matrix(diagrams, args)
        phases["matrix_s"] = time.perf_counter() - t
    phases["total_s"] = time.perf_counter() - T0

    result = {
        "mesh": args.mesh,
        "vertices": mesh.GetNumberOfPoints(),
        "cells": mesh.GetNumberOfCells(),
        "persistence_diagram": {"filter": "ttkPersistenceDiagram", "BackEnd": DMS,
                                "threads": args.threads},
        "distance_matrix": settings,
        "fields": fields,
        "diagram_cells": [d.GetNumberOfCells() for d in diagrams],
        "wasserstein": matrix,
        "seconds": phases,
    }

    if args.check_expected or args.exact_check or args.ours:
        all_pairs = [diagram_pairs(d) for d in diagrams]
        result["pairs"] = [len(pairs) for pairs in all_pairs]
        if args.check_expected:
            result["check_expected"] = check_expected(args.check_expected, fields, all_pairs)
        p = float(args.p)
        if args.exact_check and p == float("inf"):
            raise SystemExit("--exact-check needs a finite --p")
        exact = exact_matrices(all_pairs, p) if args.exact_check else None
        if exact:
            result["exact_ttk_definition"] = exact[0]
            result["exact_linf_finite"] = exact[1]
            result["ttk_vs_exact_ttk_definition"] = largest_relative_difference(matrix, exact[0])
        if args.ours:
            ours = load_json(args.ours)
            ours = ours.get("result", ours)
            if ours.get("fields") != fields:
                raise SystemExit(f"--ours has the fields {ours.get('fields')}, not {fields}")
            result["ours_vs_ttk"] = largest_relative_difference(ours["wasserstein"], matrix)
            if exact:
                result["ours_vs_exact_linf_finite"] = largest_relative_difference(
                    ours["wasserstein"], exact[1])
                result["ours_vs_exact_ttk_definition"] = largest_relative_difference(
                    ours["wasserstein"], exact[0])

    json.dump(result, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
