#include "lmf/spmap/ekf.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <boost/math/distributions/chi_squared.hpp>

namespace lmf::spmap {
namespace {

// Bound of the per-thread chi2 quantile cache (entries of (dof, alpha)).
constexpr std::size_t kMaxCachedQuantiles = 1024;

// incremental_joint_compatibility takes the block-inverse fast path only when
// the lower bound on the smallest pivot, 1 / trace(S⁻¹), exceeds the careful
// inversion's threshold by this factor, and a floor relative to the scale of S
// (so a zero tolerance still leaves rounding-level pivots to the careful inversion).
constexpr double kFastPathMargin = 4.0;
constexpr double kFastPathFloor = 1e-12;

Eigen::Index total_rows(const std::vector<ImplicitMeasurement>& measurements) {
  Eigen::Index m = 0;
  for (const ImplicitMeasurement& meas : measurements) m += meas.h.size();
  return m;
}

void validate(const StochasticMap& map, const ImplicitMeasurement& m, const char* where) {
  const Eigen::Index r = m.h.size();
  if (m.R.rows() != r || m.R.cols() != r) {
    throw std::invalid_argument(std::string(where) + ": R is " + std::to_string(m.R.rows()) + "x" +
                                std::to_string(m.R.cols()) + ", h has " + std::to_string(r) + " rows");
  }
  if (!m.h.allFinite() || !m.R.allFinite()) {
    throw std::invalid_argument(std::string(where) + ": h or R has NaN or inf entries");
  }
  for (const JacobianBlock& b : m.blocks) {
    const Entity& e = map.entity(b.entity);  // throws for an unknown entity
    if (b.J.rows() != r || b.J.cols() != dof(e.kind) || !b.J.allFinite()) {
      throw std::invalid_argument(std::string(where) + ": Jacobian block of entity " + std::to_string(b.entity) +
                                  " is " + std::to_string(b.J.rows()) + "x" + std::to_string(b.J.cols()) +
                                  " (or not finite), expected " + std::to_string(r) + "x" +
                                  std::to_string(dof(e.kind)));
    }
  }
}

// out += C Jᵀ for the n x d columns C of P an entity owns and a small J
// (rows x d, d <= 3): column axpys. A general product would pack C for a
// matrix kernel whose inner dimension is only d, which costs more than the sum.
template <typename Out, typename Columns>
void add_columns_times_Jt(Out&& out, const Columns& C, const Eigen::MatrixXd& J) {
  for (Eigen::Index i = 0; i < J.rows(); ++i) {
    for (Eigen::Index k = 0; k < J.cols(); ++k) {
      if (J(i, k) != 0.0) out.col(i) += J(i, k) * C.col(k);  // structural zeros of B_E are common
    }
  }
}

// H_m X for X with one row per state row (n x c): touches only H's blocks.
Eigen::MatrixXd apply_H(const StochasticMap& map, const ImplicitMeasurement& m, const Eigen::MatrixXd& X) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(m.h.size(), X.cols());
  for (const JacobianBlock& b : m.blocks) {
    out.noalias() += b.J * X.middleRows(map.entity(b.entity).offset, b.J.cols());
  }
  return out;
}

// max_i (Σ_blocks J P_EE Jᵀ + R)_ii of one (validated) measurement, or 0.
double reference_scale_of(const StochasticMap& map, const ImplicitMeasurement& m) {
  Eigen::VectorXd diag = m.R.diagonal();
  for (const JacobianBlock& b : m.blocks) {
    const Entity& e = map.entity(b.entity);
    const Eigen::Index d = b.J.cols();
    diag += (b.J * map.covariance().block(e.offset, e.offset, d, d)).cwiseProduct(b.J).rowwise().sum();
  }
  return diag.size() > 0 ? std::max(0.0, diag.maxCoeff()) : 0.0;
}

// Distance ĥ_kᵀ S_k⁻¹ ĥ_k over the rows the careful inversion kept.
double reduced_distance2(const Eigen::VectorXd& h, const CarefulInverse& ci) {
  Eigen::VectorXd h_k(static_cast<Eigen::Index>(ci.kept.size()));
  for (std::size_t i = 0; i < ci.kept.size(); ++i) h_k(static_cast<Eigen::Index>(i)) = h(ci.kept[i]);
  return h_k.dot(ci.inverse * h_k);
}

CompatibilityTest compatibility(const Eigen::VectorXd& h, const Eigen::MatrixXd& S, double alpha,
                                double relative_tolerance, double reference_scale) {
  const CarefulInverse ci = careful_inverse(S, relative_tolerance, reference_scale);
  CompatibilityTest t;
  t.dof = static_cast<int>(ci.kept.size());
  t.distance2 = reduced_distance2(h, ci);
  t.passed = t.dof == 0 || t.distance2 < chi2_threshold(t.dof, alpha);
  return t;
}

}  // namespace

