// Typed reads of one result's arrays, shared by the readers that rebuild a result from them
// (ResultArrays::PersistencePairs, ResultArrays::Tree): each array checked against its shape and
// counted, every error naming it as "result array '<prefix><name>'".
#ifndef ACTOPO_CLIENT_SRC_INTERNAL_COLUMNS_H_
#define ACTOPO_CLIENT_SRC_INTERNAL_COLUMNS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "actopo/client.h"

namespace actopo::client::internal {

class Columns {
 public:
  // `prefix` goes before every name ("diagram/", or "" when names carry their group);
  // `missing` follows "not found: " when an array is absent (which job gives it).
  Columns(const ResultArrays& result, std::string prefix, std::string missing)
      : result_(result), prefix_(std::move(prefix)), missing_(std::move(missing)) {}

  // INVALID_ARGUMENT naming the array.
  absl::Status Malformed(absl::string_view name, absl::string_view what) const;
  // The array, its bytes matching its shape; NOT_FOUND when absent.
  absl::StatusOr<const Array*> Get(absl::string_view name) const;
  // An integer array's values whatever their width; `count` of them unless it is negative
  // (`per` says what they count, for the error).
  absl::StatusOr<std::vector<int64_t>> Integers(absl::string_view name, int64_t count,
                                                absl::string_view per) const;
  // A floating-point array's values (any numeric dtype with `any_dtype`), `count` of them.
  absl::StatusOr<std::vector<double>> Reals(absl::string_view name, int64_t count,
                                            absl::string_view per, bool any_dtype = false) const;

 private:
  absl::Status CheckCount(absl::string_view name, size_t got, int64_t expected,
                          absl::string_view per) const;

  const ResultArrays& result_;
  std::string prefix_, missing_;
};

}  // namespace actopo::client::internal

#endif  // ACTOPO_CLIENT_SRC_INTERNAL_COLUMNS_H_
