#include "server/service/field_set.h"

#include <cmath>
#include <thread>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace actopo::service {
namespace {

using ::testing::HasSubstr;

PointField Field(std::string name, std::vector<double> values, bool integer = false) {
  return {.name = std::move(name), .values = std::move(values), .is_integer = integer};
}

std::vector<std::string> Names(const FieldSet& set) {
  std::vector<std::string> names;
  for (const FieldSet::Ref& f : set.List()) names.push_back(f->field.name);
  return names;
}

TEST(FieldSet, SelectsAsSessionsDidAndKeepsTheLoadedOrder) {
  FieldSet set;
  set.Load({Field("labels", {1, 2, 3}, true), Field("height", {0, 1, 2}), Field("t", {3, 1, 2})});
  EXPECT_EQ(Names(set), (std::vector<std::string>{"labels", "height", "t"}));
  // Empty: the first floating-point field.
  EXPECT_EQ((*set.Select(""))->field.name, "height");
  EXPECT_EQ((*set.Select("t"))->field.name, "t");
  EXPECT_EQ((*set.Select("t"))->min, 1);
  EXPECT_EQ((*set.Select("t"))->max, 3);
  const absl::Status missing = set.Select("nope").status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.message(), HasSubstr("'nope' not found; point fields: 'labels', 'height'"));
}

TEST(FieldSet, AddsAllOrNoneAndDeletes) {
  FieldSet set;
  set.Load({Field("a", {0, 1})});
  std::vector<FieldSet::Field> added;
  added.push_back(FieldSet::Make(Field("b", {2, 3}), 30.0));
  added.push_back(FieldSet::Make(Field("a", {4, 5})));
  const absl::Status taken = set.Add(std::move(added));
  EXPECT_EQ(taken.code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(taken.message(), HasSubstr("fields[1].name: the mesh has a field 'a' already"));
  EXPECT_EQ(Names(set), (std::vector<std::string>{"a"}));  // b was not added either

  added.clear();
  added.push_back(FieldSet::Make(Field("b", {2, 3}), 30.0));
  ASSERT_TRUE(set.Add(std::move(added)).ok());
  EXPECT_EQ(Names(set), (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(*(*set.Select("b"))->time, 30.0);
  EXPECT_EQ(set.bytes(), 4 * int64_t(sizeof(double)));

  // A holder keeps a deleted field.
  const FieldSet::Ref held = *set.Select("a");
  ASSERT_TRUE(set.Delete("a").ok());
  EXPECT_EQ(Names(set), (std::vector<std::string>{"b"}));
  EXPECT_EQ(held->field.values, (std::vector<double>{0, 1}));
  const absl::Status gone = set.Delete("a");
  EXPECT_EQ(gone.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(gone.message(), HasSubstr("no field 'a'; its fields: 'b'"));
}

TEST(FieldSet, AnAddedFieldsBudgetGoesWithItsLastHolder) {
  MemoryBudget budget(1000);
  FieldSet set;
  ASSERT_TRUE(budget.Reserve(800, "a field").ok());
  std::vector<FieldSet::Field> added;
  added.push_back(FieldSet::Make(Field("f", {1, 2}), std::nullopt, Reservation(&budget, 800)));
  ASSERT_TRUE(set.Add(std::move(added)).ok());
  FieldSet::Ref held = *set.Select("f");
  ASSERT_TRUE(set.Delete("f").ok());
  EXPECT_EQ(budget.used(), 800);
  held.reset();
  EXPECT_EQ(budget.used(), 0);
}

TEST(FieldSet, ConcurrentAddsDeletesAndReads) {
  FieldSet set;
  set.Load({Field("base", {0, 1, 2})});
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&set, t] {
      for (int k = 0; k < 200; ++k) {
        const std::string name = "f" + std::to_string(t) + "_" + std::to_string(k);
        std::vector<FieldSet::Field> one;
        one.push_back(FieldSet::Make(Field(name, {double(k), 1, 2})));
        EXPECT_TRUE(set.Add(std::move(one)).ok());
        EXPECT_TRUE(set.Select(name).ok());
        EXPECT_TRUE(set.Select("base").ok());
        EXPECT_TRUE(set.Delete(name).ok());
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(Names(set), (std::vector<std::string>{"base"}));
}

}  // namespace
}  // namespace actopo::service
