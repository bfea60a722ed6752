#include "src/internal/columns.h"

#include "absl/strings/str_cat.h"

namespace actopo::client::internal {

absl::Status Columns::Malformed(absl::string_view name, absl::string_view what) const {
  return absl::InvalidArgumentError(absl::StrCat("result array '", prefix_, name, "': ", what));
}

absl::StatusOr<const Array*> Columns::Get(absl::string_view name) const {
  const Array* array = result_.Find(absl::StrCat(prefix_, name));
  if (array == nullptr) {
    return absl::NotFoundError(
        absl::StrCat("result array '", prefix_, name, "' not found: ", missing_));
  }
  if (absl::Status s = array->CheckLayout(array->dtype); !s.ok()) return s;
  return array;
}

absl::Status Columns::CheckCount(absl::string_view name, size_t got, int64_t expected,
                                 absl::string_view per) const {
  if (expected < 0 || got == size_t(expected)) return absl::OkStatus();
  return Malformed(name, absl::StrCat(got, " values, expected ", expected, " (", per, ")"));
}

absl::StatusOr<std::vector<int64_t>> Columns::Integers(absl::string_view name, int64_t count,
                                                       absl::string_view per) const {
  absl::StatusOr<const Array*> array = Get(name);
  if (!array.ok()) return array.status();
  absl::StatusOr<std::vector<int64_t>> values = (*array)->ToInt64();
  if (!values.ok()) return values.status();
  if (absl::Status s = CheckCount(name, values->size(), count, per); !s.ok()) return s;
  return values;
}

absl::StatusOr<std::vector<double>> Columns::Reals(absl::string_view name, int64_t count,
                                                   absl::string_view per, bool any_dtype) const {
  absl::StatusOr<const Array*> array = Get(name);
  if (!array.ok()) return array.status();
  const DataType dtype = (*array)->dtype;
  if (!any_dtype && dtype != DataType::kFloat64 && dtype != DataType::kFloat32) {
    return Malformed(name, absl::StrCat("dtype ", std::string(DataTypeName(dtype)),
                                        " is not a floating-point type"));
  }
  std::vector<double> values = (*array)->ToDouble();
  if (absl::Status s = CheckCount(name, values.size(), count, per); !s.ok()) return s;
  return values;
}

}  // namespace actopo::client::internal
