#include "optinav/app/internal/weather_bench_report.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/io/text_parse.h"
#include "optinav/report/html_report.h"
#include "optinav/report/svg.h"
#include "optinav/util/error.h"

namespace fs = std::filesystem;

namespace optinav::app::internal {
namespace {

using Cells = std::vector<WeatherCell>;
using Runs = std::vector<WeatherRunResult>;

std::string Fixed(double v, int digits = 2) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : "-";
}

std::string Ratio(double v) { return std::isfinite(v) ? fmt::format("x{:.2f}", v) : "-"; }

std::string ImageSize(const WeatherBenchOptions& o) {
  return fmt::format("{}x{}", static_cast<int>(std::lround(800 * o.scale)),
                     static_cast<int>(std::lround(600 * o.scale)));
}

// "" for the default noise (on: 0.8:0.02); otherwise `prefix` and the setting (off or READ:SHOT).
std::string CameraNoiseNote(const sim::CameraNoiseOptions& noise, const std::string& prefix) {
  const std::string text = noise.ToString();
  return text == sim::CameraNoiseOptions().ToString() ? "" : prefix + text;
}

std::string DocumentCell(const WeatherCell& c) {
  if (!c.document) return "-";
  return c.document->lost ? "lost" : Fixed(c.document->mean_error_m);
}

// Ours: the mean over the seeds [the largest], "failed" when no run finished, " !" when some
// did not.
std::string MeanCell(const WeatherCell& c, int seeds) {
  if (c.runs == c.failed) return "failed";
  std::string s = Fixed(c.mean_error_m);
  if (seeds > 1) s += " [" + Fixed(c.mean_error_max_m) + "]";
  return s + (c.failed ? " !" : "");
}

// "no", or the lost intervals (one seed: count and total seconds; several: runs lost).
std::string LostCell(const WeatherCell& c, const Runs& runs, int seeds) {
  if (c.lost == 0) return c.runs == c.failed ? "-" : "no";
  if (seeds > 1) return fmt::format("lost in {}/{} runs", c.lost, c.runs);
  size_t n = 0;
  double s = 0;
  for (const WeatherRunResult& r : runs) {
    if (r.world != c.world || r.mode != c.mode || r.condition.ToString() != c.condition.ToString())
      continue;
    n += r.lost.size();
    for (const WeatherLost& l : r.lost) s += l.end_s - l.start_s;
  }
  return fmt::format("lost: {} interval(s), {:.1f} s", n, s);
}

}  // namespace

std::string WeatherBenchTable(const WeatherBenchOptions& o, const Cells& cells, const Runs& runs) {
  std::string t = fmt::format(
      "Mean localization error after the start pose (m; the weather document's metric), car "
      "route, {} (scale {:g}), `optinav vio` threaded, --vehicle {}{}{}{}; seeds 1..{}{}.\n"
      "x clear: the condition's error over clear's (same world and mode). lost: the VIO "
      "reported tracking lost (the document: local map lost). ORB-SLAM3: stereo, 800x600, the "
      "weather document (SEEDS.md part 1).\n\n",
      ImageSize(o), o.scale, VehicleModelName(o.vehicle),
      o.varied_asphalt ? "" : ", --asphalt tiled",
      CameraNoiseNote(o.camera_noise, ", --camera-noise "),
      o.duration_s > 0 ? fmt::format(", first {:g} s", o.duration_s) : "", o.seeds,
      o.seeds > 1 ? " (mean [max] over seeds)" : "");
  t += "| world | condition | mode | mean error (m) | x clear | odometry (m) | APE SE(3) (m) | "
       "lost | fps | ORB-SLAM3 (m) | x clear |\n"
       "|---|---|---|---:|---:|---:|---:|---|---:|---:|---:|\n";
  for (const WeatherCell& c : cells) {
    t += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                     WeatherBenchWorldName(c.world), c.condition.ToString(),
                     vio::VioModeName(c.mode), MeanCell(c, o.seeds), Ratio(c.ratio_to_clear),
                     Fixed(c.odometry_mean_error_m), Fixed(c.ape_rmse_se3_m),
                     LostCell(c, runs, o.seeds), Fixed(c.fps, 1), DocumentCell(c),
                     Ratio(c.document_ratio_to_clear));
  }
  return t;
}