ImplicitMeasurement measurement_from_chain(const std::vector<ChainLink>& links, const std::vector<int>& rows,
                                           const std::vector<Eigen::MatrixXd>& link_noise,
                                           const Eigen::VectorXd& target) {
  const auto r = static_cast<Eigen::Index>(rows.size());
  if (r == 0) throw std::invalid_argument("measurement_from_chain: no rows selected");
  for (const int row : rows) {
    if (row < 0 || row > 2) {
      throw std::invalid_argument("measurement_from_chain: row " + std::to_string(row) + " is not 0, 1 or 2");
    }
  }
  if (target.size() != 0 && target.size() != r) {
    throw std::invalid_argument("measurement_from_chain: target has " + std::to_string(target.size()) +
                                " entries for " + std::to_string(r) + " rows");
  }
  if (!link_noise.empty() && link_noise.size() != links.size()) {
    throw std::invalid_argument("measurement_from_chain: link_noise has " + std::to_string(link_noise.size()) +
                                " entries for " + std::to_string(links.size()) + " links");
  }

  const ChainValue chain = evaluate_chain(links);
  // B_out selects rows of (x, y, phi): taken as rows, not multiplied.
  const auto B_out = [&rows](const auto& M) {
    Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()), M.cols());
    for (std::size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = M.row(rows[i]);
    return out;
  };

  ImplicitMeasurement m;
  const Eigen::Vector3d value = chain.value.vector();
  m.h.resize(r);
  for (Eigen::Index i = 0; i < r; ++i) {
    m.h(i) = value(rows[static_cast<std::size_t>(i)]);
    if (target.size() != 0) m.h(i) -= target(i);
    // docs/design.md §3: angle innovations are wrapped, never a 2pi jump.
    if (rows[static_cast<std::size_t>(i)] == 2) m.h(i) = wrap_angle(m.h(i));
  }
  m.R = Eigen::MatrixXd::Zero(r, r);

  m.blocks.reserve(links.size());
  for (std::size_t l = 0; l < links.size(); ++l) {
    Eigen::MatrixXd J = B_out(chain.jacobians[l]);
    if (links[l].entity) {
      // One block per entity: an entity that appears twice (shared ancestors,
      // the target itself) gets its contributions summed.
      JacobianBlock* existing = nullptr;
      for (JacobianBlock& b : m.blocks) {
        if (b.entity == *links[l].entity) existing = &b;
      }
      if (existing != nullptr) {
        existing->J += J;
      } else {
        m.blocks.push_back({*links[l].entity, std::move(J)});
      }
    } else if (!link_noise.empty() && link_noise[l].size() != 0) {
      const Eigen::MatrixXd& R_l = link_noise[l];
      const Eigen::Index d = dof(links[l].kind);
      if (R_l.rows() != d || R_l.cols() != d) {
        throw std::invalid_argument("measurement_from_chain: noise of link " + std::to_string(l) + " is " +
                                    std::to_string(R_l.rows()) + "x" + std::to_string(R_l.cols()) +
                                    ", expected " + std::to_string(d) + "x" + std::to_string(d));
      }
      m.R.noalias() += J * R_l * J.transpose();
    }
  }
  m.R = 0.5 * (m.R + m.R.transpose()).eval();
  return m;
}

