#!/usr/bin/env python3
"""What a TTK user runs for a simplified Morse-Smale complex, as one process: read the file,
PersistenceDiagram, keep the pairs with Persistence >= t * range (the diagonal left out),
TopologicalSimplification with their vertices as constraints (LTS), MorseSmaleComplex on the
result. Upstream TTK's public filters, its defaults; for timing beside actopo-bench
(bench/versus_ttk.py), not for results (tests/ttk_reference/ has the references).

    LD_LIBRARY_PATH=/tmp/ttk/build/lib PYTHONPATH=/tmp/ttk/build/lib/python3/dist-packages \\
        /usr/bin/python3 bench/ttk_chain.py wavelet128.vtu RTData 0.01 [threads]
"""
import sys

from topologytoolkit import (
    ttkMorseSmaleComplex,
    ttkPersistenceDiagram,
    ttkTopologicalSimplification,
)
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkPolyData
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

# Only the VTK modules used: `import vtk` would load all of them, 0.2 s and 90 MB more.
POINTS = vtkDataObject.FIELD_ASSOCIATION_POINTS


def main():
    path, field, fraction = sys.argv[1], sys.argv[2], float(sys.argv[3])
    threads = int(sys.argv[4]) if len(sys.argv) > 4 else 2
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    mesh = reader.GetOutput()
    values = vtk_to_numpy(mesh.GetPointData().GetArray(field))
    threshold = fraction * float(values.max() - values.min())

    diagram = ttkPersistenceDiagram()
    diagram.SetInputDataObject(0, mesh)
    diagram.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    diagram.SetThreadNumber(threads)
    diagram.Update()
    pairs = diagram.GetOutput()

    pair_id = vtk_to_numpy(pairs.GetCellData().GetArray("PairIdentifier"))
    persistence = vtk_to_numpy(pairs.GetCellData().GetArray("Persistence"))
    vertex = pairs.GetPointData().GetArray("ttkVertexScalarField")
    ids = vertex.NewInstance()
    ids.SetName("ttkVertexScalarField")
    points = vtkPoints()
    for c in range(pairs.GetNumberOfCells()):
        if pair_id[c] >= 0 and persistence[c] >= threshold:
            cell = pairs.GetCell(c).GetPointIds()
            for k in range(2):
                points.InsertNextPoint(0, 0, 0)
                ids.InsertNextTuple1(vertex.GetTuple1(cell.GetId(k)))
    constraints = vtkPolyData()
    constraints.SetPoints(points)
    constraints.GetPointData().AddArray(ids)

    simplification = ttkTopologicalSimplification()
    simplification.SetInputDataObject(0, mesh)
    simplification.SetInputDataObject(1, constraints)
    simplification.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    simplification.SetThreadNumber(threads)

    complex_ = ttkMorseSmaleComplex()
    complex_.SetInputConnection(simplification.GetOutputPort())
    complex_.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    complex_.SetThreadNumber(threads)
    complex_.Update()
    separatrices = complex_.GetOutput(1).GetNumberOfCells()
    print(f"{points.GetNumberOfPoints() // 2} pairs kept, {separatrices} separatrix segments")


if __name__ == "__main__":
    main()
