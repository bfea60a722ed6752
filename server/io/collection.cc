#include "server/io/collection.h"

#include <vtkSmartPointer.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLUtilities.h>

#include <cmath>
#include <filesystem>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "server/core/status_macros.h"

namespace actopo::io {

absl::StatusOr<std::vector<CollectionStep>> ReadCollection(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::is_regular_file(path, error)) {
    return absl::NotFoundError(absl::StrCat(path, ": no such file"));
  }
  vtkSmartPointer<vtkXMLDataElement> root;
  root.TakeReference(vtkXMLUtilities::ReadElementFromFile(path.c_str()));
  if (root == nullptr || std::string(root->GetName()) != "VTKFile") {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": not a ParaView collection (.pvd: a VTKFile XML element)"));
  }
  vtkXMLDataElement* collection = root->FindNestedElementWithName("Collection");
  if (collection == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": no <Collection> element"));
  }
  std::vector<CollectionStep> steps;
  for (int i = 0; i < collection->GetNumberOfNestedElements(); ++i) {
    vtkXMLDataElement* data_set = collection->GetNestedElement(i);
    if (std::string(data_set->GetName()) != "DataSet") continue;
    const char* file = data_set->GetAttribute("file");
    if (file == nullptr || *file == '\0') {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": DataSet ", steps.size(), " has no file attribute"));
    }
    CollectionStep step{.path = (fs::path(path).parent_path() / file).lexically_normal().string(),
                        .time = double(steps.size())};
    if (const char* time = data_set->GetAttribute("timestep"); time != nullptr) {
      if (!absl::SimpleAtod(time, &step.time) || !std::isfinite(step.time)) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": DataSet '", file, "' has timestep '", time, "', not a number"));
      }
    }
    steps.push_back(std::move(step));
  }
  if (steps.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": the collection lists no DataSet"));
  }
  return steps;
}

std::string SeriesFieldName(const std::string& field, size_t step, size_t steps) {
  const std::string digits = std::to_string(steps > 0 ? steps - 1 : 0);
  std::string index = std::to_string(step);
  index.insert(0, digits.size() > index.size() ? digits.size() - index.size() : 0, '0');
  return absl::StrCat(field, "_", index);
}

absl::Status AppendSeriesStep(Mesh& series, const std::string& first, Mesh next,
                              const std::string& file, size_t index, size_t count, double time) {
  const auto differs = [&](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat(
        file, ": ", what, " than ", first,
        " (every file of a series must hold the same points and tetrahedra in the same order)"));
  };
  if (next.num_vertices() != series.num_vertices()) {
    return differs(absl::StrCat("has ", next.num_vertices(), " points, not ", series.num_vertices(),
                                ", so other points"));
  }
  if (next.num_tetrahedra() != series.num_tetrahedra()) {
    return differs(absl::StrCat("has ", next.num_tetrahedra(), " tetrahedra, not ",
                                series.num_tetrahedra(), ", so other cells"));
  }
  for (size_t i = 0; i < next.points.size(); ++i) {
    if (next.points[i] != series.points[i]) {
      return differs(absl::StrCat("has point ", i / 3, " elsewhere"));
    }
  }
  for (size_t i = 0; i < next.tetrahedra.size(); ++i) {
    if (next.tetrahedra[i] != series.tetrahedra[i]) {
      return differs(absl::StrCat("has tetrahedron ", i / 4, " on other vertices"));
    }
  }
  for (PointField& field : next.point_fields) {
    field.name = SeriesFieldName(field.name, index, count);
    field.time = time;
    series.point_fields.push_back(std::move(field));
  }
  return absl::OkStatus();
}

absl::StatusOr<Mesh> ReadSteps(const std::vector<CollectionStep>& steps, const StepReader& read,
                               const std::string& series, const Progress& progress) {
  if (steps.empty()) return absl::InvalidArgumentError(absl::StrCat(series, ": no files"));
  Mesh joined;
  const double n = double(steps.size());
  for (size_t k = 0; k < steps.size(); ++k) {
    const std::string& file = steps[k].path;
    if (absl::AsciiStrToLower(std::filesystem::path(file).extension().string()) == ".pvd") {
      return absl::InvalidArgumentError(
          absl::StrCat(series, ": step ", k, " is a collection itself (", file, ")"));
    }
    const auto named = [&](const absl::Status& status) {
      return absl::Status(status.code(),
                          absl::StrCat(series, ": step ", k, ": ", status.message()));
    };
    absl::StatusOr<Mesh> step = read(file, int(joined.point_fields.size()),
                                     progress.Slice(double(k) / n, double(k + 1) / n));
    if (!step.ok()) return named(step.status());
    if (k == 0) {
      joined = *std::move(step);
      for (PointField& field : joined.point_fields) {
        field.name = SeriesFieldName(field.name, 0, steps.size());
        field.time = steps[0].time;
      }
    } else if (absl::Status appended = AppendSeriesStep(joined, steps[0].path, *std::move(step),
                                                        file, k, steps.size(), steps[k].time);
               !appended.ok()) {
      return named(appended);
    }
    RETURN_IF_ERROR(progress.Update("read", double(k + 1) / n));
  }
  return joined;
}

}  // namespace actopo::io
