#include "server/io/vtk_reader.h"

#include <vtkDataSetTriangleFilter.h>
#include <vtkNew.h>
#include <vtkUnstructuredGrid.h>
#include <vtkUnstructuredGridReader.h>
#include <vtkVersion.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>

#include <exception>
#include <filesystem>
#include <new>
#include <string>
#include <string_view>
#include <system_error>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"
#include "server/io/collection.h"
#include "server/io/internal/appended_vtu.h"
#include "server/io/internal/vtk_bridge.h"

namespace actopo::io {
namespace {

constexpr char kSupportedExtensions[] =
    ".vtu (VTK XML unstructured grid), .vtk (legacy VTK unstructured grid), "
    ".vti (VTK XML image data, split into tetrahedra), .pvd (ParaView collection: a series of "
    "such files on the same mesh)";

absl::Status Prefixed(const std::string& path, const absl::Status& status) {
  return absl::Status(status.code(), absl::StrCat(path, ": ", status.message()));
}

absl::Status Unreadable(const std::string& path, const char* format,
                        const internal::VtkErrorCollector& errors) {
  std::string detail = errors.message();
  // CanReadFile fails silently for a file that is not VTK XML or holds another data set type.
  if (detail.empty()) detail = "not a file of this type, or corrupt";
  return absl::InvalidArgumentError(absl::StrCat(path, ": cannot read as ", format, ": ", detail));
}

absl::StatusOr<Mesh> Convert(const std::string& path, vtkUnstructuredGrid* grid) {
  if (grid == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": the VTK reader produced no grid"));
  }
  absl::StatusOr<Mesh> mesh = internal::UnstructuredGridToMesh(*grid);
  if (!mesh.ok()) return Prefixed(path, mesh.status());
  return mesh;
}

constexpr char kPhase[] = "read";

absl::StatusOr<Mesh> ReadXmlUnstructuredGrid(const std::string& path, const Progress& progress) {
  constexpr char kFormat[] = "a VTK XML unstructured grid (.vtu)";
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  internal::VtkErrorCollector errors(reader);
  // CanReadFile checks the XML header and the data set type (a .vtu holding poly data fails).
  if (!reader->CanReadFile(path.c_str())) return Unreadable(path, kFormat, errors);
  reader->SetFileName(path.c_str());
  internal::VtkProgressRelay relay(reader, progress, kPhase, 0, 0.9);
  reader->Update();
  RETURN_IF_ERROR(relay.status());
  if (errors.has_error()) return Unreadable(path, kFormat, errors);
  return Convert(path, reader->GetOutput());
}

// The legacy type line ("DATASET POLYDATA", ...) in words, to say what the file is instead.
const char* LegacyDataSetKind(vtkUnstructuredGridReader& reader) {
  if (reader.IsFilePolyData()) return "poly data";
  if (reader.IsFileStructuredPoints()) return "structured points (image data)";
  if (reader.IsFileStructuredGrid()) return "a structured grid";
  if (reader.IsFileRectilinearGrid()) return "a rectilinear grid";
  return nullptr;
}

absl::StatusOr<Mesh> ReadLegacyUnstructuredGrid(const std::string& path, const Progress& progress) {
  constexpr char kFormat[] = "a legacy VTK unstructured grid (.vtk)";
  vtkNew<vtkUnstructuredGridReader> reader;
  internal::VtkErrorCollector errors(reader);
  reader->SetFileName(path.c_str());
  if (!reader->IsFileUnstructuredGrid()) {
    const char* kind = LegacyDataSetKind(*reader);
    if (kind == nullptr) return Unreadable(path, kFormat, errors);
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": the legacy VTK file holds ", kind,
                     ", not an unstructured grid; only unstructured grids of tetrahedra are read"));
  }
  // By default the legacy reader keeps only the first SCALARS section of each attribute block.
  reader->ReadAllScalarsOn();
  reader->ReadAllFieldsOn();
  internal::VtkProgressRelay relay(reader, progress, kPhase, 0, 0.9);
  reader->Update();
  RETURN_IF_ERROR(relay.status());
  if (errors.has_error()) return Unreadable(path, kFormat, errors);
  return Convert(path, reader->GetOutput());
}

