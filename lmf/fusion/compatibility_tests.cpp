#include "lmf/fusion/compatibility_tests.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace lmf::fusion {
namespace {

// A relation known perfectly (S ≈ 0) passes only if its innovation is ≈ 0.
constexpr double kPerfectInnovationTolerance = 1e-6;

}  // namespace

double Chi2Table::operator()(int dof) {
  if (static_cast<std::size_t>(dof) >= cache_.size()) cache_.resize(static_cast<std::size_t>(dof) + 1, -1.0);
  double& t = cache_[static_cast<std::size_t>(dof)];
  if (t < 0.0) t = spmap::chi2_threshold(dof, alpha_);
  return t;
}

bool dropped_rows_consistent(const Eigen::MatrixXd& S, const Eigen::VectorXd& nu, const spmap::CarefulInverse& ci,
                             double pivot_threshold, Chi2Table& chi2) {
  if (ci.dropped.empty()) return true;
  const double bound = std::max(kPerfectInnovationTolerance, std::sqrt(chi2(1) * pivot_threshold));
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  Eigen::VectorXd nu_K(k);
  for (Eigen::Index a = 0; a < k; ++a) nu_K(a) = nu(ci.kept[static_cast<std::size_t>(a)]);
  const Eigen::VectorXd Sinv_nu_K = k > 0 ? Eigen::VectorXd(ci.inverse * nu_K) : Eigen::VectorXd();
  for (const int d : ci.dropped) {
    double conditional = nu(d);
    for (Eigen::Index a = 0; a < k; ++a) conditional -= S(d, ci.kept[static_cast<std::size_t>(a)]) * Sinv_nu_K(a);
    if (!(std::abs(conditional) <= bound)) return false;
  }
  return true;
}

Chi2Result chi2_test(const Eigen::MatrixXd& S, const Eigen::VectorXd& h, double reference_scale, Chi2Table& chi2,
                     double relative_tolerance, double absolute_floor) {
  Chi2Result r;
  const double scale = std::max(reference_scale, absolute_floor / relative_tolerance);
  const spmap::CarefulInverse ci = spmap::careful_inverse(S, relative_tolerance, scale);
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  const double pivot_threshold = relative_tolerance * std::max(S.diagonal().cwiseAbs().maxCoeff(), scale);
  if (!dropped_rows_consistent(S, h, ci, pivot_threshold, chi2)) return r;
  if (k == 0) {
    r.passed = true;
    return r;
  }
  Eigen::VectorXd h_k(k);
  for (Eigen::Index i = 0; i < k; ++i) h_k(i) = h(ci.kept[static_cast<std::size_t>(i)]);
  r.dof = static_cast<int>(k);
  r.distance2 = h_k.dot(ci.inverse * h_k);
  r.passed = r.distance2 < chi2(r.dof);
  return r;
}

Chi2Result chi2_test(const GlobalState& state, const spmap::ImplicitMeasurement& m, Chi2Table& chi2,
                     double relative_tolerance, double absolute_floor) {
  const GlobalState::Innovation in = state.innovation(m);
  return chi2_test(in.S, m.h, in.reference_scale, chi2, relative_tolerance, absolute_floor);
}

}  // namespace lmf::fusion
