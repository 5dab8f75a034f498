#include "lmf/common/median.hpp"

#include <stdexcept>

#include <gtest/gtest.h>

namespace {

TEST(Median, IsTheMiddleValueWhateverTheOrder) {
  EXPECT_EQ(lmf::median({3.0, -1.0, 7.0}), 3.0);
  EXPECT_EQ(lmf::median({5.0}), 5.0);
  // An even count gives the upper of the two middle values, never their mean.
  EXPECT_EQ(lmf::median({4.0, 1.0, 2.0, 3.0}), 3.0);
  // An outlier does not move it.
  EXPECT_EQ(lmf::median({1.0, 2.0, 1e9}), 2.0);
}

TEST(Median, OfNothingIsRefused) { EXPECT_THROW(lmf::median({}), std::invalid_argument); }

}  // namespace
