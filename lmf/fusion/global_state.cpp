#include "lmf/fusion/global_state.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <unordered_set>

namespace lmf::fusion {
namespace {

std::string id_text(EntityId id) { return "entity " + std::to_string(id); }

// The stored lower triangle of a symmetric d x d diagonal block, as a full matrix.
Eigen::MatrixXd symmetric_from_lower(const Eigen::Ref<const Eigen::MatrixXd>& L) {
  Eigen::MatrixXd M = L.triangularView<Eigen::Lower>();
  M.triangularView<Eigen::StrictlyUpper>() = M.transpose();
  return M;
}

}  // namespace

void GlobalState::reserve(Eigen::Index dimension) {
  if (dimension <= capacity()) return;
  Eigen::MatrixXd next(dimension, dimension);
  for (Eigen::Index j = 0; j < n_; ++j) {
    next.col(j).segment(j, n_ - j) = storage_.col(j).segment(j, n_ - j);
  }
  storage_.swap(next);
}

EntityId GlobalState::add(EntityKind kind, const Pose2& location, std::optional<EntityId> parent,
                          double length_m) {
  if (parent && !contains(*parent)) {
    throw std::invalid_argument("GlobalState::add: unknown parent " + id_text(*parent));
  }
  const Eigen::Index d = spmap::dof(kind);
  if (n_ + d > capacity()) {
    // Amortised growth: one reallocation per 25 % of growth.
    reserve(std::max<Eigen::Index>({n_ + d, capacity() + capacity() / 4, 64}));
  }
  // New rows of P start at zero (lower triangle: the new rows under the old
  // columns and the new diagonal block).
  storage_.block(n_, 0, d, n_).setZero();
  storage_.block(n_, n_, d, d).setZero();
  Entity e;
  e.id = next_id_++;
  e.kind = kind;
  e.location = location;
  e.length_m = length_m;
  e.parent = parent;
  e.offset = n_;
  n_ += d;
  index_.emplace(e.id, entities_.size());
  entities_.push_back(e);
  return e.id;
}

EntityId GlobalState::add_copy(EntityId source) {
  const Entity src = entity(source);  // copy: add() may reallocate entities_
  const EntityId id = add(src.kind, src.location, src.parent, src.length_m);
  const Eigen::Index d = spmap::dof(src.kind);
  replace_perturbation(id, {{source, Eigen::MatrixXd::Identity(d, d)}});
  return id;
}

void GlobalState::remove(const std::vector<EntityId>& ids) {
  if (ids.empty()) return;
  std::unordered_set<EntityId> doomed;
  for (const EntityId id : ids) {
    index_of(id);  // throws for an unknown id
    doomed.insert(id);
  }
  for (const Entity& e : entities_) {
    if (e.parent && doomed.count(*e.parent) != 0 && doomed.count(e.id) == 0) {
      throw std::invalid_argument("GlobalState::remove: " + id_text(*e.parent) + " is still the parent of " +
                                  id_text(e.id));
    }
  }

  // Kept rows as runs [old_begin, old_begin + size) -> [new_begin, ...).
  struct Run {
    Eigen::Index old_begin;
    Eigen::Index new_begin;
    Eigen::Index size;
  };
  std::vector<Run> runs;
  std::vector<Entity> kept;
  kept.reserve(entities_.size());
  Eigen::Index next_offset = 0;
  for (const Entity& e : entities_) {
    if (doomed.count(e.id) != 0) continue;
    const Eigen::Index d = spmap::dof(e.kind);
    if (!runs.empty() && runs.back().old_begin + runs.back().size == e.offset &&
        runs.back().new_begin + runs.back().size == next_offset) {
      runs.back().size += d;
    } else {
      runs.push_back({e.offset, next_offset, d});
    }
    Entity moved = e;
    moved.offset = next_offset;
    kept.push_back(moved);
    next_offset += d;
  }

  // Compaction of the lower triangle, column by column in increasing order.
  // A destination never lies after its source (rows and columns only move up/
  // left), and a destination column's old content was consumed earlier, so the
  // in-place forward pass never overwrites unread data.
  double* base = storage_.data();
  const Eigen::Index ld = storage_.outerStride();
  for (std::size_t r = 0; r < runs.size(); ++r) {
    const Run& run = runs[r];
    for (Eigen::Index c = 0; c < run.size; ++c) {
      const Eigen::Index jo = run.old_begin + c;
      const Eigen::Index jn = run.new_begin + c;
      const double* src = base + jo * ld;
      double* dst = base + jn * ld;
      // Same run: rows jo.. of this run (lower part only).
      if (jo != jn) {
        std::memmove(dst + jn, src + jo, static_cast<std::size_t>(run.size - c) * sizeof(double));
      }
      for (std::size_t r2 = r + 1; r2 < runs.size(); ++r2) {
        const Run& later = runs[r2];
        if (jo == jn && later.old_begin == later.new_begin) continue;
        std::memmove(dst + later.new_begin, src + later.old_begin, static_cast<std::size_t>(later.size) * sizeof(double));
      }
    }
  }

  n_ = next_offset;
  entities_ = std::move(kept);
  // The index in place: positions reassigned, the removed erased (no rebuild:
  // a node per entity allocated and freed on every fusion).
  for (const EntityId id : doomed) index_.erase(id);
  for (std::size_t i = 0; i < entities_.size(); ++i) index_.find(entities_[i].id)->second = i;
}

const Entity& GlobalState::entity(EntityId id) const { return entities_[index_of(id)]; }

Entity& GlobalState::mutable_entity(EntityId id) { return entities_[index_of(id)]; }

std::size_t GlobalState::index_of(EntityId id) const {
  const auto it = index_.find(id);
  if (it == index_.end()) throw std::invalid_argument("GlobalState: unknown " + id_text(id));
  return it->second;
}

Eigen::MatrixXd GlobalState::block(EntityId a, EntityId b) const {
  const Entity& ea = entity(a);
  const Entity& eb = entity(b);
  const Eigen::Index da = spmap::dof(ea.kind);
  const Eigen::Index db = spmap::dof(eb.kind);
  if (a == b) return symmetric_from_lower(storage_.block(ea.offset, ea.offset, da, da));
  if (ea.offset > eb.offset) return storage_.block(ea.offset, eb.offset, da, db);
  return storage_.block(eb.offset, ea.offset, db, da).transpose();
}

std::vector<Eigen::Index> GlobalState::rows_of(const std::vector<EntityId>& ids) const {
  std::vector<Eigen::Index> rows;
  for (const EntityId id : ids) {
    const Entity& e = entity(id);
    for (Eigen::Index k = 0; k < spmap::dof(e.kind); ++k) rows.push_back(e.offset + k);
  }
  return rows;
}

void GlobalState::write_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M, bool accumulate) {
  const std::vector<Eigen::Index> rows = rows_of(ids);
  const auto m = static_cast<Eigen::Index>(rows.size());
  if (M.rows() != m || M.cols() != m) {
    throw std::invalid_argument("GlobalState: marginal is " + std::to_string(M.rows()) + "x" +
                                std::to_string(M.cols()) + ", the entities need " + std::to_string(m));
  }
  for (Eigen::Index j = 0; j < m; ++j) {
    for (Eigen::Index i = j; i < m; ++i) {
      const Eigen::Index ri = rows[static_cast<std::size_t>(i)];
      const Eigen::Index rj = rows[static_cast<std::size_t>(j)];
      double& slot = ri >= rj ? storage_(ri, rj) : storage_(rj, ri);
      slot = accumulate ? slot + M(i, j) : M(i, j);
    }
  }
}

