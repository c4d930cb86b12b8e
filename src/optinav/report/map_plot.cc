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

constexpr int kBandLine = 18;  // height of one title/legend line, pixels

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
  cv::Mat img(bg.rows + band, bg.cols, CV_8UC3, cv::Scalar(255, 255, 255));
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
  return img;
}

std::string RenderMapPlotSvg(const MapPlot& p) {
  const cv::Mat bg = BackgroundBgr(p);
  const int band = BandHeight(p);
  SvgDocument svg(bg.cols, bg.rows + band);
  svg.Rect(0, 0, bg.cols, bg.rows + band, "#ffffff");
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
