#include "lmf/scan/correlative_search.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lmf {
namespace {

// One node of the branch and bound: the translations (ox .. ox + 2^level − 1) x
// (oy .. oy + 2^level − 1) cells at one rotation, with the upper bound (level > 0)
// or exact score (level 0) of its points, in units of 1/255 per point.
struct Candidate {
  int rotation = 0;
  int ox = 0;
  int oy = 0;
  int score = 0;
};

class BranchAndBound {
 public:
  BranchAndBound(const LikelihoodField& field, const std::vector<Eigen::Vector2d>& points, const Pose2& centre,
                 const CorrelativeWindow& window, const std::function<bool(const Pose2&)>& excluded)
      : field_(field), centre_(centre), window_(window), excluded_(excluded), n_(static_cast<int>(points.size())) {
    const double r = field.resolution_m();
    half_cells_ = static_cast<int>(std::floor(window.linear_m / r + 1e-9));
    half_rotations_ = static_cast<int>(std::floor(window.angular_rad / window.angular_step_rad + 1e-9));
    const int rotations = 2 * half_rotations_ + 1;
    cells_.resize(static_cast<std::size_t>(rotations) * points.size());
    const Eigen::Vector2d t(centre.x, centre.y);
    for (int k = 0; k < rotations; ++k) {
      const double phi = centre.phi + (k - half_rotations_) * window.angular_step_rad;
      const Eigen::Rotation2Dd R(phi);
      for (int i = 0; i < n_; ++i) cells_[static_cast<std::size_t>(k * n_ + i)] = field.cell(t + R * points[static_cast<std::size_t>(i)]);
    }
  }

  // Best leaf with a score above `floor` (units of 1/255 per point summed), or nothing.
  std::optional<Candidate> run(int floor) {
    best_score_ = floor;
    best_.reset();
    const int top = field_.levels() - 1;
    std::vector<Candidate> roots;
    const int rotations = 2 * half_rotations_ + 1;
    for (int k = 0; k < rotations; ++k) {
      for (int ox = -half_cells_; ox <= half_cells_; ox += 1 << top) {
        for (int oy = -half_cells_; oy <= half_cells_; oy += 1 << top) {
          roots.push_back({k, ox, oy, score(top, k, ox, oy)});
        }
      }
    }
    branch(roots, top);
    return best_;
  }

  Pose2 pose(const Candidate& c) const {
    const double r = field_.resolution_m();
    return {centre_.x + c.ox * r, centre_.y + c.oy * r,
            wrap_angle(centre_.phi + (c.rotation - half_rotations_) * window_.angular_step_rad)};
  }

 private:
  int score(int level, int rotation, int ox, int oy) const {
    int s = 0;
    const Eigen::Vector2i* c = &cells_[static_cast<std::size_t>(rotation * n_)];
    for (int i = 0; i < n_; ++i) s += field_.value(level, c[i].x() + ox, c[i].y() + oy);
    return s;
  }