std::string WeatherBenchCsv(const Cells& cells) {
  std::string csv =
      "world,condition,mode,runs,failed,lost_runs,mean_error_m,mean_error_max_m,ratio_to_clear,"
      "odometry_mean_error_m,ape_rmse_se3_m,fps,orbslam3_mean_error_m,orbslam3_lost,"
      "orbslam3_ratio_to_clear\n";
  for (const WeatherCell& c : cells)
    csv += fmt::format(
        "{},{},{},{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.2f},{:.2f},{},{:.4f}\n",
        WeatherBenchWorldName(c.world), c.condition.ToString(), vio::VioModeName(c.mode), c.runs,
        c.failed, c.lost, c.mean_error_m, c.mean_error_max_m, c.ratio_to_clear,
        c.odometry_mean_error_m, c.ape_rmse_se3_m, c.fps,
        c.document ? c.document->mean_error_m : NAN, c.document && c.document->lost ? 1 : 0,
        c.document_ratio_to_clear);
  return csv;
}

namespace {

// NaN as JSON null.
nlohmann::json Num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json RunJson(const WeatherRunResult& r) {
  nlohmann::json lost = nlohmann::json::array();
  for (const WeatherLost& l : r.lost)
    lost.push_back({{"start_s", l.start_s}, {"end_s", l.end_s}, {"reason", l.reason}});
  return {{"sequence", r.sequence},
          {"world", WeatherBenchWorldName(r.world)},
          {"condition", r.condition.ToString()},
          {"mode", vio::VioModeName(r.mode)},
          {"seed", r.seed},
          {"vehicle", r.vehicle},
          {"ok", r.ok},
          {"error", r.error},
          {"mean_error_m", Num(r.mean_error_m)},
          {"odometry_mean_error_m", Num(r.odometry_mean_error_m)},
          {"loops", r.loops},
          {"loops_checked", r.loops_checked},
          {"loops_off_truth", r.loops_off_truth},
          {"ape_rmse_se3_m", Num(r.ape_rmse_se3_m)},
          {"lost", r.Lost()},
          {"lost_intervals", lost},
          {"fps", Num(r.fps)},
          {"frame_median_ms", Num(r.frame_median_ms)},
          {"frame_p95_ms", Num(r.frame_p95_ms)},
          {"wall_s", Num(r.wall_s)},
          {"frames", r.frames},
          {"poses", r.poses},
          {"coverage", Num(r.coverage)},
          {"loops", r.loops},
          {"path_length_m", Num(r.path_length_m)},
          {"reused", r.reused}};
}

nlohmann::json CellJson(const WeatherCell& c) {
  nlohmann::json doc;  // null where the document has no figure
  if (c.document)
    doc = {{"mean_error_m", Num(c.document->mean_error_m)},
           {"lost", c.document->lost},
           {"ratio_to_clear", Num(c.document_ratio_to_clear)}};
  return {{"world", WeatherBenchWorldName(c.world)},
          {"condition", c.condition.ToString()},
          {"mode", vio::VioModeName(c.mode)},
          {"runs", c.runs},
          {"failed", c.failed},
          {"lost_runs", c.lost},
          {"mean_error_m", Num(c.mean_error_m)},
          {"mean_error_max_m", Num(c.mean_error_max_m)},
          {"ratio_to_clear", Num(c.ratio_to_clear)},
          {"odometry_mean_error_m", Num(c.odometry_mean_error_m)},
          {"ape_rmse_se3_m", Num(c.ape_rmse_se3_m)},
          {"fps", Num(c.fps)},
          {"orbslam3", doc}};
}

}  // namespace

