// A minimal SVG writer and the colour map shared by the project's plots.
#pragma once

#include <string>

namespace optinav::report {

struct Rgb {
  unsigned char r = 0, g = 0, b = 0;
  std::string Hex() const;
};

// Perceptually ordered map for values in [0, 1]: dark blue -> teal -> green -> yellow -> red.
Rgb ColorMap(double t);

// Escapes &, <, > and quotes for SVG text and attributes.
std::string XmlEscape(const std::string& text);

// Accumulates SVG elements; Finish() returns the whole SVG file as text.
class SvgDocument {
 public:
  SvgDocument(double width, double height);
  void Line(double x1, double y1, double x2, double y2, const std::string& stroke, double width,
            const std::string& extra = "");
  // points as "x,y x,y ..."
  void Polyline(const std::string& points, const std::string& stroke, double width,
                const std::string& extra = "");
  void Rect(double x, double y, double w, double h, const std::string& fill,
            const std::string& stroke = "none");
  void Circle(double cx, double cy, double r, const std::string& fill,
              const std::string& stroke = "none");
  // anchor: start|middle|end
  void Text(double x, double y, const std::string& text, double size = 12,
            const std::string& anchor = "start", const std::string& extra = "");
  void Raw(const std::string& element);
  std::string Finish() const;

 private:
  double width_, height_;
  std::string body_;
};

// "Nice" axis ticks covering [lo, hi] (about `count` of them).
struct Ticks {
  double start = 0, step = 1;
  int count = 0;
};
Ticks NiceTicks(double lo, double hi, int count = 5);
std::string FormatTick(double value, double step);

}  // namespace optinav::report
