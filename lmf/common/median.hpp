// The median of a sample: the middle element, the upper one of an even count
// (no averaging, so it is always one of the values). Header-only.
#pragma once

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <vector>

namespace lmf {

// Takes the values by value (nth_element reorders them). Throws
// std::invalid_argument on an empty sample.
inline double median(std::vector<double> values) {
  if (values.empty()) throw std::invalid_argument("median: no values");
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

}  // namespace lmf