Eigen::MatrixXd gather_PHt(const StochasticMap& map, const std::vector<ImplicitMeasurement>& measurements) {
  const StochasticMap::CovarianceView P = map.covariance();
  Eigen::MatrixXd PHt = Eigen::MatrixXd::Zero(P.rows(), total_rows(measurements));
  Eigen::Index col = 0;
  for (const ImplicitMeasurement& m : measurements) {
    validate(map, m, "gather_PHt");
    const Eigen::Index r = m.h.size();
    // docs/design.md §5.3: P Hᵀ is a gather over the few columns H touches.
    for (const JacobianBlock& b : m.blocks) {
      add_columns_times_Jt(PHt.middleCols(col, r), P.middleCols(map.entity(b.entity).offset, b.J.cols()), b.J);
    }
    col += r;
  }
  return PHt;
}

Eigen::MatrixXd innovation_covariance(const StochasticMap& map,
                                      const std::vector<ImplicitMeasurement>& measurements,
                                      const Eigen::MatrixXd& PHt) {
  const Eigen::Index total = total_rows(measurements);
  if (PHt.rows() != map.dimension() || PHt.cols() != total) {
    throw std::invalid_argument("innovation_covariance: PHt is " + std::to_string(PHt.rows()) + "x" +
                                std::to_string(PHt.cols()) + ", expected " + std::to_string(map.dimension()) +
                                "x" + std::to_string(total));
  }
  Eigen::MatrixXd S(total, total);
  Eigen::Index row = 0;
  for (const ImplicitMeasurement& m : measurements) {
    validate(map, m, "innovation_covariance");
    const Eigen::Index r = m.h.size();
    S.middleRows(row, r) = apply_H(map, m, PHt);
    S.block(row, row, r, r) += m.R;  // noise of different measurements is independent
    row += r;
  }
  return 0.5 * (S + S.transpose());
}

Eigen::VectorXd stacked_value(const std::vector<ImplicitMeasurement>& measurements) {
  Eigen::VectorXd h(total_rows(measurements));
  Eigen::Index row = 0;
  for (const ImplicitMeasurement& m : measurements) {
    h.segment(row, m.h.size()) = m.h;
    row += m.h.size();
  }
  return h;
}

double innovation_reference_scale(const StochasticMap& map, const std::vector<ImplicitMeasurement>& measurements) {
  double scale = 0.0;
  for (const ImplicitMeasurement& m : measurements) {
    validate(map, m, "innovation_reference_scale");
    scale = std::max(scale, reference_scale_of(map, m));
  }
  return scale;
}

double chi2_threshold(int dof, double alpha) {
  if (dof <= 0) throw std::invalid_argument("chi2_threshold: dof must be positive, got " + std::to_string(dof));
  if (!(alpha > 0.0 && alpha < 1.0)) {
    throw std::invalid_argument("chi2_threshold: alpha must be in (0, 1), got " + std::to_string(alpha));
  }
  // The quantile is an iterative root search (microseconds) and every pairing,
  // joint-compatibility step and constraint asks again for the same few
  // (dof, alpha): cache them. thread_local keeps it lock-free for processes
  // that run a local map and a global map on different threads.
  thread_local std::map<std::pair<int, double>, double> cache;
  const std::pair<int, double> key{dof, alpha};
  if (const auto it = cache.find(key); it != cache.end()) return it->second;
  const boost::math::chi_squared_distribution<double> chi2(static_cast<double>(dof));
  const double value = boost::math::quantile(boost::math::complement(chi2, alpha));
  if (cache.size() >= kMaxCachedQuantiles) cache.clear();  // bounded: callers with ever-new alphas
  cache.emplace(key, value);
  return value;
}