nlohmann::json WeatherBenchJson(const WeatherBenchOptions& o, const WeatherBenchResult& result) {
  nlohmann::json worlds = nlohmann::json::array(), modes = nlohmann::json::array();
  for (sim::WorldKind w : o.worlds) worlds.push_back(WeatherBenchWorldName(w));
  for (vio::VioMode m : o.modes) modes.push_back(vio::VioModeName(m));
  nlohmann::json conditions = nlohmann::json::array();
  for (const sim::WeatherSpec& c : o.conditions) conditions.push_back(c.ToString());
  nlohmann::json j;
  j["settings"] = {{"scale", o.scale},
                   {"image_size", ImageSize(o)},
                   {"worlds", worlds},
                   {"conditions", o.conditions.empty() ? nlohmann::json("suite") : conditions},
                   {"modes", modes},
                   {"seeds", o.seeds},
                   {"jobs", o.jobs},
                   {"duration_s", o.duration_s},
                   {"max_frames", o.max_frames},
                   {"vehicle", VehicleModelName(o.vehicle)},
                   {"asphalt", sim::AsphaltName(o.varied_asphalt)},
                   {"camera_noise", o.camera_noise.ToString()},
                   {"vio", "threaded"}};
  j["cells"] = nlohmann::json::array();
  for (const WeatherCell& c : result.cells) j["cells"].push_back(CellJson(c));
  j["runs"] = nlohmann::json::array();
  for (const WeatherRunResult& r : result.runs) j["runs"].push_back(RunJson(r));
  j["wall_s"] = result.wall_s;
  return j;
}

// ---------------------------------------------------------------------------------------------
// The plot, drawn twice: SVG (report::SvgDocument) and PNG (OpenCV), through one set of calls.

namespace {

cv::Scalar Bgr(const std::string& hex) {
  const unsigned v = std::stoul(hex.substr(1), nullptr, 16);
  return cv::Scalar(v & 0xff, (v >> 8) & 0xff, (v >> 16) & 0xff);
}

class Canvas {
 public:
  Canvas(int width, int height)
      : svg_(width, height), png_(height, width, CV_8UC3, cv::Scalar(255, 255, 255)) {}

  void Rect(double x, double y, double w, double h, const std::string& fill,
            const std::string& stroke = "none") {
    svg_.Rect(x, y, w, h, fill, stroke);
    const cv::Rect r(cv::Point(std::lround(x), std::lround(y)),
                     cv::Point(std::lround(x + w), std::lround(y + h)));
    if (fill != "none") cv::rectangle(png_, r, Bgr(fill), cv::FILLED);
    if (stroke != "none") cv::rectangle(png_, r, Bgr(stroke), 1);
  }
  void Line(double x1, double y1, double x2, double y2, const std::string& colour, double width) {
    svg_.Line(x1, y1, x2, y2, colour, width);
    cv::line(png_, cv::Point(std::lround(x1), std::lround(y1)),
             cv::Point(std::lround(x2), std::lround(y2)), Bgr(colour),
             std::max(1, static_cast<int>(std::lround(width))), cv::LINE_AA);
  }
  // anchor: start | middle | end. vertical: read bottom to top, the baseline at x; anchor
  // "start" ends the text at y going up (a label over a bar), "end" starts it at y going down (a
  // label under an axis).
  void Text(double x, double y, const std::string& text, double size,
            const std::string& anchor = "start", const std::string& colour = "#000000",
            bool vertical = false) {
    const std::string extra =
        (colour != "#000000" ? "fill=\"" + colour + "\" " : "") +
        (vertical ? fmt::format("transform=\"rotate(-90 {:.1f} {:.1f})\"", x, y) : "");
    svg_.Text(x, y, text, size, anchor, extra);
    const double scale = size / 30.0;
    int base = 0;
    const cv::Size ts = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &base);
    if (!vertical) {
      const double dx = anchor == "middle" ? ts.width / 2.0 : anchor == "end" ? ts.width : 0;
      cv::putText(png_, text, cv::Point(std::lround(x - dx), std::lround(y)),
                  cv::FONT_HERSHEY_SIMPLEX, scale, Bgr(colour), 1, cv::LINE_AA);
      return;
    }
    // Drawn horizontally, turned a quarter left, and laid in with min() (dark text on white).
    cv::Mat label(ts.height + base + 2, ts.width + 2, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(label, text, cv::Point(1, ts.height + 1), cv::FONT_HERSHEY_SIMPLEX, scale,
                Bgr(colour), 1, cv::LINE_AA);
    cv::rotate(label, label, cv::ROTATE_90_COUNTERCLOCKWISE);
    const double top = anchor == "end"      ? y
                       : anchor == "middle" ? y - label.rows / 2.0
                                            : y - label.rows;
    const cv::Rect at(static_cast<int>(std::lround(x - ts.height - 1)),
                      static_cast<int>(std::lround(top)), label.cols, label.rows);
    const cv::Rect clipped = at & cv::Rect(0, 0, png_.cols, png_.rows);
    if (clipped.area() == 0) return;
    cv::Mat dst = png_(clipped);
    cv::min(dst, label(cv::Rect(clipped.tl() - at.tl(), clipped.size())), dst);
  }

