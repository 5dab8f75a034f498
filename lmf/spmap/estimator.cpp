#include "lmf/spmap/estimator.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace lmf::spmap {
namespace {

// A relation known perfectly (S ≈ 0) passes only if its innovation is ≈ 0.
constexpr double kPerfectInnovationTolerance = 1e-6;

// The lower triangle of a symmetric d x d diagonal block, as a full matrix.
Eigen::MatrixXd symmetric_from_lower(const Eigen::Ref<const Eigen::MatrixXd>& L) {
  Eigen::MatrixXd M = L.triangularView<Eigen::Lower>();
  M.triangularView<Eigen::StrictlyUpper>() = M.transpose();
  return M;
}

void validate(const ImplicitMeasurement& m, const StackedMeasurements::EntityLookup& entity, const char* where) {
  const Eigen::Index r = m.h.size();
  if (m.R.rows() != r || m.R.cols() != r) {
    throw std::invalid_argument(std::string(where) + ": R is " + std::to_string(m.R.rows()) + "x" +
                                std::to_string(m.R.cols()) + ", h has " + std::to_string(r) + " rows");
  }
  if (!m.h.allFinite() || !m.R.allFinite()) {
    throw std::invalid_argument(std::string(where) + ": h or R has NaN or inf entries");
  }
  for (const JacobianBlock& b : m.blocks) {
    const Entity& e = entity(b.entity);  // throws for an unknown entity
    if (b.J.rows() != r || b.J.cols() != dof(e.kind) || !b.J.allFinite()) {
      throw std::invalid_argument(std::string(where) + ": Jacobian block of entity " + std::to_string(b.entity) +
                                  " is " + std::to_string(b.J.rows()) + "x" + std::to_string(b.J.cols()) +
                                  " (or not finite), expected " + std::to_string(r) + "x" +
                                  std::to_string(dof(e.kind)));
    }
  }
}

// P(:, touched) (n x t), read from the lower triangle: the row left of each
// diagonal block and the column below it (docs/design.md §5.3).
Eigen::MatrixXd touched_columns(const LowerCovariance& P, const StackedMeasurements& st) {
  const Eigen::Index n = P.rows();
  Eigen::MatrixXd C(n, st.H.cols());
  for (std::size_t a = 0; a < st.touched.size(); ++a) {
    const Eigen::Index off = st.offset[a];
    const Eigen::Index d = st.width[a];
    const Eigen::Index c = st.column[a];
    C.block(0, c, off, d) = P.block(off, 0, d, off).transpose();
    C.block(off, c, d, d) = symmetric_from_lower(P.block(off, off, d, d));
    C.block(off + d, c, n - off - d, d) = P.block(off + d, off, n - off - d, d);
  }
  return C;
}

// P(touched, touched) (t x t): from the gathered columns when given, else
// block by block from the lower triangle.
Eigen::MatrixXd touched_marginal(const LowerCovariance& P, const StackedMeasurements& st,
                                 const Eigen::MatrixXd* columns) {
  const Eigen::Index t = st.H.cols();
  Eigen::MatrixXd M(t, t);
  for (std::size_t a = 0; a < st.touched.size(); ++a) {
    const Eigen::Index off_a = st.offset[a];
    const Eigen::Index d_a = st.width[a];
    const Eigen::Index c_a = st.column[a];
    if (columns != nullptr) {
      M.middleRows(c_a, d_a) = columns->middleRows(off_a, d_a);
      continue;
    }
    M.block(c_a, c_a, d_a, d_a) = symmetric_from_lower(P.block(off_a, off_a, d_a, d_a));
    for (std::size_t b = 0; b < a; ++b) {
      const Eigen::Index off_b = st.offset[b];
      const Eigen::Index d_b = st.width[b];
      const Eigen::Index c_b = st.column[b];
      if (off_a > off_b) {
        M.block(c_a, c_b, d_a, d_b) = P.block(off_a, off_b, d_a, d_b);
      } else {
        M.block(c_a, c_b, d_a, d_b) = P.block(off_b, off_a, d_b, d_a).transpose();
      }
      M.block(c_b, c_a, d_b, d_a) = M.block(c_a, c_b, d_a, d_b).transpose();
    }
  }
  return M;
}

// (Σ_blocks J P_EE Jᵀ + R)_ii over H's nonzero blocks: the diagonal of S as if
// the touched entities were uncorrelated.
Eigen::VectorXd row_scales(const StackedMeasurements& st, const Eigen::MatrixXd& P_tt) {
  Eigen::VectorXd diag = st.R.diagonal();
  for (const StackedMeasurements::Block& b : st.blocks) {
    const Eigen::Index c = st.column[b.touched];
    const Eigen::Index d = st.width[b.touched];
    const auto J = st.H.block(b.row, c, b.rows, d);
    diag.segment(b.row, b.rows) += J.lazyProduct(P_tt.block(c, c, d, d)).cwiseProduct(J).rowwise().sum();
  }
  return diag;
}

// (P Hᵀ)(touched, :) (t x m), in H's column order.
Eigen::MatrixXd touched_rows(const StackedMeasurements& st, const Eigen::MatrixXd& PHt) {
  Eigen::MatrixXd out(st.H.cols(), PHt.cols());
  for (std::size_t a = 0; a < st.touched.size(); ++a) {
    out.middleRows(st.column[a], st.width[a]) = PHt.middleRows(st.offset[a], st.width[a]);
  }
  return out;
}

}  // namespace

