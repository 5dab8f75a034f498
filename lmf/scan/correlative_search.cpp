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

// Branch and bound over the window's translations at every rotation, pruning
// nodes whose bound cannot reach ratio times the best leaf found so far, so
// every leaf above that fraction of the final best is visited.
class BranchAndBound {
 public:
  BranchAndBound(const LikelihoodField& field, const std::vector<Eigen::Vector2d>& points, const Pose2& centre,
                 const CorrelativeWindow& window, double ratio)
      : field_(field), centre_(centre), window_(window), ratio_(ratio), n_(static_cast<int>(points.size())) {
    const double r = field.resolution_m();
    half_cells_x_ = static_cast<int>(std::floor(window.linear_m / r + 1e-9));
    half_cells_y_ = static_cast<int>(std::floor(window.linear_y_m.value_or(window.linear_m) / r + 1e-9));
    half_rotations_ = static_cast<int>(std::floor(window.angular_rad / window.angular_step_rad + 1e-9));
    const int rotations = 2 * half_rotations_ + 1;
    cells_.resize(static_cast<std::size_t>(rotations) * points.size());
    const Eigen::Vector2d t(centre.x, centre.y);
    for (int k = 0; k < rotations; ++k) {
      const Eigen::Rotation2Dd R(centre.phi + (k - half_rotations_) * window.angular_step_rad);
      const Eigen::Matrix2d M = R.toRotationMatrix();
      for (int i = 0; i < n_; ++i) {
        cells_[static_cast<std::size_t>(k * n_ + i)] = field.cell(t + M * points[static_cast<std::size_t>(i)]);
      }
    }
  }

  // Leaves scoring above `floor` (units of 1/255 per point, summed) and at
  // least ratio times the best, the best first; empty when none.
  std::vector<Candidate> run(int floor) {
    floor_ = floor;
    best_score_ = floor;
    leaves_.clear();
    const int top = field_.levels() - 1;
    std::vector<Candidate> roots;
    const int rotations = 2 * half_rotations_ + 1;
    for (int k = 0; k < rotations; ++k) {
      if (window_.heading_searched && !window_.heading_searched((k - half_rotations_) * window_.angular_step_rad)) {
        continue;
      }
      for (int ox = -half_cells_x_; ox <= half_cells_x_; ox += 1 << top) {
        for (int oy = -half_cells_y_; oy <= half_cells_y_; oy += 1 << top) {
          roots.push_back({k, ox, oy, score(top, k, ox, oy)});
        }
      }
    }
    branch(roots, top);
    const int keep = threshold();
    std::erase_if(leaves_, [&](const Candidate& c) { return c.score < keep && c.score != best_score_; });
    std::sort(leaves_.begin(), leaves_.end(), [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
    return leaves_;
  }

  Pose2 pose(const Candidate& c) const {
    const double r = field_.resolution_m();
    return {centre_.x + c.ox * r, centre_.y + c.oy * r,
            wrap_angle(centre_.phi + (c.rotation - half_rotations_) * window_.angular_step_rad)};
  }

 private:
  // Nodes and leaves below this cannot matter.
  int threshold() const {
    return leaves_.empty() ? floor_ + 1 : std::max(floor_ + 1, static_cast<int>(std::ceil(ratio_ * best_score_)));
  }

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
      if (c.score < threshold()) return;  // sorted: the rest are below it too
      if (level == 0) {
        leaves_.push_back(c);
        best_score_ = std::max(best_score_, c.score);
        continue;
      }
      const int half = 1 << (level - 1);
      std::vector<Candidate> children;
      children.reserve(4);
      for (const int dx : {0, half}) {
        for (const int dy : {0, half}) {
          const int ox = c.ox + dx;
          const int oy = c.oy + dy;
          if (ox > half_cells_x_ || oy > half_cells_y_) continue;
          const int s = score(level - 1, c.rotation, ox, oy);
          if (s >= threshold()) children.push_back({c.rotation, ox, oy, s});
        }
      }
      branch(children, level - 1);
    }
  }

  const LikelihoodField& field_;
  Pose2 centre_;
  CorrelativeWindow window_;
  double ratio_;
  int n_;
  int half_cells_x_ = 0;
  int half_cells_y_ = 0;
  int half_rotations_ = 0;
  std::vector<Eigen::Vector2i> cells_;  // per rotation, the level-0 cell of each point at the centre translation
  int floor_ = 0;
  int best_score_ = 0;
  std::vector<Candidate> leaves_;
};

}  // namespace

int LikelihoodField::levels_for(double window_m, double resolution_m) {
  const double cells = std::floor(window_m / resolution_m + 1e-9);
  if (!(cells >= 0.0) || cells > 1e6) return kMaxLevels + 1;  // NaN, or far beyond any pyramid
  const int half_cells = static_cast<int>(cells);
  int levels = 1;
  while ((1 << (levels - 1)) < 2 * half_cells + 1) ++levels;
  return levels;
}

