// The HTML report (`optinav report`, `--html`): one self-contained file that works offline, with
// a Leaflet slippy map (the orthophoto as an image overlay in its true position, or a plain
// background in a local metric frame), true and estimated paths, fixes coloured by error with
// popups, start/target markers and a layer switcher; under it the error-over-time chart (inline
// SVG), the summary tables and the run settings.
//
// The commands write what the report needs as a report document (`report.json`, format in
// docs/FORMATS.md) beside their other outputs; the HTML is rendered from it, so `optinav report
// DIR` and `--html` give the same file. Leaflet is not fetched at run time: it is vendored into
// the build output by scripts/vendor_leaflet.sh and inlined into every report.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace optinav::report {

// A path on the map. Points are [lat, lon] degrees in a "wgs84" view, [north, east] metres in a
// "local" view (Leaflet's order in both).
struct ReportPath {
  std::string layer;  // layer-switcher entry it belongs to
  std::string name;   // popup text
  std::string colour_hex = "#ff0000";
  double width = 2;
  bool dashed = false;
  std::vector<Eigen::Vector2d> points;
};

// An absolute fix (map localization, GNSS sample): drawn as a dot coloured by its error.
struct ReportFix {
  std::string layer;
  std::string name;  // e.g. "run 3"
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  double t_s = 0;
  double error_m = 0;  // NaN when unknown
  std::string method;  // "features", "orientation-correlation", "gnss", ...
  int inliers = -1;    // -1: not applicable
  bool accepted = true;
  std::string note;  // e.g. the rejection reason
};

struct ReportMarker {
  std::string layer;
  std::string label;
  std::string kind = "start";  // start | target | end
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
};

struct ReportSeries {
  std::string name;  // empty: not in the legend
  std::string colour_hex = "#000000";
  std::vector<double> x, y;
  bool dots = false;  // markers instead of a line
};

struct ReportChart {
  std::string title, x_label, y_label;
  std::vector<ReportSeries> series;
};

// The background image: a file beside the report document (JPEG or PNG), stretched over
// `bounds` = [[south, west], [north, east]] (wgs84, in Web Mercator so a north-up Mercator image
// lands in its true position) or [[min_north, min_east], [max_north, max_east]] (local).
struct ReportImage {
  std::string file;
  Eigen::Vector2d min = Eigen::Vector2d::Zero(), max = Eigen::Vector2d::Zero();
};

// One map with its chart (a mission; a benchmark sequence).
struct ReportView {
  std::string name;
  std::string frame = "wgs84";  // wgs84 | local
  std::optional<ReportImage> image;
  std::vector<ReportPath> paths;
  std::vector<ReportFix> fixes;
  std::vector<ReportMarker> markers;
  double fix_error_scale_m = 0;  // error at the red end of the fix colours; 0: the fixes' p95
  // Layer-switcher entries that start unticked (not drawn until the user ticks them).
  std::vector<std::string> hidden_layers;
  std::optional<ReportChart> chart;
};

struct ReportTable {
  std::string title;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

struct ReportDocument {
  std::string kind;  // mission | bench gnss | bench weather | vio gnss | nav
  std::string title;
  std::vector<std::string> notes;  // lines under the title
  std::vector<ReportView> views;
  std::vector<ReportTable> tables;
  std::string text;  // preformatted, under the tables (e.g. a benchmark's tables.md)
  nlohmann::json settings = nlohmann::json::object();
};

nlohmann::json ReportToJson(const ReportDocument& doc);
// Throws Error naming `file` and the field at fault.
ReportDocument ReportFromJson(const nlohmann::json& j, const std::string& file);
// Writes the document atomically (and nothing else: the image is the caller's).
void WriteReportDocument(const std::string& path, const ReportDocument& doc);
ReportDocument ReadReportDocument(const std::string& path);

// Leaflet's script and style sheet (its images inlined as data URIs), read from the vendored
// copy: $OPTINAV_LEAFLET_DIR, else the build's third_party/leaflet. Throws Error naming the
// folder and what to run when it is missing.
struct LeafletAssets {
  std::string js, css, version;
};
LeafletAssets LoadLeafletAssets();
// The folder LoadLeafletAssets reads.
std::string LeafletDir();

// The HTML page. `base_dir` is where image files named by the views are read from.
std::string RenderHtmlReport(const ReportDocument& doc, const LeafletAssets& leaflet,
                             const std::string& base_dir);

// The error-over-time chart as SVG (width x height px); also used by the page.
std::string RenderChartSvg(const ReportChart& chart, int width, int height);

}  // namespace optinav::report
