#include "lmf/io/svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace lmf::io {
namespace {

// Pixel numbers with two decimals: enough for any screen, keeps files small.
std::string num(double v) {
  char buf[64];
  if (std::abs(v) < 0.005) v = 0.0;  // no "-0.00"
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

void check_positive(double v, const char* what) {
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw std::invalid_argument(std::string("SvgDocument: ") + what + " must be positive and finite, got " +
                                std::to_string(v));
  }
}

void check_finite(const Eigen::Vector2d& p, const char* what) {
  if (!p.allFinite()) throw std::invalid_argument(std::string("SvgDocument::") + what + ": non-finite point");
}

std::string style_attributes(const SvgStyle& s) {
  std::string out = " stroke=\"" + xml_escape(s.stroke) + "\" stroke-width=\"" + num(s.stroke_width_px) + "\"";
  if (s.stroke_opacity < 1.0) out += " stroke-opacity=\"" + num(s.stroke_opacity) + "\"";
  if (!s.dash_px.empty()) out += " stroke-dasharray=\"" + xml_escape(s.dash_px) + "\"";
  out += " fill=\"" + xml_escape(s.fill) + "\"";
  if (s.fill_opacity < 1.0 && s.fill != "none") out += " fill-opacity=\"" + num(s.fill_opacity) + "\"";
  if (!s.css_class.empty()) out += " class=\"" + xml_escape(s.css_class) + "\"";
  return out;
}

// 1, 2 or 5 times a power of ten, at most `limit` (limit > 0).
double round_length_below(double limit) {
  const double p = std::pow(10.0, std::floor(std::log10(limit)));
  for (const double f : {5.0, 2.0, 1.0}) {
    if (f * p <= limit) return f * p;
  }
  return p;
}

}  // namespace

std::string xml_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default:
        // Control characters other than tab/newline are not allowed in XML 1.0.
        if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n' && c != '\r') {
          out += '?';
        } else {
          out += c;
        }
    }
  }
  return out;
}

SvgDocument::SvgDocument(double pixels_per_metre, double margin_px)
    : scale_x_(pixels_per_metre), scale_y_(pixels_per_metre), margin_px_(margin_px) {
  check_positive(pixels_per_metre, "pixels_per_metre");
  if (!(margin_px >= 0.0) || !std::isfinite(margin_px)) {
    throw std::invalid_argument("SvgDocument: margin_px must be >= 0 and finite");
  }
}

void SvgDocument::set_scale(double pixels_per_unit_x, double pixels_per_unit_y) {
  check_positive(pixels_per_unit_x, "pixels_per_unit_x");
  check_positive(pixels_per_unit_y, "pixels_per_unit_y");
  scale_x_ = pixels_per_unit_x;
  scale_y_ = pixels_per_unit_y;
}

void SvgDocument::set_bounds(const Eigen::Vector2d& min, const Eigen::Vector2d& max) {
  check_finite(min, "set_bounds");
  check_finite(max, "set_bounds");
  if (!(max.x() > min.x()) || !(max.y() > min.y())) {
    throw std::invalid_argument("SvgDocument::set_bounds: max must exceed min on both axes");
  }
  explicit_bounds_ = WorldBox{min, max};
}

void SvgDocument::include_point(const Eigen::Vector2d& p) {
  check_finite(p, "include_point");
  expand(p);
}

void SvgDocument::expand(const Eigen::Vector2d& p) {
  if (!auto_bounds_) {
    auto_bounds_ = WorldBox{p, p};
  } else {
    auto_bounds_->min = auto_bounds_->min.cwiseMin(p);
    auto_bounds_->max = auto_bounds_->max.cwiseMax(p);
  }
}

WorldBox SvgDocument::bounds() const {
  if (explicit_bounds_) return *explicit_bounds_;
  if (!auto_bounds_) return WorldBox{Eigen::Vector2d::Zero(), Eigen::Vector2d::Ones()};
  WorldBox box = *auto_bounds_;
  // A degenerate box (one point, a vertical line) still gets a visible extent.
  for (int i = 0; i < 2; ++i) {
    if (box.max(i) - box.min(i) < 1e-9) {
      box.min(i) -= 0.5;
      box.max(i) += 0.5;
    }
  }
  return box;
}

Eigen::Vector2d SvgDocument::to_pixels(const Eigen::Vector2d& p, const WorldBox& box) const {
  // World y grows up, SVG y grows down.
  return {margin_px_ + (p.x() - box.min.x()) * scale_x_, margin_px_ + (box.max.y() - p.y()) * scale_y_};
}

void SvgDocument::begin_group(const std::string& title, const std::string& id) {
  Item item;
  item.kind = Kind::kGroupBegin;
  item.text = title;
  item.id = id.empty() ? "layer-" + std::to_string(++group_counter_) : id;
  items_.push_back(std::move(item));
  ++open_groups_;
}

