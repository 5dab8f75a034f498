#include "lmf/spmap/ekf.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include <boost/math/distributions/chi_squared.hpp>

namespace lmf::spmap {
namespace {

// Bound of the per-thread chi2 quantile cache (entries of (dof, alpha)).
constexpr std::size_t kMaxCachedQuantiles = 1024;

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

// H_m X for X with one row per state row (n x c): touches only H's blocks.
Eigen::MatrixXd apply_H(const StochasticMap& map, const ImplicitMeasurement& m, const Eigen::MatrixXd& X) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(m.h.size(), X.cols());
  for (const JacobianBlock& b : m.blocks) {
    out.noalias() += b.J * X.middleRows(map.entity(b.entity).offset, b.J.cols());
  }
  return out;
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
  // B_out: the selected rows of (x, y, phi).
  Eigen::MatrixXd B_out = Eigen::MatrixXd::Zero(r, 3);
  for (Eigen::Index i = 0; i < r; ++i) B_out(i, rows[static_cast<std::size_t>(i)]) = 1.0;

  ImplicitMeasurement m;
  const Eigen::Vector3d value = chain.value.vector();
  m.h = B_out * value;
  for (Eigen::Index i = 0; i < r; ++i) {
    if (target.size() != 0) m.h(i) -= target(i);
    // DESIGN §3: angle innovations are wrapped, never a 2pi jump.
    if (rows[static_cast<std::size_t>(i)] == 2) m.h(i) = wrap_angle(m.h(i));
  }
  m.R = Eigen::MatrixXd::Zero(r, r);

  for (std::size_t l = 0; l < links.size(); ++l) {
    const Eigen::MatrixXd J = B_out * chain.jacobians[l];
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
        m.blocks.push_back({*links[l].entity, J});
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
    // DESIGN §5.3: P Hᵀ is a gather over the few columns H touches.
    for (const JacobianBlock& b : m.blocks) {
      PHt.middleCols(col, r).noalias() += P.middleCols(map.entity(b.entity).offset, b.J.cols()) * b.J.transpose();
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
    Eigen::VectorXd diag = m.R.diagonal();
    for (const JacobianBlock& b : m.blocks) {
      const Eigen::MatrixXd JP = b.J * map.block(b.entity, b.entity);
      diag += JP.cwiseProduct(b.J).rowwise().sum();
    }
    if (diag.size() > 0) scale = std::max(scale, diag.maxCoeff());
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
  // Eq. (8): D² = ĥᵀ S⁻¹ ĥ with the careful inversion (DESIGN §6).
  return compatibility(m.h, S, alpha, relative_tolerance, scale);
}

std::vector<std::size_t> incremental_joint_compatibility(const StochasticMap& map,
                                                         const std::vector<ImplicitMeasurement>& candidates,
                                                         double alpha, double relative_tolerance) {
  std::vector<std::size_t> kept;
  // The accepted set grows one candidate at a time; its P Hᵀ, S and ĥ are
  // extended, never recomputed.
  Eigen::MatrixXd PHt_acc(map.dimension(), 0);
  Eigen::MatrixXd S_acc(0, 0);
  Eigen::VectorXd h_acc(0);
  double scale_acc = 0.0;
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const ImplicitMeasurement& m = candidates[c];
    const std::vector<ImplicitMeasurement> one{m};
    const Eigen::MatrixXd PHt_c = gather_PHt(map, one);
    const Eigen::MatrixXd S_cc = innovation_covariance(map, one, PHt_c);
    const Eigen::MatrixXd S_ca = apply_H(map, m, PHt_acc);  // H_c P H_accᵀ
    const Eigen::Index a = S_acc.rows();
    const Eigen::Index r = m.h.size();

    Eigen::MatrixXd S(a + r, a + r);
    S.topLeftCorner(a, a) = S_acc;
    S.bottomLeftCorner(r, a) = S_ca;
    S.topRightCorner(a, r) = S_ca.transpose();
    S.bottomRightCorner(r, r) = S_cc;
    Eigen::VectorXd h(a + r);
    h << h_acc, m.h;

    const double scale = std::max(scale_acc, innovation_reference_scale(map, one));
    if (!compatibility(h, S, alpha, relative_tolerance, scale).passed) continue;
    kept.push_back(c);
    scale_acc = scale;
    S_acc = std::move(S);
    h_acc = std::move(h);
    Eigen::MatrixXd PHt_new(PHt_acc.rows(), a + r);
    PHt_new << PHt_acc, PHt_c;
    PHt_acc = std::move(PHt_new);
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

  // DESIGN §6: drop the rows whose information the others already carry.
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

  // P ← P - W (P Hᵀ)ᵀ: a rank-k update of the lower triangle only (DESIGN §5.3),
  // then mirrored so both triangles stay valid.
  StochasticMap::MutableCovarianceView P = map.mutable_covariance();
  P.triangularView<Eigen::Lower>() -= W * PHt_k.transpose();
  mirror_lower_to_upper(P);

  // Fold p̂ into every location and reset it to 0 (DESIGN §3).
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
