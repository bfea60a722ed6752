#include "server/io/vtk_writer.h"

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataSetAttributes.h>
#include <vtkDoubleArray.h>
#include <vtkErrorCode.h>
#include <vtkFloatArray.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSignedCharArray.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLPolyDataWriter.h>
#include <vtkXMLUnstructuredGridWriter.h>
#include <vtkXMLWriter.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <string_view>
#include <system_error>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "server/core/status_macros.h"
#include "server/io/internal/vtk_bridge.h"

namespace actopo::io {
namespace {

template <typename T>
struct VtkArrayFor;
template <>
struct VtkArrayFor<int32_t> {
  using type = vtkIntArray;
};
template <>
struct VtkArrayFor<int8_t> {
  using type = vtkSignedCharArray;
};
template <>
struct VtkArrayFor<double> {
  using type = vtkDoubleArray;
};
template <>
struct VtkArrayFor<float> {
  using type = vtkFloatArray;
};

template <typename T>
vtkSmartPointer<vtkDataArray> MakeArray(const std::string& name, const std::vector<T>& values,
                                        int components = 1) {
  auto array = vtkSmartPointer<typename VtkArrayFor<T>::type>::New();
  array->SetName(name.c_str());
  array->SetNumberOfComponents(components);
  array->SetNumberOfValues(static_cast<vtkIdType>(values.size()));
  std::copy(values.begin(), values.end(), array->GetPointer(0));
  return array;
}

vtkSmartPointer<vtkDataArray> MakeArray(const NamedArray& array) {
  return std::visit(
      [&](const auto& values) { return MakeArray(array.name, values, array.components); },
      array.values);
}

// A field keeps the type it was loaded with where its values allow: Int32 keeps label fields
// integral in ParaView, Float32 keeps a float32 field's file as small as TTK's and its bytes the
// same. A value outside int32 (the source array was wider) or not a float (the field was
// changed since) falls back to Float64, which loses nothing for values up to 2^53.
vtkSmartPointer<vtkDataArray> MakeArray(const PointField& field) {
  if (!field.is_integer && field.source_bytes == 4 &&
      std::all_of(field.values.begin(), field.values.end(),
                  [](double v) { return double(float(v)) == v; })) {
    auto array = vtkSmartPointer<vtkFloatArray>::New();
    array->SetName(field.name.c_str());
    array->SetNumberOfValues(static_cast<vtkIdType>(field.values.size()));
    std::transform(field.values.begin(), field.values.end(), array->GetPointer(0),
                   [](double v) { return static_cast<float>(v); });
    return array;
  }
  const bool fits_int32 =
      field.is_integer && std::all_of(field.values.begin(), field.values.end(), [](double v) {
        return v >= INT32_MIN && v <= INT32_MAX && v == std::trunc(v);
      });
  if (!fits_int32) return MakeArray(field.name, field.values);
  auto array = vtkSmartPointer<vtkIntArray>::New();
  array->SetName(field.name.c_str());
  array->SetNumberOfValues(static_cast<vtkIdType>(field.values.size()));
  std::transform(field.values.begin(), field.values.end(), array->GetPointer(0),
                 [](double v) { return static_cast<int32_t>(v); });
  return array;
}

// Adds arrays to point or cell data after checking their names and lengths. `names` collects
// the names already used in the same attribute set: VTK would silently replace a duplicate.
absl::Status AddArrays(std::span<const NamedArray> arrays, size_t expected_size, const char* what,
                       std::set<std::string>& names, vtkDataSetAttributes& attributes) {
  for (const NamedArray& array : arrays) {
    if (array.name.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(what, " array: the name is empty"));
    }
    if (!names.insert(array.name).second) {
      return absl::InvalidArgumentError(
          absl::StrCat(what, " array '", array.name, "': the name is used twice"));
    }
    const size_t values = std::visit([](const auto& v) { return v.size(); }, array.values);
    if (array.components < 1 || values % size_t(array.components) != 0) {
      return absl::InvalidArgumentError(absl::StrCat(what, " array '", array.name, "' has ", values,
                                                     " values in tuples of ", array.components));
    }
    if (array.size() != expected_size) {
      return absl::InvalidArgumentError(absl::StrCat(what, " array '", array.name, "' has ",
                                                     array.size(), " values, expected ",
                                                     expected_size));
    }
    attributes.AddArray(MakeArray(array));
  }
  return absl::OkStatus();
}

absl::Status CheckOutputPath(const std::string& path, const std::string& extension,
                             const std::string& other_extension = "") {
  namespace fs = std::filesystem;
  const std::string ext = absl::AsciiStrToLower(fs::path(path).extension().string());
  if (ext != extension && (other_extension.empty() || ext != other_extension)) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": the file name must end in ", extension,
                     other_extension.empty() ? std::string() : " or " + other_extension,
                     " (ParaView picks its reader by it)"));
  }
  std::error_code error;
  fs::path directory = fs::path(path).parent_path();
  if (directory.empty()) directory = ".";
  if (!fs::is_directory(directory, error)) {
    return absl::NotFoundError(
        absl::StrCat(path, ": cannot write, directory '", directory.string(), "' does not exist"));
  }
  if (fs::is_directory(path, error)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": cannot write, it is a directory"));
  }
  return absl::OkStatus();
}

