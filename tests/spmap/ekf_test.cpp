#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/estimator.hpp"

#include <algorithm>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>
#include <boost/math/distributions/chi_squared.hpp>
#include <gtest/gtest.h>

#include "lmf/spmap/covariance_check.hpp"
#include "spmap_test_util.hpp"
#include "test_support.hpp"

namespace lmf::spmap {
namespace {

using lmf::testing::matrices_near;

// The estimator (estimator.hpp) at the default careful tolerance, one chi2
// table per call: the forms these tests use.
CompatibilityTest individual_compatibility(const StochasticMap& map, const ImplicitMeasurement& m, double alpha) {
  Chi2Table chi2(alpha);
  return individual_compatibility(map, m, CarefulTolerance{}, chi2);
}
std::vector<std::size_t> incremental_joint_compatibility(const StochasticMap& map,
                                                         const std::vector<ImplicitMeasurement>& ms, double alpha) {
  Chi2Table chi2(alpha);
  return incremental_joint_compatibility(map, ms, CarefulTolerance{}, chi2);
}
UpdateReport ekf_update(StochasticMap& map, const std::vector<ImplicitMeasurement>& ms) {
  return ekf_update(map, ms, CarefulTolerance{});
}
Eigen::MatrixXd innovation_covariance(const StochasticMap& map, const std::vector<ImplicitMeasurement>& ms) {
  return innovation(map, ms).S;
}
double innovation_reference_scale(const StochasticMap& map, const std::vector<ImplicitMeasurement>& ms) {
  return innovation(map, ms).reference_scale;
}
Eigen::VectorXd stacked_value(const StochasticMap& map, const std::vector<ImplicitMeasurement>& ms) {
  return stack(map, ms, "test").h;
}

// Dense H (rows x n) of stacked measurements, for the textbook reference.
Eigen::MatrixXd dense_H(const StochasticMap& map, const std::vector<ImplicitMeasurement>& ms) {
  Eigen::Index rows = 0;
  for (const auto& m : ms) rows += m.h.size();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(rows, map.dimension());
  Eigen::Index row = 0;
  for (const auto& m : ms) {
    for (const auto& b : m.blocks) H.block(row, map.entity(b.entity).offset, m.h.size(), b.J.cols()) += b.J;
    row += m.h.size();
  }
  return H;
}

Eigen::MatrixXd dense_R(const std::vector<ImplicitMeasurement>& ms) {
  Eigen::Index rows = 0;
  for (const auto& m : ms) rows += m.h.size();
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(rows, rows);
  Eigen::Index row = 0;
  for (const auto& m : ms) {
    R.block(row, row, m.h.size(), m.h.size()) = m.R;
    row += m.h.size();
  }
  return R;
}

ImplicitMeasurement scalar_measurement(EntityId e, int dof_e, int component, double h, double r) {
  ImplicitMeasurement m;
  m.h = Eigen::VectorXd::Constant(1, h);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(1, dof_e);
  J(0, component) = 1.0;
  m.blocks.push_back({e, J});
  m.R = Eigen::MatrixXd::Constant(1, 1, r);
  return m;
}

TEST(Chi2Threshold, KnownQuantilesAndBadInput) {
  EXPECT_NEAR(chi2_threshold(1, 0.05), 3.841458820694124, 1e-9);
  EXPECT_NEAR(chi2_threshold(2, 0.05), 5.991464547107979, 1e-9);
  EXPECT_NEAR(chi2_threshold(4, 0.01), 13.276704135987622, 1e-9);
  EXPECT_THROW(chi2_threshold(0, 0.05), std::invalid_argument);
  EXPECT_THROW(chi2_threshold(2, 1.5), std::invalid_argument);
}

// chi2_threshold caches its quantiles: repeated and interleaved calls (more
// keys than the cache holds, so it is also refilled) return the Boost value.
TEST(Chi2Threshold, CachedValuesEqualTheQuantile) {
  for (int round = 0; round < 2; ++round) {
    for (int dof = 1; dof <= 60; ++dof) {
      for (const double alpha : {0.001, 0.01, 0.05, 0.2}) {
        const boost::math::chi_squared_distribution<double> chi2(static_cast<double>(dof));
        const double expected = boost::math::quantile(boost::math::complement(chi2, alpha));
        ASSERT_EQ(chi2_threshold(dof, alpha), expected) << "dof " << dof << " alpha " << alpha;
      }
    }
  }
  for (int k = 0; k < 1500; ++k) {  // more distinct keys than the cache bound
    const double alpha = 0.001 + 1e-5 * k;
    const boost::math::chi_squared_distribution<double> chi2(2.0);
    ASSERT_EQ(chi2_threshold(2, alpha), boost::math::quantile(boost::math::complement(chi2, alpha)));
  }
  EXPECT_NEAR(chi2_threshold(2, 0.05), 5.991464547107979, 1e-9);
  EXPECT_THROW(chi2_threshold(-1, 0.05), std::invalid_argument);
}

class LinearGaussian : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937 rng(31);
    R_ = map_.add(EntityKind::kRobot, Pose2(1.0, 2.0, 0.3));
    S_ = map_.add(EntityKind::kSegment, Pose2(3.0, -1.0, 2.0), std::nullopt, 2.0);
    F_ = map_.add(EntityKind::kFrame, Pose2(-1.0, 0.5, -2.9));
    S2_ = map_.add(EntityKind::kSegment, Pose2(0.0, 4.0, -1.0), F_, 1.0);
    map_.mutable_covariance() = test::random_spd(map_.dimension(), rng, 0.1);

