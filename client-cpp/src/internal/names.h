// Names users write for the API's enums ("vertex_edges", "morse-smale") and the mapping of the
// public enums to the proto's.
#ifndef ACTOPO_CLIENT_SRC_INTERNAL_NAMES_H_
#define ACTOPO_CLIENT_SRC_INTERNAL_NAMES_H_

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "actopo/client.h"
#include "actopo/v1/topology_service.pb.h"

namespace actopo::client::internal {

// "vertex_star" -> RELATION_VERTEX_STAR; case is ignored and '-' equals '_'. Unknown names are
// INVALID_ARGUMENT listing the known ones.
absl::StatusOr<v1::Relation> RelationFromName(std::string_view name);
// "morse-smale" (or "morse_smale") -> ALGORITHM_MORSE_SMALE.
absl::StatusOr<v1::Algorithm> AlgorithmFromName(std::string_view name);
// ALGORITHM_MORSE_SMALE -> "morse-smale".
std::string AlgorithmName(v1::Algorithm algorithm);

v1::DataType ToProto(DataType dtype);
DataType FromProto(v1::DataType dtype);
v1::Structure ToProto(Structure structure);
Structure FromProto(v1::Structure structure);
v1::Prefetch ToProto(Prefetch prefetch);
Prefetch FromProto(v1::Prefetch prefetch);
v1::Precompute ToProto(Precompute precompute);
Precompute FromProto(v1::Precompute precompute);

}  // namespace actopo::client::internal

#endif  // ACTOPO_CLIENT_SRC_INTERNAL_NAMES_H_
