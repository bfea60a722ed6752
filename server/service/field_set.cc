#include "server/service/field_set.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace actopo::service {

FieldSet::Field FieldSet::Make(PointField field, std::optional<double> time,
                               Reservation reservation) {
  Field out{.field = std::move(field), .time = time, .reservation = std::move(reservation)};
  if (!out.field.values.empty()) {
    // Branch-free, so that it vectorizes (std::minmax_element does not); the values are finite.
    double lo = out.field.values[0], hi = lo;
    for (const double v : out.field.values) {
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
    }
    out.min = lo;
    out.max = hi;
  }
  return out;
}

void FieldSet::Load(std::vector<PointField> loaded) {
  MutexLock lock(mu_);
  for (PointField& f : loaded) {
    const std::optional<double> time = f.time;
    fields_.push_back(std::make_shared<const Field>(Make(std::move(f), time)));
  }
}

std::vector<FieldSet::Ref> FieldSet::List() const {
  MutexLock lock(mu_);
  return fields_;
}

absl::StatusOr<FieldSet::Ref> FieldSet::Select(std::string_view name) const {
  const std::vector<Ref> fields = List();
  std::vector<const PointField*> views;
  for (const Ref& f : fields) views.push_back(&f->field);
  absl::StatusOr<int> chosen = SelectScalarField(views, name);
  if (!chosen.ok()) return chosen.status();
  return fields[*chosen];
}

bool FieldSet::Contains(std::string_view name) const {
  MutexLock lock(mu_);
  return std::any_of(fields_.begin(), fields_.end(),
                     [&](const Ref& f) { return f->field.name == name; });
}

absl::Status FieldSet::Add(std::vector<Field> fields, std::string_view what) {
  MutexLock lock(mu_);
  for (size_t i = 0; i < fields.size(); ++i) {
    const std::string& name = fields[i].field.name;
    for (const Ref& f : fields_) {
      if (f->field.name == name) {
        return absl::AlreadyExistsError(absl::StrCat(std::string(what), "[", i,
                                                     "].name: the mesh has a field '", name,
                                                     "' already; delete it first"));
      }
    }
  }
  for (Field& f : fields) fields_.push_back(std::make_shared<const Field>(std::move(f)));
  return absl::OkStatus();
}

absl::Status FieldSet::Delete(std::string_view name) {
  MutexLock lock(mu_);
  const auto it = std::find_if(fields_.begin(), fields_.end(),
                               [&](const Ref& f) { return f->field.name == name; });
  if (it == fields_.end()) {
    std::vector<std::string> names;
    for (const Ref& f : fields_) names.push_back("'" + f->field.name + "'");
    return absl::NotFoundError(
        absl::StrCat("name: the mesh has no field '", std::string(name),
                     "'; its fields: ", names.empty() ? "none" : absl::StrJoin(names, ", ")));
  }
  fields_.erase(it);
  return absl::OkStatus();
}

int64_t FieldSet::bytes() const {
  MutexLock lock(mu_);
  int64_t b = 0;
  for (const Ref& f : fields_) b += int64_t(f->field.values.capacity() * sizeof(double));
  return b;
}

}  // namespace actopo::service
