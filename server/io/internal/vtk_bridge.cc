#include "server/io/internal/vtk_bridge.h"

#include <vtkAlgorithm.h>
#include <vtkArrayDispatch.h>
#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkDataArrayRange.h>
#include <vtkExecutive.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkType.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLReader.h>

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/core/status_macros.h"
#include "server/io/cell_types.h"

namespace actopo::io::internal {
namespace {

std::string_view TrimWhitespace(std::string_view text) {
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  return text.substr(first, text.find_last_not_of(" \t\r\n") + 1 - first);
}

// VTK formats an event text as "ERROR: In <source file>, line <n>\n<Class> (<address>): <text>".
// Only <text> means something to the caller.
std::string CleanVtkMessage(std::string_view text) {
  if (text.starts_with("ERROR: In ") || text.starts_with("Warning: In ")) {
    const size_t newline = text.find('\n');
    text = newline == std::string_view::npos ? std::string_view() : text.substr(newline + 1);
  }
  const size_t address = text.find(" (0x");
  const size_t colon = text.find("): ");
  if (address != std::string_view::npos && colon != std::string_view::npos && address < colon &&
      text.substr(0, address).find(' ') == std::string_view::npos) {
    text = text.substr(colon + 3);
  }
  return std::string(TrimWhitespace(text));
}

class CollectingCommand : public vtkCommand {
 public:
  static CollectingCommand* New() { return new CollectingCommand; }

  void Execute(vtkObject*, unsigned long event, void* call_data) override {
    // Warnings are swallowed: they would only clutter the server's log, and a read that really
    // failed also raises an error.
    if (event != vtkCommand::ErrorEvent) return;
    std::string text = CleanVtkMessage(call_data ? static_cast<const char*>(call_data) : "");
    // Probing a file (e.g. the legacy reader's IsFile* checks) can repeat the same complaint.
    if (std::find(errors.begin(), errors.end(), text) == errors.end()) {
      errors.push_back(std::move(text));
    }
  }

  std::vector<std::string> errors;
};

// Attaches one command to an object for the error and warning events; detaches on destruction.
struct Observation {
  vtkSmartPointer<vtkObject> subject;
  vtkSmartPointer<CollectingCommand> command = vtkSmartPointer<CollectingCommand>::New();
  unsigned long error_tag = 0;
  unsigned long warning_tag = 0;

  explicit Observation(vtkObject* object) : subject(object) {
    if (subject == nullptr) return;
    error_tag = subject->AddObserver(vtkCommand::ErrorEvent, command);
    warning_tag = subject->AddObserver(vtkCommand::WarningEvent, command);
  }
  ~Observation() {
    if (subject == nullptr) return;
    subject->RemoveObserver(error_tag);
    subject->RemoveObserver(warning_tag);
  }
};

// Converts any numeric array to double. The dispatch covers VTK's usual array layouts with
// direct, devirtualized access; anything else (e.g. vtkBitArray) takes the per-value path.
struct CopyToDoubleWorker {
  double* out;
  template <typename ArrayT>
  void operator()(ArrayT* array) {
    const auto values = vtk::DataArrayValueRange(array);
    std::copy(values.begin(), values.end(), out);
  }
};

void CopyToDouble(vtkDataArray& array, double* out) {
  CopyToDoubleWorker worker{out};
  if (vtkArrayDispatch::Dispatch::Execute(&array, worker)) return;
  const int components = array.GetNumberOfComponents();
  const vtkIdType tuples = array.GetNumberOfTuples();
  for (vtkIdType t = 0; t < tuples; ++t) {
    for (int c = 0; c < components; ++c) out[t * components + c] = array.GetComponent(t, c);
  }
}

bool IsIntegerType(int vtk_data_type) {
  return vtk_data_type != VTK_FLOAT && vtk_data_type != VTK_DOUBLE;
}

template <typename Id>
absl::Status CopyTetrahedra(const Id* offsets, const Id* connectivity, vtkIdType num_cells,
                            vtkIdType num_points, std::vector<SimplexId>& tetrahedra) {
  // All cells are VTK_TETRA here, yet a hand-made file can still give one the wrong point count.
  for (vtkIdType c = 0; c <= num_cells; ++c) {
    if (offsets[c] != static_cast<Id>(4 * c)) {
      const vtkIdType bad = c == 0 ? 0 : c - 1;
      return absl::InvalidArgumentError(absl::StrCat("cells: tetrahedron ", bad, " has ",
                                                     offsets[bad + 1] - offsets[bad],
                                                     " points instead of 4"));
    }
  }
  tetrahedra.resize(4 * static_cast<size_t>(num_cells));
  for (size_t i = 0; i < tetrahedra.size(); ++i) {
    const Id id = connectivity[i];
    // Checking the range before narrowing also rejects ids that do not fit in int32.
    if (id < 0 || id >= static_cast<Id>(num_points)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "cells: tetrahedron ", i / 4, " has vertex id ", id, " outside [0, ", num_points, ")"));
    }
    tetrahedra[i] = static_cast<SimplexId>(id);
  }
  return absl::OkStatus();
}

