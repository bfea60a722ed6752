// The main of every GoogleTest binary of the project (the server's and client-cpp's): GoogleTest's
// own, plus one line per skipped test, `actopo-test-skip: Suite.Test: reason`, which `make check`
// and `make test` print after ctest (ctest shows a skipped test as "Skipped" but not why).
// Tests skip with ACTOPO_SKIP (skip.h), which fails instead when $ACTOPO_NO_SKIPS is set; a skip
// that still happens then fails the run here.
#include <cstdio>

#include "gtest/gtest.h"
#include "tests/testing/skip.h"

namespace {

class SkipReporter : public testing::EmptyTestEventListener {
 public:
  void OnTestEnd(const testing::TestInfo& test) override {
    const testing::TestResult& result = *test.result();
    if (!result.Skipped()) return;
    for (int i = 0; i < result.total_part_count(); ++i) {
      const testing::TestPartResult& part = result.GetTestPartResult(i);
      if (!part.skipped()) continue;
      std::fprintf(stderr, "actopo-test-skip: %s.%s: %s\n", test.test_suite_name(), test.name(),
                   part.message());
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  testing::UnitTest& unit = *testing::UnitTest::GetInstance();
  unit.listeners().Append(new SkipReporter);  // the listener list owns it
  const int result = RUN_ALL_TESTS();
  if (result == 0 && unit.skipped_test_count() > 0 && actopo::testing::NoSkips()) {
    std::fprintf(stderr, "actopo-test-skip: %d skipped while $ACTOPO_NO_SKIPS is set\n",
                 unit.skipped_test_count());
    return 1;
  }
  return result;
}
