#include "optinav/app/internal/gnss_bench_report.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "optinav/io/text_parse.h"
#include "optinav/report/html_report.h"
#include "optinav/report/svg.h"

namespace optinav::app::internal {
namespace {

using Condition = std::optional<GnssCondition>;
using Norm = std::optional<vio::GnssNorm>;
using Runs = std::vector<GnssRunResult>;

constexpr Condition kNoGnss = std::nullopt;
constexpr Norm kNoNorm = std::nullopt;

// Mean and max of a figure over the seeds of a row; failed: runs without it.
struct Cell {
  double mean = NAN, max = NAN;
  int n = 0, failed = 0;
};

Cell Summarise(const Runs& runs, const std::string& sequence, Condition condition, Norm norm,
               double GnssRunResult::*field) {
  Cell c;
  double sum = 0, mx = -INFINITY;
  for (const GnssRunResult& r : runs) {
    if (r.sequence != sequence || r.condition != condition || r.norm != norm) continue;
    if (!r.ok || !std::isfinite(r.*field)) {
      if (r.ok && !r.aligned && r.condition) continue;  // world frame: no global error
      ++c.failed;
      continue;
    }
    sum += r.*field;
    mx = std::max(mx, r.*field);
    ++c.n;
  }
  if (c.n) c.mean = sum / c.n, c.max = mx;
  return c;
}

std::string MeanMax(const Cell& c, bool mark_failed) {
  return fmt::format("{:.3f} [{:.3f}]{}", c.mean, c.max, mark_failed && c.failed ? " !" : "");
}

// The four condition x norm tables, filled row by row.
struct Tables {
  std::string ate, global, global_10s, live;
  bool all_never_worse = true;
};

void AddRow(const std::vector<GnssBenchSequenceInfo>& sequences, const Runs& runs,
            Condition condition, Norm norm, Tables* t) {
  std::string r1 = fmt::format("| {:<22} | {:<5} |", ConditionLabel(condition), NormLabel(norm));
  std::string r2 = r1, r3 = r1, r4 = r1;
  bool never_worse = true;
  for (const GnssBenchSequenceInfo& s : sequences) {
    const auto cell = [&](double GnssRunResult::*field) {
      return Summarise(runs, s.name, condition, norm, field);
    };
    const Cell a = cell(&GnssRunResult::ate_se3), g = cell(&GnssRunResult::global_rmse);
    const Cell g10 = cell(&GnssRunResult::global_rmse_10s);
    const Cell la = cell(&GnssRunResult::ate_se3_live), lg = cell(&GnssRunResult::global_rmse_live);
    const std::string no_global = a.n ? "not aligned" : "failed";
    r1 += fmt::format(" {:>20} |", a.n ? MeanMax(a, true) : "failed");
    r2 += fmt::format(" {:>20} |", g.n ? MeanMax(g, true) : no_global);
    r3 += fmt::format(" {:>20} |", g10.n ? MeanMax(g10, false) : no_global);
    r4 += fmt::format(" {:>20} |", la.n ? fmt::format("{:.3f} / {:.3f}", la.mean, lg.mean) : "-");
    const Cell base = Summarise(runs, s.name, kNoGnss, kNoNorm, &GnssRunResult::ate_se3);
    if (condition && (a.failed || !(a.max <= 1.05 * base.mean))) never_worse = false;
  }
  if (condition) t->all_never_worse &= never_worse;
  t->ate += r1 +
            (!condition    ? "             |"
             : never_worse ? " yes         |"
                           : " NO          |") +
            "\n";
  t->global += r2 + "\n";
  t->global_10s += r3 + "\n";
  if (condition) t->live += r4 + "\n";
}

std::string ConditionTables(const std::vector<GnssBenchSequenceInfo>& sequences,
                            const std::vector<GnssCondition>& conditions,
                            const std::vector<vio::GnssNorm>& norms, const Runs& runs,
                            bool* never_worse) {
  std::string header = fmt::format("| {:<22} | {:<5} |", "GNSS", "norm");
  for (const GnssBenchSequenceInfo& s : sequences)
    header += fmt::format(" {:>20} |", s.name + fmt::format(" ({:.0f} m)", s.length_m));
  Tables t;
  t.ate =
      "RMSE ATE after SE(3) alignment (m), mean over seeds [max]; last column: fused <= 1.05 x "
      "no GNSS in every seed\n" +
      header + " never worse |\n";
  t.global =
      "Global RMSE in ENU without alignment (m), mean over seeds [max] (no GNSS: SE(3)-aligned "
      "on its first 5 s)\n" +
      header + "\n";
  t.global_10s =
      "Global RMSE in ENU without alignment from 10 s on (m): after the VIO's in-motion start-up "
      "and the ENU alignment\n" +
      header + "\n";
  t.live =
      "The live (causal) estimate, each frame through the alignment known right after it: RMSE "
      "ATE after SE(3) / global RMSE (m), mean over seeds\n" +
      header + "\n";
  AddRow(sequences, runs, kNoGnss, kNoNorm, &t);
  for (GnssCondition c : conditions)
    for (vio::GnssNorm n : norms) AddRow(sequences, runs, c, n, &t);
  *never_worse = t.all_never_worse;
  return t.ate + "\n" + t.global + "\n" + t.global_10s + "\n" + t.live + "\n";
}

// The outage condition's runs: how the error grew over the outage and came back after it.
std::string OutageTable(const Runs& runs) {
  std::string rows;
  for (const GnssRunResult& r : runs) {
    // Without an ENU alignment there is no global error.
    if (!r.ok || !r.aligned || !r.condition || !(ConditionSpec(*r.condition).outage_s > 0))
      continue;
    rows += fmt::format(
        "| {:<8} | {:<5} | {:>4} | {:>10.2f} | {:>10.2f} | {:>10.2f} | {:>14.2f} | {:>12.2f} | "
        "{:>11.2f} | {:>11.2f} |\n",
        r.sequence, NormLabel(r.norm), r.seed, r.outage_start_err, r.outage_end_err,
        r.outage_end_err - r.outage_start_err, r.vio_drift_over_outage, r.err_10s_after,
        r.outage_growth_live, r.err_10s_after_live);
  }
  const double outage_s = ConditionSpec(GnssCondition::kOutage).outage_s;
  return fmt::format(
             "{:g} s outage: error at its start and end (m), growth, VIO alone's drift over the "
             "same {:g} s (m), error 10 s after GNSS returns (m); the same two for the live "
             "estimate (which does not see the samples after the outage)\n",
             outage_s, outage_s) +
         "| sequence | norm  | seed | start      | end        | growth     | VIO-alone drift | "
         "+10 s        | live growth | live +10 s  |\n" +
         rows;
}

// Backend time per frame and per keyframe, VIO alone vs sigma 3 m Huber.
std::string SpeedLines(const std::vector<GnssBenchSequenceInfo>& sequences, const Runs& runs) {
  std::string speed;
  const Condition sigma3 = GnssCondition::kSigma3;
  const Norm huber = vio::GnssNorm::kHuber;
  for (const GnssBenchSequenceInfo& s : sequences) {
    const auto mean = [&](Condition c, Norm n, double GnssRunResult::*field) {
      return Summarise(runs, s.name, c, n, field).mean;
    };
    const double b0 = mean(kNoGnss, kNoNorm, &GnssRunResult::backend_median_ms);
    const double b1 = mean(sigma3, huber, &GnssRunResult::backend_median_ms);
    const double k0 = mean(kNoGnss, kNoNorm, &GnssRunResult::backend_keyframe_median_ms);
    const double k1 = mean(sigma3, huber, &GnssRunResult::backend_keyframe_median_ms);
    speed += fmt::format(
        "backend median, {}: per frame no GNSS {:.2f} ms, GNSS sigma 3 m (Huber) {:.2f} ms "
        "(x{:.3f}); per keyframe {:.2f} ms vs {:.2f} ms (x{:.3f}); runs in parallel, noisy: "
        "bench/RESULTS.md has side-by-side runs\n",
        s.name, b0, b1, b1 / b0, k0, k1, k1 / k0);
  }
  return speed;
}

}  // namespace

std::string GnssBenchTables(const std::vector<GnssBenchSequenceInfo>& sequences,
                            const std::vector<GnssCondition>& conditions,
                            const std::vector<vio::GnssNorm>& norms, const Runs& runs,
                            bool* never_worse) {
  return ConditionTables(sequences, conditions, norms, runs, never_worse) + OutageTable(runs) +
         "\n" + SpeedLines(sequences, runs);
}

std::string GnssBenchCsv(const Runs& runs) {
  std::string csv =
      "sequence,condition,norm,seed,ok,aligned,ate_se3_m,global_rmse_m,poses,lost,factors,"
      "rejected,global_rmse_10s_m,backend_median_ms,backend_keyframe_median_ms,outage_start_err_"
      "m,outage_end_err_m,vio_drift_over_outage_m,"
      "err_10s_after_m,live_ate_se3_m,live_global_rmse_m,error\n";
  for (const GnssRunResult& r : runs)
    csv += fmt::format(
        "{},{},{},{},{},{},{:.4f},{:.4f},{},{},{},{},{:.4f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:"
        ".3f},{:.4f},{:.4f},\"{}\"\n",
        r.sequence, ConditionLabel(r.condition), NormLabel(r.norm), r.seed, r.ok ? 1 : 0,
        r.aligned ? 1 : 0, r.ate_se3, r.global_rmse, r.poses, r.lost, r.factors, r.rejected,
        r.global_rmse_10s, r.backend_median_ms, r.backend_keyframe_median_ms, r.outage_start_err,
        r.outage_end_err, r.vio_drift_over_outage, r.err_10s_after, r.ate_se3_live,
        r.global_rmse_live, r.error);
  return csv;
}

nlohmann::json GnssBenchJson(const std::vector<GnssBenchSequenceInfo>& sequences, const Runs& runs,
                             bool never_worse) {
  nlohmann::json j;
  j["sequences"] = nlohmann::json::array();
  for (const GnssBenchSequenceInfo& s : sequences)
    j["sequences"].push_back({{"name", s.name}, {"dir", s.dir}, {"length_m", s.length_m}});
  j["runs"] = nlohmann::json::array();
  for (const GnssRunResult& r : runs)
    j["runs"].push_back({{"sequence", r.sequence},
                         {"condition", ConditionLabel(r.condition)},
                         {"norm", NormLabel(r.norm)},
                         {"seed", r.seed},
                         {"ok", r.ok},
                         {"enu_aligned", r.aligned},
                         {"ate_se3_m", r.ate_se3},
                         {"global_rmse_m", r.global_rmse},
                         {"global_rmse_from_10s_m", r.global_rmse_10s},
                         {"live_ate_se3_m", r.ate_se3_live},
                         {"live_global_rmse_m", r.global_rmse_live},
                         {"live_outage_growth_m", r.outage_growth_live},
                         {"live_err_10s_after_m", r.err_10s_after_live},
                         {"lost_intervals", r.lost},
                         {"factors", r.factors},
                         {"rejected", r.rejected},
                         {"backend_median_ms", r.backend_median_ms},
                         {"backend_keyframe_median_ms", r.backend_keyframe_median_ms},
                         {"outage_start_err_m", r.outage_start_err},
                         {"outage_end_err_m", r.outage_end_err},
                         {"vio_drift_over_outage_m", r.vio_drift_over_outage},
                         {"err_10s_after_m", r.err_10s_after},
                         {"error", r.error}});
  j["never_worse"] = never_worse;
  return j;
}

namespace {

// A curve of the plot: a run's output (or its live estimate).
struct PlotSeries {
  Condition condition;
  std::string colour;
  bool live;
};

std::vector<PlotSeries> PlotSeriesList() {
  return {{kNoGnss, "#888888", false},
          {GnssCondition::kSigma3, "#9ecae1", true},
          {GnssCondition::kSigma3, "#1f77b4", false},
          {GnssCondition::kOutliers, "#2ca02c", false},
          {GnssCondition::kOutage, "#d62728", false}};
}

// The first seed's Huber run (or the VIO alone) of a condition; nullptr if there is none.
const GnssRunResult* PickRun(const Runs& runs, const std::string& sequence, Condition condition) {
  const GnssRunResult* best = nullptr;
  for (const GnssRunResult& r : runs)
    if (r.ok && r.sequence == sequence && r.condition == condition &&
        (!r.norm || *r.norm == vio::GnssNorm::kHuber) && (!best || r.seed < best->seed))
      best = &r;
  return best;
}

const std::vector<std::pair<double, double>>& Curve(const GnssRunResult& r, bool live) {
  return live ? r.live_error_over_time : r.error_over_time;
}

std::string LegendLabel(const PlotSeries& s, const GnssRunResult& r) {
  return ConditionLabel(s.condition) +
         (!s.condition ? " (first 5 s aligned)"
          : s.live     ? ", Huber, live"
                       : ", Huber") +
         fmt::format(": RMSE {:.2f} m", s.live ? r.global_rmse_live : r.global_rmse);
}

}  // namespace

void WriteGnssErrorPlot(const std::string& path, const Runs& runs,
                        const GnssBenchSequenceInfo& sequence) {
  const std::vector<PlotSeries> series = PlotSeriesList();
  std::vector<const GnssRunResult*> picked;
  double t_max = 1, e_max = 0.5;
  for (const PlotSeries& s : series) {
    picked.push_back(PickRun(runs, sequence.name, s.condition));
    if (!picked.back()) continue;
    for (const auto& [t, e] : Curve(*picked.back(), s.live))
      t_max = std::max(t_max, t), e_max = std::max(e_max, e);
  }
  e_max = std::min(e_max, 20.0);
  const double W = 900, H = 420, left = 60, right = 20, top = 40, bottom = 50;
  report::SvgDocument svg(W, H);
  svg.Rect(0, 0, W, H, "white");
  auto X = [&](double t) { return left + (W - left - right) * t / t_max; };
  auto Y = [&](double e) { return H - bottom - (H - top - bottom) * std::min(e, e_max) / e_max; };
  svg.Text(W / 2, 22,
           "optinav bench gnss: global position error (no alignment), " + sequence.name + " flight",
           15, "middle");
  const report::Ticks yt = report::NiceTicks(0, e_max), xt = report::NiceTicks(0, t_max, 8);
  for (double v = yt.start; v <= e_max + 1e-9; v += yt.step) {
    svg.Line(left, Y(v), W - right, Y(v), "#eeeeee", 1);
    svg.Text(left - 6, Y(v) + 4, report::FormatTick(v, yt.step), 11, "end");
  }
  for (double v = xt.start; v <= t_max + 1e-9; v += xt.step)
    svg.Text(X(v), H - bottom + 16, report::FormatTick(v, xt.step), 11, "middle");
  svg.Text(W / 2, H - 12, "time (s)", 12, "middle");
  svg.Text(16, H / 2, "error (m)", 12, "middle",
           "transform=\"rotate(-90 16 " + std::to_string(H / 2) + ")\"");
  const double outage_start = sequence.outage_start_s;
  const double outage_s = ConditionSpec(GnssCondition::kOutage).outage_s;
  svg.Rect(X(outage_start), top, X(outage_start + outage_s) - X(outage_start), H - top - bottom,
           "#fde0dd");
  svg.Text(X(outage_start + outage_s / 2), top + 14,
           fmt::format("{:g} s outage (red run)", outage_s), 11, "middle");
  for (size_t k = 0; k < series.size(); ++k) {
    if (!picked[k] || (series[k].live && picked[k]->live_error_over_time.empty())) continue;
    std::string pts;
    const auto& s = Curve(*picked[k], series[k].live);
    const size_t step = std::max<size_t>(1, s.size() / 1500);
    for (size_t i = 0; i < s.size(); i += step)
      pts += fmt::format("{:.1f},{:.1f} ", X(s[i].first), Y(s[i].second));
    svg.Polyline(pts, series[k].colour, 1.5);
    svg.Rect(W - 260, top + 10 + 18 * k, 14, 4, series[k].colour);
    svg.Text(W - 240, top + 16 + 18 * k, LegendLabel(series[k], *picked[k]), 11);
  }
  svg.Line(left, H - bottom, W - right, H - bottom, "black", 1);
  svg.Line(left, top, left, H - bottom, "black", 1);
  io::WriteFileAtomically(path, svg.Finish());
}

}  // namespace optinav::app::internal

