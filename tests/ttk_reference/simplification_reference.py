#!/usr/bin/env python3
"""TTK's references for topological-simplification and the simplified Morse-Smale complex.

Runs upstream TTK's public filters as a ParaView user chains them: PersistenceDiagram (its
default backend), the pairs with Persistence >= t (the diagonal left out) as constraints,
TopologicalSimplification (its default backend, LTS, no perturbation), then MorseSmaleComplex
(its defaults) on the simplified field, which carries TTK's "<field>_Order" array. t is a
fraction of the field's range. Writes simplification-ttk.json beside this file; the fidelity
test tests/simplification_fidelity_test.cc compares our results with it.

    LD_LIBRARY_PATH=/tmp/ttk/build/lib PYTHONPATH=/tmp/ttk/build/lib/python3/dist-packages \\
        /usr/bin/python3 tests/ttk_reference/simplification_reference.py /work/shared/data

TTK (commit 0a69faad) built by shared/tools/build-ttk.sh with the extra modules
ttkTopologicalSimplification ttkPersistenceDiagram ttkMorseSmaleComplex (its Python wrappers
come with it). Needs Debian's python3-vtk9.
"""
import hashlib
import json
import os
import sys

import vtk
from topologytoolkit import (
    ttkMorseSmaleComplex,
    ttkPersistenceDiagram,
    ttkTopologicalSimplification,
)
from vtk.util.numpy_support import vtk_to_numpy

CASES = [
    ("manifoldCheck0_tet.vtu", "height"),
    ("fertility_tet.vtu", "eigenfunction4"),
    ("fertility_tet.vtu", "height"),
    ("viscousFingers001_s2_tet.vtu", "density"),
    ("isabel02_s2_tet.vtu", "velocityMag"),
]
FRACTIONS = [0.01, 0.05]
# TTK's legacy backend (UseLTS off), on the smaller meshes: it sweeps the whole mesh per iteration.
LEGACY_CASES = [
    ("manifoldCheck0_tet.vtu", "height"),
    ("fertility_tet.vtu", "eigenfunction4"),
    ("fertility_tet.vtu", "height"),
    ("viscousFingers001_s2_tet.vtu", "density"),
]
POINTS = vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS


def sha256(lines):
    return hashlib.sha256("".join(lines).encode()).hexdigest()


def read(path):
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput()


def diagram_of(mesh, field):
    pd = ttkPersistenceDiagram()
    pd.SetInputDataObject(0, mesh)
    pd.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    pd.SetThreadNumber(2)
    pd.Update()
    return pd.GetOutput()


def constraints_of(diagram, threshold):
    """The kept pairs' two vertices each, as points with ttkVertexScalarField."""
    cells = diagram.GetCellData()
    pair_id = vtk_to_numpy(cells.GetArray("PairIdentifier"))
    persistence = vtk_to_numpy(cells.GetArray("Persistence"))
    vertex = diagram.GetPointData().GetArray("ttkVertexScalarField")
    ids = vertex.NewInstance()
    ids.SetName("ttkVertexScalarField")
    points = vtk.vtkPoints()
    kept = 0
    for c in range(diagram.GetNumberOfCells()):
        if pair_id[c] < 0 or persistence[c] < threshold:
            continue
        kept += 1
        cell_points = diagram.GetCell(c).GetPointIds()
        for k in range(2):
            points.InsertNextPoint(0, 0, 0)
            ids.InsertNextTuple1(vertex.GetTuple1(cell_points.GetId(k)))
    out = vtk.vtkPolyData()
    out.SetPoints(points)
    out.GetPointData().AddArray(ids)
    return out, kept