absl::StatusOr<Mesh> ReadXmlImageData(const std::string& path, const Progress& progress) {
  constexpr char kFormat[] = "VTK XML image data (.vti)";
  vtkNew<vtkXMLImageDataReader> reader;
  internal::VtkErrorCollector reader_errors(reader);
  if (!reader->CanReadFile(path.c_str())) return Unreadable(path, kFormat, reader_errors);
  reader->SetFileName(path.c_str());
  // ParaView's Tetrahedralize is this filter; using it (rather than an own split) keeps the
  // tetrahedra and their ids identical to what a ParaView/TTK user gets from the same file.
  vtkNew<vtkDataSetTriangleFilter> tetrahedralize;
  tetrahedralize->SetInputConnection(reader->GetOutputPort());
  internal::VtkErrorCollector filter_errors(tetrahedralize);
  internal::VtkProgressRelay read_relay(reader, progress, kPhase, 0, 0.3);
  internal::VtkProgressRelay split_relay(tetrahedralize, progress, kPhase, 0.3, 0.9);
  tetrahedralize->Update();
  RETURN_IF_ERROR(split_relay.status());
  if (reader_errors.has_error()) return Unreadable(path, kFormat, reader_errors);
  if (filter_errors.has_error()) return Unreadable(path, kFormat, filter_errors);
  return Convert(path, tetrahedralize->GetOutput());
}

// A .pvd: every step read and appended to the first (collection.h).
absl::StatusOr<Mesh> ReadSeries(const std::string& path, const ReadOptions& options,
                                const Progress& progress) {
  ASSIGN_OR_RETURN(const std::vector<CollectionStep> steps, ReadCollection(path));
  return ReadSteps(
      steps,
      [&](const std::string& file, int, const Progress& step) {
        return ReadMesh(file, options, step);
      },
      path, progress);
}

}  // namespace

absl::StatusOr<Mesh> ReadMesh(const std::string& path, const ReadOptions& options,
                              const Progress& progress) {
  const std::string extension =
      absl::AsciiStrToLower(std::filesystem::path(path).extension().string());
  if (extension == ".pvd") return ReadSeries(path, options, progress);
  if (extension != ".vtu" && extension != ".vtk" && extension != ".vti") {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": ",
                     extension.empty() ? std::string("no file extension")
                                       : absl::StrCat("unsupported extension '", extension, "'"),
                     "; supported: ", kSupportedExtensions));
  }
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (!std::filesystem::exists(status)) {
    return absl::NotFoundError(absl::StrCat(path, ": no such file"));
  }
  if (std::filesystem::is_directory(status)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": is a directory, not a file"));
  }
  // VTK's parsers throw on some corrupt files (a compressed block header promising an absurd
  // size ends in std::length_error or std::bad_alloc): a bad file, not a reason to stop the
  // process. Whatever was built is released as the stack unwinds. The parallel reader can run out
  // of memory too (the isolated reader's limit).
  absl::StatusOr<Mesh> mesh;
  try {
    std::optional<Mesh> fast;
    if (extension == ".vtu" && options.parallel_vtu) {
      const int threads = options.threads > 0 ? options.threads : DefaultThreads();
      ASSIGN_OR_RETURN(fast, internal::ReadAppendedVtu(path, threads, progress));
    }
    if (fast) {
      mesh = std::move(*fast);
    } else {
      mesh = extension == ".vtu"   ? ReadXmlUnstructuredGrid(path, progress)
             : extension == ".vtk" ? ReadLegacyUnstructuredGrid(path, progress)
                                   : ReadXmlImageData(path, progress);
    }
  } catch (const std::bad_alloc&) {
    return absl::ResourceExhaustedError(
        absl::StrCat(path,
                     ": ran out of memory reading it (a mesh beyond the memory allowed, or "
                     "corrupt sizes in the file?)"));
  } catch (const std::exception& e) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": cannot read: VTK failed with '", e.what(), "' (corrupt file?)"));
  }
  if (mesh.ok()) RETURN_IF_ERROR(progress.Update(kPhase, 1));
  return mesh;
}

std::string VtkVersion() { return vtkVersion::GetVTKVersion(); }

}  // namespace actopo::io
