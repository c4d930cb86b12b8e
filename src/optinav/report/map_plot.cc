#include "optinav/report/map_plot.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/io/text_parse.h"
#include "optinav/util/error.h"

namespace optinav::report {

namespace {

constexpr int kBandLine = 18;      // height of one title/legend line, pixels
constexpr int kChartHeight = 170;  // pixels, axes included
constexpr int kChartLeft = 56, kChartRight = 12, kChartTop = 22, kChartBottom = 30;

// The chart's data ranges and the pixel mapping inside a box of width w at vertical offset y0.
struct ChartFrame {
  double x0 = 0, x1 = 1, y1 = 1;  // y starts at 0
  Ticks xt, yt;
  int w = 0, y0 = 0;
  double X(double x) const {
    return kChartLeft + (x - x0) / (x1 - x0) * (w - kChartLeft - kChartRight);
  }
  double Y(double y) const {
    return y0 + kChartHeight - kChartBottom - y / y1 * (kChartHeight - kChartTop - kChartBottom);
  }
};

ChartFrame MakeChartFrame(const MapPlot& p, int w, int y0) {
  ChartFrame f;
  f.w = w;
  f.y0 = y0;
  bool any = false;
  double x0 = 0, x1 = 1, y1 = 0;
  for (const ChartSeries& s : p.chart) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = any ? std::min(x0, s.x[i]) : s.x[i];
      x1 = any ? std::max(x1, s.x[i]) : s.x[i];
      y1 = std::max(y1, s.y[i]);
      any = true;
    }
  }
  if (!(x1 > x0)) x1 = x0 + 1;
  if (!(y1 > 0)) y1 = 1;
  f.yt = NiceTicks(0, y1 * 1.05, 4);
  f.y1 = std::max(y1 * 1.05, f.yt.start + (f.yt.count - 1) * f.yt.step);
  f.x0 = x0;
  f.x1 = x1;
  f.xt = NiceTicks(x0, x1, 8);
  return f;
}

int ChartHeight(const MapPlot& p) { return p.chart.empty() ? 0 : kChartHeight; }

int BandHeight(const MapPlot& p) {
  return kBandLine * (1 + static_cast<int>(p.notes.size()) + 1) + 8;
}

cv::Scalar Bgr(const Rgb& c) { return cv::Scalar(c.b, c.g, c.r); }

cv::Mat BackgroundBgr(const MapPlot& p) {
  cv::Mat bg;
  if (p.background.empty()) {
    bg = cv::Mat(480, 640, CV_8UC3, cv::Scalar(255, 255, 255));
  } else if (p.background.channels() == 1) {
    cv::cvtColor(p.background, bg, cv::COLOR_GRAY2BGR);
  } else {
    bg = p.background.clone();
  }
  return bg;
}

}  // namespace

