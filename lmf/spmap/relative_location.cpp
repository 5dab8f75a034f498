#include "lmf/spmap/relative_location.hpp"

#include <stdexcept>
#include <string>

namespace lmf::spmap {

ChainValue evaluate_chain(const std::vector<ChainLink>& links) {
  const std::size_t k = links.size();
  // Link values at p = 0 (inverted where asked).
  std::vector<Pose2> v(k);
  for (std::size_t l = 0; l < k; ++l) v[l] = links[l].inverted ? inverse(links[l].location) : links[l].location;
  // prefix[l] = v_0 ⊕ ... ⊕ v_{l-1}; suffix[l] = v_{l+1} ⊕ ... ⊕ v_{k-1}.
  std::vector<Pose2> prefix(k + 1);
  for (std::size_t l = 0; l < k; ++l) prefix[l + 1] = compose(prefix[l], v[l]);
  std::vector<Pose2> suffix(k);
  if (k > 0) {
    for (std::size_t l = k - 1; l > 0; --l) suffix[l - 1] = compose(v[l], suffix[l]);
  }

  ChainValue out;
  out.value = prefix[k];
  out.jacobians.reserve(k);
  const Pose2 zero;
  for (std::size_t l = 0; l < k; ++l) {
    const ChainLink& link = links[l];
    // ∂(x̂ ⊕ Bᵀp)/∂p at p = 0 (paper eq. 1), then through ⊖ when inverted;
    // B selects (y, phi) for a segment, all of (x, y, phi) otherwise (docs/design.md §3).
    Eigen::Matrix3d J_link = J2compose(link.location, zero);
    if (link.inverted) J_link = (Jinverse(link.location) * J_link).eval();
    // value = prefix ⊕ (v_l ⊕ suffix): chain rule through both compositions
    // (J2compose does not depend on its second argument).
    const Eigen::Matrix3d J_through = J2compose(prefix[l], zero) * J1compose(v[l], suffix[l]);
    const Eigen::Matrix3d J = J_through * J_link;
    if (dof(link.kind) == 2) {  // a segment (dof also rejects an out-of-range kind)
      out.jacobians.emplace_back(J.rightCols<2>());
    } else {
      out.jacobians.emplace_back(J);
    }
  }
  return out;
}

namespace detail {

void throw_parent_cycle(const char* where, EntityId id) {
  throw std::invalid_argument(std::string(where) + ": parent cycle through entity " + std::to_string(id));
}

}  // namespace detail

}  // namespace lmf::spmap
