// Paths drawn over a map image (an orthophoto), as a PNG people can open anywhere and as an SVG
// with the image embedded; used for mission pictures.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "optinav/report/svg.h"

namespace optinav::report {

struct MapPath {
  std::string name;
  Rgb colour;
  std::vector<Eigen::Vector2d> px;  // background pixels
  double width = 2.0;
  bool dashed = false;
};

struct MapMarker {
  std::string label;
  Rgb colour;
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  char shape = 'o';  // 'o' circle, 'x' cross, '*' target (circle with cross)
};

// A time series for the chart under the map (e.g. localization error over time).
struct ChartSeries {
  std::string name;
  Rgb colour;
  std::vector<double> x, y;
  bool dots = false;  // markers instead of a line
};

struct MapPlot {
  cv::Mat background;  // 8-bit grey or BGR, at plot resolution
  std::string title;
  std::vector<std::string> notes;  // lines under the title
  std::vector<MapPath> paths;
  std::vector<MapMarker> markers;
  // Optional chart under the map (drawn when it has series).
  std::string chart_x_label, chart_y_label;
  std::vector<ChartSeries> chart;
};

// BGR image: background, paths, markers, then a title/legend band on top.
cv::Mat RenderMapPlotImage(const MapPlot& plot);
std::string RenderMapPlotSvg(const MapPlot& plot);
// Writes stem.png and stem.svg atomically; throws Error on I/O failure.
void WriteMapPlot(const std::string& stem, const MapPlot& plot);

std::string Base64(const std::vector<unsigned char>& bytes);

}  // namespace optinav::report