std::string Base64(const std::vector<unsigned char>& bytes) {
  static const char* kTable = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = bytes[i] << 16 | bytes[i + 1] << 8 | bytes[i + 2];
    for (int s = 18; s >= 0; s -= 6) out += kTable[(v >> s) & 63];
  }
  if (i < bytes.size()) {
    const unsigned v = bytes[i] << 16 | (i + 1 < bytes.size() ? bytes[i + 1] << 8 : 0);
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

cv::Mat RenderMapPlotImage(const MapPlot& p) {
  const cv::Mat bg = BackgroundBgr(p);
  const int band = BandHeight(p);
  cv::Mat img(bg.rows + band + ChartHeight(p), bg.cols, CV_8UC3, cv::Scalar(255, 255, 255));
  bg.copyTo(img(cv::Rect(0, band, bg.cols, bg.rows)));
  cv::Mat map = img(cv::Rect(0, band, bg.cols, bg.rows));
  auto pt = [](const Eigen::Vector2d& v) {
    return cv::Point(std::lround(v.x() * 16), std::lround(v.y() * 16));
  };
  for (const MapPath& path : p.paths) {
    const int w = std::max(1, static_cast<int>(std::lround(path.width)));
    for (size_t i = 1; i < path.px.size(); ++i) {
      if (path.dashed && i % 2 == 0) continue;
      cv::line(map, pt(path.px[i - 1]), pt(path.px[i]), Bgr(path.colour), w, cv::LINE_AA, 4);
    }
  }
  for (const MapMarker& m : p.markers) {
    const cv::Point c = pt(m.px);
    const cv::Scalar col = Bgr(m.colour);
    const int r = 7 * 16;
    if (m.shape == 'x' || m.shape == '*') {
      cv::line(map, c + cv::Point(-r, -r), c + cv::Point(r, r), col, 2, cv::LINE_AA, 4);
      cv::line(map, c + cv::Point(-r, r), c + cv::Point(r, -r), col, 2, cv::LINE_AA, 4);
    }
    if (m.shape == 'o' || m.shape == '*') cv::circle(map, c, r, col, 2, cv::LINE_AA, 4);
    cv::putText(map, m.label, cv::Point(std::lround(m.px.x()) + 9, std::lround(m.px.y()) - 9),
                cv::FONT_HERSHEY_SIMPLEX, 0.45, col, 1, cv::LINE_AA);
  }
  int y = kBandLine;
  cv::putText(img, p.title, cv::Point(6, y), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  for (const std::string& n : p.notes) {
    y += kBandLine;
    cv::putText(img, n, cv::Point(6, y), cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(40, 40, 40), 1,
                cv::LINE_AA);
  }
  y += kBandLine;
  int x = 6;
  for (const MapPath& path : p.paths) {
    if (path.name.empty()) continue;
    cv::line(img, cv::Point(x, y - 5), cv::Point(x + 24, y - 5), Bgr(path.colour), 3, cv::LINE_AA);
    cv::putText(img, path.name, cv::Point(x + 30, y), cv::FONT_HERSHEY_SIMPLEX, 0.42,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    int baseline = 0;
    x += 40 + cv::getTextSize(path.name, cv::FONT_HERSHEY_SIMPLEX, 0.42, 1, &baseline).width;
  }
  if (!p.chart.empty()) {
    const ChartFrame f = MakeChartFrame(p, img.cols, band + bg.rows);
    const cv::Scalar grey(200, 200, 200), black(0, 0, 0);
    auto P = [&](double x, double y) { return cv::Point2d(f.X(x), f.Y(y)); };
    for (int i = 0; i < f.yt.count; ++i) {
      const double v = f.yt.start + i * f.yt.step;
      cv::line(img, P(f.x0, v), P(f.x1, v), grey, 1);
      cv::putText(img, FormatTick(v, f.yt.step), P(f.x0, v) + cv::Point2d(-40, 4),
                  cv::FONT_HERSHEY_SIMPLEX, 0.35, black, 1, cv::LINE_AA);
    }
    for (int i = 0; i < f.xt.count; ++i) {
      const double v = f.xt.start + i * f.xt.step;
      cv::putText(img, FormatTick(v, f.xt.step), P(v, 0) + cv::Point2d(-8, 14),
                  cv::FONT_HERSHEY_SIMPLEX, 0.35, black, 1, cv::LINE_AA);
    }
    cv::line(img, P(f.x0, 0), P(f.x1, 0), black, 1);
    cv::line(img, P(f.x0, 0), P(f.x0, f.y1), black, 1);
    cv::putText(img, p.chart_y_label, cv::Point(6, f.y0 + 14), cv::FONT_HERSHEY_SIMPLEX, 0.4, black,
                1, cv::LINE_AA);
    cv::putText(img, p.chart_x_label, cv::Point(img.cols / 2 - 20, f.y0 + kChartHeight - 4),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, black, 1, cv::LINE_AA);
    int lx = img.cols - 12;
    for (auto it = p.chart.rbegin(); it != p.chart.rend(); ++it) {
      int baseline = 0;
      lx -= cv::getTextSize(it->name, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &baseline).width + 30;
      cv::line(img, cv::Point(lx, f.y0 + 10), cv::Point(lx + 20, f.y0 + 10), Bgr(it->colour), 2);
      cv::putText(img, it->name, cv::Point(lx + 24, f.y0 + 14), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                  black, 1, cv::LINE_AA);
    }
    for (const ChartSeries& c : p.chart) {
      for (size_t i = 0; i < c.x.size(); ++i) {
        if (!std::isfinite(c.y[i])) continue;
        const cv::Point2d q = P(c.x[i], std::min(c.y[i], f.y1));
        if (c.dots) {
          cv::circle(img, q, 2, Bgr(c.colour), -1, cv::LINE_AA);
        } else if (i > 0 && std::isfinite(c.y[i - 1])) {
          cv::line(img, P(c.x[i - 1], std::min(c.y[i - 1], f.y1)), q, Bgr(c.colour), 1,
                   cv::LINE_AA);
        }
      }
    }
  }
  return img;
}

std::string RenderMapPlotSvg(const MapPlot& p) {
  const cv::Mat bg = BackgroundBgr(p);
  const int band = BandHeight(p);
  SvgDocument svg(bg.cols, bg.rows + band + ChartHeight(p));
  svg.Rect(0, 0, bg.cols, bg.rows + band + ChartHeight(p), "#ffffff");
  std::vector<unsigned char> png;
  cv::imencode(".png", bg, png);
  svg.Raw(fmt::format(
      "<image x=\"0\" y=\"{}\" width=\"{}\" height=\"{}\" href=\"data:image/png;base64,{}\"/>",
      band, bg.cols, bg.rows, Base64(png)));
  for (const MapPath& path : p.paths) {
    std::string pts;
    for (const Eigen::Vector2d& v : path.px)
      pts += fmt::format("{:.1f},{:.1f} ", v.x(), v.y() + band);
    svg.Polyline(pts, path.colour.Hex(), path.width, path.dashed ? "stroke-dasharray=\"6,4\"" : "");
  }
  for (const MapMarker& m : p.markers) {
    const double x = m.px.x(), y = m.px.y() + band;
    if (m.shape == 'x' || m.shape == '*') {
      svg.Line(x - 7, y - 7, x + 7, y + 7, m.colour.Hex(), 2);
      svg.Line(x - 7, y + 7, x + 7, y - 7, m.colour.Hex(), 2);
    }
    if (m.shape == 'o' || m.shape == '*') {
      svg.Raw(
          fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"7\" fill=\"none\" stroke=\"{}\" "
                      "stroke-width=\"2\"/>",
                      x, y, m.colour.Hex()));
    }
    svg.Text(x + 9, y - 9, m.label, 11, "start", fmt::format("fill=\"{}\"", m.colour.Hex()));
  }
  double y = kBandLine;
  svg.Text(6, y - 4, p.title, 14);
  for (const std::string& n : p.notes) {
    y += kBandLine;
    svg.Text(6, y - 4, n, 11);
  }
  y += kBandLine;
  double x = 6;
  for (const MapPath& path : p.paths) {
    if (path.name.empty()) continue;
    svg.Line(x, y - 8, x + 24, y - 8, path.colour.Hex(), 3);
    svg.Text(x + 30, y - 4, path.name, 11);
    x += 40 + 6.5 * path.name.size();
  }
  if (!p.chart.empty()) {
    const ChartFrame f = MakeChartFrame(p, bg.cols, band + bg.rows);
    for (int i = 0; i < f.yt.count; ++i) {
      const double v = f.yt.start + i * f.yt.step;
      svg.Line(f.X(f.x0), f.Y(v), f.X(f.x1), f.Y(v), "#cccccc", 1);
      svg.Text(f.X(f.x0) - 6, f.Y(v) + 4, FormatTick(v, f.yt.step), 10, "end");
    }
    for (int i = 0; i < f.xt.count; ++i) {
      const double v = f.xt.start + i * f.xt.step;
      svg.Text(f.X(v), f.Y(0) + 14, FormatTick(v, f.xt.step), 10, "middle");
    }
    svg.Line(f.X(f.x0), f.Y(0), f.X(f.x1), f.Y(0), "#000000", 1);
    svg.Line(f.X(f.x0), f.Y(0), f.X(f.x0), f.Y(f.y1), "#000000", 1);
    svg.Text(6, f.y0 + 14, p.chart_y_label, 11);
    svg.Text(bg.cols / 2.0, f.y0 + kChartHeight - 4, p.chart_x_label, 11, "middle");
    double lx = bg.cols - 12;
    for (auto it = p.chart.rbegin(); it != p.chart.rend(); ++it) {
      lx -= 6.5 * it->name.size() + 30;
      svg.Line(lx, f.y0 + 10, lx + 20, f.y0 + 10, it->colour.Hex(), 2);
      svg.Text(lx + 24, f.y0 + 14, it->name, 11);
    }
    for (const ChartSeries& c : p.chart) {
      std::string pts;
      for (size_t i = 0; i < c.x.size(); ++i) {
        if (!std::isfinite(c.y[i])) continue;
        const double x = f.X(c.x[i]), y = f.Y(std::min(c.y[i], f.y1));
        if (c.dots) {
          svg.Circle(x, y, 2, c.colour.Hex());
        } else {
          pts += fmt::format("{:.1f},{:.1f} ", x, y);
        }
      }
      if (!c.dots) svg.Polyline(pts, c.colour.Hex(), 1.2);
    }
  }
  return svg.Finish();
}

void WriteMapPlot(const std::string& stem, const MapPlot& plot) {
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", RenderMapPlotImage(plot), png)) {
    throw Error("could not encode " + stem + ".png");
  }
  io::WriteFileAtomically(stem + ".png", std::string(png.begin(), png.end()));
  io::WriteFileAtomically(stem + ".svg", RenderMapPlotSvg(plot));
}

}  // namespace optinav::report
