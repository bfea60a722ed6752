#!/usr/bin/env python3
"""What a TTK user runs for a discrete gradient and its critical cells, as one process: read the
file, then TTK's MorseSmaleComplex filter with every separatrix and segmentation turned off, so
it computes the gradient and outputs the critical cells only (TTK has no standalone program for
the gradient). Upstream TTK's public filter, its other defaults; for timing beside
actopo-bench --algorithm discrete-gradient (bench/versus_ttk.py), not for results.

    LD_LIBRARY_PATH=/tmp/ttk/build/lib PYTHONPATH=/tmp/ttk/build/lib/python3/dist-packages \\
        /usr/bin/python3 bench/ttk_gradient.py wavelet128.vtu RTData [threads]
"""
import sys

from topologytoolkit import ttkMorseSmaleComplex
from vtkmodules.vtkCommonDataModel import vtkDataObject
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

POINTS = vtkDataObject.FIELD_ASSOCIATION_POINTS


def main():
    path, field = sys.argv[1], sys.argv[2]
    threads = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)

    gradient = ttkMorseSmaleComplex()
    gradient.SetInputConnection(reader.GetOutputPort())
    gradient.SetInputArrayToProcess(0, 0, 0, POINTS, field)
    gradient.SetThreadNumber(threads)
    gradient.SetComputeCriticalPoints(True)
    for off in ("AscendingSeparatrices1", "DescendingSeparatrices1", "SaddleConnectors",
                "AscendingSeparatrices2", "DescendingSeparatrices2", "AscendingSegmentation",
                "DescendingSegmentation", "FinalSegmentation"):
        getattr(gradient, f"SetCompute{off}")(False)
    gradient.Update()
    dimensions = gradient.GetOutput(0).GetPointData().GetArray("CellDimension")
    counts = [0, 0, 0, 0]
    for i in range(dimensions.GetNumberOfTuples()):
        counts[int(dimensions.GetTuple1(i))] += 1
    print(f"critical cells by dimension: {counts}")


if __name__ == "__main__":
    main()