    ImplicitMeasurement a;
    a.h = 0.1 * test::random_matrix(2, 1, rng);
    a.blocks = {{R_, test::random_matrix(2, 3, rng)}, {S_, test::random_matrix(2, 2, rng)}};
    a.R = test::random_spd(2, rng, 0.01);
    ImplicitMeasurement b;
    b.h = 0.1 * test::random_matrix(1, 1, rng);
    b.blocks = {{F_, test::random_matrix(1, 3, rng)}};
    b.R = Eigen::MatrixXd::Constant(1, 1, 0.05);
    measurements_ = {a, b};
  }

  StochasticMap map_;
  EntityId R_ = 0, S_ = 0, F_ = 0, S2_ = 0;
  std::vector<ImplicitMeasurement> measurements_;
};

TEST_F(LinearGaussian, GatherAndInnovationMatchDense) {
  const Eigen::MatrixXd& P = map_.covariance();
  const Eigen::MatrixXd H = dense_H(map_, measurements_);
  const Eigen::MatrixXd PHt = gather_PHt(map_, measurements_);
  EXPECT_TRUE(matrices_near(PHt, P * H.transpose(), 1e-12));
  EXPECT_TRUE(matrices_near(innovation_covariance(map_, measurements_),
                            H * P * H.transpose() + dense_R(measurements_), 1e-12));
  Eigen::VectorXd h(3);
  h << measurements_[0].h, measurements_[1].h;
  EXPECT_TRUE(matrices_near(stacked_value(map_, measurements_), h, 0.0));
}

TEST_F(LinearGaussian, UpdateEqualsTextbookKalman) {
  const Eigen::MatrixXd P = map_.covariance();
  const Eigen::MatrixXd H = dense_H(map_, measurements_);
  const Eigen::MatrixXd S = H * P * H.transpose() + dense_R(measurements_);
  const Eigen::VectorXd h = stacked_value(map_, measurements_);
  const Eigen::MatrixXd S_inv = S.inverse();
  const Eigen::MatrixXd P_expected = P - P * H.transpose() * S_inv * H * P;
  const Eigen::VectorXd p_hat = -P * H.transpose() * S_inv * h;
  std::vector<Pose2> expected_locations;
  for (const Entity& e : map_.entities()) {
    expected_locations.push_back(fold(e.location, e.kind, p_hat.segment(e.offset, dof(e.kind))));
  }

  const UpdateReport report = ekf_update(map_, measurements_);
  EXPECT_EQ(report.rows, 3);
  EXPECT_EQ(report.rows_dropped, 0);
  EXPECT_NEAR(report.distance2, h.dot(S_inv * h), 1e-9);
  EXPECT_TRUE(matrices_near(map_.covariance(), P_expected, 1e-12));
  EXPECT_TRUE(matrices_near(map_.covariance(), map_.covariance().transpose(), 0.0));
  for (std::size_t i = 0; i < map_.entities().size(); ++i) {
    EXPECT_TRUE(is_near(map_.entities()[i].location, expected_locations[i], 1e-12, 1e-12)) << i;
  }
  // p̂ really moved something (the test would be vacuous otherwise).
  EXPECT_GT(p_hat.norm(), 1e-3);
}

