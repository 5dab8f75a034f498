#include "lmf/io/svg_legend.hpp"

#include <algorithm>

namespace lmf::io {
namespace {

constexpr double kRowPx = 16.0;
constexpr double kPaddingPx = 6.0;
constexpr double kSamplePx = 22.0;
constexpr double kFontPx = 11.0;
constexpr double kCharPx = 6.2;  // average advance of the 11 px sans-serif font

}  // namespace

Eigen::Vector2d legend_size_px(const std::vector<SvgLegendEntry>& entries, const std::string& title) {
  std::size_t chars = title.size();
  for (const SvgLegendEntry& e : entries) chars = std::max(chars, e.label.size() + 4);
  const double rows = static_cast<double>(entries.size()) + (title.empty() ? 0.0 : 1.0);
  return {2.0 * kPaddingPx + kSamplePx + static_cast<double>(chars) * kCharPx - 4.0 * kCharPx + 6.0,
          2.0 * kPaddingPx + rows * kRowPx};
}

void add_legend(SvgDocument& doc, const std::vector<SvgLegendEntry>& entries, const Eigen::Vector2d& top_left,
                const std::string& title) {
  const double sx = 1.0 / doc.pixels_per_unit_x();  // world units per pixel
  const double sy = 1.0 / doc.pixels_per_unit_y();
  const auto at = [&](double x_px, double y_px) {  // pixels right and DOWN from the top-left corner
    return Eigen::Vector2d(top_left.x() + x_px * sx, top_left.y() - y_px * sy);
  };
  const Eigen::Vector2d size = legend_size_px(entries, title);
  doc.begin_group("legend", "legend");
  SvgStyle frame;
  frame.stroke = "#999";
  frame.fill = "white";
  frame.fill_opacity = 0.9;
  doc.add_polygon({at(0, 0), at(size.x(), 0), at(size.x(), size.y()), at(0, size.y())}, frame);
  double y = kPaddingPx;
  SvgTextStyle text;
  text.size_px = kFontPx;
  if (!title.empty()) {
    text.bold = true;
    doc.add_text(at(kPaddingPx, y + 0.75 * kRowPx), title, text);
    text.bold = false;
    y += kRowPx;
  }
  for (const SvgLegendEntry& e : entries) {
    const double mid = y + 0.5 * kRowPx;
    switch (e.mark) {
      case SvgLegendEntry::Mark::kLine:
        doc.add_line(at(kPaddingPx, mid), at(kPaddingPx + kSamplePx, mid), e.style);
        break;
      case SvgLegendEntry::Mark::kDot:
        doc.add_dot(at(kPaddingPx + 0.5 * kSamplePx, mid), 3.0, e.style);
        break;
      case SvgLegendEntry::Mark::kPatch:
        doc.add_polygon({at(kPaddingPx, mid - 4), at(kPaddingPx + kSamplePx, mid - 4),
                         at(kPaddingPx + kSamplePx, mid + 4), at(kPaddingPx, mid + 4)},
                        e.style);
        break;
    }
    doc.add_text(at(2.0 * kPaddingPx + kSamplePx, mid + 0.35 * kFontPx), e.label, text);
    y += kRowPx;
  }
  doc.end_group();
}

Eigen::Vector2d legend_right_of_bounds(const SvgDocument& doc, double gap_px) {
  const WorldBox box = doc.bounds();
  return {box.max.x() + gap_px / doc.pixels_per_unit_x(), box.max.y()};
}

}  // namespace lmf::io