void SvgDocument::end_group() {
  if (open_groups_ == 0) throw std::logic_error("SvgDocument::end_group without begin_group");
  --open_groups_;
  Item item;
  item.kind = Kind::kGroupEnd;
  items_.push_back(std::move(item));
}

void SvgDocument::add_line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const SvgStyle& style) {
  check_finite(a, "add_line");
  check_finite(b, "add_line");
  expand(a);
  expand(b);
  items_.push_back(Item{Kind::kLine, {a, b}, 0.0, style, {}, {}, {}});
}

void SvgDocument::add_polyline(const std::vector<Eigen::Vector2d>& points, const SvgStyle& style) {
  for (const auto& p : points) check_finite(p, "add_polyline");
  if (points.size() < 2) return;
  for (const auto& p : points) expand(p);
  items_.push_back(Item{Kind::kPolyline, points, 0.0, style, {}, {}, {}});
}

void SvgDocument::add_polygon(const std::vector<Eigen::Vector2d>& points, const SvgStyle& style) {
  for (const auto& p : points) check_finite(p, "add_polygon");
  if (points.size() < 3) return;
  for (const auto& p : points) expand(p);
  items_.push_back(Item{Kind::kPolygon, points, 0.0, style, {}, {}, {}});
}

void SvgDocument::add_band(const std::vector<Eigen::Vector2d>& left, const std::vector<Eigen::Vector2d>& right,
                           const SvgStyle& style) {
  std::vector<Eigen::Vector2d> ring(left);
  ring.insert(ring.end(), right.rbegin(), right.rend());
  add_polygon(ring, style);
}

void SvgDocument::add_circle(const Eigen::Vector2d& center, double radius, const SvgStyle& style) {
  check_finite(center, "add_circle");
  if (!(radius >= 0.0) || !std::isfinite(radius)) {
    throw std::invalid_argument("SvgDocument::add_circle: radius must be >= 0 and finite");
  }
  expand(center - Eigen::Vector2d(radius, radius));
  expand(center + Eigen::Vector2d(radius, radius));
  items_.push_back(Item{Kind::kCircle, {center}, radius, style, {}, {}, {}});
}

void SvgDocument::add_dot(const Eigen::Vector2d& center, double radius_px, const SvgStyle& style) {
  check_finite(center, "add_dot");
  expand(center);
  items_.push_back(Item{Kind::kDot, {center}, radius_px, style, {}, {}, {}});
}

void SvgDocument::add_ellipse(const Eigen::Vector2d& center, double semi_axis_a, double semi_axis_b,
                              double rotation_rad, const SvgStyle& style) {
  constexpr int kSides = 48;
  const double c = std::cos(rotation_rad);
  const double s = std::sin(rotation_rad);
  std::vector<Eigen::Vector2d> ring;
  ring.reserve(kSides);
  for (int i = 0; i < kSides; ++i) {
    const double t = 2.0 * std::numbers::pi * i / kSides;
    const double u = semi_axis_a * std::cos(t);
    const double v = semi_axis_b * std::sin(t);
    ring.emplace_back(center.x() + c * u - s * v, center.y() + s * u + c * v);
  }
  add_polygon(ring, style);
}

void SvgDocument::add_text(const Eigen::Vector2d& position, const std::string& text, const SvgTextStyle& style) {
  check_finite(position, "add_text");
  expand(position);
  items_.push_back(Item{Kind::kText, {position}, 0.0, {}, style, text, {}});
}

void SvgDocument::add_scale_bar(double length, const std::string& unit) {
  if (!std::isfinite(length)) throw std::invalid_argument("SvgDocument::add_scale_bar: non-finite length");
  items_.push_back(Item{Kind::kScaleBar, {}, length, {}, {}, unit, {}});
}