void GlobalState::set_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M) {
  write_marginal(ids, M, false);
}

void GlobalState::add_to_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M) {
  write_marginal(ids, M, true);
}

Eigen::MatrixXd GlobalState::marginal(const std::vector<EntityId>& ids) const {
  const std::vector<Eigen::Index> rows = rows_of(ids);
  const auto m = static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd M(m, m);
  for (Eigen::Index j = 0; j < m; ++j) {
    for (Eigen::Index i = j; i < m; ++i) {
      M(i, j) = M(j, i) = covariance(rows[static_cast<std::size_t>(i)], rows[static_cast<std::size_t>(j)]);
    }
  }
  return M;
}

Eigen::MatrixXd GlobalState::columns(EntityId id) const {
  const Entity& e = entity(id);
  const Eigen::Index off = e.offset;
  const Eigen::Index d = spmap::dof(e.kind);
  Eigen::MatrixXd C(n_, d);
  // Above the entity: its rows left of the diagonal; below: its columns.
  C.topRows(off) = storage_.block(off, 0, d, off).transpose();
  C.middleRows(off, d) = symmetric_from_lower(storage_.block(off, off, d, d));
  C.bottomRows(n_ - off - d) = storage_.block(off + d, off, n_ - off - d, d);
  return C;
}

Eigen::MatrixXd GlobalState::full_covariance() const {
  Eigen::MatrixXd P = storage_.topLeftCorner(n_, n_).triangularView<Eigen::Lower>();
  P.triangularView<Eigen::StrictlyUpper>() = P.transpose();
  return P;
}

