// Where the robots have been (beyond the paper): every fused scan pose's
// position in W, as estimated when its local map was fused.
//
// No wall can lie where a robot's body was. A segment lying entirely within the
// footprint radius of one recorded position is therefore another robot (or
// something right next to one) that a laser saw, not a wall: robots see each
// other's bodies, and a robot that stood still while another one passed is not
// seen through before the observer's local map ships (the local map's
// free-space evidence, lmf/scan/see_through.hpp, cannot remove it then).
// GlobalMapConfig::footprint_radius_m: the body radius plus the error of the
// robots' poses relative to each other.
//
// A uniform grid of cells of the radius: the positions within the radius of a
// point lie in the point's cell or its 8 neighbours. A position within
// min_spacing() = radius / 20 of a recorded one is not recorded: a robot that
// stands still for an hour adds one position, not one per scan, so memory and
// the cost of covers() grow with the area visited, not with the time spent
// (a segment only the skipped disc would have covered reaches at most that
// spacing beyond the recorded disc).
#pragma once
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

namespace lmf::fusion {

class RobotFootprints {
 public:
  // Throws std::invalid_argument unless radius_m is finite and > 0.
  explicit RobotFootprints(double radius_m);

  double radius() const { return radius_; }
  double min_spacing() const { return radius_ / 20.0; }

  // Records the position unless one within min_spacing() is recorded already;
  // returns whether it did. Throws std::invalid_argument for a non-finite position.
  bool add(const Eigen::Vector2d& position_W);

  // True when one recorded position lies within the radius of both a and b, and
  // so of every point of the segment ab (a disc is convex).
  bool covers(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

  std::size_t size() const { return positions_.size(); }
  // In the order added (for the archive).
  const std::vector<Eigen::Vector2d>& positions() const { return positions_; }

 private:
  std::uint64_t key(std::int64_t ix, std::int64_t iy) const;
  std::int64_t cell(double v) const;
  // True when some recorded position p satisfies pred(p), among those within the radius of `a`.
  template <typename Pred>
  bool any_near(const Eigen::Vector2d& a, Pred pred) const;

  double radius_;
  std::vector<Eigen::Vector2d> positions_;
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> grid_;  // indices into positions_
};

}  // namespace lmf::fusion
