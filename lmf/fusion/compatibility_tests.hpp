// The chi2 tests of the fusion (paper eq. 8; docs/design.md §5 steps 2-4) through the
// careful inversion of the innovation covariance (docs/design.md §6).
//
// Pure and synchronous; a Chi2Table is not thread-safe (it caches).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "lmf/fusion/global_state.hpp"
#include "lmf/spmap/careful_inverse.hpp"
#include "lmf/spmap/ekf.hpp"

namespace lmf::fusion {

// chi2 thresholds at one significance, computed once per degree of freedom.
class Chi2Table {
 public:
  explicit Chi2Table(double alpha) : alpha_(alpha) {}
  double operator()(int dof);

 private:
  double alpha_;
  std::vector<double> cache_;
};

struct Chi2Result {
  double distance2 = 0.0;
  int dof = 0;
  bool passed = false;
};

// The rows the careful inversion `ci` of S dropped are determined by the kept
// ones: given them, their variance is below `pivot_threshold`. Each such row's
// innovation given the kept rows, ν_d − S_dK S_KK⁻¹ ν_K, must then be ≈ 0
// (within what a variance at the threshold allows at the chi2(1) bound):
// otherwise the measurement contradicts a relation the map already knows
// exactly (a pairing 90° off two segments the local map made perpendicular),
// and dropping the row would accept it silently.
bool dropped_rows_consistent(const Eigen::MatrixXd& S, const Eigen::VectorXd& nu, const spmap::CarefulInverse& ci,
                             double pivot_threshold, Chi2Table& chi2);

// The test of one measurement (innovation h) from its block S of a joint
// innovation covariance and that block's reference scale (GlobalState::Innovation).
// A relation known perfectly (S ≈ 0) passes only if its innovation is ≈ 0.
Chi2Result chi2_test(const Eigen::MatrixXd& S, const Eigen::VectorXd& h, double reference_scale, Chi2Table& chi2,
                     double relative_tolerance, double absolute_floor);

// The same for one measurement on the state.
Chi2Result chi2_test(const GlobalState& state, const spmap::ImplicitMeasurement& m, Chi2Table& chi2,
                     double relative_tolerance, double absolute_floor);

}  // namespace lmf::fusion