absl::Status Write(vtkXMLWriter& writer, const std::string& path) {
  writer.SetFileName(path.c_str());
  writer.SetDataModeToAppended();
  writer.EncodeAppendedDataOff();  // raw bytes, not base64: smaller and faster
  writer.SetCompressorTypeToZLib();
  // Level 1 writes much faster than VTK's default (5) for files barely larger: float
  // coordinates and fields barely compress at any level.
  writer.SetCompressionLevel(1);
  writer.SetHeaderTypeToUInt64();  // UInt32 block headers cap arrays at 4 GiB
  internal::VtkErrorCollector errors(&writer);
  if (writer.Write() == 1 && !errors.has_error()) return absl::OkStatus();
  const std::string message = absl::StrCat(path, ": cannot write: ", errors.message());
  // After a failed open or write VTK stores errno as the error code; its own codes start at
  // vtkErrorCode::FirstVTKErrorCode.
  const unsigned long code = writer.GetErrorCode();
  if (code == EACCES || code == EPERM || code == EROFS) {
    return absl::PermissionDeniedError(message);
  }
  if (code == ENOSPC || code == EDQUOT || code == vtkErrorCode::OutOfDiskSpaceError) {
    return absl::ResourceExhaustedError(message);
  }
  if (code == vtkErrorCode::CannotOpenFileError ||
      (code != vtkErrorCode::NoError && code < vtkErrorCode::FirstVTKErrorCode)) {
    return absl::InvalidArgumentError(message);  // the path cannot be written
  }
  return absl::InternalError(message);
}

template <typename T>
vtkSmartPointer<vtkCellArray::ArrayType32> MakeIdArray(const std::vector<T>& ids) {
  auto array = vtkSmartPointer<vtkCellArray::ArrayType32>::New();
  array->SetNumberOfValues(static_cast<vtkIdType>(ids.size()));
  std::copy(ids.begin(), ids.end(), array->GetPointer(0));
  return array;
}

vtkSmartPointer<vtkPoints> MakePoints(const std::vector<double>& coordinates) {
  vtkNew<vtkDoubleArray> data;
  data->SetNumberOfComponents(3);
  data->SetNumberOfTuples(static_cast<vtkIdType>(coordinates.size() / 3));
  std::copy(coordinates.begin(), coordinates.end(), data->GetPointer(0));
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetData(data);
  return points;
}