void GlobalState::set_block(EntityId a, EntityId b, const Eigen::MatrixXd& M) {
  const Entity& ea = entity(a);
  const Entity& eb = entity(b);
  const Eigen::Index da = spmap::dof(ea.kind);
  const Eigen::Index db = spmap::dof(eb.kind);
  if (M.rows() != da || M.cols() != db) {
    throw std::invalid_argument("GlobalState::set_block: block is " + std::to_string(M.rows()) + "x" +
                                std::to_string(M.cols()) + ", expected " + std::to_string(da) + "x" +
                                std::to_string(db));
  }
  if (a == b) {
    storage_.block(ea.offset, ea.offset, da, da) = 0.5 * (M + M.transpose());
  } else if (ea.offset > eb.offset) {
    storage_.block(ea.offset, eb.offset, da, db) = M;
  } else {
    storage_.block(eb.offset, ea.offset, db, da) = M.transpose();
  }
}

void GlobalState::add_to_block(EntityId a, const Eigen::MatrixXd& M) {
  set_block(a, a, block(a, a) + 0.5 * (M + M.transpose()));
}

Pose2 GlobalState::root_location(EntityId id) const { return spmap::root_location(*this, id); }

std::vector<spmap::ChainLink> GlobalState::chain_from_root(EntityId id) const {
  return spmap::chain_from_root(*this, id);
}

std::vector<spmap::ChainLink> GlobalState::chain_between(EntityId a, EntityId b) const {
  return spmap::chain_between(*this, a, b);
}

