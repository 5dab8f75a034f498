// Where an input stops being plausible and becomes garbage: one default shared
// by the checks on the wire (runtime/convert.hpp, DecodeLimits) and the fusion's
// own (GlobalMapConfig), so both layers refuse the same poses.
#pragma once

namespace lmf {

// |x|, |y| of any pose or point beyond this (m) are refused: a building is far
// smaller, and a finite but absurd coordinate would overflow a covariance.
inline constexpr double kDefaultMaxCoordinateM = 1e6;

}  // namespace lmf
