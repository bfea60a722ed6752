// RelationBuffer: the (block, relation) state machine, pins, eviction of the oldest half, the
// memory accounting, and pinning racing eviction (run under ASan and TSan in make test).
#include "server/core/relation_buffer.h"

#include <algorithm>
#include <atomic>
#include <thread>
#include <utility>
#include <vector>

#include "gtest/gtest.h"

namespace actopo {
namespace {

using State = RelationBuffer::State;

// A relation block whose values say which block it belongs to.
std::unique_ptr<RelationBlock> Block(int32_t block, Relation r, int values = 8) {
  auto data = std::make_unique<RelationBlock>();
  data->relation = r;
  data->block = block;
  data->count = values;
  data->stride = 1;
  data->values.assign(values, block);
  return data;
}

int64_t BytesOf(int32_t block, Relation r, int values = 8) {
  return Block(block, r, values)->bytes();
}

void Put(RelationBuffer& buffer, int32_t block, Relation r = Relation::kVT) {
  ASSERT_TRUE(buffer.StartComputing(block, r));
  buffer.Publish(block, r, Block(block, r), /*pin=*/false);
}

TEST(RelationBuffer, MovesAbsentComputingReadyOnceEach) {
  RelationBuffer buffer(4, 4);
  EXPECT_EQ(buffer.state(1, Relation::kVE), State::kAbsent);
  EXPECT_EQ(buffer.TryPin(1, Relation::kVE), nullptr);
  ASSERT_TRUE(buffer.StartComputing(1, Relation::kVE));
  EXPECT_EQ(buffer.state(1, Relation::kVE), State::kComputing);
  EXPECT_FALSE(buffer.StartComputing(1, Relation::kVE)) << "computing: nobody else may start";
  EXPECT_EQ(buffer.TryPin(1, Relation::kVE), nullptr) << "not readable while computing";
  buffer.Publish(1, Relation::kVE, Block(1, Relation::kVE), /*pin=*/false);
  EXPECT_EQ(buffer.state(1, Relation::kVE), State::kReady);
  EXPECT_FALSE(buffer.StartComputing(1, Relation::kVE)) << "ready: nothing to compute";
  const RelationBlock* data = buffer.TryPin(1, Relation::kVE);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(data->block, 1);
  buffer.Unpin(1, Relation::kVE);
  // Other relations of the block and the same relation of other blocks are independent.
  EXPECT_EQ(buffer.state(1, Relation::kVT), State::kAbsent);
  EXPECT_EQ(buffer.state(2, Relation::kVE), State::kAbsent);
}

TEST(RelationBuffer, AnEmptyRelationIsReady) {
  RelationBuffer buffer(2, 1);
  ASSERT_TRUE(buffer.StartComputing(0, Relation::kTT));
  buffer.Publish(0, Relation::kTT, Block(0, Relation::kTT, /*values=*/0), /*pin=*/false);
  const RelationBlock* data = buffer.TryPin(0, Relation::kTT);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(data->count, 0);
  buffer.Unpin(0, Relation::kTT);
}

TEST(RelationBuffer, EvictsTheOldestHalfBeyondCapacity) {
  RelationBuffer buffer(8, 4);
  for (int32_t b = 0; b < 4; ++b) Put(buffer, b);
  Put(buffer, 0, Relation::kVE);  // a second relation of a resident block is no new block
  EXPECT_EQ(buffer.stats().blocks, 4);
  EXPECT_EQ(buffer.stats().evictions, 0);
  // 5 blocks > 4: the oldest half of the 5 (2 blocks) goes, block 0 first. Their data comes
  // back to the caller, to be freed outside its locks, already out of the statistics.
  ASSERT_TRUE(buffer.StartComputing(4, Relation::kVT));
  RelationBuffer::Evicted evicted =
      buffer.Publish(4, Relation::kVT, Block(4, Relation::kVT), /*pin=*/false);
  EXPECT_EQ(evicted.blocks, 2);
  std::vector<std::pair<int32_t, Relation>> returned;
  for (const auto& data : evicted.data) returned.push_back({data->block, data->relation});
  std::sort(returned.begin(), returned.end());
  EXPECT_EQ(returned, (std::vector<std::pair<int32_t, Relation>>{
                          {0, Relation::kVE}, {0, Relation::kVT}, {1, Relation::kVT}}));
  EXPECT_EQ(buffer.stats().bytes, 3 * BytesOf(0, Relation::kVT));
  evicted.data.clear();
  for (Relation r : {Relation::kVT, Relation::kVE}) {
    EXPECT_EQ(buffer.state(0, r), State::kAbsent) << RelationCode(r);
  }
  EXPECT_EQ(buffer.state(1, Relation::kVT), State::kAbsent);
  for (int32_t b : {2, 3, 4}) EXPECT_EQ(buffer.state(b, Relation::kVT), State::kReady) << b;
  const RelationBuffer::Stats s = buffer.stats();
  EXPECT_EQ(s.evictions, 2);
  EXPECT_EQ(s.blocks, 3);
  EXPECT_EQ(s.peak_blocks, 5);
  EXPECT_EQ(s.blocks_inserted, 5);
  EXPECT_EQ(s.bytes, 3 * BytesOf(0, Relation::kVT));
  EXPECT_EQ(s.peak_bytes, 5 * BytesOf(0, Relation::kVT) + BytesOf(0, Relation::kVE));
  // An evicted relation can be computed again.
  Put(buffer, 0);
  EXPECT_EQ(buffer.state(0, Relation::kVT), State::kReady);
}

TEST(RelationBuffer, EvictAllSparesOnlyPinnedAndComputingBlocks) {
  RelationBuffer buffer(8, 8);
  for (int32_t b = 0; b < 4; ++b) Put(buffer, b);
  ASSERT_NE(buffer.TryPin(1, Relation::kVT), nullptr);
  ASSERT_TRUE(buffer.StartComputing(2, Relation::kVE));  // block 2 is being extended
  const RelationBuffer::Evicted evicted = buffer.EvictAll();
  EXPECT_EQ(evicted.blocks, 2);
  EXPECT_EQ(evicted.data.size(), 2u);
  for (int32_t b : {0, 3}) EXPECT_EQ(buffer.state(b, Relation::kVT), State::kAbsent) << b;
  for (int32_t b : {1, 2}) EXPECT_EQ(buffer.state(b, Relation::kVT), State::kReady) << b;
  EXPECT_EQ(buffer.stats().blocks, 2);
  EXPECT_EQ(buffer.stats().bytes, 2 * BytesOf(0, Relation::kVT));
  buffer.Unpin(1, Relation::kVT);
  buffer.Publish(2, Relation::kVE, Block(2, Relation::kVE), /*pin=*/false);
  EXPECT_EQ(buffer.EvictAll().blocks, 2);
  EXPECT_EQ(buffer.stats().bytes, 0);
  Put(buffer, 0);  // and it fills again
  EXPECT_EQ(buffer.state(0, Relation::kVT), State::kReady);
}

TEST(RelationBuffer, EvictsOneFinishedBlockAtOnce) {
  RelationBuffer buffer(8, 8);
  for (int32_t b = 0; b < 4; ++b) Put(buffer, b);
  Put(buffer, 2, Relation::kVE);
  // Block 2 goes whole, now, though the buffer is far from full; the others stay.
  RelationBuffer::Evicted evicted = buffer.Evict(2);
  EXPECT_EQ(evicted.blocks, 1);
  EXPECT_EQ(evicted.data.size(), 2u);
  for (Relation r : {Relation::kVT, Relation::kVE}) {
    EXPECT_EQ(buffer.state(2, r), State::kAbsent) << RelationCode(r);
  }
  for (int32_t b : {0, 1, 3}) EXPECT_EQ(buffer.state(b, Relation::kVT), State::kReady) << b;
  EXPECT_EQ(buffer.stats().blocks, 3);
  EXPECT_EQ(buffer.stats().evictions, 1);
  EXPECT_EQ(buffer.stats().bytes, 3 * BytesOf(0, Relation::kVT));
  // Absent, or never there: nothing happens.
  EXPECT_EQ(buffer.Evict(2).blocks, 0);
  EXPECT_EQ(buffer.Evict(6).blocks, 0);
  // A pinned relation stays, and its block with it; the block's other relations go.
  Put(buffer, 1, Relation::kVE);
  ASSERT_NE(buffer.TryPin(1, Relation::kVT), nullptr);
  evicted = buffer.Evict(1);
  EXPECT_EQ(evicted.blocks, 0);
  ASSERT_EQ(evicted.data.size(), 1u);
  EXPECT_EQ(evicted.data[0]->relation, Relation::kVE);
  EXPECT_EQ(buffer.state(1, Relation::kVT), State::kReady);
  buffer.Unpin(1, Relation::kVT);
  EXPECT_EQ(buffer.Evict(1).blocks, 1);
  // A block with a relation being computed is spared whole.
  ASSERT_TRUE(buffer.StartComputing(3, Relation::kVE));
  EXPECT_TRUE(buffer.Evict(3).data.empty());
  EXPECT_EQ(buffer.state(3, Relation::kVT), State::kReady);
  buffer.Publish(3, Relation::kVE, Block(3, Relation::kVE), /*pin=*/false);
  EXPECT_EQ(buffer.Evict(3).blocks, 1);
  EXPECT_EQ(buffer.stats().blocks, 1);  // block 0
  Put(buffer, 2);                       // an evicted block comes back as any other
  EXPECT_EQ(buffer.stats().blocks, 2);
}

TEST(RelationBuffer, KeepsPinnedRelationsAndTheirBlocks) {
  RelationBuffer buffer(8, 2);
  Put(buffer, 0);
  ASSERT_NE(buffer.TryPin(0, Relation::kVT), nullptr);
  Put(buffer, 1);
  Put(buffer, 2);  // over capacity: block 0 is pinned, so block 1 goes instead
  EXPECT_EQ(buffer.state(0, Relation::kVT), State::kReady);
  EXPECT_EQ(buffer.state(1, Relation::kVT), State::kAbsent);
  buffer.Unpin(0, Relation::kVT);
  Put(buffer, 3);  // now block 0 is the oldest and free to go
  EXPECT_EQ(buffer.state(0, Relation::kVT), State::kAbsent);
  EXPECT_EQ(buffer.stats().evictions, 2);
}

TEST(RelationBuffer, PublishPinsForTheCallerBeforeEvicting) {
  RelationBuffer buffer(4, 1);
  ASSERT_TRUE(buffer.StartComputing(0, Relation::kVT));
  const RelationBlock* mine = nullptr;
  buffer.Publish(0, Relation::kVT, Block(0, Relation::kVT), /*pin=*/true);
  mine = buffer.TryPin(0, Relation::kVT);  // a second pin, to read it back
  ASSERT_NE(mine, nullptr);
  buffer.Unpin(0, Relation::kVT);
  Put(buffer, 1);
  Put(buffer, 2);  // block 0 still holds the publisher's pin
  EXPECT_EQ(buffer.state(0, Relation::kVT), State::kReady);
  EXPECT_EQ(mine->block, 0);
  buffer.Unpin(0, Relation::kVT);
}

TEST(RelationBuffer, SparesBlocksWithARelationBeingComputed) {
  RelationBuffer buffer(8, 2);
  Put(buffer, 0);
  ASSERT_TRUE(buffer.StartComputing(0, Relation::kVE));  // block 0 is being extended
  Put(buffer, 1);
  Put(buffer, 2);
  EXPECT_EQ(buffer.state(0, Relation::kVT), State::kReady);
  EXPECT_EQ(buffer.state(1, Relation::kVT), State::kAbsent);
  buffer.Publish(0, Relation::kVE, Block(0, Relation::kVE), /*pin=*/false);
}

// A reader pins and reads while a producer keeps publishing new blocks into a one-block buffer,
// so eviction runs on nearly every publish. A relation read under a pin must be whole and its
// own (ASan: never freed under the reader; TSan: the pin protocol orders both sides).
TEST(RelationBuffer, PinningRacesEvictionSafely) {
  constexpr int32_t kBlocks = 16;
  RelationBuffer buffer(kBlocks, 1);
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (int round = 0; round < 400; ++round) {
      for (int32_t b = 0; b < kBlocks; ++b) {
        if (buffer.StartComputing(b, Relation::kVT)) {
          buffer.Publish(b, Relation::kVT, Block(b, Relation::kVT), /*pin=*/false);
        }
      }
    }
    done = true;
  });
  int64_t reads = 0;
  while (!done) {
    for (int32_t b = 0; b < kBlocks; ++b) {
      if (const RelationBlock* data = buffer.TryPin(b, Relation::kVT)) {
        ASSERT_EQ(data->block, b);
        for (SimplexId v : data->values) ASSERT_EQ(v, b);
        ++reads;
        buffer.Unpin(b, Relation::kVT);
      }
    }
  }
  producer.join();
  EXPECT_GT(buffer.stats().evictions, 0);
  // Blocks the reader held while a publish tried to evict them stay resident, so more than
  // capacity + 1 blocks may be left when the race ends. With no pins, each publish evicts the
  // oldest half again, so one more pass brings the buffer back within capacity + 1.
  for (int32_t b = 0; b < kBlocks; ++b) {
    if (buffer.StartComputing(b, Relation::kVT)) {
      buffer.Publish(b, Relation::kVT, Block(b, Relation::kVT), /*pin=*/false);
    }
  }
  EXPECT_LE(buffer.stats().blocks, 2);
  RecordProperty("reads", std::to_string(reads));
}

}  // namespace
}  // namespace actopo