void GlobalState::replace_perturbation(EntityId target, const std::vector<LinearTerm>& terms) {
  const Entity& t = entity(target);
  const Eigen::Index off_t = t.offset;
  const Eigen::Index d_t = spmap::dof(t.kind);
  for (const LinearTerm& term : terms) {
    const Entity& e = entity(term.entity);
    if (term.J.rows() != d_t || term.J.cols() != spmap::dof(e.kind)) {
      throw std::invalid_argument("GlobalState::replace_perturbation: J for " + id_text(term.entity) + " is " +
                                  std::to_string(term.J.rows()) + "x" + std::to_string(term.J.cols()) +
                                  ", expected " + std::to_string(d_t) + "x" + std::to_string(spmap::dof(e.kind)));
    }
  }
  // P' = A P Aᵀ, A = I except A(t, :) = Σ J_i at e_i's columns: only t's row
  // changes, G = Σ J_i P(e_i, :), and P'(t, t) = Σ_j G(:, e_j) J_jᵀ, all from the old P.
  // The products are d x d' by d' x n: written as lazy (coefficient) products,
  // since Eigen's blocked GEMM costs more than the arithmetic at these shapes.
  Eigen::MatrixXd G;
  if (terms.size() == 1 && terms.front().entity == target) {
    // p_t ← J p_t (a segment's frame moved along its axis, §3): G = J P(t, :)
    // straight from the stored row and column of t, no gather.
    const Eigen::MatrixXd& J = terms.front().J;
    G.resize(d_t, n_);
    G.leftCols(off_t).noalias() = J.lazyProduct(storage_.block(off_t, 0, d_t, off_t));
    G.middleCols(off_t, d_t).noalias() = J.lazyProduct(symmetric_from_lower(storage_.block(off_t, off_t, d_t, d_t)));
    const Eigen::Index below = n_ - off_t - d_t;
    G.rightCols(below).noalias() = J.lazyProduct(storage_.block(off_t + d_t, off_t, below, d_t).transpose());
  } else {
    G = Eigen::MatrixXd::Zero(d_t, n_);
    for (const LinearTerm& term : terms) G.noalias() += term.J.lazyProduct(columns(term.entity).transpose());
  }
  Eigen::MatrixXd G_tt = Eigen::MatrixXd::Zero(d_t, d_t);
  for (const LinearTerm& term : terms) {
    G_tt.noalias() += G.middleCols(entity(term.entity).offset, term.J.cols()).lazyProduct(term.J.transpose());
  }
  storage_.block(off_t, 0, d_t, off_t) = G.leftCols(off_t);
  const Eigen::Index below = n_ - off_t - d_t;
  storage_.block(off_t + d_t, off_t, below, d_t) = G.rightCols(below).transpose();
  storage_.block(off_t, off_t, d_t, d_t) = 0.5 * (G_tt + G_tt.transpose());
}

void GlobalState::transform_perturbations(const std::vector<LinearTerm>& maps) {
  // Each J is at most 3 x 3: copied into a fixed array so the sweeps below run
  // on registers, not through a dynamic matrix per element.
  struct Target {
    Eigen::Index offset;
    Eigen::Index dof;
    Eigen::Matrix3d J;  // top-left dof x dof used
  };
  std::vector<Target> targets;
  targets.reserve(maps.size());
  for (const LinearTerm& map : maps) {
    const Entity& e = entity(map.entity);
    const Eigen::Index d = spmap::dof(e.kind);
    if (map.J.rows() != d || map.J.cols() != d) {
      throw std::invalid_argument("GlobalState::transform_perturbations: J for " + id_text(map.entity) + " is " +
                                  std::to_string(map.J.rows()) + "x" + std::to_string(map.J.cols()) +
                                  ", expected " + std::to_string(d) + "x" + std::to_string(d));
    }
    Target t{e.offset, d, Eigen::Matrix3d::Zero()};
    t.J.topLeftCorner(d, d) = map.J;
    targets.push_back(t);
  }
  std::sort(targets.begin(), targets.end(), [](const Target& a, const Target& b) { return a.offset < b.offset; });
  for (std::size_t i = 1; i < targets.size(); ++i) {
    if (targets[i].offset == targets[i - 1].offset) {
      throw std::invalid_argument("GlobalState::transform_perturbations: an entity is listed twice");
    }
  }
  // v ← J v for the dof (2 or 3) values at v, v + stride, ...
  const auto apply = [](const Target& t, double* v, Eigen::Index stride) {
    const double v0 = v[0];
    const double v1 = v[stride];
    if (t.dof == 2) {
      v[0] = t.J(0, 0) * v0 + t.J(0, 1) * v1;
      v[stride] = t.J(1, 0) * v0 + t.J(1, 1) * v1;
      return;
    }
    const double v2 = v[2 * stride];
    for (Eigen::Index a = 0; a < 3; ++a) v[a * stride] = t.J(a, 0) * v0 + t.J(a, 1) * v1 + t.J(a, 2) * v2;
  };
  // Diagonal blocks from the old P: J D Jᵀ.
  std::vector<Eigen::Matrix3d> diagonal;
  diagonal.reserve(targets.size());
  for (const Target& t : targets) {
    Eigen::Matrix3d D = Eigen::Matrix3d::Zero();
    D.topLeftCorner(t.dof, t.dof) = symmetric_from_lower(storage_.block(t.offset, t.offset, t.dof, t.dof));
    diagonal.push_back(t.J * D * t.J.transpose());
  }
  // Rows: P(t, j) ← J_t P(t, j) for every stored column j left of t's block,
  // column by column (a target's rows in column j are contiguous).
  std::size_t first = 0;  // the first target whose block starts after column j
  for (Eigen::Index j = 0; j < n_ && first < targets.size(); ++j) {
    while (first < targets.size() && targets[first].offset <= j) ++first;
    double* column = &storage_(0, j);
    for (std::size_t i = first; i < targets.size(); ++i) apply(targets[i], column + targets[i].offset, 1);
  }
  // Columns: P(i, t) ← P(i, t) J_tᵀ below t's block, row by row (rows of later
  // targets already carry their J: J_a P_ab J_bᵀ).
  const Eigen::Index ld = storage_.outerStride();
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const Target& t = targets[i];
    const Eigen::Index below = n_ - t.offset - t.dof;
    double* c0 = &storage_(t.offset + t.dof, t.offset);  // the dof columns, from the row under the block
    double* c1 = c0 + ld;
    if (t.dof == 2) {  // segments: a loop the compiler vectorises over the rows
      const double j00 = t.J(0, 0), j01 = t.J(0, 1), j10 = t.J(1, 0), j11 = t.J(1, 1);
      for (Eigen::Index r = 0; r < below; ++r) {
        const double a = c0[r];
        const double b = c1[r];
        c0[r] = j00 * a + j01 * b;
        c1[r] = j10 * a + j11 * b;
      }
    } else {
      for (Eigen::Index r = 0; r < below; ++r) apply(t, c0 + r, ld);
    }
    const Eigen::Matrix3d sym = 0.5 * (diagonal[i] + diagonal[i].transpose());
    storage_.block(t.offset, t.offset, t.dof, t.dof) = sym.topLeftCorner(t.dof, t.dof);
  }
}