double CarefulTolerance::scale(double reference_scale) const {
  return std::max(reference_scale, absolute_floor / relative);
}

double CarefulTolerance::pivot_threshold(double max_abs_diagonal, double reference_scale) const {
  return relative * std::max(max_abs_diagonal, scale(reference_scale));
}

Chi2Table::Chi2Table(double alpha) : alpha_(alpha) {
  if (!(alpha > 0.0 && alpha < 1.0)) {
    throw std::invalid_argument("Chi2Table: alpha must be in (0, 1), got " + std::to_string(alpha));
  }
}

double Chi2Table::operator()(int dof) {
  if (dof <= 0) throw std::invalid_argument("Chi2Table: dof must be positive, got " + std::to_string(dof));
  if (static_cast<std::size_t>(dof) >= cache_.size()) cache_.resize(static_cast<std::size_t>(dof) + 1, -1.0);
  double& t = cache_[static_cast<std::size_t>(dof)];
  if (t < 0.0) t = chi2_threshold(dof, alpha_);
  return t;
}

StackedMeasurements::StackedMeasurements(std::span<const ImplicitMeasurement> measurements,
                                         const EntityLookup& entity, const char* where) {
  touched.reserve(4 * measurements.size());
  column.reserve(4 * measurements.size());
  width.reserve(4 * measurements.size());
  offset.reserve(4 * measurements.size());
  blocks.reserve(4 * measurements.size());
  Eigen::Index m = 0;
  Eigen::Index t = 0;
  for (const ImplicitMeasurement& meas : measurements) {
    validate(meas, entity, where);
    m += meas.h.size();
    for (const JacobianBlock& b : meas.blocks) {
      if (std::find(touched.begin(), touched.end(), b.entity) == touched.end()) {
        touched.push_back(b.entity);
        column.push_back(t);
        width.push_back(b.J.cols());
        offset.push_back(entity(b.entity).offset);
        t += b.J.cols();
      }
    }
  }
  H = Eigen::MatrixXd::Zero(m, t);
  R = Eigen::MatrixXd::Zero(m, m);
  h.resize(m);
  Eigen::Index row = 0;
  for (const ImplicitMeasurement& meas : measurements) {
    const Eigen::Index r = meas.h.size();
    const std::size_t first_block = blocks.size();
    for (const JacobianBlock& b : meas.blocks) {
      const auto a =
          static_cast<std::size_t>(std::find(touched.begin(), touched.end(), b.entity) - touched.begin());
      H.block(row, column[a], r, b.J.cols()) += b.J;
      const bool listed = std::any_of(blocks.begin() + static_cast<std::ptrdiff_t>(first_block), blocks.end(),
                                      [a](const Block& k) { return k.touched == a; });
      if (!listed) blocks.push_back({row, r, a});
    }
    R.block(row, row, r, r) = meas.R;  // noise of different measurements is independent
    h.segment(row, r) = meas.h;
    row += r;
  }
}

