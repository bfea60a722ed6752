#include "server/io/samples.h"

#include <vtkDataSetTriangleFilter.h>
#include <vtkNew.h>
#include <vtkRTAnalyticSource.h>
#include <vtkUnstructuredGrid.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/core/parallel.h"
#include "server/io/internal/vtk_bridge.h"

namespace actopo::io {
namespace {

struct SampleKind {
  const char* name;
  int default_n;
  int min_n;
  int max_n;
  const char* description;
};

// wavelet stops at 512^3 points (670M tetrahedra), jittered at 400^3 (380M): both still fit the
// int32 ids, and beyond them the memory, not the code, is the limit.
constexpr std::array<SampleKind, 2> kSamples = {{
    {"wavelet", 21, 2, 512,
     "ParaView's Wavelet (vtkRTAnalyticSource, field RTData) on N^3 points centred on 0, "
     "split into 5 tetrahedra per voxel by Tetrahedralize (vtkDataSetTriangleFilter)"},
    {"jittered", 32, 2, 400,
     "the unit cube as an N^3 lattice with hashed point jitter, 6 tetrahedra per cube "
     "(Freudenthal split), fields scalar (smooth, several extrema) and height (z)"},
}};

// The error names the sample as given and the samples there are, briefly (SampleNames() has
// their descriptions).
absl::Status BadSample(std::string_view name, const std::string& why) {
  std::vector<std::string> kinds;
  for (const SampleKind& kind : kSamples) {
    kinds.push_back(absl::StrCat(kind.name, ":N (", kind.min_n, " <= N <= ", kind.max_n, ")"));
  }
  return absl::InvalidArgumentError(absl::StrCat("sample '", std::string(name), "': ", why,
                                                 "; samples: ", absl::StrJoin(kinds, ", ")));
}

absl::StatusOr<Mesh> MakeWavelet(int n) {
  // Odd n is symmetric around 0 (21 gives ParaView's default -10..10); even n has one more point
  // below 0 than above.
  const int low = n % 2 == 1 ? -(n - 1) / 2 : -n / 2;
  const int high = low + n - 1;
  vtkNew<vtkRTAnalyticSource> source;
  source->SetWholeExtent(low, high, low, high, low, high);
  vtkNew<vtkDataSetTriangleFilter> tetrahedralize;
  tetrahedralize->SetInputConnection(source->GetOutputPort());
  internal::VtkErrorCollector errors(tetrahedralize);
  tetrahedralize->Update();
  if (errors.has_error()) {
    return absl::InternalError(absl::StrCat("sample wavelet:", n, ": ", errors.message()));
  }
  return internal::UnstructuredGridToMesh(*tetrahedralize->GetOutput());
}

uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// In [-1, 1), from the top 53 bits.
double HashToSigned(uint64_t hash) { return static_cast<double>(hash >> 11) * 0x1p-52 - 1.0; }

// Smooth, with several maxima, minima and saddles inside the unit cube.
double BumpyScalar(double x, double y, double z) {
  constexpr double kTwoPi = 2 * std::numbers::pi;
  return std::sin(kTwoPi * (1.5 * x + 0.05)) * std::cos(kTwoPi * (y - 0.1)) +
         0.6 * std::cos(kTwoPi * (1.2 * z + 0.5 * x)) +
         0.3 * std::sin(kTwoPi * (2.0 * x + 1.3 * y - z + 0.2));
}

Mesh MakeJittered(int n) {
  const size_t side = static_cast<size_t>(n);
  const size_t num_vertices = side * side * side;
  const double spacing = 1.0 / (n - 1);
  // 0.1 spacing per axis moves a vertex by at most 0.17 spacing, which stays below the smallest
  // height of a Freudenthal tetrahedron (spacing / sqrt(2)) even when a vertex and the opposite
  // face move towards each other, so every tetrahedron keeps its orientation.
  const double amplitude = 0.1 * spacing;

  Mesh mesh;
  mesh.points.resize(3 * num_vertices);
  PointField scalar{.name = "scalar", .values = std::vector<double>(num_vertices)};
  PointField height{.name = "height", .values = std::vector<double>(num_vertices)};
  // One z-slice of vertices, then of cubes, per task, on every core: each slice writes its own
  // ranges, and the jitter is a hash of the vertex id, so the mesh is the same on any core count.
  ParallelFor(int64_t(side), DefaultThreads(), [&](int64_t k, int) {
    size_t v = size_t(k) * side * side;
    for (size_t j = 0; j < side; ++j) {
      for (size_t i = 0; i < side; ++i, ++v) {
        const std::array<size_t, 3> index = {i, j, size_t(k)};
        for (int axis = 0; axis < 3; ++axis) {
          // A boundary point moves only within its boundary plane, so the box stays a box.
          const bool on_boundary = index[axis] == 0 || index[axis] == side - 1;
          const double jitter =
              on_boundary ? 0.0 : amplitude * HashToSigned(SplitMix64(3 * v + axis));
          mesh.points[3 * v + axis] = index[axis] * spacing + jitter;
        }
        const double* p = &mesh.points[3 * v];
        scalar.values[v] = BumpyScalar(p[0], p[1], p[2]);
        height.values[v] = p[2];
      }
    }
  });

  // The Freudenthal (Kuhn) split: one tetrahedron per order in which the axes are walked from a
  // cube's lowest corner to its highest. Every cube uses the same diagonal, so neighbouring cubes
  // split their shared face the same way. The determinant of such a tetrahedron equals the sign
  // of the axis permutation; the odd ones swap two vertices to become positive.
  const std::array<SimplexId, 3> stride = {1, n, n * n};
  constexpr std::array<std::array<int, 3>, 6> kAxisOrders = {
      {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}}};
  const size_t cells = side - 1;
  mesh.tetrahedra.resize(24 * cells * cells * cells);
  ParallelFor(int64_t(cells), DefaultThreads(), [&](int64_t k, int) {
    size_t t = 24 * cells * cells * size_t(k);
    for (size_t j = 0; j < cells; ++j) {
      for (size_t i = 0; i < cells; ++i) {
        const SimplexId corner = static_cast<SimplexId>(i + side * (j + side * size_t(k)));
        for (int order = 0; order < 6; ++order) {
          const std::array<int, 3>& axes = kAxisOrders[order];
          const SimplexId v1 = corner + stride[axes[0]];
          const SimplexId v2 = v1 + stride[axes[1]];
          const SimplexId v3 = v2 + stride[axes[2]];
          const bool odd = order >= 3;
          mesh.tetrahedra[t++] = corner;
          mesh.tetrahedra[t++] = odd ? v2 : v1;
          mesh.tetrahedra[t++] = odd ? v1 : v2;
          mesh.tetrahedra[t++] = v3;
        }
      }
    }
  });
  mesh.point_fields.push_back(std::move(scalar));
  mesh.point_fields.push_back(std::move(height));
  return mesh;
}

// The kind and N a sample name gives.
// "sample:" before the name, as LoadMesh's clients write a sample, is accepted.
absl::StatusOr<std::pair<const SampleKind*, int>> ParseSample(std::string_view name) {
  if (name.substr(0, 7) == "sample:") name.remove_prefix(7);
  const size_t colon = name.find(':');
  const std::string_view base = name.substr(0, colon);
  for (const SampleKind& kind : kSamples) {
    if (base != std::string_view(kind.name)) continue;
    int n = kind.default_n;
    if (colon != std::string_view::npos) {
      const std::string_view digits = name.substr(colon + 1);
      if (!absl::SimpleAtoi(absl::string_view(digits.data(), digits.size()), &n)) {
        return BadSample(name, absl::StrCat("N '", std::string(digits), "' is not an integer"));
      }
    }
    if (n < kind.min_n || n > kind.max_n) {
      return BadSample(name,
                       absl::StrCat("N = ", n, " is outside [", kind.min_n, ", ", kind.max_n, "]"));
    }
    return std::make_pair(&kind, n);
  }
  return BadSample(name, "unknown sample");
}

}  // namespace

