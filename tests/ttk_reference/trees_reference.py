#!/usr/bin/env python3
"""TTK's references for merge-tree and contour-tree, every output array.

For each case, runs upstream TTK's MergeTree (join and split) and ContourTree filters (FTM) on
the field, and on the field simplified as a ParaView user chains the filters: PersistenceDiagram,
the pairs with Persistence >= t (the diagonal left out) as constraints, TopologicalSimplification
(LTS), then the tree on the simplified field (which carries TTK's "<field>_Order"); t is a
fraction of the field's range. Records per tree the counts, the digests of
../shared/data/README.md ("merge_trees") and the SHA-256 of every tree array's bytes
(little-endian, TTK's types). Writes trees-ttk.json beside this file; tests/trees_fidelity_test.cc
compares our outputs with it, array by array.

    LD_LIBRARY_PATH=/tmp/ttk/build/lib PYTHONPATH=/tmp/ttk/build/lib/python3/dist-packages \\
        /usr/bin/python3 tests/ttk_reference/trees_reference.py /work/shared/data

TTK (commit 0a69faad) built by shared/tools/build-ttk.sh with the extra modules ttkMergeTree
ttkContourTree ttkTopologicalSimplification (its Python wrappers come with it; built with
-march=native, so its spans are FMA sums). Needs Debian's python3-vtk9.
"""
import hashlib
import json
import os
import sys

import numpy as np
import vtk
from topologytoolkit import (
    ttkContourTree,
    ttkMergeTree,
    ttkPersistenceDiagram,
    ttkTopologicalSimplification,
)
from vtk.util.numpy_support import vtk_to_numpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from simplification_reference import constraints_of, read, sha256

CASES = [
    ("manifoldCheck0_tet.vtu", "height"),
    ("fertility_tet.vtu", "eigenfunction4"),
    ("fertility_tet.vtu", "height"),
    ("viscousFingers001_s2_tet.vtu", "density"),
    ("isabel02_s2_tet.vtu", "velocityMag"),
]
# Two components: the file twice, the copy moved by (100, 0, 0) with the field + 1000 and its
# vertex and tetrahedron ids after the original's (no ties across the copies). TTK runs FTM on
# each component on its own; NodeId and SegmentationId go on across them.
TWICE = ("fertility_tet.vtu", "height")
FRACTIONS = [0.01, 0.05]
POINTS = vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS
NODE_ARRAYS = ["NodeId", "Scalar", "VertexId", "CriticalType", "RegionSize", "RegionSpan"]
ARC_POINT_ARRAYS = ["Scalar", "ttkMaskScalarField"]
ARC_CELL_ARRAYS = ["SegmentationId", "upNodeId", "downNodeId", "RegionSize", "RegionSpan"]
SEGMENTATION_ARRAYS = ["SegmentationId", "RegionSize", "RegionSpan", "RegionType"]


def array(data, name):
    a = data.GetArray(name)
    if a is None:
        raise KeyError(name)
    return vtk_to_numpy(a)


def tree_entry(nodes, arcs, segmentation):
    """Counts, README digests and array digests of TTK's three outputs."""
    nd = nodes.GetPointData()
    vertex = array(nd, "VertexId")
    types = array(nd, "CriticalType")
    node_id = array(nd, "NodeId")
    vertex_of = {int(i): int(v) for i, v in zip(node_id, vertex, strict=True)}
    ac = arcs.GetCellData()
    seg_id = array(ac, "SegmentationId")
    # Arcs' ends by vertex: up/downNodeId are relative to their component, whose first NodeId
    # is the smallest NodeId of the cells' points... simplest exact route: the arc's two points
    # carry no ids, so map them by position to nodes.
    node_points = vtk_to_numpy(nodes.GetPoints().GetData())
    by_position = {}
    for k in range(len(node_id)):
        by_position.setdefault(tuple(node_points[k].tolist()), []).append(int(node_id[k]))
    arc_points = vtk_to_numpy(arcs.GetPoints().GetData())
    down_local = array(ac, "downNodeId")
    up_local = array(ac, "upNodeId")
    ends = []
    for c in range(arcs.GetNumberOfCells()):
        ids = arcs.GetCell(c).GetPointIds()
        candidates = [by_position[tuple(arc_points[ids.GetId(k)].tolist())] for k in range(2)]
        assert all(len(x) == 1 for x in candidates), "two nodes at one position"
        a, b = candidates[0][0], candidates[1][0]
        # The cell runs from the lower-valued node; tree sense from the local ids' difference.
        if down_local[c] - up_local[c] == a - b:
            ends.append((vertex_of[a], vertex_of[b]))
        else:
            ends.append((vertex_of[b], vertex_of[a]))
    seg = segmentation.GetPointData()
    vertex_seg = array(seg, "SegmentationId")
    arc_of_id = {int(s): c for c, s in enumerate(seg_id)}
    counts = {}
    for t in types.tolist():
        counts[str(int(t))] = counts.get(str(int(t)), 0) + 1
    entry = {
        "nodes": len(node_id),
        "arcs": int(arcs.GetNumberOfCells()),
        "critical_types": dict(sorted(counts.items())),
        "nodes_sha256": sha256(f"{v} {int(t)}\n" for v, t in
                               sorted(zip(vertex.tolist(), types.tolist(), strict=True))),
        "arcs_sha256": sha256(f"{d} {u}\n" for d, u in sorted(ends)),
        "segmentation_sha256": sha256(
            f"{v} {ends[arc_of_id[int(s)]][0]} {ends[arc_of_id[int(s)]][1]}\n"
            for v, s in enumerate(vertex_seg.tolist())),
        "arrays_sha256": {},
    }
    # The same, order-free: where FTM moves the join tree in as the contour tree (a split tree
    # with at most one leaf), node and arc order are its construction order, which follows its
    # task scheduling; ours is the join tree's sorted one.
    scalar = array(nd, "Scalar")
    size = array(nd, "RegionSize")
    span = array(nd, "RegionSpan")
    entry["node_rows_sha256"] = sha256(sorted(
        f"{int(vertex[k])} {int(types[k])} {int(size[k])} {int(span[k])} {float(scalar[k]):.9g}\n"
        for k in range(len(node_id))))
    arc_size = array(ac, "RegionSize")
    arc_span = array(ac, "RegionSpan")
    entry["arc_rows_sha256"] = sha256(sorted(
        f"{int(seg_id[c])} {ends[c][0]} {ends[c][1]} {int(arc_size[c])} {float(arc_span[c]):.9g}\n"
        for c in range(len(seg_id))))
    arrays = entry["arrays_sha256"]
    for name in NODE_ARRAYS:
        arrays["tree_nodes/" + name] = digest(array(nd, name))
    for name in ARC_POINT_ARRAYS:
        arrays["tree_arcs/" + name] = digest(array(arcs.GetPointData(), name))
    for name in ARC_CELL_ARRAYS:
        arrays["tree_arcs/" + name] = digest(array(ac, name))
    for name in SEGMENTATION_ARRAYS:
        arrays["segmentation/" + name] = digest(array(seg, name))
    return entry