Eigen::MatrixXd StackedMeasurements::times_Ht(const Eigen::MatrixXd& X) const {
  // Column axpys: at these shapes (n x 3 times 3 x 2 per block) Eigen's
  // blocked product costs more in packing than the arithmetic.
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(X.rows(), H.rows());
  for (const Block& b : blocks) {
    const Eigen::Index c = column[b.touched];
    const Eigen::Index d = width[b.touched];
    for (Eigen::Index i = 0; i < b.rows; ++i) {
      for (Eigen::Index j = 0; j < d; ++j) {
        const double J_ij = H(b.row + i, c + j);
        if (J_ij != 0.0) out.col(b.row + i) += J_ij * X.col(c + j);  // B_E has structural zeros
      }
    }
  }
  return out;
}

Innovation innovation(const LowerCovariance& P, const StackedMeasurements& st) {
  const Eigen::MatrixXd P_tt = touched_marginal(P, st, nullptr);
  Innovation out;
  // H P_tt Hᵀ + R = ((P_tt Hᵀ)ᵀ Hᵀ) + R, P_tt symmetric.
  out.S = st.times_Ht(st.times_Ht(P_tt).transpose()) + st.R;
  out.S = (0.5 * (out.S + out.S.transpose())).eval();
  out.row_scale = row_scales(st, P_tt);
  out.reference_scale = out.row_scale.size() > 0 ? std::max(0.0, out.row_scale.maxCoeff()) : 0.0;
  return out;
}

Eigen::MatrixXd gather_PHt(const LowerCovariance& P, const StackedMeasurements& st) {
  return st.times_Ht(touched_columns(P, st));
}

