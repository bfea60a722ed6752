// The C++ client and the server's core in one program. Both define EngineStats, MemoryStats,
// PartitionOptions, Prefetch and Precompute, each in its own shape: the server's in `actopo`, the
// client's in `actopo::client`. Were the client's back in `actopo`, this file would not compile
// (the structs would be defined twice), and a program linking the two libraries would break the
// one-definition rule without a diagnostic.
//
// The client links its own code generated from topology_service.proto; this test must not also
// link the server's (actopo_proto), as both register the file in protobuf's descriptor pool.
#include <gtest/gtest.h>

#include <type_traits>
#include <vector>

#include "actopo/client.h"
#include "server/core/actopo_structure.h"
#include "server/core/partition.h"
#include "server/core/stats.h"

namespace {

static_assert(!std::is_same_v<actopo::EngineStats, actopo::client::EngineStats>);
static_assert(!std::is_same_v<actopo::MemoryStats, actopo::client::MemoryStats>);
static_assert(!std::is_same_v<actopo::PartitionOptions, actopo::client::PartitionOptions>);
static_assert(!std::is_same_v<actopo::Prefetch, actopo::client::Prefetch>);
static_assert(!std::is_same_v<actopo::Precompute, actopo::client::Precompute>);

// The server's per-consumer counters, summed the server's way, then reported the client's way
// (the fields the proto's EngineStats carries).
TEST(ClientWithServerTest, BothEngineStatsSideBySide) {
  actopo::EngineStats server;
  server.access.requests = 3;
  server.access.hits = 2;
  server.access.misses = 1;
  server.leader_relations = 5;
  actopo::EngineStats other;
  other.access.requests = 1;
  other.access.hits = 1;
  other.worker_relations = 7;
  server += other;  // defined in actopo_core

  const actopo::client::EngineStats client{.requests = server.access.requests,
                                           .hits = server.access.hits,
                                           .misses = server.access.misses,
                                           .leader_relations = server.leader_relations,
                                           .worker_relations = server.worker_relations};
  EXPECT_EQ(client.requests, 4);
  EXPECT_EQ(client.hits, 3);
  EXPECT_EQ(client.worker_relations, 7);
  EXPECT_EQ(client.hit_rate(), 0.75);
  EXPECT_EQ(actopo::client::EngineStats{}.hit_rate(), 1.0);
  EXPECT_EQ(sizeof(actopo::MemoryStats), 3 * sizeof(int64_t));
  EXPECT_EQ(sizeof(actopo::client::MemoryStats), 4 * sizeof(int64_t));
}

// Functions of both libraries with the same name, each on its own namespace's enums.
TEST(ClientWithServerTest, BothLibrariesLinked) {
  EXPECT_EQ(actopo::PrefetchName(actopo::Prefetch::kLinear), "linear");
  EXPECT_EQ(actopo::client::PrefetchName(actopo::client::Prefetch::kLinear), "linear");
  EXPECT_EQ(actopo::PrecomputeName(actopo::Precompute::kDeclared), "declared");
  EXPECT_EQ(actopo::client::PrecomputeName(actopo::client::Precompute::kDeclared), "declared");

  const actopo::PartitionOptions server_partition{.bucket_capacity = 2};
  const actopo::client::PartitionOptions client_partition{.block_size = 2};
  const std::vector<double> points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const std::vector<int32_t> blocks =
      actopo::OctreeBlocks(points, {.bucket_capacity = server_partition.bucket_capacity});
  EXPECT_EQ(blocks.size(), 4u);
  EXPECT_EQ(client_partition.block_size, server_partition.bucket_capacity);

  // A client (lazy: nothing listens on port 1) and the check it makes before sending anything.
  absl::StatusOr<std::unique_ptr<actopo::client::Client>> client =
      actopo::client::Client::Connect("127.0.0.1:1");
  ASSERT_TRUE(client.ok()) << client.status();
  EXPECT_EQ((*client)->LoadMesh("x.vtu", {.block_size = -1}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