TEST(EkfUpdate, LargerMapMatchesDenseAndMirrorsExactly) {
  // 70 entities (n = 175): several 64-blocks of the mirrored triangle.
  std::mt19937 rng(43);
  StochasticMap map;
  std::vector<EntityId> ids;
  for (int i = 0; i < 70; ++i) {
    ids.push_back(map.add(i % 2 == 0 ? EntityKind::kSegment : EntityKind::kFrame, Pose2(0.1 * i, -0.05 * i, 0.01 * i),
                          std::nullopt, 1.0));
  }
  map.mutable_covariance() = test::random_spd(map.dimension(), rng, 0.1);
  std::vector<ImplicitMeasurement> ms;
  for (int k = 0; k < 4; ++k) {
    ImplicitMeasurement m;
    m.h = 0.1 * test::random_matrix(2, 1, rng);
    for (const int idx : {3 * k, 17 + 11 * k, 69 - 5 * k}) {
      const EntityId id = ids[static_cast<std::size_t>(idx)];
      m.blocks.push_back({id, test::random_matrix(2, dof(map.entity(id).kind), rng)});
    }
    m.R = test::random_spd(2, rng, 0.01);
    ms.push_back(m);
  }
  const Eigen::MatrixXd P = map.covariance();
  const Eigen::MatrixXd H = dense_H(map, ms);
  const Eigen::MatrixXd S = H * P * H.transpose() + dense_R(ms);
  const Eigen::MatrixXd P_expected = P - P * H.transpose() * S.inverse() * H * P;
  ekf_update(map, ms);
  EXPECT_TRUE(matrices_near(map.covariance(), P_expected, 1e-12));
  EXPECT_TRUE(matrices_near(map.covariance(), map.covariance().transpose(), 0.0));
}

TEST(EkfUpdate, MirrorLowerToUpper) {
  std::mt19937 rng(47);
  Eigen::MatrixXd empty(0, 0);
  mirror_lower_to_upper(empty);  // no-op, no crash
  for (const Eigen::Index n : {1, 5, 64, 130}) {
    Eigen::MatrixXd M = test::random_matrix(n, n, rng);
    Eigen::MatrixXd expected = M;
    expected.triangularView<Eigen::StrictlyUpper>() = M.transpose();
    mirror_lower_to_upper(M);
    EXPECT_TRUE(matrices_near(M, expected, 0.0)) << n;
  }
  Eigen::MatrixXd not_square(2, 3);
  EXPECT_THROW(mirror_lower_to_upper(not_square), std::invalid_argument);
}

TEST(EkfUpdate, DuplicatePerfectConstraintDropsRowsAndStaysPsd) {
  // The paper §III.B failure: two identical perfect constraints make S singular.
  std::mt19937 rng(37);
  StochasticMap map;
  const EntityId R = map.add(EntityKind::kRobot, Pose2(0.0, 0.0, 0.0));
  const EntityId S1 = map.add(EntityKind::kSegment, Pose2(1.0, 2.0, 0.01), std::nullopt, 3.0);
  const EntityId S2 = map.add(EntityKind::kSegment, Pose2(3.5, 2.05, -0.02), std::nullopt, 3.0);
  map.mutable_covariance() = test::random_spd(map.dimension(), rng, 0.01);
  (void)R;
  const ImplicitMeasurement m = measurement_from_chain(chain_between(map, S1, S2), {1, 2});

  StochasticMap single = map;
  ekf_update(single, {m});

  const UpdateReport report = ekf_update(map, {m, m});
  EXPECT_EQ(report.rows, 4);
  EXPECT_EQ(report.rows_dropped, 2);
  const CovarianceHealth health = check_covariance(map.covariance());
  EXPECT_TRUE(health.ok()) << health.describe();
  EXPECT_TRUE(matrices_near(map.covariance(), single.covariance(), 1e-12));
  for (std::size_t i = 0; i < map.entities().size(); ++i) {
    EXPECT_TRUE(is_near(map.entities()[i].location, single.entities()[i].location, 1e-12, 1e-12));
  }
  // The constraint now holds in the covariance: H P⁺ Hᵀ = 0 up to rounding
  // (with the H of the update; the relinearised one differs at second order).
  const Eigen::MatrixXd S_same_H = innovation_covariance(map, {m});
  EXPECT_LT(S_same_H.cwiseAbs().maxCoeff(), 1e-15);
  const ImplicitMeasurement after = measurement_from_chain(chain_between(map, S1, S2), {1, 2});
  EXPECT_LT(after.h.norm(), 1e-3);  // and nearly in the estimate (one linearisation step)

  // The same constraint once more: S is rounding noise (~1e-18 here). Judged
  // against S alone a noise pivot can look invertible (it did in this build:
  // one row kept, gain ~ noise/noise); against the uncorrelated scale all rows go.
  const Eigen::MatrixXd P_before = map.covariance();
  const UpdateReport again = ekf_update(map, {m});
  EXPECT_EQ(again.rows_dropped, 2);
  EXPECT_TRUE(matrices_near(map.covariance(), P_before, 0.0));
}