  void Write(const std::string& stem) const {
    io::WriteFileAtomically(stem + ".svg", svg_.Finish());
    std::vector<uchar> png;
    if (!cv::imencode(".png", png_, png)) throw Error("cannot encode the plot", {.file = stem});
    io::WriteFileAtomically(stem + ".png", std::string(png.begin(), png.end()));
  }

 private:
  report::SvgDocument svg_;
  cv::Mat png_;
};

constexpr const char* kDocumentColour = "#9e9e9e";

std::string ModeColour(vio::VioMode mode) {
  return mode == vio::VioMode::kStereo ? "#1f77b4" : "#2ca02c";
}

// The log-scale range covering every figure, in whole decades.
std::pair<double, double> LogRange(const Cells& cells) {
  double lo = INFINITY, hi = -INFINITY;
  for (const WeatherCell& c : cells) {
    for (double v : {c.mean_error_m, c.document ? c.document->mean_error_m : NAN}) {
      if (!(v > 0) || !std::isfinite(v)) continue;
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
  }
  if (!std::isfinite(lo)) lo = 1, hi = 10;
  return {std::floor(std::log10(lo)),
          std::max(std::ceil(std::log10(hi)), std::floor(std::log10(lo)) + 1)};
}

struct Panel {
  double left, top, width, height;  // the plot area
  double lo_decade, hi_decade;
  double Y(double v) const {
    const double f =
        (std::log10(std::max(v, std::pow(10.0, lo_decade))) - lo_decade) / (hi_decade - lo_decade);
    return top + height * (1 - std::min(f, 1.0));
  }
};

void DrawAxes(Canvas& cv, const Panel& p, const std::string& title) {
  cv.Text(p.left, p.top - 12, title, 13);
  for (double d = p.lo_decade; d <= p.hi_decade + 1e-9; ++d) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, d);
      if (std::log10(v) > p.hi_decade + 1e-9) break;
      cv.Line(p.left, p.Y(v), p.left + p.width, p.Y(v), m == 1 ? "#d0d0d0" : "#eeeeee", 1);
      cv.Text(p.left - 5, p.Y(v) + 4, fmt::format("{:g}", v), 10, "end");
    }
  }
  cv.Line(p.left, p.top, p.left, p.top + p.height, "#000000", 1);
  cv.Line(p.left, p.top + p.height, p.left + p.width, p.top + p.height, "#000000", 1);
}

// One bar: a value, or "lost" (the bar to the top, outlined), or nothing (no figure).
void DrawBar(Canvas& cv, const Panel& p, double x, double w, double value, bool lost,
             const std::string& colour) {
  const double bottom = p.top + p.height;
  if (lost && !std::isfinite(value)) {
    cv.Rect(x, p.top, w, p.height, "#f4f4f4", colour);
    cv.Text(x + w / 2 + 4, p.top + 4, "lost", 9, "end", "#d62728", true);
    return;
  }
  if (!std::isfinite(value)) return;
  cv.Rect(x, p.Y(value), w, bottom - p.Y(value), colour);
  if (lost) cv.Text(x + w / 2 + 4, p.Y(value) - 3, "lost", 9, "start", "#d62728", true);
}

}  // namespace