CompatibilityTest individual_compatibility(const StochasticMap& map, const ImplicitMeasurement& m,
                                           double alpha, double relative_tolerance) {
  validate(map, m, "individual_compatibility");
  const StochasticMap::CovarianceView P = map.covariance();
  struct Touched {
    Eigen::Index offset;
    Eigen::Index dof;
    const Eigen::MatrixXd* J;
  };
  std::vector<Touched> touched;
  touched.reserve(m.blocks.size());
  for (const JacobianBlock& b : m.blocks) touched.push_back({map.entity(b.entity).offset, b.J.cols(), &b.J});

  // S = H P Hᵀ + R = Σ_a Σ_b J_a P_ab J_bᵀ + R from the few entity blocks H
  // touches: no n x rows gather of P (the same S as innovation_covariance).
  // The reference scale is the a == b part (innovation_reference_scale).
  const Eigen::Index r = m.h.size();
  Eigen::MatrixXd S = m.R;
  Eigen::VectorXd uncorrelated = m.R.diagonal();
  Eigen::MatrixXd JP(r, 3);
  for (const Touched& b : touched) {
    // JP = Σ_a J_a P_ab (r x dof(b)), then S += JP J_bᵀ.
    auto JP_b = JP.leftCols(b.dof);
    JP_b.setZero();
    for (const Touched& a : touched) JP_b.noalias() += *a.J * P.block(a.offset, b.offset, a.dof, b.dof);
    S.noalias() += JP_b * b.J->transpose();
    uncorrelated += (*b.J * P.block(b.offset, b.offset, b.dof, b.dof)).cwiseProduct(*b.J).rowwise().sum();
  }
  S = 0.5 * (S + S.transpose()).eval();
  const double scale = uncorrelated.size() > 0 ? std::max(0.0, uncorrelated.maxCoeff()) : 0.0;
  // Eq. (8): D² = ĥᵀ S⁻¹ ĥ with the careful inversion (docs/design.md §6).
  return compatibility(m.h, S, alpha, relative_tolerance, scale);
}