def morse_smale(mesh, field):
    ms = ttkMorseSmaleComplex()
    ms.SetInputDataObject(0, mesh)
    ms.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    ms.SetThreadNumber(2)
    ms.Update()
    points = ms.GetOutput(0)
    dims = vtk_to_numpy(points.GetPointData().GetArray("CellDimension"))
    seps = ms.GetOutput(1)
    sep_id = vtk_to_numpy(seps.GetCellData().GetArray("SeparatrixId"))
    sep_type = vtk_to_numpy(seps.GetCellData().GetArray("SeparatrixType"))
    by_type = {t: len({int(i) for i, tt in zip(sep_id, sep_type, strict=True) if tt == t})
               for t in (0, 1, 2)}
    seg = ms.GetOutput(3).GetPointData()
    result = {
        "critical_cells": [int((dims == d).sum()) for d in range(4)],
        "separatrices": {"descending": by_type[0], "ascending": by_type[2],
                         "saddle_connectors": by_type[1], "segments": int(seps.GetNumberOfCells())},
        "regions": {}, "segmentation_sha256": {}}
    for key, name in (("descending", "DescendingManifold"), ("ascending", "AscendingManifold"),
                      ("morse_smale", "MorseSmaleManifold")):
        labels = vtk_to_numpy(seg.GetArray(name))
        result["regions"][key] = len(set(labels.tolist()))
        result["segmentation_sha256"][key] = sha256(
            f"{v} {int(label)}\n" for v, label in enumerate(labels))
    return result


def case(path, field, legacy=False):
    mesh = read(path)
    mesh.GetPointData().SetActiveScalars(field)
    values = vtk_to_numpy(mesh.GetPointData().GetArray(field)).astype(float)
    diagram = diagram_of(mesh, field)
    out = {}
    for fraction in FRACTIONS:
        threshold = fraction * (values.max() - values.min())
        constraints, kept = constraints_of(diagram, threshold)
        ts = ttkTopologicalSimplification()
        ts.SetInputDataObject(0, mesh)
        ts.SetInputDataObject(1, constraints)
        ts.SetInputArrayToProcess(0, 0, 0, POINTS, field)
        ts.SetUseLTS(not legacy)
        ts.SetThreadNumber(2)
        ts.Update()
        simplified = ts.GetOutput()
        new_values = vtk_to_numpy(simplified.GetPointData().GetArray(field)).astype(float)
        order = vtk_to_numpy(simplified.GetPointData().GetArray(field + "_Order"))
        changed = [int(v) for v in (new_values != values).nonzero()[0]]
        entry = {
            "threshold": threshold,
            "kept_pairs": kept,
            "changed_values": len(changed),
            "scalars_sha256": sha256(f"{v} {x:.17g}\n" for v, x in enumerate(new_values.tolist())),
            "order_sha256": sha256(f"{v} {int(o)}\n" for v, o in enumerate(order)),
            "morse_smale": morse_smale(simplified, field),
        }
        if len(changed) <= 200:  # small edits in full, for a readable diff
            entry["changes"] = [[v, new_values[v]] for v in changed]
        out[f"{fraction:g}"] = entry
        print(f"{os.path.basename(path)} {field} t={fraction:g}: {kept} pairs kept, "
              f"{len(changed)} values changed", file=sys.stderr)
    return out


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data"
    results, legacy = {}, {}
    for name, field in CASES:
        results.setdefault(name, {})[field] = case(os.path.join(data, name), field)
    for name, field in LEGACY_CASES:
        legacy.setdefault(name, {})[field] = case(os.path.join(data, name), field, legacy=True)
    target = os.path.join(os.path.dirname(os.path.abspath(__file__)), "simplification-ttk.json")
    with open(target, "w") as f:
        json.dump({"ttk_commit": "0a69faadd10224bf136f4f517a93dcd56c67f867",
                   "pipeline": "PersistenceDiagram -> Persistence >= t * range (no diagonal) -> "
                               "TopologicalSimplification (LTS) -> MorseSmaleComplex",
                   "value_format": "one line '<vertex id> <float64 value as %.17g>' per vertex",
                   "results": results, "legacy_results": legacy}, f, indent=1)
    print(target)


if __name__ == "__main__":
    main()