void WriteWeatherPlot(const std::string& stem, const WeatherBenchOptions& options,
                      const Cells& cells) {
  // The conditions of each world, in the cells' order.
  std::vector<std::pair<sim::WorldKind, std::vector<sim::WeatherSpec>>> worlds;
  for (const WeatherCell& c : cells) {
    if (worlds.empty() || worlds.back().first != c.world) worlds.push_back({c.world, {}});
    auto& conds = worlds.back().second;
    if (conds.empty() || conds.back().ToString() != c.condition.ToString())
      conds.push_back(c.condition);
  }
  size_t max_conditions = 1;
  for (const auto& w : worlds) max_conditions = std::max(max_conditions, w.second.size());
  const double bars = options.modes.size() + 1;
  const double group = std::max({36.0, 13.0 * bars + 10, 480.0 / max_conditions});
  const double left = 60, right = 20, panel_h = 375, plot_h = 220;  // room for "road-wetness:100"
  const int width = static_cast<int>(std::max(580.0, left + right + group * max_conditions));
  const int height = static_cast<int>(50 + panel_h * worlds.size());
  Canvas cv(width, height);
  cv.Rect(0, 0, width, height, "#ffffff");
  cv.Text(10, 20,
          fmt::format("optinav bench weather: mean error after the start pose, car route, {}{}{}",
                      ImageSize(options), options.varied_asphalt ? "" : ", tiled asphalt",
                      CameraNoiseNote(options.camera_noise, ", camera noise ")),
          13);
  // Legend.
  double lx = left;
  for (vio::VioMode m : options.modes) {
    cv.Rect(lx, 32, 12, 10, ModeColour(m));
    cv.Text(lx + 16, 41, "optinav " + vio::VioModeName(m), 11);
    lx += 150;
  }
  cv.Rect(lx, 32, 12, 10, kDocumentColour);
  cv.Text(lx + 16, 41, "ORB-SLAM3 (weather document)", 11);
  const auto [lo, hi] = LogRange(cells);
  for (size_t k = 0; k < worlds.size(); ++k) {
    const auto& [world, conditions] = worlds[k];
    const Panel p{left, 50 + panel_h * k + 40, group * conditions.size(), plot_h, lo, hi};
    DrawAxes(cv, p, WeatherBenchWorldName(world) + ": mean error (m, log scale)");
    for (size_t i = 0; i < conditions.size(); ++i) {
      const double x0 = p.left + group * i + 5;
      const WeatherCell* any = nullptr;
      for (size_t b = 0; b < options.modes.size(); ++b) {
        for (const WeatherCell& c : cells) {
          if (c.world != world || c.mode != options.modes[b] ||
              c.condition.ToString() != conditions[i].ToString())
            continue;
          any = &c;
          DrawBar(cv, p, x0 + 13 * b, 12, c.mean_error_m, c.lost > 0, ModeColour(c.mode));
        }
      }
      if (any && any->document)
        DrawBar(cv, p, x0 + 13 * options.modes.size(), 12, any->document->mean_error_m,
                any->document->lost, kDocumentColour);
      cv.Text(x0 + 13 * bars / 2, p.top + p.height + 6, conditions[i].ToString(), 10, "end",
              "#000000", true);
    }
  }
  cv.Write(stem);
}