LikelihoodField::LikelihoodField(const std::vector<Eigen::Vector2d>& points, const Eigen::AlignedBox2d& region,
                                 double resolution_m, double sigma_m, int levels)
    : resolution_m_(resolution_m) {
  if (!(resolution_m > 0.0) || !(sigma_m > 0.0) || levels < 1 || levels > kMaxLevels) {
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

  // Level 0: each point stamps exp(−d²/(2σ²)) = exp(−dx²/(2σ²)) exp(−dy²/(2σ²))
  // on the cells within 2σ of it.
  std::vector<std::uint8_t>& base = levels_[0];
  const int reach = static_cast<int>(std::ceil(2.0 * sigma_m / resolution_m));
  const double inv_two_sigma2 = 1.0 / (2.0 * sigma_m * sigma_m);
  std::vector<double> fx(static_cast<std::size_t>(2 * reach + 1));
  std::vector<double> fy(fx.size());
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2i c = cell(p);
    if (c.x() + reach < 0 || c.y() + reach < 0 || c.x() - reach >= width || c.y() - reach >= height) continue;
    for (int o = -reach; o <= reach; ++o) {
      const double dx = origin_.x() + resolution_m * (c.x() + o + 0.5) - p.x();
      const double dy = origin_.y() + resolution_m * (c.y() + o + 0.5) - p.y();
      fx[static_cast<std::size_t>(o + reach)] = 255.0 * std::exp(-dx * dx * inv_two_sigma2);
      fy[static_cast<std::size_t>(o + reach)] = std::exp(-dy * dy * inv_two_sigma2);
    }
    for (int iy = std::max(0, c.y() - reach); iy <= std::min(height - 1, c.y() + reach); ++iy) {
      std::uint8_t* row = &base[static_cast<std::size_t>(iy + padding_) * padded_width_ + padding_];
      const double wy = fy[static_cast<std::size_t>(iy - c.y() + reach)];
      for (int ix = std::max(0, c.x() - reach); ix <= std::min(width - 1, c.x() + reach); ++ix) {
        const auto v = static_cast<std::uint8_t>(fx[static_cast<std::size_t>(ix - c.x() + reach)] * wy + 0.5);
        row[ix] = std::max(row[ix], v);
      }
    }
  }
  // Level l from level l − 1: the maximum of four blocks of half the size
  // (cells beyond the padded array read 0).
  const auto W = static_cast<std::size_t>(padded_width_);
  for (int l = 1; l < levels; ++l) {
    const auto half = static_cast<std::size_t>(1 << (l - 1));
    const std::vector<std::uint8_t>& below = levels_[static_cast<std::size_t>(l - 1)];
    std::vector<std::uint8_t>& here = levels_[static_cast<std::size_t>(l)];
    for (std::size_t y = 0; y < static_cast<std::size_t>(padded_height_); ++y) {
      const std::uint8_t* r0 = &below[y * W];
      const std::uint8_t* r1 = y + half < static_cast<std::size_t>(padded_height_) ? &below[(y + half) * W] : nullptr;
      std::uint8_t* out = &here[y * W];
      const std::size_t inner = W > half ? W - half : 0;
      if (r1 != nullptr) {
        for (std::size_t x = 0; x < inner; ++x) out[x] = std::max(std::max(r0[x], r0[x + half]), std::max(r1[x], r1[x + half]));
        for (std::size_t x = inner; x < W; ++x) out[x] = std::max(r0[x], r1[x]);
      } else {
        for (std::size_t x = 0; x < inner; ++x) out[x] = std::max(r0[x], r0[x + half]);
        for (std::size_t x = inner; x < W; ++x) out[x] = r0[x];
      }
    }
  }
}

std::optional<CorrelativeResult> correlative_search(const LikelihoodField& field,
                                                    const std::vector<Eigen::Vector2d>& points, const Pose2& centre,
                                                    const CorrelativeWindow& window, double min_score,
                                                    double contender_ratio) {
  if (!(window.linear_m >= 0.0) || !(window.linear_y_m.value_or(0.0) >= 0.0) || !(window.angular_rad >= 0.0) ||
      !(window.angular_step_rad > 0.0)) {
    throw std::invalid_argument("correlative_search: the window must be >= 0 and its angular step > 0");
  }
  if (!(contender_ratio > 0.0 && contender_ratio <= 1.0)) {
    throw std::invalid_argument("correlative_search: contender_ratio must be in (0, 1]");
  }
  if (points.empty()) return std::nullopt;
  BranchAndBound search(field, points, centre, window, contender_ratio);
  const double n = static_cast<double>(points.size());
  // Scores strictly above floor: the best must exceed min_score.
  const int floor = static_cast<int>(std::floor(std::max(0.0, min_score) * 255.0 * n));
  const std::vector<Candidate> leaves = search.run(floor);
  if (leaves.empty()) return std::nullopt;
  CorrelativeResult result;
  result.best = {search.pose(leaves.front()), leaves.front().score / (255.0 * n)};
  for (std::size_t i = 1; i < leaves.size(); ++i) {
    result.contenders.push_back({search.pose(leaves[i]), leaves[i].score / (255.0 * n)});
  }
  return result;
}

bool on_window_edge(const Pose2& x, const Pose2& centre, const CorrelativeWindow& window, double resolution_m) {
  // The grid index of an offset along one axis, against the outermost index.
  const auto at_edge = [](double offset, double half_width, double step) {
    const int outermost = static_cast<int>(std::floor(half_width / step + 1e-9));
    return outermost > 0 && std::lround(std::abs(offset) / step) >= outermost;
  };
  return at_edge(x.x - centre.x, window.linear_m, resolution_m) ||
         at_edge(x.y - centre.y, window.linear_y_m.value_or(window.linear_m), resolution_m) ||
         at_edge(wrap_angle(x.phi - centre.phi), window.angular_rad, window.angular_step_rad);
}

}  // namespace lmf