TEST(EkfUpdate, EmptyAndBadInput) {
  StochasticMap map;
  const EntityId R = map.add(EntityKind::kRobot, Pose2());
  EXPECT_EQ(ekf_update(map, {}).rows, 0);
  ImplicitMeasurement bad = scalar_measurement(R, 3, 0, 0.1, 0.1);
  bad.blocks[0].J = Eigen::MatrixXd::Zero(1, 2);
  EXPECT_THROW(ekf_update(map, {bad}), std::invalid_argument);
  ImplicitMeasurement unknown = scalar_measurement(EntityId{42}, 3, 0, 0.1, 0.1);
  EXPECT_THROW(ekf_update(map, {unknown}), std::invalid_argument);
}

TEST(Compatibility, IndividualAcceptsConsistentRejectsOutlier) {
  StochasticMap map;
  const EntityId S1 = map.add(EntityKind::kSegment, Pose2(0.0, 0.0, 0.0), std::nullopt, 2.0);
  const EntityId S2 = map.add(EntityKind::kSegment, Pose2(1.5, 0.02, 0.01), std::nullopt, 2.0);
  const EntityId S3 = map.add(EntityKind::kSegment, Pose2(1.5, 0.8, 0.01), std::nullopt, 2.0);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(6, 6);
  for (int i = 0; i < 3; ++i) P.block(2 * i, 2 * i, 2, 2) = Eigen::Vector2d(0.05 * 0.05, 0.02 * 0.02).asDiagonal();
  map.mutable_covariance() = P;

  const ImplicitMeasurement good = measurement_from_chain(chain_between(map, S1, S2), {1, 2});
  const ImplicitMeasurement outlier = measurement_from_chain(chain_between(map, S1, S3), {1, 2});
  const CompatibilityTest t_good = individual_compatibility(map, good, 0.05);
  const CompatibilityTest t_out = individual_compatibility(map, outlier, 0.05);
  EXPECT_TRUE(t_good.passed);
  EXPECT_EQ(t_good.dof, 2);
  EXPECT_FALSE(t_out.passed);
  const Eigen::MatrixXd S = innovation_covariance(map, {good});
  EXPECT_NEAR(t_good.distance2, good.h.dot(S.inverse() * good.h), 1e-9);

  // A measurement that touches nothing uncertain and has no noise keeps no rows (dof 0). The
  // dropped rows then decide alone: an exact pairing that agrees passes, one that disagrees fails
  // (before the one estimator, the local map judged kept rows only and passed both).
  StochasticMap exact;
  const EntityId A = exact.add(EntityKind::kSegment, Pose2(), std::nullopt, 1.0);
  const EntityId B = exact.add(EntityKind::kSegment, Pose2(1.0, 0.0, 0.0), std::nullopt, 1.0);
  const EntityId C = exact.add(EntityKind::kSegment, Pose2(1.0, 0.5, 0.0), std::nullopt, 1.0);
  const CompatibilityTest t_agree =
      individual_compatibility(exact, measurement_from_chain(chain_between(exact, A, B), {1, 2}), 0.05);
  EXPECT_EQ(t_agree.dof, 0);
  EXPECT_TRUE(t_agree.passed);
  const CompatibilityTest t_disagree =
      individual_compatibility(exact, measurement_from_chain(chain_between(exact, A, C), {1, 2}), 0.05);
  EXPECT_EQ(t_disagree.dof, 0);
  EXPECT_FALSE(t_disagree.passed);
}