namespace optinav::app::internal {
namespace {

constexpr size_t kMaxPathPoints = 1500;

// [north, east] of every k-th pose, at most kMaxPathPoints (Leaflet's order in a local view).
std::vector<Eigen::Vector2d> LocalPoints(const Trajectory& t) {
  std::vector<Eigen::Vector2d> pts;
  const size_t step = std::max<size_t>(1, t.size() / kMaxPathPoints);
  for (size_t i = 0; i < t.size(); i += step)
    pts.emplace_back(t.positions[i].y(), t.positions[i].x());
  return pts;
}

report::ReportSeries ErrorSeries(const std::string& name, const std::string& colour,
                                 const std::vector<std::pair<double, double>>& curve) {
  report::ReportSeries s{name, colour, {}, {}, false};
  const size_t step = std::max<size_t>(1, curve.size() / kMaxPathPoints);
  for (size_t i = 0; i < curve.size(); i += step) {
    s.x.push_back(curve[i].first);
    s.y.push_back(curve[i].second);
  }
  return s;
}

std::string ConditionColour(Condition c) {
  if (!c) return "#777777";
  switch (*c) {
    case GnssCondition::kIdeal:
      return "#17becf";
    case GnssCondition::kSigma0_5:
      return "#9467bd";
    case GnssCondition::kSigma1_5:
      return "#8c564b";
    case GnssCondition::kSigma3:
      return "#1f77b4";
    case GnssCondition::kOutliers:
      return "#2ca02c";
    case GnssCondition::kOutage:
      return "#d62728";
  }
  return "#000000";
}

// The run whose GNSS samples are shown: an aligned run (its samples were used), the first seed
// of the outliers condition (else the noisiest one present), Huber when it ran.
const GnssRunResult* SamplesRun(const Runs& runs, const std::string& sequence) {
  const GnssRunResult* best = nullptr;
  const auto rank = [](const GnssRunResult& r) {
    const GnssCondition c = *r.condition;
    return (r.aligned ? 1000 : 0) + (c == GnssCondition::kOutliers ? 100 : 0) +
           static_cast<int>(c) * 10 + (*r.norm == vio::GnssNorm::kHuber ? 5 : 0) - r.seed;
  };
  for (const GnssRunResult& r : runs)
    if (r.ok && r.condition && r.sequence == sequence && (!best || rank(r) > rank(*best)))
      best = &r;
  return best;
}

report::ReportView SequenceView(const GnssBenchSequenceInfo& seq, const Runs& runs) {
  report::ReportView v;
  v.name = fmt::format("{} flight ({:.0f} m): local ENU frame, metres", seq.name, seq.length_m);
  v.frame = "local";
  v.paths.push_back({"ground truth", "ground truth", "#14a03c", 3, false, LocalPoints(seq.truth)});
  report::ReportChart chart{"global position error (no alignment)", "time (s)", "error (m)", {}};
  // Huber's layers start shown (or the first norm's when Huber did not run); the others hidden.
  std::optional<vio::GnssNorm> shown;
  for (const GnssRunResult& r : runs)
    if (r.sequence == seq.name && r.norm && (!shown || *r.norm == vio::GnssNorm::kHuber))
      shown = r.norm;
  for (const GnssRunResult& r : runs) {
    if (r.sequence != seq.name || !r.ok || r.global.empty()) continue;
    const std::string layer = r.condition ? ConditionLabel(r.condition) + ", " + NormLabel(r.norm)
                                          : std::string("VIO alone (first 5 s aligned)");
    const std::string name =
        r.condition ? fmt::format("{}, seed {}: global RMSE {:.2f} m", layer, r.seed, r.global_rmse)
                    : fmt::format("VIO alone: global RMSE {:.2f} m", r.global_rmse);
    v.paths.push_back({layer, name, ConditionColour(r.condition), r.condition ? 1.5 : 2,
                       r.norm && *r.norm == vio::GnssNorm::kL2, LocalPoints(r.global)});
    if (r.norm != shown && r.condition &&
        std::find(v.hidden_layers.begin(), v.hidden_layers.end(), layer) == v.hidden_layers.end())
      v.hidden_layers.push_back(layer);
    if (r.seed <= 1 && r.norm == (r.condition ? shown : std::nullopt))
      chart.series.push_back(ErrorSeries(r.condition ? ConditionLabel(r.condition) : "VIO alone",
                                         ConditionColour(r.condition), r.error_over_time));
  }
  if (const GnssRunResult* g = SamplesRun(runs, seq.name)) {
    const std::vector<vio::GnssSample> samples = MakeConditionGnss(
        seq.truth, seq.lever_arm_in_body, seq.outage_start_s, *g->condition, g->seed);
    std::map<int64_t, std::string> rejected(g->gnss_rejected.begin(), g->gnss_rejected.end());
    const std::string layer =
        fmt::format("GNSS samples ({}, {}, seed {})", ConditionLabel(g->condition),
                    NormLabel(g->norm), g->seed);
    report::ReportSeries dots{"GNSS sample error", "#c828c8", {}, {}, true};
    for (const vio::GnssSample& s : samples) {
      const auto pose = seq.truth.InterpolateAt(s.t_ns);
      if (!pose) continue;
      const Eigen::Vector3d antenna = *pose * seq.lever_arm_in_body;
      const double error_m = (s.position_enu_m - antenna).norm();
      const double t_s = (s.t_ns - seq.truth.t_ns.front()) * 1e-9;
      const auto it = rejected.find(s.t_ns);
      v.fixes.push_back({layer, fmt::format("GNSS sample at {:.1f} s", t_s),
                         Eigen::Vector2d(s.position_enu_m.y(), s.position_enu_m.x()), t_s, error_m,
                         "gnss", -1, it == rejected.end(), it == rejected.end() ? "" : it->second});
      dots.x.push_back(t_s);
      dots.y.push_back(error_m);
    }
    v.fix_error_scale_m = 3 * ConditionSpec(*g->condition).sigma_m + 1;
    chart.series.insert(chart.series.begin(), std::move(dots));
  }
  v.markers.push_back({"start / end", "start", "start", LocalPoints(seq.truth).front()});
  v.markers.push_back(
      {"start / end", "end", "end",
       Eigen::Vector2d(seq.truth.positions.back().y(), seq.truth.positions.back().x())});
  v.chart = std::move(chart);
  return v;
}

std::string F3(double v) { return std::isfinite(v) ? fmt::format("{:.3f}", v) : "-"; }

}  // namespace

void WriteGnssBenchReportDocument(const std::string& path,
                                  const std::vector<GnssBenchSequenceInfo>& sequences,
                                  const std::vector<GnssRunResult>& runs,
                                  const nlohmann::json& settings, const std::string& tables) {
  report::ReportDocument doc;
  doc.kind = "bench gnss";
  doc.title =
      fmt::format("optinav bench gnss: {} run(s) on {} sequence(s)", runs.size(), sequences.size());
  doc.notes.push_back(
      "Paths: the fused output in the local ENU frame of the GNSS origin (the VIO alone aligned "
      "on its first 5 s); one layer per condition and norm (Huber shown, the others in the layer "
      "switcher). Dots: one run's GNSS samples coloured by their error, rejected ones ringed red.");
  for (const GnssBenchSequenceInfo& s : sequences) doc.views.push_back(SequenceView(s, runs));
  report::ReportTable t{
      "Runs (errors in m)",
      {"sequence", "condition", "norm", "seed", "ATE SE(3)", "global RMSE", "global from 10 s",
       "live ATE", "live global", "factors", "rejected", "status"},
      {}};
  for (const GnssRunResult& r : runs)
    t.rows.push_back({r.sequence, ConditionLabel(r.condition), NormLabel(r.norm),
                      std::to_string(r.seed), F3(r.ate_se3), F3(r.global_rmse),
                      F3(r.global_rmse_10s), F3(r.ate_se3_live), F3(r.global_rmse_live),
                      std::to_string(r.factors), std::to_string(r.rejected),
                      r.ok ? (r.reused ? "ok (reused)" : "ok") : "failed: " + r.error});
  doc.tables.push_back(std::move(t));
  doc.settings = settings;
  doc.text = tables;
  report::WriteReportDocument(path, doc);
}

}  // namespace optinav::app::internal
