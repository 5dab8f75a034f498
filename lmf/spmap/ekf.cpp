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

}  // namespace lmf::spmap
