// A small SVG document builder for maps drawn in world units (metres).
//
// Everything is added in world coordinates (x right, y UP); the document maps
// them to SVG pixels (y down) when it is rendered, so the bounding box can keep
// growing while things are added. Widths, dash lengths, dot radii and font sizes
// are in pixels (they do not scale with the map); circle radii are in world units.
//
// Layers: begin_group(title)/end_group() wrap what is added in between in an
// `<g>` with an `id`, a `class="layer"` and a `<title>`, so a viewer (Inkscape's
// layers panel, a browser's devtools) can show or hide them one by one.
//
// Not thread-safe; str() and write() do not modify the document.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace lmf::io {

// Stroke and fill of a shape. Colours are any SVG colour ("#1f77b4", "red", "none").
struct SvgStyle {
  std::string stroke = "black";
  double stroke_width_px = 1.0;
  double stroke_opacity = 1.0;
  std::string dash_px;          // SVG dash array in pixels, e.g. "6 3"; empty: solid
  std::string fill = "none";
  double fill_opacity = 1.0;
  std::string css_class;        // optional class attribute
};

struct SvgTextStyle {
  std::string color = "black";
  double size_px = 12.0;
  std::string anchor = "start";  // SVG text-anchor: start, middle, end
  double opacity = 1.0;
  bool bold = false;
};

// Axis-aligned box in world units.
struct WorldBox {
  Eigen::Vector2d min = Eigen::Vector2d::Zero();
  Eigen::Vector2d max = Eigen::Vector2d::Zero();
};

class SvgDocument {
 public:
  // pixels_per_metre: the scale of both axes; margin_px: empty border around
  // the bounding box. Throws std::invalid_argument for non-positive values.
  explicit SvgDocument(double pixels_per_metre = 20.0, double margin_px = 20.0);

  // A different scale per axis (plots whose axes have different units).
  void set_scale(double pixels_per_unit_x, double pixels_per_unit_y);
  double pixels_per_unit_x() const { return scale_x_; }
  double pixels_per_unit_y() const { return scale_y_; }

  // Fixes the drawn world box (things outside are clipped by the viewport);
  // without it the box is the union of everything added.
  void set_bounds(const Eigen::Vector2d& min, const Eigen::Vector2d& max);
  // Grows the automatic box (e.g. to keep several maps at the same extent).
  void include_point(const Eigen::Vector2d& p);
  // The box that will be drawn (the explicit one, or the automatic one; a unit
  // box at the origin when nothing was added).
  WorldBox bounds() const;

  void set_title(const std::string& title) { title_ = title; }
  void set_background(const std::string& color) { background_ = color; }

  // Layers: nestable; end_group() closes the innermost one. Throws std::logic_error
  // on an unmatched end_group(); unclosed groups are closed when rendering.
  void begin_group(const std::string& title, const std::string& id = "");
  void end_group();

  void add_line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const SvgStyle& style = {});
  void add_polyline(const std::vector<Eigen::Vector2d>& points, const SvgStyle& style = {});
  void add_polygon(const std::vector<Eigen::Vector2d>& points, const SvgStyle& style = {});
  // A closed band between two boundaries given in the same direction (e.g. the
  // 2-sigma envelope of a segment or trajectory): left forward, right backward.
  void add_band(const std::vector<Eigen::Vector2d>& left, const std::vector<Eigen::Vector2d>& right,
                const SvgStyle& style = {});
  // Circle of a radius in world units.
  void add_circle(const Eigen::Vector2d& center, double radius, const SvgStyle& style = {});
  // Dot of a radius in pixels (a marker that does not scale).
  void add_dot(const Eigen::Vector2d& center, double radius_px, const SvgStyle& style = {});
  // Ellipse with semi-axes (world units) rotated by rotation_rad (counter-clockwise
  // in the world), drawn as a 48-sided polygon (e.g. a covariance ellipse).
  void add_ellipse(const Eigen::Vector2d& center, double semi_axis_a, double semi_axis_b, double rotation_rad,
                   const SvgStyle& style = {});
  // Text anchored at a world point; escaped for XML.
  void add_text(const Eigen::Vector2d& position, const std::string& text, const SvgTextStyle& style = {});
  // A scale bar at the bottom left of the drawing. length <= 0: a round length
  // of about a fifth of the drawing's width. The label uses `unit` ("m").
  void add_scale_bar(double length = 0.0, const std::string& unit = "m");

  std::size_t num_elements() const { return items_.size(); }

  // The whole document as text, starting with `<svg`.
  std::string str() const;
  // Writes str() to a file; throws std::runtime_error when it cannot.
  void write(const std::filesystem::path& file) const;

 private:
  enum class Kind { kLine, kPolyline, kPolygon, kCircle, kDot, kText, kGroupBegin, kGroupEnd, kScaleBar };
  struct Item {
    Kind kind = Kind::kLine;
    std::vector<Eigen::Vector2d> points;
    double radius = 0.0;
    SvgStyle style;
    SvgTextStyle text_style;
    std::string text;  // text, group title, or scale bar unit
    std::string id;    // group id
  };

  void expand(const Eigen::Vector2d& p);
  Eigen::Vector2d to_pixels(const Eigen::Vector2d& p, const WorldBox& box) const;

  double scale_x_;
  double scale_y_;
  double margin_px_;
  std::string title_;
  std::string background_ = "white";
  std::optional<WorldBox> explicit_bounds_;
  std::optional<WorldBox> auto_bounds_;
  std::vector<Item> items_;
  int open_groups_ = 0;
  int group_counter_ = 0;
};

// Escapes &, <, >, " and ' for XML text and attribute values.
std::string xml_escape(const std::string& text);

}  // namespace lmf::io