std::vector<std::string> SampleNames() {
  std::vector<std::string> names;
  for (const SampleKind& kind : kSamples) {
    names.push_back(absl::StrCat(kind.name, ":N  ", kind.description, "; ", kind.min_n,
                                 " <= N <= ", kind.max_n, ", plain '", kind.name, "' is ",
                                 kind.name, ":", kind.default_n));
  }
  return names;
}

absl::StatusOr<Mesh> MakeSample(std::string_view name) {
  absl::StatusOr<std::pair<const SampleKind*, int>> sample = ParseSample(name);
  if (!sample.ok()) return sample.status();
  const auto [kind, n] = *sample;
  if (std::string_view(kind->name) == "wavelet") return MakeWavelet(n);
  return MakeJittered(n);
}

bool IsSampleName(std::string_view name) { return ParseSample(name).ok(); }

absl::StatusOr<MeshCounts> SampleCounts(std::string_view name) {
  absl::StatusOr<std::pair<const SampleKind*, int>> sample = ParseSample(name);
  if (!sample.ok()) return sample.status();
  const auto [kind, n] = *sample;
  const int64_t cubes = int64_t(n - 1) * (n - 1) * (n - 1);
  const bool wavelet = std::string_view(kind->name) == "wavelet";
  return MeshCounts{.vertices = int64_t(n) * n * n,
                    .tetrahedra = (wavelet ? 5 : 6) * cubes,
                    .point_fields = wavelet ? 1 : 2};
}

}  // namespace actopo::io
