#include "lmf/spmap/stochastic_map.hpp"

#include <algorithm>
#include <cassert>
#include <cstring>
#include <stdexcept>
#include <string>

#include "lmf/spmap/relative_location.hpp"

namespace lmf::spmap {
namespace {

std::string id_text(EntityId id) { return "entity " + std::to_string(id); }

// Smallest buffer allocated by the first addition (rows/columns).
constexpr Eigen::Index kMinCapacity = 32;

}  // namespace

EntityId StochasticMap::add(EntityKind kind, const Pose2& location, std::optional<EntityId> parent,
                            double length_m) {
  if (parent && !contains(*parent)) {
    throw std::invalid_argument("StochasticMap::add: unknown parent " + id_text(*parent));
  }
  const Eigen::Index n = n_;
  const Eigen::Index d = dof(kind);
  if (n + d > capacity()) {
    // Geometric growth: a reallocation and copy of P every few additions, not
    // at every one (amortised O(n) per addition instead of O(n²)).
    reserve(std::max({n + d, capacity() + capacity() / 2, kMinCapacity}));
  }
  Entity e;
  e.id = next_id_++;
  e.kind = kind;
  e.location = location;
  e.length_m = length_m;
  e.parent = parent;
  e.offset = n;
  // New rows/columns start at zero: the entity is known exactly until a caller
  // (prediction, replace_perturbation, the augmentation) says otherwise. The
  // spare part of the buffer may hold stale values from removed entities.
  P_.block(0, n, n + d, d).setZero();
  P_.block(n, 0, d, n).setZero();
  n_ = n + d;
  index_.emplace(e.id, entities_.size());
  entities_.push_back(e);
  return e.id;
}

void StochasticMap::remove(EntityId id) {
  const std::size_t i = index_of(id);
  for (const Entity& e : entities_) {
    if (e.parent == id) {
      throw std::invalid_argument("StochasticMap::remove: " + id_text(id) + " is still the parent of " +
                                  id_text(e.id));
    }
  }
  const Eigen::Index n = n_;
  const Eigen::Index off = entities_[i].offset;
  const Eigen::Index d = dof(entities_[i].kind);
  const Eigen::Index m = n - d;
  // Compact P in place, one column at a time in increasing order: column j of
  // the result is old column j (j < off) or j + d (j >= off) without rows
  // [off, off + d). A write to column j never touches a column still to be
  // read (those are > j), and within a column the rows move up (memmove).
  const Eigen::Index stride = P_.rows();  // column-major, outer stride = capacity
  double* data = P_.data();
  const auto bytes = [](Eigen::Index count) { return static_cast<std::size_t>(count) * sizeof(double); };
  for (Eigen::Index j = 0; j < m; ++j) {
    const Eigen::Index src = j < off ? j : j + d;
    double* dst_col = data + j * stride;
    const double* src_col = data + src * stride;
    if (src != j) std::memcpy(dst_col, src_col, bytes(off));  // different columns: no overlap
    std::memmove(dst_col + off, src_col + off + d, bytes(m - off));
  }
  n_ = m;

  entities_.erase(entities_.begin() + static_cast<std::ptrdiff_t>(i));
  index_.erase(id);
  for (std::size_t j = i; j < entities_.size(); ++j) {
    entities_[j].offset -= d;
    index_[entities_[j].id] = j;
  }
}

bool StochasticMap::contains(EntityId id) const { return index_.count(id) != 0; }

const Entity& StochasticMap::entity(EntityId id) const { return entities_[index_of(id)]; }

Entity& StochasticMap::mutable_entity(EntityId id) { return entities_[index_of(id)]; }

std::vector<EntityId> StochasticMap::children(std::optional<EntityId> parent) const {
  std::vector<EntityId> out;
  for (const Entity& e : entities_) {
    if (e.parent == parent) out.push_back(e.id);
  }
  return out;
}

Eigen::MatrixXd StochasticMap::block(EntityId a, EntityId b) const {
  const Entity& ea = entity(a);
  const Entity& eb = entity(b);
  return P_.block(ea.offset, eb.offset, dof(ea.kind), dof(eb.kind));
}

void StochasticMap::reserve(Eigen::Index dimension) {
  if (dimension <= capacity()) return;
  // The spare part is zeroed once here so the buffer never holds
  // uninitialised values (copies of the map copy the whole buffer).
  Eigen::MatrixXd grown = Eigen::MatrixXd::Zero(dimension, dimension);
  grown.topLeftCorner(n_, n_) = P_.topLeftCorner(n_, n_);
  P_.swap(grown);
}

Pose2 StochasticMap::root_location(EntityId id) const { return spmap::root_location(*this, id); }

void StochasticMap::replace_perturbation(EntityId target, const std::vector<LinearTerm>& terms) {
  const Entity& t = entity(target);
  const Eigen::Index off_t = t.offset;
  const Eigen::Index d_t = dof(t.kind);
  const Eigen::Index n = n_;

  struct Resolved {
    Eigen::Index offset;
    const Eigen::MatrixXd* J;
  };
  std::vector<Resolved> resolved;
  resolved.reserve(terms.size());
  for (const LinearTerm& term : terms) {
    const Entity& e = entity(term.entity);
    if (term.J.rows() != d_t || term.J.cols() != dof(e.kind)) {
      throw std::invalid_argument("StochasticMap::replace_perturbation: J for " + id_text(term.entity) + " is " +
                                  std::to_string(term.J.rows()) + "x" + std::to_string(term.J.cols()) +
                                  ", expected " + std::to_string(d_t) + "x" + std::to_string(dof(e.kind)));
    }
    resolved.push_back({e.offset, &term.J});
  }

  // P' = A P Aᵀ with A = I except A(t, :) = Σ J_i at e_i's columns. Only t's
  // rows/columns change: P'(t, :) = G = Σ J_i P(e_i, :) off the diagonal block,
  // P'(t, t) = Σ_j G(:, e_j) J_jᵀ. Both use the old P (terms may include t).
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(d_t, n);
  for (const Resolved& r : resolved) G.noalias() += *r.J * P_.block(r.offset, 0, r.J->cols(), n);
  Eigen::MatrixXd G_tt = Eigen::MatrixXd::Zero(d_t, d_t);
  for (const Resolved& r : resolved) G_tt.noalias() += G.middleCols(r.offset, r.J->cols()) * r.J->transpose();

  P_.block(off_t, 0, d_t, n) = G;
  P_.block(0, off_t, n, d_t) = G.transpose();
  P_.block(off_t, off_t, d_t, d_t) = 0.5 * (G_tt + G_tt.transpose());
}

EntityId StochasticMap::add_copy(EntityId source) {
  const Entity src = entity(source);  // copy: add() may reallocate entities_
  const EntityId id = add(src.kind, src.location, src.parent, src.length_m);
  // p_copy = p_source: the same rows and columns, perfect correlation.
  replace_perturbation(id, {{source, Eigen::MatrixXd::Identity(dof(src.kind), dof(src.kind))}});
  return id;
}

void StochasticMap::clear() {
  entities_.clear();
  index_.clear();
  n_ = 0;  // the buffer is kept: the next local map grows to a similar size
}

std::size_t StochasticMap::index_of(EntityId id) const {
  const auto it = index_.find(id);
  if (it == index_.end()) throw std::invalid_argument("StochasticMap: unknown " + id_text(id));
  assert(entities_[it->second].id == id);
  return it->second;
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

void StochasticMap::subtract_outer_product(const Eigen::MatrixXd& U) {
  if (U.rows() != n_) {
    throw std::invalid_argument("StochasticMap::subtract_outer_product: U has " + std::to_string(U.rows()) +
                                " rows, the map " + std::to_string(n_));
  }
  if (U.cols() == 0) return;
  MutableCovarianceView P = mutable_covariance();
  P.selfadjointView<Eigen::Lower>().rankUpdate(U, -1.0);
  mirror_lower_to_upper(P);
}

}  // namespace lmf::spmap
