"""Run by pvbatch for tests/test_paraview_plugin.py: loads the ACTOPO plugin with
paraview/load_actopo.py, applies each case's filter to its mesh, and writes what every output port
holds: arrays.npz (points, line offsets and connectivity, an unstructured grid's cell types,
offsets and connectivity, point and cell arrays, a table's numeric columns, by
"<case>/<port>/<kind>/<name>") and outputs.json (types, counts, field data, a table's columns
and string columns, the Python modules the plugin ended up using).

    pvbatch tests/paraview_driver.py CASES.json OUT_DIR [PLUGIN_DIR]

CASES.json: {"cases": [{"name", "filter", "mesh", "properties": {...}, "before": [[filter,
{...}], ...]}, ...]}; "before" (optional) are ParaView filters applied to the mesh, in order,
before the case's filter. A filter that fails leaves its outputs empty; the test reads its message
from pvbatch's output.
"""

import json
import runpy
import sys
from pathlib import Path

import numpy as np
from vtkmodules.util import numpy_support

ROOT = Path(__file__).resolve().parent.parent


def field_data(data):
    values = {}
    for i in range(data.GetNumberOfArrays()):
        array = data.GetAbstractArray(i)
        if array.IsA("vtkStringArray"):
            values[array.GetName()] = array.GetValue(0)
        else:
            values[array.GetName()] = numpy_support.vtk_to_numpy(array)[0].item()
    return values


def attribute_arrays(data, prefix, arrays):
    names = []
    for i in range(data.GetNumberOfArrays()):
        array = data.GetArray(i)
        names.append(array.GetName())
        arrays[f"{prefix}/{array.GetName()}"] = numpy_support.vtk_to_numpy(array)
    return names


def plain(value):
    """A property's value as JSON takes it (a vector property as a list)."""
    if isinstance(value, (str, int, float)) or value is None:
        return value
    return [plain(v) for v in value]


def describe_table(table, prefix, arrays):
    """A vtkTable: its columns in order, numeric ones into `arrays` ("<prefix>/row/<name>"),
    string ones in the description."""
    port = {"type": table.GetClassName(), "rows": table.GetNumberOfRows(), "columns": [],
            "strings": {},
            "field_data": field_data(table.GetFieldData())}
    for i in range(table.GetNumberOfColumns()):
        column = table.GetColumn(i)
        port["columns"].append(column.GetName())
        if column.IsA("vtkStringArray"):
            port["strings"][column.GetName()] = [column.GetValue(j)
                                                 for j in range(column.GetNumberOfValues())]
        else:
            arrays[f"{prefix}/row/{column.GetName()}"] = numpy_support.vtk_to_numpy(column)
    return port


def describe(output, prefix, arrays):
    """What one output port holds; its bulk arrays go into `arrays`."""
    if output.IsA("vtkTable"):
        return describe_table(output, prefix, arrays)
    port = {"type": output.GetClassName(), "points": output.GetNumberOfPoints(),
            "cells": output.GetNumberOfCells(), "field_data": field_data(output.GetFieldData())}
    if output.GetPoints() is not None:
        arrays[f"{prefix}/geometry/Points"] = numpy_support.vtk_to_numpy(
            output.GetPoints().GetData())
    port["point_arrays"] = attribute_arrays(output.GetPointData(), f"{prefix}/point", arrays)
    port["cell_arrays"] = attribute_arrays(output.GetCellData(), f"{prefix}/cell", arrays)
    if output.IsA("vtkPolyData"):
        port["verts"] = output.GetNumberOfVerts()
        port["lines"] = output.GetNumberOfLines()
        arrays[f"{prefix}/geometry/LineOffsets"] = numpy_support.vtk_to_numpy(
            output.GetLines().GetOffsetsArray())
        arrays[f"{prefix}/geometry/LineConnectivity"] = numpy_support.vtk_to_numpy(
            output.GetLines().GetConnectivityArray())
    elif output.IsA("vtkUnstructuredGrid") and output.GetNumberOfCells():
        arrays[f"{prefix}/geometry/CellTypes"] = numpy_support.vtk_to_numpy(
            output.GetCellTypesArray())
        arrays[f"{prefix}/geometry/CellOffsets"] = numpy_support.vtk_to_numpy(
            output.GetCells().GetOffsetsArray())
        arrays[f"{prefix}/geometry/Connectivity"] = numpy_support.vtk_to_numpy(
            output.GetCells().GetConnectivityArray())
    return port


def main(cases_path, out_dir, plugin_dir):
    runpy.run_path(str(Path(plugin_dir) / "load_actopo.py"))
    from paraview import simple

    spec = json.loads(Path(cases_path).read_text())
    readers = {}
    report = {"cases": {}}
    arrays = {}
    for case in spec["cases"]:
        mesh = case["mesh"]
        if mesh not in readers:
            readers[mesh] = simple.XMLUnstructuredGridReader(FileName=[mesh])
            readers[mesh].UpdatePipeline()
        upstream = readers[mesh]
        before = []
        for filter_name, properties in case.get("before", []):
            upstream = getattr(simple, filter_name)(Input=upstream, **properties)
            upstream.UpdatePipeline()
            before.append(upstream)
        proxy = getattr(simple, case["filter"])(Input=upstream)
        for name, value in case["properties"].items():
            setattr(proxy, name, value)
        print(f"driver: running {case['name']}", flush=True)
        proxy.UpdatePipeline()
        algorithm = proxy.GetClientSideObject()
        report["cases"][case["name"]] = [
            describe(algorithm.GetOutputDataObject(port), f"{case['name']}/{port}", arrays)
            for port in range(algorithm.GetNumberOfOutputPorts())]
        # What the properties held when the filter ran (the defaults the domains chose).
        report.setdefault("properties", {})[case["name"]] = {
            name: plain(getattr(proxy, name)) for name in case.get("report", [])}
        simple.Delete(proxy)
        for step in reversed(before):
            simple.Delete(step)

    # The modules the plugin ended up with: ParaView's numpy, the client's gRPC stack.
    report["python"] = sys.version.split()[0]
    report["modules"] = {
        name: [getattr(module, "__version__", ""), module.__file__]
        for name in ("numpy", "google.protobuf", "grpc", "actopo")
        if (module := sys.modules.get(name)) is not None}
    report["finished"] = True
    np.savez(Path(out_dir) / "arrays.npz", **arrays)
    (Path(out_dir) / "outputs.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else ROOT / "paraview")
