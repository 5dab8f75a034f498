// A legend for an SvgDocument: one row per entry, a sample of the mark (a line,
// a dot or a filled patch in the entry's style) and its label, in a framed box.
// Sizes are in pixels, like the document's stroke widths and fonts; the box is
// placed by its top-left corner in world units, so a caller can put it beside
// the drawing (the automatic bounds grow to hold it) or inside a fixed plot area.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "lmf/io/svg.hpp"

namespace lmf::io {

struct SvgLegendEntry {
  enum class Mark { kLine, kDot, kPatch };
  Mark mark = Mark::kLine;
  SvgStyle style;  // of the sample: the line's stroke, the dot's or patch's fill
  std::string label;
};

// The legend's size in pixels for these entries (to place it).
Eigen::Vector2d legend_size_px(const std::vector<SvgLegendEntry>& entries, const std::string& title = "");

// Adds the legend as a layer "legend" with its top-left corner at `top_left` (world units).
void add_legend(SvgDocument& doc, const std::vector<SvgLegendEntry>& entries, const Eigen::Vector2d& top_left,
                const std::string& title = "");

// The top-left corner that puts the legend just right of the document's current
// bounds, level with their top (`gap_px` away).
Eigen::Vector2d legend_right_of_bounds(const SvgDocument& doc, double gap_px = 15.0);

}  // namespace lmf::io
