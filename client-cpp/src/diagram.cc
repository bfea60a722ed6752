// ResultArrays::PersistencePairs: the diagram/ arrays of a persistence diagram (TTK's diagram
// grid) read back into its pairs.
//
// The grid holds two points per pair, birth then death, and one line per pair; in the "diagram"
// embedding one more line comes last, TTK's diagonal, from the first point to a pair's birth
// point. The wire carries Offsets but no connectivity, so the diagonal's entry cannot name the two
// points it reuses (it points past the last point). The pairs are therefore read by position,
// pair i being points 2i and 2i + 1 and line i, after checking that the arrays have that layout.
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/columns.h"

namespace actopo::client {
namespace {

// What a missing diagram/ array's NOT_FOUND says.
constexpr char kFromWhere[] =
    "persistence pairs come from a persistence-diagram job (or a field of a diagram-distance or "
    "tracking job) run with JobOptions::include_arrays";

}  // namespace

absl::StatusOr<std::vector<PersistencePair>> ResultArrays::PersistencePairs() const {
  const internal::Columns columns(*this, "diagram/", kFromWhere);
  // PairIdentifier counts the lines and tells whether the last one is TTK's diagonal (-1).
  absl::StatusOr<const Array*> identifiers = columns.Get("PairIdentifier");
  if (!identifiers.ok()) return identifiers.status();
  absl::StatusOr<std::vector<int64_t>> ids = (*identifiers)->ToInt64();
  if (!ids.ok()) return ids.status();
  const size_t lines = ids->size();
  // The server leaves Offsets out of an empty diagram; there is nothing to read anyway.
  if (lines == 0) return std::vector<PersistencePair>();
  const bool diagonal = ids->back() == -1;
  const size_t n = lines - (diagonal ? 1 : 0);

  absl::StatusOr<std::vector<int64_t>> offsets =
      columns.Integers("Offsets", lines + 1, "one more than the lines");
  if (!offsets.ok()) return offsets.status();
  for (size_t i = 0; i <= n; ++i) {
    if ((*offsets)[i] != int64_t(2 * i)) {
      return columns.Malformed("Offsets",
                               absl::StrCat("entry ", i, " is ", (*offsets)[i], ", not ", 2 * i,
                                            ": the pairs' lines are not two points each"));
    }
  }
  absl::StatusOr<std::vector<int64_t>> type = columns.Integers("PairType", lines, "one per line");
  if (!type.ok()) return type.status();
  absl::StatusOr<std::vector<int64_t>> finite = columns.Integers("IsFinite", lines, "one per line");
  if (!finite.ok()) return finite.status();
  absl::StatusOr<std::vector<double>> birth = columns.Reals("Birth", lines, "one per line");
  if (!birth.ok()) return birth.status();
  absl::StatusOr<std::vector<double>> persistence =
      columns.Reals("Persistence", lines, "one per line");
  if (!persistence.ok()) return persistence.status();
  absl::StatusOr<std::vector<int64_t>> vertex =
      columns.Integers("ttkVertexScalarField", 2 * n, "two points per pair");
  if (!vertex.ok()) return vertex.status();
  absl::StatusOr<std::vector<double>> points =
      columns.Reals("Points", 6 * n, "x, y, z of two points per pair");
  if (!points.ok()) return points.status();

  std::vector<PersistencePair> pairs(n);
  for (size_t i = 0; i < n; ++i) {
    PersistencePair& p = pairs[i];
    if ((*type)[i] < 0 || (*type)[i] > 2) {
      return columns.Malformed("PairType", absl::StrCat("line ", i, " of ", lines, " has type ",
                                                        (*type)[i], "; a pair's is 0, 1 or 2"));
    }
    p.type = int((*type)[i]);
    p.birth_vertex = (*vertex)[2 * i];
    p.death_vertex = (*vertex)[2 * i + 1];
    p.birth = (*birth)[i];
    p.persistence = (*persistence)[i];
    // The diagram embedding draws the death at (birth, death, 0): its value, exactly. Points in
    // the domain are the vertices' positions, which say nothing of it.
    p.death = diagonal ? (*points)[6 * i + 4] : p.birth + p.persistence;
    p.finite = (*finite)[i] != 0;
  }
  return pairs;
}

}  // namespace actopo::client
