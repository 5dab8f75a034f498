#include "lmf/local_map/consistency.hpp"

#include <stdexcept>

#include <gtest/gtest.h>

namespace lmf {
namespace {

TEST(PoseNees, IsTheMahalanobisDistanceOfThePerturbation) {
  const Pose2 x_hat(1.0, 2.0, 3.1);
  const Pose2 x_true = compose(x_hat, Pose2(0.1, -0.2, 0.1));  // crosses ±pi: wrapped
  const Eigen::Matrix3d P = Eigen::Vector3d(0.01, 0.04, 0.01).asDiagonal();
  const std::optional<double> nees = pose_nees(x_hat, P, x_true);
  ASSERT_TRUE(nees.has_value());
  EXPECT_NEAR(*nees, 1.0 + 1.0 + 1.0, 1e-9);
  EXPECT_FALSE(pose_nees(x_hat, Eigen::Matrix3d::Zero(), x_true).has_value());
  EXPECT_FALSE(pose_nees(x_hat, Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal().toDenseMatrix(), x_true).has_value());
}

TEST(AverageNeesBand, MatchesChiSquareQuantiles) {
  const NeesBand one = average_nees_band(3, 1);
  EXPECT_NEAR(one.lower, 0.2158, 1e-4);  // chi2inv(0.025, 3)
  EXPECT_NEAR(one.upper, 9.3484, 1e-4);  // chi2inv(0.975, 3)
  const NeesBand twenty = average_nees_band(3, 20);
  EXPECT_NEAR(twenty.lower, 40.4817 / 20.0, 1e-4);  // chi2inv(0.025, 60) / 20
  EXPECT_NEAR(twenty.upper, 83.2977 / 20.0, 1e-4);  // chi2inv(0.975, 60) / 20
  EXPECT_THROW(average_nees_band(3, 0), std::invalid_argument);
  EXPECT_THROW(average_nees_band(3, 5, 1.0), std::invalid_argument);
}

}  // namespace
}  // namespace lmf
