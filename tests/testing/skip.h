// ACTOPO_SKIP() << "why": skips the test, or fails it when $ACTOPO_NO_SKIPS is set (CI sets it).
// In CI every tool and file a test needs is installed, so a skip there would be a test that
// silently stopped testing. Tests use this instead of GTEST_SKIP (`make lint-tests` checks).
//
//   if (!std::filesystem::is_directory(DataDir())) ACTOPO_SKIP() << "no data in " << DataDir();
#ifndef ACTOPO_TESTS_TESTING_SKIP_H_
#define ACTOPO_TESTS_TESTING_SKIP_H_

#include <cstdlib>

#include "gtest/gtest.h"

namespace actopo::testing {

inline bool NoSkips() {
  const char* value = std::getenv("ACTOPO_NO_SKIPS");
  return value != nullptr && *value != '\0';
}

}  // namespace actopo::testing

// GTEST_SKIP() and GTEST_FAIL() are this statement with a fixed result type; here the type
// depends on $ACTOPO_NO_SKIPS.
#define ACTOPO_SKIP()                                                                             \
  return ::testing::internal::AssertHelper(                                                       \
             ::actopo::testing::NoSkips() ? ::testing::TestPartResult::kFatalFailure              \
                                          : ::testing::TestPartResult::kSkip,                     \
             __FILE__, __LINE__,                                                                  \
             ::actopo::testing::NoSkips() ? "skipped, and $ACTOPO_NO_SKIPS is set" : "Skipped") = \
             ::testing::Message()

#endif  // ACTOPO_TESTS_TESTING_SKIP_H_