namespace {

constexpr size_t kMaxPoints = 1500;

// [north, east] of every k-th pose (Leaflet's order in a local view).
std::vector<Eigen::Vector2d> LocalPoints(const Trajectory& t) {
  std::vector<Eigen::Vector2d> pts;
  const size_t step = std::max<size_t>(1, t.size() / kMaxPoints);
  for (size_t i = 0; i < t.size(); i += step)
    pts.emplace_back(t.positions[i].y(), t.positions[i].x());
  return pts;
}

std::string Fmt2(double v) { return std::isfinite(v) ? fmt::format("{:.2f}", v) : "-"; }

// The HTML report's document: per world the ground truth and every run's output (first pose
// aligned) in the local frame, the error over time, the run table and table.md.
report::ReportDocument WeatherBenchReportDocument(const WeatherBenchOptions& options,
                                                  const WeatherBenchResult& result) {
  report::ReportDocument doc;
  doc.kind = "bench weather";
  doc.title = fmt::format("optinav bench weather: {} run(s)", result.runs.size());
  doc.notes.push_back(
      "Car route per world in the simulator's world frame (metres; no map): the ground truth and "
      "each run's output with its first pose put on the truth's (the weather document's "
      "metric), one layer per condition and mode.");
  for (sim::WorldKind world : options.worlds) {
    report::ReportView v;
    v.name = WeatherBenchWorldName(world) + " world";
    v.frame = "local";
    report::ReportChart chart{"error over time (first pose aligned)", "time (s)", "error (m)", {}};
    size_t k = 0, n = 0;
    for (const WeatherRunResult& r : result.runs) n += r.world == world && r.ok;
    for (const WeatherRunResult& r : result.runs) {
      if (r.world != world || !r.ok || r.aligned.empty()) continue;
      if (v.paths.empty()) {
        v.paths.push_back(
            {"ground truth", "ground truth", "#14a03c", 3, false, LocalPoints(r.truth)});
        v.markers.push_back({"start / end", "start", "start", LocalPoints(r.truth).front()});
        const Eigen::Vector3d end = r.truth.positions.back();
        v.markers.push_back({"start / end", "end", "end", {end.y(), end.x()}});
      }
      const std::string colour =
          report::ColorMap(n > 1 ? static_cast<double>(k) / (n - 1) : 0).Hex();
      ++k;
      const std::string layer =
          fmt::format("{}, {}", r.condition.ToString(), vio::VioModeName(r.mode));
      v.paths.push_back({layer,
                         fmt::format("{}, seed {}: mean error {:.2f} m{}", layer, r.seed,
                                     r.mean_error_m, r.Lost() ? " (lost)" : ""),
                         colour, 1.5, r.mode == vio::VioMode::kStereoImu, LocalPoints(r.aligned)});
      report::ReportSeries s{layer, colour, {}, {}, false};
      const size_t step = std::max<size_t>(1, r.error_over_time.size() / kMaxPoints);
      for (size_t i = 0; i < r.error_over_time.size(); i += step) {
        s.x.push_back(r.error_over_time[i].first);
        s.y.push_back(r.error_over_time[i].second);
      }
      chart.series.push_back(std::move(s));
    }
    if (chart.series.size() > 8)  // a legend of every run would not fit on the line
      for (report::ReportSeries& s : chart.series) s.name.clear();
    v.chart = std::move(chart);
    doc.views.push_back(std::move(v));
  }
  report::ReportTable t{"Runs (errors in m)",
                        {"sequence", "mode", "seed", "mean error", "odometry mean error",
                         "APE SE(3)", "lost intervals", "fps", "status"},
                        {}};
  for (const WeatherRunResult& r : result.runs)
    t.rows.push_back({r.sequence, vio::VioModeName(r.mode), std::to_string(r.seed),
                      Fmt2(r.mean_error_m), Fmt2(r.odometry_mean_error_m), Fmt2(r.ape_rmse_se3_m),
                      std::to_string(r.lost.size()), Fmt2(r.fps),
                      r.ok ? (r.reused ? "ok (reused)" : "ok") : "failed: " + r.error});
  doc.tables.push_back(std::move(t));
  doc.text = result.table;
  doc.settings = WeatherBenchJson(options, result).at("settings");
  return doc;
}

}  // namespace

void WriteWeatherBenchFiles(const WeatherBenchOptions& options, const WeatherBenchResult& result) {
  const fs::path out = options.out_dir;
  io::WriteFileAtomically((out / "table.md").string(), result.table);
  io::WriteFileAtomically((out / "table.csv").string(), WeatherBenchCsv(result.cells));
  io::WriteFileAtomically((out / "results.json").string(),
                          WeatherBenchJson(options, result).dump(2) + "\n");
  WriteWeatherPlot((out / "weather_error").string(), options, result.cells);
  report::WriteReportDocument((out / "report.json").string(),
                              WeatherBenchReportDocument(options, result));
}

}  // namespace optinav::app::internal
