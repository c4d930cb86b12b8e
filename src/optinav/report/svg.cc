#include "optinav/report/svg.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace optinav::report {

std::string Rgb::Hex() const { return fmt::format("#{:02x}{:02x}{:02x}", r, g, b); }

Rgb ColorMap(double t) {
  if (!std::isfinite(t)) t = 0;
  t = std::clamp(t, 0.0, 1.0);
  // Control points (similar in spirit to matplotlib's "jet"-free perceptual maps).
  static constexpr double kStops[][3] = {{0.19, 0.07, 0.48}, {0.13, 0.41, 0.66},
                                         {0.13, 0.66, 0.53}, {0.55, 0.82, 0.22},
                                         {0.99, 0.85, 0.15}, {0.86, 0.19, 0.12}};
  constexpr int kN = 6;
  const double x = t * (kN - 1);
  const int i = std::min(static_cast<int>(x), kN - 2);
  const double f = x - i;
  Rgb c;
  auto mix = [&](int k) {
    return static_cast<unsigned char>(
        std::lround(255.0 * ((1 - f) * kStops[i][k] + f * kStops[i + 1][k])));
  };
  c.r = mix(0);
  c.g = mix(1);
  c.b = mix(2);
  return c;
}

std::string XmlEscape(const std::string& text) {
  std::string out;
  for (char ch : text) {
    switch (ch) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

SvgDocument::SvgDocument(double width, double height) : width_(width), height_(height) {}

void SvgDocument::Line(double x1, double y1, double x2, double y2, const std::string& stroke,
                       double width, const std::string& extra) {
  body_ += fmt::format(
      "<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\" stroke=\"{}\" "
      "stroke-width=\"{}\" {}/>\n",
      x1, y1, x2, y2, stroke, width, extra);
}

void SvgDocument::Polyline(const std::string& points, const std::string& stroke, double width,
                           const std::string& extra) {
  body_ += fmt::format(
      "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{}\" "
      "stroke-linejoin=\"round\" {}/>\n",
      points, stroke, width, extra);
}

void SvgDocument::Rect(double x, double y, double w, double h, const std::string& fill,
                       const std::string& stroke) {
  body_ += fmt::format(
      "<rect x=\"{:.2f}\" y=\"{:.2f}\" width=\"{:.2f}\" height=\"{:.2f}\" fill=\"{}\" "
      "stroke=\"{}\"/>\n",
      x, y, w, h, fill, stroke);
}

void SvgDocument::Circle(double cx, double cy, double r, const std::string& fill,
                         const std::string& stroke) {
  body_ += fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"{}\" fill=\"{}\" stroke=\"{}\"/>\n",
                       cx, cy, r, fill, stroke);
}

void SvgDocument::Text(double x, double y, const std::string& text, double size,
                       const std::string& anchor, const std::string& extra) {
  body_ += fmt::format(
      "<text x=\"{:.2f}\" y=\"{:.2f}\" font-size=\"{}\" text-anchor=\"{}\" {}>{}</text>\n", x, y,
      size, anchor, extra, XmlEscape(text));
}

void SvgDocument::Raw(const std::string& element) { body_ += element + "\n"; }

std::string SvgDocument::Finish() const {
  return fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" "
      "viewBox=\"0 0 {0} {1}\" font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{2}</svg>\n",
      width_, height_, body_);
}

Ticks NiceTicks(double lo, double hi, int count) {
  Ticks t;
  if (!(hi > lo)) {
    hi = lo + 1;
  }
  const double raw = (hi - lo) / std::max(count, 1);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  const double step = (norm < 1.5 ? 1 : norm < 3 ? 2 : norm < 7 ? 5 : 10) * mag;
  t.step = step;
  t.start = std::ceil(lo / step - 1e-9) * step;
  t.count = static_cast<int>(std::floor((hi - t.start) / step + 1e-9)) + 1;
  return t;
}

std::string FormatTick(double value, double step) {
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(step) + 1e-9)));
  if (std::abs(value) < step * 1e-6) value = 0;
  return fmt::format("{:.{}f}", value, decimals);
}

}  // namespace optinav::report
