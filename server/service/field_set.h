// A mesh's point fields: a set that changes while the mesh stays loaded. It starts with the
// fields the mesh was loaded with; AddFields adds more and DeleteField removes any. The topology
// never changes with them (DESIGN.md "A mesh's fields are a set that grows").
//
//   ASSIGN_OR_RETURN(FieldSet::Ref field, mesh.fields.Select("height"));   // held by a job
//   RETURN_IF_ERROR(mesh.fields.Add(std::move(new_fields)));               // all or none
//
// Whoever reads a field holds it (Ref, shared ownership): deleting a field never pulls it from
// under a session or a job, and an added field's share of the memory budget is released with
// its last holder.
#ifndef ACTOPO_SERVER_SERVICE_FIELD_SET_H_
#define ACTOPO_SERVER_SERVICE_FIELD_SET_H_

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/sync.h"
#include "server/service/memory_budget.h"

namespace actopo::service {

class FieldSet {
 public:
  struct Field {
    PointField field;
    std::optional<double> time;  // a series member's time value
    double min = 0, max = 0;     // the values' range
    Reservation reservation;     // an added field's bytes in the budget
  };
  using Ref = std::shared_ptr<const Field>;

  // A field of these values, its range computed.
  static Field Make(PointField field, std::optional<double> time = std::nullopt,
                    Reservation reservation = {});

  // The fields a mesh was loaded with, in its order (the mesh's reservation covers them).
  void Load(std::vector<PointField> loaded);

  std::vector<Ref> List() const;
  // The field a session or job reads: `name`, or when it is empty the first floating-point
  // field (SelectScalarField's rules and messages), checked finite.
  absl::StatusOr<Ref> Select(std::string_view name) const;
  // Adds every field or none: ALREADY_EXISTS naming `what`[i] and the first name taken.
  absl::Status Add(std::vector<Field> fields, std::string_view what = "fields");
  // NOT_FOUND naming the field and the fields there are.
  absl::Status Delete(std::string_view name);
  bool Contains(std::string_view name) const;
  int64_t bytes() const;  // the values of every field held here

 private:
  mutable Mutex mu_;
  std::vector<Ref> fields_ ABSL_GUARDED_BY(mu_);
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_FIELD_SET_H_
