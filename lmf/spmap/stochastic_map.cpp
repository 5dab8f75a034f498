#include "lmf/spmap/stochastic_map.hpp"

#include <cassert>
#include <stdexcept>
#include <string>

namespace lmf::spmap {
namespace {

std::string id_text(EntityId id) { return "entity " + std::to_string(id); }

}  // namespace

EntityId StochasticMap::add(EntityKind kind, const Pose2& location, std::optional<EntityId> parent,
                            double length_m) {
  if (parent && !contains(*parent)) {
    throw std::invalid_argument("StochasticMap::add: unknown parent " + id_text(*parent));
  }
  const Eigen::Index n = P_.rows();
  const Eigen::Index d = dof(kind);
  Entity e;
  e.id = next_id_++;
  e.kind = kind;
  e.location = location;
  e.length_m = length_m;
  e.parent = parent;
  e.offset = n;
  // New rows/columns start at zero: the entity is known exactly until a caller
  // (prediction, replace_perturbation, the augmentation) says otherwise.
  P_.conservativeResize(n + d, n + d);
  P_.rightCols(d).setZero();
  P_.bottomRows(d).setZero();
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
  const Eigen::Index n = P_.rows();
  const Eigen::Index off = entities_[i].offset;
  const Eigen::Index d = dof(entities_[i].kind);
  const Eigen::Index tail = n - off - d;
  // Compact P in place: move the trailing block up-left over the removed rows.
  // Each move only reads from indices >= the ones it writes, row- and
  // column-wise, so going top-left to bottom-right never overwrites unread data.
  if (tail > 0) {
    P_.block(0, off, off, tail) = P_.block(0, off + d, off, tail).eval();
    P_.block(off, 0, tail, off) = P_.block(off + d, 0, tail, off).eval();
    P_.block(off, off, tail, tail) = P_.block(off + d, off + d, tail, tail).eval();
  }
  P_.conservativeResize(n - d, n - d);

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

Pose2 StochasticMap::root_location(EntityId id) const {
  const Entity* e = &entity(id);
  Pose2 x = e->location;
  std::size_t depth = 0;
  while (e->parent) {
    e = &entity(*e->parent);
    x = compose(e->location, x);
    if (++depth > entities_.size()) {
      throw std::invalid_argument("StochasticMap::root_location: parent cycle through " + id_text(id));
    }
  }
  return x;
}

void StochasticMap::replace_perturbation(EntityId target, const std::vector<LinearTerm>& terms) {
  const Entity& t = entity(target);
  const Eigen::Index off_t = t.offset;
  const Eigen::Index d_t = dof(t.kind);
  const Eigen::Index n = P_.rows();

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
  for (const Resolved& r : resolved) G.noalias() += *r.J * P_.middleRows(r.offset, r.J->cols());
  Eigen::MatrixXd G_tt = Eigen::MatrixXd::Zero(d_t, d_t);
  for (const Resolved& r : resolved) G_tt.noalias() += G.middleCols(r.offset, r.J->cols()) * r.J->transpose();

  P_.middleRows(off_t, d_t) = G;
  P_.middleCols(off_t, d_t) = G.transpose();
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
  P_.resize(0, 0);
}

std::size_t StochasticMap::index_of(EntityId id) const {
  const auto it = index_.find(id);
  if (it == index_.end()) throw std::invalid_argument("StochasticMap: unknown " + id_text(id));
  assert(entities_[it->second].id == id);
  return it->second;
}

}  // namespace lmf::spmap