def digest(values):
    return f"{values.dtype.name}:{len(values)}:" + hashlib.sha256(
        np.ascontiguousarray(values).astype(values.dtype.newbyteorder("<")).tobytes()).hexdigest()


def trees_of(mesh, field):
    out = {}
    for name, tree_type in (("join_tree", 0), ("split_tree", 1), ("contour_tree", None)):
        f = ttkContourTree() if tree_type is None else ttkMergeTree()
        if tree_type is not None:
            f.SetTreeType(tree_type)
        f.SetInputDataObject(0, mesh)
        f.SetInputArrayToProcess(0, 0, 0, POINTS, field)
        f.SetThreadNumber(2)
        f.Update()
        out[name] = tree_entry(f.GetOutput(0), f.GetOutput(1), f.GetOutput(2))
    contour, join = out["contour_tree"], out["join_tree"]
    contour["moved_join_tree"] = all(contour[k] == join[k] for k in ("nodes_sha256", "arcs_sha256"))
    return out


def simplified(mesh, field, fraction):
    values = vtk_to_numpy(mesh.GetPointData().GetArray(field)).astype(float)
    pd = ttkPersistenceDiagram()
    pd.SetInputDataObject(0, mesh)
    pd.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    pd.SetThreadNumber(2)
    pd.Update()
    ts = ttkTopologicalSimplification()
    ts.SetInputDataObject(0, mesh)
    threshold = fraction * (values.max() - values.min())
    ts.SetInputDataObject(1, constraints_of(pd.GetOutput(), threshold)[0])
    ts.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    ts.SetThreadNumber(2)
    ts.Update()
    return ts.GetOutput()


def twice(mesh, field):
    copy = vtk.vtkUnstructuredGrid()
    copy.DeepCopy(mesh)
    points = vtk_to_numpy(copy.GetPoints().GetData())
    points[:, 0] += 100
    values = vtk_to_numpy(copy.GetPointData().GetArray(field))
    values += 1000
    copy.Modified()
    append = vtk.vtkAppendFilter()
    append.AddInputData(mesh)
    append.AddInputData(copy)
    append.Update()
    out = append.GetOutput()
    out.GetPointData().SetActiveScalars(field)
    return out


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data"
    results = {}
    for name, field in CASES:
        mesh = read(os.path.join(data, name))
        mesh.GetPointData().SetActiveScalars(field)
        entry = {"trees": trees_of(mesh, field), "simplified": {}}
        for fraction in FRACTIONS:
            simple = simplified(mesh, field, fraction)
            entry["simplified"][f"{fraction:g}"] = trees_of(simple, field)
        results.setdefault(name, {})[field] = entry
        print(f"{name} {field}: " + ", ".join(
            f"{k} {v['nodes']}" for k, v in entry["trees"].items()), file=sys.stderr)
    name, field = TWICE
    mesh = twice(read(os.path.join(data, name)), field)
    results["twice:" + name] = {field: {"trees": trees_of(mesh, field)}}
    target = os.path.join(os.path.dirname(os.path.abspath(__file__)), "trees-ttk.json")
    with open(target, "w") as f:
        json.dump({"ttk_commit": "0a69faadd10224bf136f4f517a93dcd56c67f867",
                   "pipeline": "MergeTree (TreeType 0, 1) and ContourTree on the field, and on "
                               "PersistenceDiagram -> Persistence >= t * range (no diagonal) -> "
                               "TopologicalSimplification (LTS) -> the tree",
                   "arrays_format": "'<dtype>:<count>:<sha256 of the little-endian bytes>'",
                   "results": results}, f, indent=1)
    print(target)


if __name__ == "__main__":
    main()
