#include "lmf/io/svg.hpp"

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace lmf::io {
namespace {

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + 1)) ++n;
  return n;
}

TEST(Svg, EmptyDocumentIsWellFormed) {
  const SvgDocument doc;
  const std::string s = doc.str();
  EXPECT_EQ(s.rfind("<svg", 0), 0u);
  EXPECT_NE(s.find("</svg>"), std::string::npos);
}

TEST(Svg, MapsWorldToPixelsWithYFlipped) {
  SvgDocument doc(10.0, 5.0);  // 10 px per metre, 5 px margin
  doc.add_line({0.0, 0.0}, {4.0, 2.0});
  // Box x [0, 4], y [0, 2]: 50 x 30 px with margins.
  const std::string s = doc.str();
  EXPECT_NE(s.find("width=\"50.00\" height=\"30.00\""), std::string::npos) << s;
  // (0, 0) is at the bottom left; (4, 2) at the top right.
  EXPECT_NE(s.find("<line x1=\"5.00\" y1=\"25.00\" x2=\"45.00\" y2=\"5.00\""), std::string::npos) << s;
}

TEST(Svg, ExplicitBoundsAndSeparateScales) {
  SvgDocument doc(1.0, 0.0);
  doc.set_scale(2.0, 4.0);
  doc.set_bounds({-1.0, -1.0}, {9.0, 4.0});
  doc.add_dot({0.0, 0.0}, 3.0);
  doc.add_dot({100.0, 100.0}, 3.0);  // outside: does not grow an explicit box
  const std::string s = doc.str();
  EXPECT_NE(s.find("width=\"20.00\" height=\"20.00\""), std::string::npos) << s;
  EXPECT_NE(s.find("<circle cx=\"2.00\" cy=\"16.00\" r=\"3.00\""), std::string::npos) << s;
  EXPECT_THROW(doc.set_bounds({0.0, 0.0}, {0.0, 1.0}), std::invalid_argument);
}

TEST(Svg, HasEveryElementKindLayersAndStyles) {
  SvgDocument doc(20.0);
  doc.set_title("map <1>");
  doc.begin_group("segments & bands", "segments");
  SvgStyle red;
  red.stroke = "#d62728";
  red.stroke_width_px = 2.5;
  red.stroke_opacity = 0.5;
  red.dash_px = "4 2";
  doc.add_line({0.0, 0.0}, {1.0, 0.0}, red);
  SvgStyle band;
  band.stroke = "none";
  band.fill = "#1f77b4";
  band.fill_opacity = 0.25;
  doc.add_band({{0.0, 0.1}, {1.0, 0.1}}, {{0.0, -0.1}, {1.0, -0.1}}, band);
  doc.end_group();
  doc.begin_group("path");
  doc.add_polyline({{0.0, 0.0}, {1.0, 1.0}, {2.0, 0.5}});
  doc.add_polygon({{0.0, 0.0}, {1.0, 1.0}, {2.0, 0.5}});
  doc.add_circle({1.0, 1.0}, 0.5);
  doc.add_ellipse({1.0, 1.0}, 0.5, 0.2, 0.3);
  doc.add_text({0.5, 0.5}, "a<b & \"c\"");
  doc.end_group();
  doc.add_scale_bar();
  EXPECT_THROW(doc.end_group(), std::logic_error);

  const std::string s = doc.str();
  EXPECT_EQ(count(s, "<line "), 1u + 3u);  // the segment plus the scale bar's three
  EXPECT_EQ(count(s, "<polyline "), 1u);
  EXPECT_EQ(count(s, "<polygon "), 3u);  // band, polygon, ellipse
  EXPECT_EQ(count(s, "<circle "), 1u);
  EXPECT_EQ(count(s, "<text "), 2u);  // label and scale bar
  EXPECT_EQ(count(s, "<g "), count(s, "</g>"));
  EXPECT_NE(s.find("<g id=\"segments\" class=\"layer\"><title>segments &amp; bands</title>"), std::string::npos);
  EXPECT_NE(s.find("<title>map &lt;1&gt;</title>"), std::string::npos);
  EXPECT_NE(s.find(">a&lt;b &amp; &quot;c&quot;</text>"), std::string::npos);
  EXPECT_NE(s.find("stroke=\"#d62728\" stroke-width=\"2.50\" stroke-opacity=\"0.50\" stroke-dasharray=\"4 2\""),
            std::string::npos);
  EXPECT_NE(s.find("fill=\"#1f77b4\" fill-opacity=\"0.25\""), std::string::npos);
  EXPECT_NE(s.find("class=\"scale-bar\""), std::string::npos);
  // The raw text must not leak unescaped.
  EXPECT_EQ(s.find("a<b"), std::string::npos);
  // Every tag opened with '<x' is a known element or a closing tag.
  const std::regex tag("<([a-z/]+)");
  for (auto it = std::sregex_iterator(s.begin(), s.end(), tag); it != std::sregex_iterator(); ++it) {
    const std::string name = (*it)[1];
    EXPECT_TRUE(name == "svg" || name == "title" || name == "desc" || name == "rect" || name == "g" ||
                name == "line" || name == "polyline" || name == "polygon" || name == "circle" || name == "text" ||
                name[0] == '/')
        << name;
  }
}

TEST(Svg, AutoBoundsGrowWithCirclesAndScaleBarIsRound) {
  SvgDocument doc(10.0, 0.0);
  doc.add_circle({0.0, 0.0}, 1.0);
  doc.add_dot({12.0, 3.0}, 2.0);
  const WorldBox box = doc.bounds();
  EXPECT_DOUBLE_EQ(box.min.x(), -1.0);
  EXPECT_DOUBLE_EQ(box.min.y(), -1.0);
  EXPECT_DOUBLE_EQ(box.max.x(), 12.0);
  EXPECT_DOUBLE_EQ(box.max.y(), 3.0);
  doc.add_scale_bar();  // width 13 m: about a fifth is 2.6 m -> 2 m
  EXPECT_NE(doc.str().find(">2 m</text>"), std::string::npos) << doc.str();
}

TEST(Svg, WriteCreatesTheFile) {
  SvgDocument doc;
  doc.add_line({0.0, 0.0}, {1.0, 1.0});
  const auto path = std::filesystem::path(::testing::TempDir()) / "lmf_svg_test.svg";
  doc.write(path);
  std::ifstream f(path);
  std::stringstream buf;
  buf << f.rdbuf();
  EXPECT_EQ(buf.str(), doc.str());
  std::filesystem::remove(path);
  EXPECT_THROW(doc.write("/nonexistent-dir/x.svg"), std::runtime_error);
}

TEST(Svg, RejectsNonFinitePoints) {
  SvgDocument doc;
  EXPECT_THROW(doc.add_line({0.0, std::nan("")}, {1.0, 1.0}), std::invalid_argument);
  EXPECT_THROW(SvgDocument(0.0), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::io