absl::Status CopyPoints(vtkUnstructuredGrid& grid, std::vector<double>& points) {
  vtkPoints* vtk_points = grid.GetPoints();
  const vtkIdType num_points = vtk_points == nullptr ? 0 : vtk_points->GetNumberOfPoints();
  if (num_points > INT32_MAX) {
    return absl::InvalidArgumentError(
        absl::StrCat("points: ", num_points, " vertices is more than 2^31 - 1"));
  }
  points.resize(3 * static_cast<size_t>(num_points));
  if (num_points > 0) CopyToDouble(*vtk_points->GetData(), points.data());
  return absl::OkStatus();
}

absl::Status CopyCells(vtkUnstructuredGrid& grid, std::vector<SimplexId>& tetrahedra) {
  const vtkIdType num_cells = grid.GetNumberOfCells();
  if (num_cells == 0) return absl::OkStatus();  // ValidateMesh names the empty mesh
  if (num_cells > INT32_MAX) {
    return absl::InvalidArgumentError(
        absl::StrCat("cells: ", num_cells, " cells is more than 2^31 - 1"));
  }
  vtkUnsignedCharArray* types = grid.GetCellTypesArray();
  if (types == nullptr || types->GetNumberOfValues() != num_cells) {
    return absl::InvalidArgumentError("cells: the cell types array is missing or incomplete");
  }
  RETURN_IF_ERROR(ValidateCellTypes(
      std::span<const uint8_t>(types->GetPointer(0), static_cast<size_t>(num_cells))));

  vtkCellArray* cells = grid.GetCells();
  const vtkIdType num_points = grid.GetNumberOfPoints();
  if (cells->IsStorage64Bit()) {
    return CopyTetrahedra(cells->GetOffsetsArray64()->GetPointer(0),
                          cells->GetConnectivityArray64()->GetPointer(0), num_cells, num_points,
                          tetrahedra);
  }
  return CopyTetrahedra(cells->GetOffsetsArray32()->GetPointer(0),
                        cells->GetConnectivityArray32()->GetPointer(0), num_cells, num_points,
                        tetrahedra);
}

void CopyPointFields(vtkUnstructuredGrid& grid, std::vector<PointField>& fields) {
  vtkPointData* point_data = grid.GetPointData();
  const vtkIdType num_points = grid.GetNumberOfPoints();
  for (int i = 0; i < point_data->GetNumberOfArrays(); ++i) {
    // Vectors, tensors and string arrays are not scalar fields; they are skipped, not refused,
    // because real files often carry them next to the scalar of interest.
    vtkDataArray* array = vtkDataArray::SafeDownCast(point_data->GetAbstractArray(i));
    if (array == nullptr || array->GetNumberOfComponents() != 1 ||
        array->GetNumberOfTuples() != num_points) {
      continue;
    }
    PointField field;
    field.name = array->GetName() != nullptr ? array->GetName() : absl::StrCat("array", i);
    field.is_integer = IsIntegerType(array->GetDataType());
    field.source_bytes = int8_t(array->GetDataTypeSize() <= 4 ? 4 : 8);
    field.values.resize(static_cast<size_t>(num_points));
    CopyToDouble(*array, field.values.data());
    fields.push_back(std::move(field));
  }
}

}  // namespace

