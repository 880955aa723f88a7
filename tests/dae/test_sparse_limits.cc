// Sparse patterns at the limits of int: a column count of INT_MAX would need INT_MAX + 1
// column starts; it is refused (it overflowed int in cols + 1, undefined behaviour).
#include "dae/sparse.h"

#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>
#include <string>

namespace mbdae::dae {
namespace {

constexpr int kMax = std::numeric_limits<int>::max();

TEST(SparseLimits, ColumnCountOfIntMaxIsRefused) {
  try {
    CscPattern::FromEntries(2, kMax, {{0, 0}});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("2147483647 columns are too many"), std::string::npos) << e.what();
  }
  // As many rows as int holds are fine for a column-compressed pattern.
  const CscPattern p = CscPattern::FromEntries(kMax, 2, {{kMax - 1, 1}, {0, 0}});
  std::string why;
  EXPECT_TRUE(p.IsValid(&why)) << why;
  EXPECT_EQ(p.find(kMax - 1, 1), 1);
  EXPECT_EQ(p.find(kMax - 1, 0), -1);
}

TEST(SparseLimits, IsValidNamesTheExpectedSizeWithoutOverflow) {
  CscPattern p;
  p.rows = 1;
  p.cols = kMax;
  std::string why;
  EXPECT_FALSE(p.IsValid(&why));
  EXPECT_NE(why.find("expected 2147483648"), std::string::npos) << why;
}

}  // namespace
}  // namespace mbdae::dae
