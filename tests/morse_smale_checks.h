// The Morse-Smale checks the fidelity tests share: a result against TTK's counts and
// segmentation digests in expected-ttk.json's "morse_smale" format.
#ifndef ACTOPO_TESTS_MORSE_SMALE_CHECKS_H_
#define ACTOPO_TESTS_MORSE_SMALE_CHECKS_H_

#include <cstdint>
#include <string>

#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/morse_smale.h"

namespace actopo::testing {

inline void ExpectMorseSmaleEquals(const MorseSmaleResult& r, const nlohmann::json& ms) {
  EXPECT_EQ(nlohmann::json(r.gradient.critical_cells), ms["critical_cells"]);
  EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kDescending),
            ms["separatrices"]["descending"].get<int64_t>());
  EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kAscending),
            ms["separatrices"]["ascending"].get<int64_t>());
  EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kSaddleConnector),
            ms["separatrices"]["saddle_connectors"].get<int64_t>());
  EXPECT_EQ(r.Segments(), ms["separatrices"]["segments"].get<int64_t>());
  EXPECT_EQ(MorseSmaleResult::Regions(r.descending), ms["regions"]["descending"].get<int64_t>());
  EXPECT_EQ(MorseSmaleResult::Regions(r.ascending), ms["regions"]["ascending"].get<int64_t>());
  EXPECT_EQ(MorseSmaleResult::Regions(r.morse_smale), ms["regions"]["morse_smale"].get<int64_t>());
  for (const auto& [key, labels] :
       {std::pair{"descending", &r.descending}, std::pair{"ascending", &r.ascending},
        std::pair{"morse_smale", &r.morse_smale}}) {
    EXPECT_EQ(MorseSmaleResult::SegmentationDigest(*labels),
              ms["segmentation_sha256"][key].get<std::string>())
        << key;
  }
}

}  // namespace actopo::testing

#endif  // ACTOPO_TESTS_MORSE_SMALE_CHECKS_H_