std::vector<EntityId> GlobalState::add_many(const std::vector<NewEntity>& entities) {
  Eigen::Index total = 0;
  for (const NewEntity& e : entities) {
    if (e.parent && !contains(*e.parent)) {
      // Parents may also be earlier entries of this batch: those get ids next_id_ + i.
      const EntityId first_new = next_id_;
      if (*e.parent < first_new || *e.parent >= first_new + static_cast<EntityId>(entities.size())) {
        throw std::invalid_argument("GlobalState::add_many: unknown parent " + id_text(*e.parent));
      }
    }
    total += spmap::dof(e.kind);
  }
  if (n_ + total > capacity()) reserve(std::max<Eigen::Index>({n_ + total, capacity() + capacity() / 4, 64}));
  // One pass over the new rows: zero under the old columns and the new block.
  storage_.block(n_, 0, total, n_).setZero();
  storage_.block(n_, n_, total, total).setZero();
  std::vector<EntityId> ids;
  ids.reserve(entities.size());
  for (const NewEntity& ne : entities) {
    Entity e;
    e.id = next_id_++;
    e.kind = ne.kind;
    e.location = ne.location;
    e.length_m = ne.length_m;
    e.parent = ne.parent;
    e.offset = n_;
    n_ += spmap::dof(ne.kind);
    index_.emplace(e.id, entities_.size());
    entities_.push_back(e);
    ids.push_back(e.id);
  }
  return ids;
}

void GlobalState::subtract_outer_product(const Eigen::MatrixXd& U) {
  if (U.rows() != n_) {
    throw std::invalid_argument("GlobalState::subtract_outer_product: U has " + std::to_string(U.rows()) +
                                " rows, the state " + std::to_string(n_));
  }
  if (U.cols() == 0) return;
  storage_.topLeftCorner(n_, n_).selfadjointView<Eigen::Lower>().rankUpdate(U, -1.0);
}

}  // namespace lmf::fusion