std::vector<std::size_t> incremental_joint_compatibility(const StochasticMap& map,
                                                         const std::vector<ImplicitMeasurement>& candidates,
                                                         double alpha, double relative_tolerance) {
  for (const ImplicitMeasurement& m : candidates) validate(map, m, "incremental_joint_compatibility");
  const StochasticMap::CovarianceView P = map.covariance();
  const Eigen::Index total = total_rows(candidates);

  // The accepted set grows one candidate at a time. Buffers sized for "all
  // kept": columns/rows [0, a) belong to the accepted set, [a, a + r) to the
  // candidate under test; a rejected candidate's slot is simply overwritten.
  Eigen::MatrixXd PHt(map.dimension(), total);  // P H_accᵀ, then the candidate's gather
  Eigen::MatrixXd S(total, total);              // joint innovation covariance
  Eigen::VectorXd h(total);                     // stacked ĥ
  // S_acc⁻¹ while the careful inversion of the accepted set kept every row
  // (always, unless a perfect constraint repeats what the set already says).
  Eigen::MatrixXd S_inv(total, total);
  bool have_inverse = true;    // the empty set
  double distance_acc = 0.0;   // ĥ_accᵀ S_acc⁻¹ ĥ_acc
  double trace_acc = 0.0;      // trace(S_acc⁻¹)
  double scale_acc = 0.0;      // reference scale of the accepted set
  double diagonal_acc = 0.0;   // largest |S_ii| of the accepted set

  std::vector<std::size_t> kept;
  Eigen::Index a = 0;
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const ImplicitMeasurement& m = candidates[c];
    const Eigen::Index r = m.h.size();
    if (r == 0) {  // adds nothing: the set stays as compatible as it was
      kept.push_back(c);
      continue;
    }
    // P H_cᵀ: a gather over the columns H_c touches (docs/design.md §5.3), computed
    // once per candidate and kept in place if it is accepted.
    auto PHt_c = PHt.middleCols(a, r);
    PHt_c.setZero();
    for (const JacobianBlock& b : m.blocks) {
      add_columns_times_Jt(PHt_c, P.middleCols(map.entity(b.entity).offset, b.J.cols()), b.J);
    }
    // [H_c P H_accᵀ, H_c P H_cᵀ + R_c]: the candidate's rows of the joint S.
    Eigen::MatrixXd S_c = Eigen::MatrixXd::Zero(r, a + r);
    for (const JacobianBlock& b : m.blocks) {
      S_c.noalias() += b.J * PHt.block(map.entity(b.entity).offset, 0, b.J.cols(), a + r);
    }
    S_c.rightCols(r) += m.R;
    const Eigen::MatrixXd S_cc = 0.5 * (S_c.rightCols(r) + S_c.rightCols(r).transpose());
    S.block(a, 0, r, a) = S_c.leftCols(a);
    S.block(0, a, a, r) = S_c.leftCols(a).transpose();
    S.block(a, a, r, r) = S_cc;
    h.segment(a, r) = m.h;

    // The careful inversion of the joint S (docs/design.md §6) judges pivots against
    // this threshold (careful_inverse.hpp).
    const double scale = std::max(scale_acc, reference_scale_of(map, m));
    const double diagonal = std::max(diagonal_acc, S_cc.diagonal().cwiseAbs().maxCoeff());
    const double threshold = relative_tolerance * std::max(diagonal, scale);

    // Fast path, block (Schur complement) update of S⁻¹: with A = S_acc,
    // B = S_acc,c, C = S_cc: Sc = C - Bᵀ A⁻¹ B, d² = d²_acc + vᵀ Sc⁻¹ v with
    // v = ĥ_c - Bᵀ A⁻¹ ĥ_acc. It gives the careful inversion's answer when that
    // keeps every row, which is certain when λ_min(S) is clearly above the
    // threshold: every pivot of the symmetric sweep is a diagonal entry of a
    // Schur complement of S, hence >= λ_min(S) >= 1 / trace(S⁻¹). Otherwise
    // (near-singular S) the full careful inversion decides, as it always did.
    bool decided = false;
    bool passed = false;
    if (have_inverse) {
      const auto A_inv = S_inv.topLeftCorner(a, a);
      const Eigen::MatrixXd X = A_inv * S.block(0, a, a, r);  // A⁻¹ B
      Eigen::MatrixXd Sc = S_cc;
      Sc.noalias() -= S.block(0, a, a, r).transpose() * X;
      const Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (Sc + Sc.transpose()));
      if (llt.info() == Eigen::Success) {
        Eigen::MatrixXd Sc_inv = llt.solve(Eigen::MatrixXd::Identity(r, r));
        Sc_inv = 0.5 * (Sc_inv + Sc_inv.transpose()).eval();
        const Eigen::MatrixXd Y = X * Sc_inv;  // A⁻¹ B Sc⁻¹
        const double trace = trace_acc + Y.cwiseProduct(X).sum() + Sc_inv.trace();
        const double safe = std::max(kFastPathMargin * threshold, kFastPathFloor * std::max(diagonal, scale));
        if (trace > 0.0 && std::isfinite(trace) && 1.0 / trace > safe) {
          const Eigen::VectorXd v = m.h - X.transpose() * h.head(a);
          const double d2 = distance_acc + v.dot(Sc_inv * v);
          decided = true;
          passed = d2 < chi2_threshold(static_cast<int>(a + r), alpha);
          if (passed) {
            // S⁻¹ = [[A⁻¹ + Y Xᵀ, -Y], [-Yᵀ, Sc⁻¹]] (block inverse).
            S_inv.topLeftCorner(a, a).noalias() += Y * X.transpose();
            S_inv.block(0, a, a, r) = -Y;
            S_inv.block(a, 0, r, a) = -Y.transpose();
            S_inv.block(a, a, r, r) = Sc_inv;
            distance_acc = d2;
            trace_acc = trace;
          }
        }
      }
    }
    if (!decided) {
      const CarefulInverse ci = careful_inverse(S.topLeftCorner(a + r, a + r), relative_tolerance, scale);
      const int dof_kept = static_cast<int>(ci.kept.size());
      const double d2 = reduced_distance2(h.head(a + r), ci);
      passed = dof_kept == 0 || d2 < chi2_threshold(dof_kept, alpha);
      if (passed) {
        have_inverse = dof_kept == a + r;
        if (have_inverse) {
          S_inv.topLeftCorner(a + r, a + r) = ci.inverse;  // kept = all rows, in order
          distance_acc = d2;
          trace_acc = ci.inverse.trace();
        }
      }
    }
    if (!passed) continue;
    kept.push_back(c);
    a += r;
    scale_acc = scale;
    diagonal_acc = diagonal;
  }
  return kept;
}

