#include "server/service/wire.h"

#include <algorithm>
#include <cctype>
#include <string>

#include "gmock/gmock.h"
#include "google/protobuf/util/json_util.h"
#include "google/protobuf/util/message_differencer.h"
#include "gtest/gtest.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/io/samples.h"

namespace actopo::service {
namespace {

using ::testing::HasSubstr;

// "vertex_neighbors" and "critical-points" compare with the API's "VERTEX_NEIGHBORS" and
// "CRITICAL_POINTS" (prefix removed).
std::string Normalized(std::string_view name) {
  std::string out(name);
  for (char& c : out) c = c == '-' ? '_' : char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// Checks one mapping against the API enum's descriptor: every value but _UNSPECIFIED (number 0)
// has exactly one row, no core value has two, each row round-trips through FromProto and
// ToProto, and the names agree. A value added to the proto without a row fails here.
template <class P, class C, size_t N, class CoreName>
void ExpectComplete(const EnumMapping<P, C> (&mapping)[N], std::string_view prefix,
                    CoreName core_name) {
  const google::protobuf::EnumDescriptor* descriptor = google::protobuf::GetEnumDescriptor<P>();
  for (int i = 0; i < descriptor->value_count(); ++i) {
    const google::protobuf::EnumValueDescriptor* value = descriptor->value(i);
    const auto rows = std::count_if(std::begin(mapping), std::end(mapping), [&](const auto& row) {
      return int(row.proto) == value->number();
    });
    EXPECT_EQ(rows, value->number() == 0 ? 0 : 1) << value->name();
    if (value->number() == 0) {
      EXPECT_EQ(FromProto(P(0)).status().code(), absl::StatusCode::kInvalidArgument)
          << value->name();
    }
  }
  for (const auto& row : mapping) {
    const google::protobuf::EnumValueDescriptor* value =
        descriptor->FindValueByNumber(int(row.proto));
    ASSERT_NE(value, nullptr) << int(row.proto);
    const auto core = FromProto(row.proto);
    ASSERT_TRUE(core.ok()) << core.status();
    EXPECT_EQ(*core, row.core) << value->name();
    EXPECT_EQ(ToProto(row.core), row.proto) << value->name();
    EXPECT_EQ(std::count_if(std::begin(mapping), std::end(mapping),
                            [&](const auto& other) { return other.core == row.core; }),
              1)
        << value->name();
    ASSERT_TRUE(value->name().starts_with(prefix)) << value->name();
    EXPECT_EQ(Normalized(value->name().substr(prefix.size())), Normalized(core_name(row.core)));
  }
}

TEST(WireMapping, RelationsOneRowPerValueBothWays) {
  ExpectComplete(kRelationMapping, "RELATION_", RelationName);
  for (Relation r : AllRelations()) EXPECT_EQ(OkValue(FromProto(ToProto(r))), r) << RelationName(r);
}

TEST(WireMapping, AlgorithmsOneRowPerValueBothWays) {
  ExpectComplete(kAlgorithmMapping, "ALGORITHM_", AlgorithmName);
  for (Algorithm a : AllAlgorithms())
    EXPECT_EQ(OkValue(FromProto(ToProto(a))), a) << AlgorithmName(a);
}

TEST(WireMapping, StructuresPrefetchAndPrecomputeOneRowPerValueBothWays) {
  ExpectComplete(kStructureMapping, "STRUCTURE_", StructureName);
  ExpectComplete(kPrefetchMapping, "PREFETCH_", PrefetchName);
  ExpectComplete(kPrecomputeMapping, "PRECOMPUTE_", PrecomputeName);
  // Every core value has a row: the structures are listed, the prefetch modes named up to the
  // last ("?" past it).
  for (StructureKind kind : AllStructures()) {
    EXPECT_EQ(OkValue(FromProto(ToProto(kind))), kind) << StructureName(kind);
  }
  for (int i = 0; PrefetchName(Prefetch(i)) != "?"; ++i) {
    EXPECT_NE(ToProto(Prefetch(i)), v1::PREFETCH_UNSPECIFIED) << i;
  }
}

TEST(WireMapping, UnknownValuesNameTheFieldAndValue) {
  const auto message = [](const auto& status_or) {
    EXPECT_EQ(status_or.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(status_or.status().message());
  };
  EXPECT_THAT(message(FromProto(static_cast<v1::Relation>(99))),
              HasSubstr("relation: 99 is not a relation; set one of RELATION_VERTEX_NEIGHBORS "
                        "... RELATION_TRIANGLE_NEIGHBORS"));
  EXPECT_THAT(message(FromProto(v1::RELATION_UNSPECIFIED)),
              HasSubstr("relation: RELATION_UNSPECIFIED is not a relation"));
  EXPECT_THAT(message(FromProto(static_cast<v1::Algorithm>(11))),
              HasSubstr("algorithm: 11 is not an algorithm; set ALGORITHM_TOPO_RELATIONS, "
                        "ALGORITHM_CRITICAL_POINTS, ALGORITHM_DISCRETE_GRADIENT, "
                        "ALGORITHM_MORSE_SMALE, ALGORITHM_PERSISTENCE_DIAGRAM, "
                        "ALGORITHM_TOPOLOGICAL_SIMPLIFICATION, ALGORITHM_DIAGRAM_DISTANCE, "
                        "ALGORITHM_TRACKING, ALGORITHM_MERGE_TREE or ALGORITHM_CONTOUR_TREE"));
  v1::OpenSessionRequest request;
  request.set_structure(static_cast<v1::Structure>(42));
  EXPECT_THAT(message(FromProto(request)), HasSubstr("structure: 42 is not a structure"));
  request.set_structure(v1::STRUCTURE_UNSPECIFIED);
  request.mutable_engine()->set_prefetch(static_cast<v1::Prefetch>(17));
  EXPECT_THAT(message(FromProto(request)), HasSubstr("engine.prefetch: 17 is not a prefetch mode"));
  request.mutable_engine()->set_prefetch(v1::PREFETCH_UNSPECIFIED);
  request.mutable_engine()->set_precompute(static_cast<v1::Precompute>(9));
  EXPECT_THAT(message(FromProto(request)), HasSubstr("engine.precompute: 9 is not a scope"));
}

TEST(WireMapping, UnspecifiedMeansTheDefaults) {
  v1::OpenSessionRequest request;
  const absl::StatusOr<SessionOptions> options = FromProto(request);
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->structure.kind, StructureKind::kActopo);
  EXPECT_FALSE(options->structure.prefetch.has_value());
  EXPECT_FALSE(options->structure.precompute.has_value());
  // Zeros become the module's defaults (structure_options.h) here, at the edge.
  EXPECT_EQ(options->structure.consumers, WithDefaults({}).consumers);
  EXPECT_GE(options->structure.producers, 1);
  EXPECT_GE(options->structure.query_readers, 1);
  request.set_structure(v1::STRUCTURE_COMPACT);
  request.mutable_engine()->set_prefetch(v1::PREFETCH_SPATIAL);
  request.mutable_engine()->set_precompute(v1::PRECOMPUTE_DECLARED);
  const absl::StatusOr<SessionOptions> set = FromProto(request);
  ASSERT_TRUE(set.ok()) << set.status();
  EXPECT_EQ(set->structure.kind, StructureKind::kCompact);
  EXPECT_EQ(set->structure.prefetch, Prefetch::kSpatial);
  EXPECT_EQ(set->structure.precompute, Precompute::kDeclared);
}

// The summary built from the result equals, value for value, actopo-bench's JSON of the same
// run parsed into a Struct.
TEST(WireSummary, EqualsTheBenchJsonForEveryAlgorithm) {
  const Mesh mesh = OkValue(io::MakeSample("jittered:6"));
  auto topology =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 40})));
  auto structure = OkValue(ExplicitStructure::Build(topology, {}));
  AlgorithmInput input;
  input.order = VertexOrder(*topology, mesh.point_fields[0].values);
  input.input_corners = std::make_shared<const std::vector<uint8_t>>(
      OkValue(InputCorners(*topology, mesh.tetrahedra)));
  input.scalars = mesh.point_fields[0].values;
  for (Algorithm a : AllAlgorithms()) {
    input.algorithm = a;
    const absl::StatusOr<AlgorithmOutcome> outcome = RunAlgorithm(*structure, input, {});
    ASSERT_TRUE(outcome.ok()) << outcome.status();
    for (bool digests : {false, true}) {
      google::protobuf::Struct expected, built;
      ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(
                      Summarize(outcome->result, *topology, {.digests = digests}).dump(), &expected)
                      .ok());
      FillSummary(outcome->result, *topology, {.digests = digests}, &built);
      EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(built, expected))
          << AlgorithmName(a) << "\nbuilt:\n"
          << built.DebugString() << "\nexpected:\n"
          << expected.DebugString();
      EXPECT_GT(built.fields_size(), digests ? 1 : 0) << AlgorithmName(a);
    }
  }
}

}  // namespace
}  // namespace actopo::service