absl::Status ValidateLines(const PolyData& poly) {
  const std::vector<int32_t>& offsets = poly.line_offsets;
  const std::vector<int32_t>& connectivity = poly.line_connectivity;
  if (offsets.empty()) {
    if (connectivity.empty()) return absl::OkStatus();
    return absl::InvalidArgumentError(absl::StrCat("line_offsets: empty but line_connectivity has ",
                                                   connectivity.size(), " ids"));
  }
  if (offsets.front() != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("line_offsets: starts at ", offsets.front(), ", expected 0"));
  }
  for (size_t i = 0; i + 1 < offsets.size(); ++i) {
    if (offsets[i + 1] - offsets[i] < 2) {
      return absl::InvalidArgumentError(absl::StrCat("line_offsets: line ", i, " has ",
                                                     offsets[i + 1] - offsets[i],
                                                     " points; a line needs at least 2"));
    }
  }
  if (static_cast<size_t>(offsets.back()) != connectivity.size()) {
    return absl::InvalidArgumentError(absl::StrCat("line_offsets: ends at ", offsets.back(),
                                                   " but line_connectivity has ",
                                                   connectivity.size(), " ids"));
  }
  const size_t num_points = poly.points.size() / 3;
  for (size_t i = 0; i < connectivity.size(); ++i) {
    if (connectivity[i] < 0 || static_cast<size_t>(connectivity[i]) >= num_points) {
      return absl::InvalidArgumentError(absl::StrCat("line_connectivity: entry ", i, " is ",
                                                     connectivity[i], ", outside [0, ", num_points,
                                                     ")"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status WriteUnstructuredGrid(const std::string& path, const Mesh& mesh,
                                   std::span<const NamedArray> extra_point_arrays) {
  RETURN_IF_ERROR(CheckOutputPath(path, ".vtu"));
  RETURN_IF_ERROR(ValidateMesh(mesh));

  vtkNew<vtkUnstructuredGrid> grid;
  grid->SetPoints(MakePoints(mesh.points));
  std::vector<int32_t> offsets(static_cast<size_t>(mesh.num_tetrahedra()) + 1);
  for (size_t t = 0; t < offsets.size(); ++t) offsets[t] = static_cast<int32_t>(4 * t);
  vtkNew<vtkCellArray> cells;
  cells->SetData(MakeIdArray(offsets), MakeIdArray(mesh.tetrahedra));
  grid->SetCells(VTK_TETRA, cells);

  std::set<std::string> names;
  for (const PointField& field : mesh.point_fields) {
    names.insert(field.name);
    grid->GetPointData()->AddArray(MakeArray(field));
  }
  RETURN_IF_ERROR(
      AddArrays(extra_point_arrays, mesh.points.size() / 3, "point", names, *grid->GetPointData()));

  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  writer->SetInputData(grid);
  return Write(*writer, path);
}

absl::Status WritePolyData(const std::string& path, const PolyData& poly_data) {
  RETURN_IF_ERROR(CheckOutputPath(path, ".vtp", ".vtu"));
  const bool grid =
      absl::AsciiStrToLower(std::filesystem::path(path).extension().string()) == ".vtu";
  if (poly_data.points.size() % 3 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("points: ", poly_data.points.size(), " coordinates is not a multiple of 3"));
  }
  if (poly_data.points.size() / 3 > static_cast<size_t>(INT32_MAX)) {
    return absl::InvalidArgumentError("points: more than 2^31 - 1 points");
  }
  RETURN_IF_ERROR(ValidateLines(poly_data));
  const size_t num_points = poly_data.points.size() / 3;
  const bool has_lines = poly_data.line_offsets.size() > 1;

  vtkNew<vtkPolyData> poly;
  vtkNew<vtkUnstructuredGrid> unstructured;
  vtkDataSet& data_set = grid ? static_cast<vtkDataSet&>(*unstructured) : *poly;
  poly->SetPoints(MakePoints(poly_data.points));
  unstructured->SetPoints(poly->GetPoints());
  vtkNew<vtkCellArray> cells;
  size_t num_cells = 0;
  if (has_lines) {
    num_cells = poly_data.line_offsets.size() - 1;
    cells->SetData(MakeIdArray(poly_data.line_offsets), MakeIdArray(poly_data.line_connectivity));
    poly->SetLines(cells);
    const bool segments = poly_data.line_connectivity.size() == 2 * num_cells;
    unstructured->SetCells(segments ? VTK_LINE : VTK_POLY_LINE, cells);
  } else {
    // ParaView draws no points of a poly data without cells, so each point gets a vertex cell.
    num_cells = num_points;
    std::vector<int32_t> ids(num_points + 1);
    for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int32_t>(i);
    std::vector<int32_t> vertex_ids(ids.begin(), ids.end() - 1);
    cells->SetData(MakeIdArray(ids), MakeIdArray(vertex_ids));
    poly->SetVerts(cells);
    unstructured->SetCells(VTK_VERTEX, cells);
  }

  std::set<std::string> point_names;
  RETURN_IF_ERROR(AddArrays(poly_data.point_arrays, num_points, "point", point_names,
                            *data_set.GetPointData()));
  std::set<std::string> cell_names;
  RETURN_IF_ERROR(AddArrays(poly_data.cell_arrays, num_cells, has_lines ? "line" : "vertex cell",
                            cell_names, *data_set.GetCellData()));

  if (grid) {
    vtkNew<vtkXMLUnstructuredGridWriter> writer;
    writer->SetInputData(unstructured);
    return Write(*writer, path);
  }
  vtkNew<vtkXMLPolyDataWriter> writer;
  writer->SetInputData(poly);
  return Write(*writer, path);
}

}  // namespace actopo::io
