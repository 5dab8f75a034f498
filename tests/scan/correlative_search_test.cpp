// The correlative search (correlative_search.hpp): the likelihood field's
// max-pooled levels against brute force, and the branch and bound against an
// exhaustive scan of the same window of poses.
#include "lmf/scan/correlative_search.hpp"

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace lmf {
namespace {

std::vector<Eigen::Vector2d> random_points(std::mt19937& rng, int n, double extent) {
  std::uniform_real_distribution<double> coordinate(0.0, extent);
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < n; ++i) points.emplace_back(coordinate(rng), coordinate(rng));
  return points;
}

TEST(LikelihoodField, LevelsAreBlockMaximaOfLevelZero) {
  std::mt19937 rng(1);
  const std::vector<Eigen::Vector2d> points = random_points(rng, 40, 3.0);
  const Eigen::AlignedBox2d region(Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(3.0, 3.0));
  const LikelihoodField field(points, region, 0.1, 0.1, 4);
  // A point's own cell: within half a cell diagonal (0.07 m) of it, so e^(-0.25) or more.
  for (const Eigen::Vector2d& p : points) EXPECT_GE(field.likelihood(p), 0.77);
  EXPECT_EQ(field.value(0, -1, 5), 0);
  EXPECT_EQ(field.value(0, 5, 1000), 0);
  for (int level = 1; level < 4; ++level) {
    const int size = 1 << level;
    for (int iy = -size - 1; iy <= 33; ++iy) {
      for (int ix = -size - 1; ix <= 33; ++ix) {
        int expected = 0;
        for (int dy = 0; dy < size; ++dy) {
          for (int dx = 0; dx < size; ++dx) expected = std::max(expected, field.value(0, ix + dx, iy + dy));
        }
        ASSERT_EQ(field.value(level, ix, iy), expected) << level << " " << ix << " " << iy;
      }
    }
  }
  EXPECT_THROW(LikelihoodField(points, region, 0.0, 0.1, 2), std::invalid_argument);
}

TEST(CorrelativeSearch, BranchAndBoundFindsTheExhaustiveBest) {
  std::mt19937 rng(2);
  // A reference of random points and a scan of a subset of them seen from a
  // pose inside the window, with some clutter.
  const std::vector<Eigen::Vector2d> reference = random_points(rng, 300, 8.0);
  const Pose2 truth(4.13, 3.92, 0.07);
  std::vector<Eigen::Vector2d> scan;
  for (std::size_t i = 0; i < reference.size(); i += 2) scan.push_back(between(truth, Pose2(reference[i].x(), reference[i].y(), 0.0)).vector().head<2>());
  for (const Eigen::Vector2d& p : random_points(rng, 20, 3.0)) scan.push_back(p);
  const Eigen::AlignedBox2d region(Eigen::Vector2d(-1.0, -1.0), Eigen::Vector2d(9.0, 9.0));
  const LikelihoodField field(reference, region, 0.1, 0.1, 4);
  const Pose2 centre(4.0, 4.0, 0.0);
  const CorrelativeWindow window{0.3, 0.1, 0.01};
  const std::optional<CorrelativeResult> result = correlative_search(field, scan, centre, window, 0.1, 0.8);
  ASSERT_TRUE(result.has_value());
  // Exhaustive: every pose of the window.
  double best = -1.0;
  Pose2 best_pose;
  int above = 0;
  std::vector<double> scores;
  for (int k = -10; k <= 10; ++k) {
    const Eigen::Rotation2Dd R(centre.phi + k * 0.01);
    for (int i = -3; i <= 3; ++i) {
      for (int j = -3; j <= 3; ++j) {
        const Eigen::Vector2d t(centre.x + 0.1 * i, centre.y + 0.1 * j);
        int s = 0;
        for (const Eigen::Vector2d& p : scan) {
          const Eigen::Vector2i c = field.cell(Eigen::Vector2d(centre.x, centre.y) + R * p);
          s += field.value(0, c.x() + i, c.y() + j);
        }
        const double score = s / (255.0 * static_cast<double>(scan.size()));
        scores.push_back(score);
        if (score > best) {
          best = score;
          best_pose = Pose2(t.x(), t.y(), centre.phi + k * 0.01);
        }
      }
    }
  }
  for (const double s : scores) above += s >= 0.8 * best - 1e-12 ? 1 : 0;
  EXPECT_NEAR(result->best.score, best, 1e-12);
  EXPECT_TRUE(is_near(result->best.x, truth, 0.051, 0.006)) << result->best.x.x << " " << result->best.x.y << " " << result->best.x.phi;
  EXPECT_TRUE(is_near(result->best.x, best_pose, 1e-9, 1e-9) || std::abs(result->best.score - best) < 1e-12);
  // Every pose scoring at least 0.8 of the best is a contender (or the best).
  EXPECT_EQ(static_cast<int>(result->contenders.size()) + 1, above);
  for (const CorrelativeMatch& c : result->contenders) EXPECT_GE(c.score, 0.8 * best - 1e-12);
  // Nothing above a score no pose reaches.
  EXPECT_FALSE(correlative_search(field, scan, centre, window, best + 0.01).has_value());
  EXPECT_FALSE(correlative_search(field, {}, centre, window, 0.0).has_value());
  EXPECT_THROW(correlative_search(field, scan, centre, CorrelativeWindow{0.3, 0.1, 0.0}, 0.1), std::invalid_argument);
}

TEST(CorrelativeSearch, OnlyTheOutermostRingOfTheWindowIsItsEdge) {
  // ± 0.3 m at 0.1 m cells (3 cells out), ± 0.1 rad at 0.02 rad steps (5 steps out).
  const CorrelativeWindow window{0.3, 0.1, 0.02};
  const Pose2 centre(1.0, 2.0, 0.5);
  EXPECT_FALSE(on_window_edge(centre, centre, window, 0.1));
  EXPECT_FALSE(on_window_edge(Pose2(1.2, 1.8, 0.42), centre, window, 0.1));
  EXPECT_TRUE(on_window_edge(Pose2(1.3, 2.0, 0.5), centre, window, 0.1));
  EXPECT_TRUE(on_window_edge(Pose2(1.0, 1.7, 0.5), centre, window, 0.1));
  EXPECT_TRUE(on_window_edge(Pose2(1.0, 2.0, 0.4), centre, window, 0.1));
  EXPECT_TRUE(on_window_edge(Pose2(1.0, 2.0, 0.6), centre, window, 0.1));
  // A heading across ±π from the centre's is measured the short way round.
  const Pose2 near_pi(0.0, 0.0, 3.1);
  EXPECT_FALSE(on_window_edge(Pose2(0.0, 0.0, -3.1), near_pi, window, 0.1));
  // An axis the window does not search has no edge.
  EXPECT_FALSE(on_window_edge(Pose2(1.0, 2.0, 0.5), centre, CorrelativeWindow{0.0, 0.0, 0.02}, 0.1));
}

TEST(CorrelativeSearch, ARectangularWindowHasEachAxisItsOwnEdge) {
  // ± 0.3 m in x, ± 0.8 m in y (8 cells out).
  CorrelativeWindow window{0.3, 0.1, 0.02};
  window.linear_y_m = 0.8;
  const Pose2 centre(1.0, 2.0, 0.5);
  EXPECT_TRUE(on_window_edge(Pose2(1.3, 2.0, 0.5), centre, window, 0.1));
  EXPECT_FALSE(on_window_edge(Pose2(1.0, 2.3, 0.5), centre, window, 0.1));
  EXPECT_FALSE(on_window_edge(Pose2(1.0, 1.3, 0.5), centre, window, 0.1));
  EXPECT_TRUE(on_window_edge(Pose2(1.0, 2.8, 0.5), centre, window, 0.1));
  EXPECT_TRUE(on_window_edge(Pose2(1.0, 1.2, 0.5), centre, window, 0.1));
}

}  // namespace
}  // namespace lmf