// individual_compatibility forms S from the touched entity blocks; it must
// equal the dense textbook test H P Hᵀ + R (random correlated P, measurements
// of 1-3 rows touching 1-4 entities of both kinds, with and without noise).
TEST(Compatibility, IndividualMatchesDenseReference) {
  std::mt19937 rng(21);
  StochasticMap map;
  std::vector<EntityId> ids;
  for (int i = 0; i < 9; ++i) {
    ids.push_back(map.add(i % 3 == 0 ? EntityKind::kRobot : EntityKind::kSegment, Pose2(), std::nullopt, 1.0));
  }
  map.mutable_covariance() = test::random_spd(map.dimension(), rng, 0.01);
  std::uniform_int_distribution<int> rows_dist(1, 3);
  std::uniform_int_distribution<std::size_t> entity_dist(0, ids.size() - 1);
  for (int trial = 0; trial < 50; ++trial) {
    ImplicitMeasurement m;
    const int r = rows_dist(rng);
    m.h = test::random_matrix(r, 1, rng) * 0.2;
    std::vector<EntityId> used;
    for (int k = 0; k < 1 + trial % 4; ++k) {
      const EntityId e = ids[entity_dist(rng)];
      if (std::find(used.begin(), used.end(), e) != used.end()) continue;
      used.push_back(e);
      m.blocks.push_back({e, test::random_matrix(r, dof(map.entity(e).kind), rng)});
    }
    m.R = trial % 3 == 0 ? Eigen::MatrixXd::Zero(r, r) : test::random_spd(r, rng, 1e-3);
    const Eigen::MatrixXd H = dense_H(map, {m});
    const Eigen::MatrixXd S = H * map.covariance() * H.transpose() + m.R;
    const Eigen::MatrixXd S_sym = 0.5 * (S + S.transpose());
    const CarefulInverse ci = careful_inverse(S_sym, 1e-9, innovation_reference_scale(map, {m}));
    Eigen::VectorXd h_k(static_cast<Eigen::Index>(ci.kept.size()));
    for (std::size_t i = 0; i < ci.kept.size(); ++i) h_k(static_cast<Eigen::Index>(i)) = m.h(ci.kept[i]);
    const double d2 = h_k.dot(ci.inverse * h_k);
    const CompatibilityTest t = individual_compatibility(map, m, 0.05);
    EXPECT_EQ(t.dof, static_cast<int>(ci.kept.size())) << "trial " << trial;
    EXPECT_NEAR(t.distance2, d2, 1e-9 * std::max(1.0, d2)) << "trial " << trial;
    EXPECT_EQ(t.passed, t.dof == 0 || d2 < chi2_threshold(t.dof, 0.05)) << "trial " << trial;
  }
  ImplicitMeasurement bad = scalar_measurement(ids[0], 3, 0, 0.1, 0.1);
  bad.blocks[0].J = Eigen::MatrixXd::Zero(1, 2);
  EXPECT_THROW(individual_compatibility(map, bad, 0.05), std::invalid_argument);
}

TEST(Compatibility, JointRejectsIndividuallyPlausibleOutlier) {
  StochasticMap map;
  const EntityId X = map.add(EntityKind::kRobot, Pose2());
  map.mutable_covariance() = Eigen::Vector3d(1.0, 1.0, 0.1).asDiagonal();
  const ImplicitMeasurement m1 = scalar_measurement(X, 3, 1, 0.010, 1e-4);
  const ImplicitMeasurement m2 = scalar_measurement(X, 3, 1, -0.500, 1e-4);  // outlier
  const ImplicitMeasurement m3 = scalar_measurement(X, 3, 1, 0.012, 1e-4);
  for (const auto& m : {m1, m2, m3}) EXPECT_TRUE(individual_compatibility(map, m, 0.05).passed);

  EXPECT_EQ(incremental_joint_compatibility(map, {m1, m2, m3}, 0.05), (std::vector<std::size_t>{0, 2}));
  // Visiting order decides which of two contradicting pairings wins.
  EXPECT_EQ(incremental_joint_compatibility(map, {m2, m1, m3}, 0.05), (std::vector<std::size_t>{0}));
  // A repeated perfect constraint adds no dof and stays compatible.
  const ImplicitMeasurement perfect = scalar_measurement(X, 3, 2, 0.01, 0.0);
  EXPECT_EQ(incremental_joint_compatibility(map, {perfect, perfect, m1}, 0.05),
            (std::vector<std::size_t>{0, 1, 2}));
}