void mirror_lower_to_upper(Eigen::Ref<Eigen::MatrixXd> P) {
  if (P.rows() != P.cols()) throw std::invalid_argument("mirror_lower_to_upper: matrix is not square");
  // Block transposes: a column-by-column mirror reads rows with stride n and
  // costs more than the rank-k update itself on a large P.
  const Eigen::Index n = P.rows();
  constexpr Eigen::Index kBlock = 64;
  for (Eigen::Index j0 = 0; j0 < n; j0 += kBlock) {
    const Eigen::Index bj = std::min(kBlock, n - j0);
    for (Eigen::Index i0 = 0; i0 < j0; i0 += kBlock) {
      P.block(i0, j0, kBlock, bj) = P.block(j0, i0, bj, kBlock).transpose();
    }
    for (Eigen::Index j = j0 + 1; j < j0 + bj; ++j) {
      for (Eigen::Index i = j0; i < j; ++i) P(i, j) = P(j, i);
    }
  }
}

UpdateReport ekf_update(StochasticMap& map, const std::vector<ImplicitMeasurement>& measurements,
                        double relative_tolerance) {
  UpdateReport report;
  const Eigen::MatrixXd PHt = gather_PHt(map, measurements);
  report.rows = static_cast<int>(PHt.cols());
  if (report.rows == 0) return report;
  const Eigen::MatrixXd S = innovation_covariance(map, measurements, PHt);
  const Eigen::VectorXd h = stacked_value(measurements);

  // docs/design.md §6: drop the rows whose information the others already carry.
  const CarefulInverse ci =
      careful_inverse(S, relative_tolerance, innovation_reference_scale(map, measurements));
  report.rows_dropped = static_cast<int>(ci.dropped.size());
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  if (k == 0) return report;
  Eigen::MatrixXd PHt_k(PHt.rows(), k);
  Eigen::VectorXd h_k(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    PHt_k.col(i) = PHt.col(ci.kept[static_cast<std::size_t>(i)]);
    h_k(i) = h(ci.kept[static_cast<std::size_t>(i)]);
  }
  report.distance2 = h_k.dot(ci.inverse * h_k);

  // Eq. (9): W = P Hᵀ S⁻¹, p̂ = -W ĥ (the measurement predicts ĥ, observes 0).
  const Eigen::MatrixXd W = PHt_k * ci.inverse;
  const Eigen::VectorXd p_hat = -W * h_k;

  // P ← P - W (P Hᵀ)ᵀ: a rank-k update of the lower triangle only (docs/design.md §5.3),
  // then mirrored so both triangles stay valid.
  StochasticMap::MutableCovarianceView P = map.mutable_covariance();
  P.triangularView<Eigen::Lower>() -= W * PHt_k.transpose();
  mirror_lower_to_upper(P);

  // Fold p̂ into every location and reset it to 0 (docs/design.md §3).
  for (const Entity& e : map.entities()) {
    const Eigen::Index d = dof(e.kind);
    const Eigen::VectorXd p_E = p_hat.segment(e.offset, d);
    if (p_E.isZero(0.0)) continue;
    Entity& target = map.mutable_entity(e.id);
    target.location = fold(target.location, e.kind, p_E);
  }
  return report;
}

}  // namespace lmf::spmap