std::string SvgDocument::str() const {
  const WorldBox box = bounds();
  const double width = 2.0 * margin_px_ + (box.max.x() - box.min.x()) * scale_x_;
  const double height = 2.0 * margin_px_ + (box.max.y() - box.min.y()) * scale_y_;
  std::ostringstream out;
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" << num(width) << "\" height=\""
      << num(height) << "\" viewBox=\"0 0 " << num(width) << " " << num(height) << "\">\n";
  if (!title_.empty()) out << "<title>" << xml_escape(title_) << "</title>\n";
  // The world box, so a reader (or a test) can map pixels back to metres.
  out << "<desc>world box x [" << box.min.x() << ", " << box.max.x() << "] y [" << box.min.y() << ", "
      << box.max.y() << "]; " << scale_x_ << " px per unit in x, " << scale_y_ << " in y; y up</desc>\n";
  if (!background_.empty() && background_ != "none") {
    out << "<rect x=\"0\" y=\"0\" width=\"" << num(width) << "\" height=\"" << num(height) << "\" fill=\""
        << xml_escape(background_) << "\"/>\n";
  }
  const auto points_attr = [&](const std::vector<Eigen::Vector2d>& pts) {
    std::string s;
    for (const auto& p : pts) {
      const Eigen::Vector2d q = to_pixels(p, box);
      if (!s.empty()) s += ' ';
      s += num(q.x()) + "," + num(q.y());
    }
    return s;
  };
  int depth = 0;
  for (const Item& it : items_) {
    switch (it.kind) {
      case Kind::kGroupBegin:
        out << "<g id=\"" << xml_escape(it.id) << "\" class=\"layer\"><title>" << xml_escape(it.text)
            << "</title>\n";
        ++depth;
        break;
      case Kind::kGroupEnd:
        out << "</g>\n";
        --depth;
        break;
      case Kind::kLine: {
        const Eigen::Vector2d a = to_pixels(it.points[0], box);
        const Eigen::Vector2d b = to_pixels(it.points[1], box);
        out << "<line x1=\"" << num(a.x()) << "\" y1=\"" << num(a.y()) << "\" x2=\"" << num(b.x()) << "\" y2=\""
            << num(b.y()) << "\"" << style_attributes(it.style) << "/>\n";
        break;
      }
      case Kind::kPolyline:
        out << "<polyline points=\"" << points_attr(it.points) << "\"" << style_attributes(it.style) << "/>\n";
        break;
      case Kind::kPolygon:
        out << "<polygon points=\"" << points_attr(it.points) << "\"" << style_attributes(it.style) << "/>\n";
        break;
      case Kind::kCircle:
      case Kind::kDot: {
        const Eigen::Vector2d c = to_pixels(it.points[0], box);
        const bool world = it.kind == Kind::kCircle;
        const double rx = world ? it.radius * scale_x_ : it.radius;
        const double ry = world ? it.radius * scale_y_ : it.radius;
        if (std::abs(rx - ry) < 1e-9) {
          out << "<circle cx=\"" << num(c.x()) << "\" cy=\"" << num(c.y()) << "\" r=\"" << num(rx) << "\"";
        } else {
          out << "<ellipse cx=\"" << num(c.x()) << "\" cy=\"" << num(c.y()) << "\" rx=\"" << num(rx)
              << "\" ry=\"" << num(ry) << "\"";
        }
        out << style_attributes(it.style) << "/>\n";
        break;
      }
      case Kind::kText: {
        const Eigen::Vector2d p = to_pixels(it.points[0], box);
        const SvgTextStyle& t = it.text_style;
        out << "<text x=\"" << num(p.x()) << "\" y=\"" << num(p.y()) << "\" font-family=\"sans-serif\" font-size=\""
            << num(t.size_px) << "\" fill=\"" << xml_escape(t.color) << "\" text-anchor=\"" << xml_escape(t.anchor)
            << "\"";
        if (t.opacity < 1.0) out << " fill-opacity=\"" << num(t.opacity) << "\"";
        if (t.bold) out << " font-weight=\"bold\"";
        out << ">" << xml_escape(it.text) << "</text>\n";
        break;
      }
      case Kind::kScaleBar: {
        const double drawing_width = (box.max.x() - box.min.x());
        const double length = it.radius > 0.0 ? it.radius : round_length_below(drawing_width / 5.0);
        const double x0 = margin_px_;
        const double x1 = margin_px_ + length * scale_x_;
        const double y = height - std::max(4.0, margin_px_ * 0.3);
        char label[64];
        std::snprintf(label, sizeof label, "%g ", length);
        out << "<g class=\"scale-bar\"><title>scale bar</title>\n"
            << "<line x1=\"" << num(x0) << "\" y1=\"" << num(y) << "\" x2=\"" << num(x1) << "\" y2=\"" << num(y)
            << "\" stroke=\"black\" stroke-width=\"2\"/>\n"
            << "<line x1=\"" << num(x0) << "\" y1=\"" << num(y - 4) << "\" x2=\"" << num(x0) << "\" y2=\""
            << num(y + 2) << "\" stroke=\"black\" stroke-width=\"1\"/>\n"
            << "<line x1=\"" << num(x1) << "\" y1=\"" << num(y - 4) << "\" x2=\"" << num(x1) << "\" y2=\""
            << num(y + 2) << "\" stroke=\"black\" stroke-width=\"1\"/>\n"
            << "<text x=\"" << num(0.5 * (x0 + x1)) << "\" y=\"" << num(y - 5)
            << "\" font-family=\"sans-serif\" font-size=\"11\" text-anchor=\"middle\">" << xml_escape(label)
            << xml_escape(it.text) << "</text>\n</g>\n";
        break;
      }
    }
  }
  for (; depth > 0; --depth) out << "</g>\n";
  out << "</svg>\n";
  return out.str();
}

void SvgDocument::write(const std::filesystem::path& file) const {
  std::ofstream f(file, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open " + file.string() + " for writing");
  f << str();
  f.close();
  if (!f) throw std::runtime_error("error writing " + file.string());
}

}  // namespace lmf::io