  void branch(std::vector<Candidate>& candidates, int level) {
    std::sort(candidates.begin(), candidates.end(),
              [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
    for (const Candidate& c : candidates) {
      if (c.score <= best_score_) return;  // sorted: no other can beat the best either
      if (level == 0) {
        if (excluded_ && excluded_(pose(c))) continue;
        best_score_ = c.score;
        best_ = c;
        continue;
      }
      const int half = 1 << (level - 1);
      std::vector<Candidate> children;
      children.reserve(4);
      for (const int dx : {0, half}) {
        for (const int dy : {0, half}) {
          const int ox = c.ox + dx;
          const int oy = c.oy + dy;
          if (ox > half_cells_ || oy > half_cells_) continue;
          const int s = score(level - 1, c.rotation, ox, oy);
          if (s > best_score_) children.push_back({c.rotation, ox, oy, s});
        }
      }
      branch(children, level - 1);
    }
  }

  const LikelihoodField& field_;
  Pose2 centre_;
  CorrelativeWindow window_;
  const std::function<bool(const Pose2&)>& excluded_;
  int n_;
  int half_cells_ = 0;
  int half_rotations_ = 0;
  std::vector<Eigen::Vector2i> cells_;  // per rotation, the level-0 cell of each point at the centre translation
  int best_score_ = 0;
  std::optional<Candidate> best_;
};

}  // namespace

LikelihoodField::LikelihoodField(const std::vector<Eigen::Vector2d>& points, const Eigen::AlignedBox2d& region,
                                 double resolution_m, double sigma_m, int levels)
    : resolution_m_(resolution_m) {
  if (!(resolution_m > 0.0) || !(sigma_m > 0.0) || levels < 1 || levels > 8) {
    throw std::invalid_argument("LikelihoodField: resolution and sigma must be > 0, levels in [1, 8]");
  }
  origin_ = region.isEmpty() ? Eigen::Vector2d::Zero() : region.min();
  const Eigen::Vector2d size = region.isEmpty() ? Eigen::Vector2d(Eigen::Vector2d::Zero()) : Eigen::Vector2d(region.sizes());
  const int width = static_cast<int>(std::ceil(size.x() / resolution_m)) + 1;
  const int height = static_cast<int>(std::ceil(size.y() / resolution_m)) + 1;
  padding_ = (1 << (levels - 1)) - 1;
  padded_width_ = width + padding_;
  padded_height_ = height + padding_;
  const std::size_t cells = static_cast<std::size_t>(padded_width_) * static_cast<std::size_t>(padded_height_);
  levels_.assign(static_cast<std::size_t>(levels), std::vector<std::uint8_t>(cells, 0));

  // Level 0: each point stamps exp(−d²/(2σ²)) on the cells within 2σ of it.
  std::vector<std::uint8_t>& base = levels_[0];
  const int reach = static_cast<int>(std::ceil(2.0 * sigma_m / resolution_m));
  const double inv_two_sigma2 = 1.0 / (2.0 * sigma_m * sigma_m);
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2i c = cell(p);
    for (int iy = std::max(0, c.y() - reach); iy <= std::min(height - 1, c.y() + reach); ++iy) {
      for (int ix = std::max(0, c.x() - reach); ix <= std::min(width - 1, c.x() + reach); ++ix) {
        const Eigen::Vector2d centre = origin_ + resolution_m * Eigen::Vector2d(ix + 0.5, iy + 0.5);
        const double value = 255.0 * std::exp(-(centre - p).squaredNorm() * inv_two_sigma2);
        std::uint8_t& v = base[static_cast<std::size_t>(iy + padding_) * padded_width_ + (ix + padding_)];
        v = std::max(v, static_cast<std::uint8_t>(std::lround(value)));
      }
    }
  }
  // Level l from level l − 1: the maximum of four blocks of half the size.
  for (int l = 1; l < levels; ++l) {
    const int half = 1 << (l - 1);
    const std::vector<std::uint8_t>& below = levels_[static_cast<std::size_t>(l - 1)];
    std::vector<std::uint8_t>& here = levels_[static_cast<std::size_t>(l)];
    auto at = [&](int x, int y) -> std::uint8_t {
      return x < padded_width_ && y < padded_height_ ? below[static_cast<std::size_t>(y) * padded_width_ + x] : 0;
    };
    for (int y = 0; y < padded_height_; ++y) {
      for (int x = 0; x < padded_width_; ++x) {
        here[static_cast<std::size_t>(y) * padded_width_ + x] =
            std::max({at(x, y), at(x + half, y), at(x, y + half), at(x + half, y + half)});
      }
    }
  }
}

Eigen::Vector2i LikelihoodField::cell(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d c = (p - origin_) / resolution_m_;
  // Clamped far outside so the integer conversion stays defined (those cells read 0).
  constexpr double kFar = 1e6;
  return {static_cast<int>(std::floor(std::clamp(c.x(), -kFar, kFar))),
          static_cast<int>(std::floor(std::clamp(c.y(), -kFar, kFar)))};
}

std::optional<CorrelativeMatch> correlative_search(const LikelihoodField& field,
                                                   const std::vector<Eigen::Vector2d>& points, const Pose2& centre,
                                                   const CorrelativeWindow& window, double min_score,
                                                   const std::function<bool(const Pose2&)>& excluded) {
  if (!(window.linear_m >= 0.0) || !(window.angular_rad >= 0.0) || !(window.angular_step_rad > 0.0)) {
    throw std::invalid_argument("correlative_search: the window must be >= 0 and its angular step > 0");
  }
  if (points.empty()) return std::nullopt;
  BranchAndBound search(field, points, centre, window, excluded);
  const double n = static_cast<double>(points.size());
  // Scores strictly above floor: the best must exceed min_score.
  const int floor = static_cast<int>(std::floor(std::max(0.0, min_score) * 255.0 * n));
  const std::optional<Candidate> best = search.run(floor);
  if (!best) return std::nullopt;
  return CorrelativeMatch{search.pose(*best), best->score / (255.0 * n)};
}

}  // namespace lmf