// Reference incremental JC: the joint S of (kept + candidate) built densely and
// inverted carefully at every step (the textbook algorithm, no reuse).
std::vector<std::size_t> reference_joint_compatibility(const StochasticMap& map,
                                                       const std::vector<ImplicitMeasurement>& candidates,
                                                       double alpha) {
  std::vector<std::size_t> kept;
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    std::vector<ImplicitMeasurement> trial;
    for (std::size_t k : kept) trial.push_back(candidates[k]);
    trial.push_back(candidates[c]);
    const Eigen::MatrixXd H = dense_H(map, trial);
    const Eigen::MatrixXd S = H * map.covariance() * H.transpose() + dense_R(trial);
    const CarefulInverse ci = careful_inverse(0.5 * (S + S.transpose()), 1e-9, innovation_reference_scale(map, trial));
    const Eigen::VectorXd h = stacked_value(map, trial);
    Eigen::VectorXd h_k(static_cast<Eigen::Index>(ci.kept.size()));
    for (std::size_t i = 0; i < ci.kept.size(); ++i) h_k(static_cast<Eigen::Index>(i)) = h(ci.kept[i]);
    const int dof_kept = static_cast<int>(ci.kept.size());
    if (dof_kept == 0 || h_k.dot(ci.inverse * h_k) < chi2_threshold(dof_kept, alpha)) kept.push_back(c);
  }
  return kept;
}

// incremental_joint_compatibility reuses the gathers and updates S⁻¹ by blocks
// (falling back to the careful inversion near singularity); it must keep the
// same candidates as the reference on random correlated maps with consistent
// measurements, outliers, perfect constraints and their repetitions (which
// make S singular and rows drop), and measurements of exactly known entities.
TEST(Compatibility, JointMatchesCarefulReference) {
  std::mt19937 rng(33);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> kind_dist(0, 9);
  int total_kept = 0;
  int total_rejected = 0;
  for (int trial = 0; trial < 40; ++trial) {
    StochasticMap map;
    std::vector<EntityId> ids;
    for (int i = 0; i < 8; ++i) {
      ids.push_back(map.add(i % 4 == 0 ? EntityKind::kRobot : EntityKind::kSegment, Pose2(), std::nullopt, 1.0));
    }
    const EntityId exact = map.add(EntityKind::kSegment, Pose2(), std::nullopt, 1.0);  // zero covariance
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(map.dimension(), map.dimension());
    P.topLeftCorner(map.dimension() - 2, map.dimension() - 2) = test::random_spd(map.dimension() - 2, rng, 0.01);
    map.mutable_covariance() = P;

    std::uniform_int_distribution<std::size_t> entity_dist(0, ids.size() - 1);
    std::vector<ImplicitMeasurement> candidates;
    for (int k = 0; k < 14; ++k) {
      const int kind = kind_dist(rng);
      if (kind == 0 && !candidates.empty()) {  // repeat an earlier candidate (perfect ones: redundant rows)
        candidates.push_back(candidates[static_cast<std::size_t>(k) % candidates.size()]);
        continue;
      }
      ImplicitMeasurement m;
      const Eigen::Index r = 1 + k % 2;
      m.h = Eigen::VectorXd::Zero(r);
      const bool perfect = kind == 1 || kind == 2;
      const bool on_exact = kind == 3;
      std::vector<EntityId> used;
      for (int b = 0; b < 2; ++b) {
        const EntityId e = on_exact ? exact : ids[entity_dist(rng)];
        if (std::find(used.begin(), used.end(), e) != used.end()) continue;
        used.push_back(e);
        m.blocks.push_back({e, test::random_matrix(r, dof(map.entity(e).kind), rng)});
      }
      m.R = perfect || on_exact ? Eigen::MatrixXd::Zero(r, r) : test::random_spd(r, rng, 1e-3);
      // ĥ drawn from N(0, S_ii) (consistent), scaled up for outliers (kind 4, 5).
      const Eigen::MatrixXd H = dense_H(map, {m});
      const Eigen::MatrixXd S_m = H * map.covariance() * H.transpose() + m.R;
      const double gain = kind == 4 || kind == 5 ? 6.0 : 0.7;
      for (Eigen::Index i = 0; i < r; ++i) m.h(i) = gain * std::sqrt(std::max(S_m(i, i), 0.0)) * normal(rng);
      if (on_exact) m.h.setZero();
      candidates.push_back(m);
    }
    const std::vector<std::size_t> expected = reference_joint_compatibility(map, candidates, 0.05);
    EXPECT_EQ(incremental_joint_compatibility(map, candidates, 0.05), expected) << "trial " << trial;
    total_kept += static_cast<int>(expected.size());
    total_rejected += static_cast<int>(candidates.size() - expected.size());
  }
  // The scenarios exercise both outcomes.
  EXPECT_GT(total_kept, 100);
  EXPECT_GT(total_rejected, 20);
}

}  // namespace
}  // namespace lmf::spmap