struct VtkErrorCollector::Impl {
  Observation algorithm;
  Observation executive;
  // XML readers parse with an internal vtkXMLDataParser created per read; it reports the most
  // telling errors (e.g. a truncated compressed block) and accepts an observer only this way.
  vtkSmartPointer<vtkXMLReader> xml_reader;
  vtkSmartPointer<CollectingCommand> parser = vtkSmartPointer<CollectingCommand>::New();

  explicit Impl(vtkAlgorithm* a)
      : algorithm(a),
        executive(a == nullptr ? nullptr : a->GetExecutive()),
        xml_reader(vtkXMLReader::SafeDownCast(a)) {
    if (xml_reader != nullptr) xml_reader->SetParserErrorObserver(parser);
  }
  ~Impl() {
    if (xml_reader != nullptr) xml_reader->SetParserErrorObserver(nullptr);
  }
};

VtkErrorCollector::VtkErrorCollector(vtkAlgorithm* algorithm)
    : impl_(std::make_unique<Impl>(algorithm)) {}

VtkErrorCollector::~VtkErrorCollector() = default;

bool VtkErrorCollector::has_error() const {
  return !impl_->algorithm.command->errors.empty() || !impl_->executive.command->errors.empty() ||
         !impl_->parser->errors.empty();
}

std::string VtkErrorCollector::message() const {
  std::vector<std::string> own = impl_->parser->errors;
  own.insert(own.end(), impl_->algorithm.command->errors.begin(),
             impl_->algorithm.command->errors.end());
  if (!own.empty()) return absl::StrJoin(own, "; ");
  // The executive only says that the algorithm failed, followed by a dump of the pipeline
  // request; its first line is the useful part.
  const std::vector<std::string>& pipeline = impl_->executive.command->errors;
  if (pipeline.empty()) return "";
  const std::string& first = pipeline.front();
  return std::string(TrimWhitespace(std::string_view(first).substr(0, first.find('\n'))));
}

class ProgressCommand : public vtkCommand {
 public:
  static ProgressCommand* New() { return new ProgressCommand; }

  void Execute(vtkObject* caller, unsigned long, void* call_data) override {
    const double fraction = call_data != nullptr ? *static_cast<double*>(call_data) : 0;
    if (progress == nullptr) return;
    // Readers go from 0 to 1 more than once (information pass, then data): report the furthest.
    reached = std::max(reached, from + (to - from) * fraction);
    if (!progress->Update(phase, reached).ok()) {
      vtkAlgorithm::SafeDownCast(caller)->SetAbortExecute(1);
    }
  }

  const Progress* progress = nullptr;
  std::string phase;
  double from = 0, to = 1;
  double reached = 0;
};

struct VtkProgressRelay::Impl {
  vtkSmartPointer<vtkAlgorithm> algorithm;
  vtkSmartPointer<ProgressCommand> command = vtkSmartPointer<ProgressCommand>::New();
  unsigned long tag = 0;
};

VtkProgressRelay::VtkProgressRelay(vtkAlgorithm* algorithm, const Progress& progress,
                                   std::string_view phase, double from, double to)
    : impl_(std::make_unique<Impl>()) {
  impl_->algorithm = algorithm;
  impl_->command->progress = &progress;
  impl_->command->phase = std::string(phase);
  impl_->command->from = from;
  impl_->command->to = to;
  impl_->tag = algorithm->AddObserver(vtkCommand::ProgressEvent, impl_->command);
}

VtkProgressRelay::~VtkProgressRelay() { impl_->algorithm->RemoveObserver(impl_->tag); }

absl::Status VtkProgressRelay::status() const {
  return impl_->command->progress->status(impl_->command->phase);
}

absl::StatusOr<Mesh> UnstructuredGridToMesh(vtkUnstructuredGrid& grid) {
  Mesh mesh;
  RETURN_IF_ERROR(CopyPoints(grid, mesh.points));
  RETURN_IF_ERROR(CopyCells(grid, mesh.tetrahedra));
  CopyPointFields(grid, mesh.point_fields);
  RETURN_IF_ERROR(ValidateMesh(mesh));
  return mesh;
}

}  // namespace actopo::io::internal