bool dropped_rows_consistent(const Eigen::MatrixXd& S, const Eigen::VectorXd& nu, const CarefulInverse& ci,
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

CompatibilityTest chi2_test(const Eigen::MatrixXd& S, const Eigen::VectorXd& h, double reference_scale,
                            const CarefulTolerance& tolerance, Chi2Table& chi2) {
  CompatibilityTest r;
  if (S.rows() == 0) {
    r.passed = true;
    return r;
  }
  const double scale = tolerance.scale(reference_scale);
  const CarefulInverse ci = careful_inverse(S, tolerance.relative, scale);
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  const double pivot_threshold = tolerance.pivot_threshold(S.diagonal().cwiseAbs().maxCoeff(), reference_scale);
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

JointCompatibility::JointCompatibility(const Eigen::MatrixXd& S, const Eigen::VectorXd& row_scale,
                                       const Eigen::VectorXd& h, std::vector<Rows> candidates,
                                       const CarefulTolerance& tolerance, Chi2Table& chi2)
    : S_(S), h_(h), candidates_(std::move(candidates)), relative_(tolerance.relative), chi2_(chi2) {
  if (S.rows() != S.cols() || h.size() != S.rows() || row_scale.size() != S.rows()) {
    throw std::invalid_argument("JointCompatibility: S, row_scale and h sizes disagree");
  }
  double diagonal = 0.0;
  double scale = 0.0;
  bool any = false;
  for (const Rows& c : candidates_) {
    if (c.first < 0 || c.count < 0 || c.first + c.count > S.rows()) {
      throw std::invalid_argument("JointCompatibility: candidate rows outside S");
    }
    for (Eigen::Index i = c.first; i < c.first + c.count; ++i) {
      diagonal = any ? std::max(diagonal, S(i, i)) : S(i, i);
      scale = any ? std::max(scale, row_scale(i)) : row_scale(i);
      any = true;
    }
  }
  // One threshold for every step: the candidates' largest diagonal and reference scale.
  threshold_ = tolerance.pivot_threshold(diagonal, std::max(0.0, scale));
}

bool JointCompatibility::try_add(std::size_t candidate) {
  const Rows& rows = candidates_.at(candidate);
  const Eigen::Index r0 = rows.first;
  const Eigen::Index r = rows.count;
  if (r == 0) return true;  // adds nothing: the set stays as compatible as it was
  const auto nK = static_cast<Eigen::Index>(K_.size());
  Eigen::MatrixXd B(r, nK);
  for (Eigen::Index a = 0; a < nK; ++a) B.col(a) = S_.block(r0, K_[static_cast<std::size_t>(a)], r, 1);
  // Products of a few rows: coefficient-based (lazyProduct); Eigen's blocked
  // GEMM spends more on packing than on the arithmetic at these shapes.
  const Eigen::MatrixXd B_Sinv = B.lazyProduct(S_K_inv_);
  Eigen::MatrixXd residual = S_.block(r0, r0, r, r) - B_Sinv.lazyProduct(B.transpose());
  residual = (0.5 * (residual + residual.transpose())).eval();
  const Eigen::VectorXd nu = h_.segment(r0, r) - B_Sinv * h_K_;
  const CarefulInverse ci = careful_inverse(residual, relative_, threshold_ / relative_);
  const double pivot_threshold = std::max(threshold_, relative_ * residual.diagonal().cwiseAbs().maxCoeff());
  if (!dropped_rows_consistent(residual, nu, ci, pivot_threshold, chi2_)) return false;
  const auto kc = static_cast<Eigen::Index>(ci.kept.size());
  Eigen::VectorXd nu_k(kc);
  for (Eigen::Index a = 0; a < kc; ++a) nu_k(a) = nu(ci.kept[static_cast<std::size_t>(a)]);
  const double d2_new = d2_ + (kc > 0 ? nu_k.dot(ci.inverse * nu_k) : 0.0);
  const int dof_new = dof_ + static_cast<int>(kc);
  if (dof_new > 0 && !(d2_new < chi2_(dof_new))) return false;
  d2_ = d2_new;
  dof_ = dof_new;
  if (kc > 0) grow(rows, B_Sinv, ci);
  return true;
}

void JointCompatibility::grow(const Rows& rows, const Eigen::MatrixXd& B_Sinv, const CarefulInverse& ci) {
  // Block inverse of the grown accepted S:
  // [[A⁻¹ + A⁻¹B Sc⁻¹ BᵀA⁻¹, −A⁻¹B Sc⁻¹], [·, Sc⁻¹]] over the kept rows of c.
  const auto nK = static_cast<Eigen::Index>(K_.size());
  const auto kc = static_cast<Eigen::Index>(ci.kept.size());
  Eigen::MatrixXd Bk_Sinv(kc, nK);
  for (Eigen::Index a = 0; a < kc; ++a) Bk_Sinv.row(a) = B_Sinv.row(ci.kept[static_cast<std::size_t>(a)]);
  const Eigen::MatrixXd& Rk_inv = ci.inverse;
  Eigen::MatrixXd grown(nK + kc, nK + kc);
  grown.topRightCorner(nK, kc).noalias() = -Bk_Sinv.transpose().lazyProduct(Rk_inv);
  grown.topLeftCorner(nK, nK).noalias() = S_K_inv_ - grown.topRightCorner(nK, kc).lazyProduct(Bk_Sinv);
  grown.bottomLeftCorner(kc, nK) = grown.topRightCorner(nK, kc).transpose();
  grown.bottomRightCorner(kc, kc) = Rk_inv;
  S_K_inv_ = std::move(grown);
  Eigen::VectorXd h_grown(nK + kc);
  h_grown.head(nK) = h_K_;
  for (Eigen::Index a = 0; a < kc; ++a) h_grown(nK + a) = h_(rows.first + ci.kept[static_cast<std::size_t>(a)]);
  h_K_ = std::move(h_grown);
  for (const int kept_row : ci.kept) K_.push_back(rows.first + kept_row);
}

UpdateStep update_step(const LowerCovariance& P, const StackedMeasurements& st, const CarefulTolerance& tolerance) {
  UpdateStep step;
  UpdateReport& report = step.report;
  report.touched = st.touched;
  const Eigen::Index m_total = st.rows();
  report.rows = static_cast<int>(m_total);
  if (m_total == 0) return step;

  // P Hᵀ from the gathered columns, block by block of H; S = H P Hᵀ + R from
  // its touched rows (P(touched, :) Hᵀ = (P Hᵀ)(touched, :)).
  const Eigen::MatrixXd C = touched_columns(P, st);
  const Eigen::MatrixXd P_tt = touched_marginal(P, st, &C);
  Eigen::MatrixXd PHt = st.times_Ht(C);
  Eigen::MatrixXd S = st.times_Ht(touched_rows(st, PHt).transpose()) + st.R;
  S = (0.5 * (S + S.transpose())).eval();

  // docs/design.md §6: full-pivot Gauss–Jordan; the rows whose pivots fall below
  // the threshold repeat what the others say and are dropped.
  const Eigen::VectorXd row_scale = row_scales(st, P_tt);
  const CarefulInverse ci =
      careful_inverse(S, tolerance.relative, tolerance.scale(std::max(0.0, row_scale.maxCoeff())));
  report.rows_dropped = static_cast<int>(ci.dropped.size());
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  report.rows_kept = static_cast<int>(k);
  if (k == 0) return step;

  Eigen::MatrixXd S_k(k, k);
  Eigen::VectorXd h_k(k);
  for (Eigen::Index a = 0; a < k; ++a) {
    const Eigen::Index ra = ci.kept[static_cast<std::size_t>(a)];
    h_k(a) = st.h(ra);
    for (Eigen::Index b = 0; b < k; ++b) S_k(a, b) = S(ra, ci.kept[static_cast<std::size_t>(b)]);
  }
  if (k < m_total) {
    Eigen::MatrixXd PHt_k(P.rows(), k);
    for (Eigen::Index a = 0; a < k; ++a) PHt_k.col(a) = PHt.col(ci.kept[static_cast<std::size_t>(a)]);
    PHt = std::move(PHt_k);
  }
  const Eigen::VectorXd Sinv_h = ci.inverse * h_k;
  report.distance2 = h_k.dot(Sinv_h);

  // Eq. (9): p̂ = −W ĥ with W = P Hᵀ S⁻¹ (the measurement predicts ĥ, observes 0).
  step.p_hat = -(PHt * Sinv_h);
  assert(step.p_hat.allFinite());

  // P ← P − P Hᵀ S⁻¹ H P = P − U Uᵀ, U = P Hᵀ L⁻ᵀ with S_k = L Lᵀ.
  const Eigen::LLT<Eigen::MatrixXd> llt(S_k);
  if (llt.info() == Eigen::Success) {
    llt.matrixU().solveInPlace<Eigen::OnTheRight>(PHt);  // PHt ← PHt L⁻ᵀ
  } else {
    // The kept pivots are well above the threshold, so this is rounding only:
    // factor the careful inverse itself, negative rounding clipped.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(ci.inverse);
    const Eigen::VectorXd root = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
    PHt = (PHt * es.eigenvectors() * root.asDiagonal()).eval();
  }
  step.U = std::move(PHt);
  return step;
}

}  // namespace lmf::spmap
