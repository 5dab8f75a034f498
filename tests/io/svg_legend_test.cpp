// The SVG legend: a layer with one row per entry, beside the drawing.
#include "lmf/io/svg_legend.hpp"

#include <string>

#include <gtest/gtest.h>

namespace lmf::io {
namespace {

TEST(SvgLegend, OneRowPerEntryInItsOwnLayerRightOfTheDrawing) {
  SvgDocument doc(10.0, 5.0);
  doc.add_line({0.0, 0.0}, {4.0, 2.0});
  SvgStyle red;
  red.stroke = "red";
  const Eigen::Vector2d corner = legend_right_of_bounds(doc, 10.0);
  EXPECT_NEAR(corner.x(), 5.0, 1e-12);  // 10 px right of x = 4 at 10 px/m
  EXPECT_NEAR(corner.y(), 2.0, 1e-12);
  add_legend(doc,
             {{SvgLegendEntry::Mark::kLine, red, "wall <segment>"},
              {SvgLegendEntry::Mark::kDot, red, "node"},
              {SvgLegendEntry::Mark::kPatch, red, "band"}},
             corner, "Legend");
  const std::string svg = doc.str();
  EXPECT_NE(svg.find("id=\"legend\""), std::string::npos);
  EXPECT_NE(svg.find("wall &lt;segment&gt;"), std::string::npos);
  EXPECT_NE(svg.find(">node<"), std::string::npos);
  EXPECT_NE(svg.find(">band<"), std::string::npos);
  EXPECT_NE(svg.find(">Legend<"), std::string::npos);
  // The drawing grew to hold the legend: wider than the 4 m line alone.
  EXPECT_GT(doc.bounds().max.x(), 5.0 + legend_size_px({{}, {}, {}}).x() / 10.0 - 1e-9);
}

TEST(SvgLegend, SizeGrowsWithRowsAndLabels) {
  const Eigen::Vector2d one = legend_size_px({{SvgLegendEntry::Mark::kLine, {}, "a"}});
  const Eigen::Vector2d two = legend_size_px({{SvgLegendEntry::Mark::kLine, {}, "a"}, {SvgLegendEntry::Mark::kLine, {}, "a much longer label"}});
  EXPECT_GT(two.y(), one.y());
  EXPECT_GT(two.x(), one.x());
}

}  // namespace
}  // namespace lmf::io
