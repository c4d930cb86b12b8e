#include "optinav/app/evaluation.h"

#include <fmt/format.h>

#include "optinav/io/text_parse.h"
#include "optinav/report/trajectory_plot.h"

namespace optinav::app {
namespace {

std::string AlignmentDescription(const eval::AlignmentResult& a, size_t pairs) {
  const auto& o = a.options;
  std::string s;
  switch (o.mode) {
    case eval::AlignMode::kNone:
      s = "none";
      break;
    case eval::AlignMode::kSe3:
      s = "SE(3) Umeyama";
      break;
    case eval::AlignMode::kSim3:
      s = "Sim(3) Umeyama";
      break;
    case eval::AlignMode::kScale:
      s = "scale only (Umeyama)";
      break;
    case eval::AlignMode::kPosYaw:
      s = "4-DoF position + yaw";
      break;
  }
  if (o.mode != eval::AlignMode::kNone) {
    s += o.n_to_align > 0 ? fmt::format(" on the first {} pairs", std::min(o.n_to_align, pairs))
                          : " on all pairs";
  }
  if (o.align_origin) s += ", origin aligned";
  return s;
}

nlohmann::json StatisticsJson(const EvaluationSettings& st, const EvaluationOutcome& out) {
  const eval::Statistics& s = out.series.stats;
  nlohmann::json j;
  j["metric"] = st.metric == EvaluationSettings::Metric::kApe ? "ape" : "rpe";
  j["pose_relation"] = eval::PoseRelationName(st.relation);
  j["unit"] = eval::PoseRelationUnit(st.relation);
  j["n"] = s.n;
  j["rmse"] = s.rmse;
  j["mean"] = s.mean;
  j["median"] = s.median;
  j["std"] = s.std;
  j["min"] = s.min;
  j["max"] = s.max;
  j["sse"] = s.sse;
  const Eigen::Matrix4d total = out.alignment.Total();
  nlohmann::json matrix = nlohmann::json::array();
  for (int r = 0; r < 4; ++r)
    matrix.push_back({total(r, 0), total(r, 1), total(r, 2), total(r, 3)});
  j["alignment"] = {{"mode", eval::AlignModeName(st.alignment.mode)},
                    {"n_to_align", st.alignment.n_to_align},
                    {"align_origin", st.alignment.align_origin},
                    {"scale", out.alignment.ref_from_est.scale},
                    {"ref_from_est", matrix}};
  j["association"] = {{"max_diff_s", st.association.max_diff_s},
                      {"t_offset_s", st.association.t_offset_s},
                      {"matched", out.synced.ref.size()},
                      {"max_pairs", out.synced.max_pairs},
                      {"by_index", out.synced.by_index}};
  const auto label = [](const std::string& path) {
    return path.empty() ? nlohmann::json(nullptr) : nlohmann::json(path);
  };
  j["ref"] = label(st.ref_path);
  j["est"] = label(st.est_path);
  if (st.metric == EvaluationSettings::Metric::kRpe) {
    j["delta"] = st.rpe.delta;
    j["delta_unit"] = eval::DeltaUnitName(st.rpe.unit);
    j["all_pairs"] = st.rpe.all_pairs;
  }
  return j;
}

void WriteOutputs(const EvaluationSettings& st, const EvaluationOutcome& out) {
  if (!st.json_path.empty()) io::WriteFileAtomically(st.json_path, out.json.dump(2) + "\n");
  if (!st.plot_path.empty()) {
    report::ErrorPlotInput plot;
    plot.title = out.title;
    plot.subtitle = fmt::format("{} vs {} | alignment: {} | {} pairs", st.est_path, st.ref_path,
                                AlignmentDescription(out.alignment, out.synced.ref.size()),
                                out.synced.ref.size());
    plot.unit = eval::PoseRelationUnit(st.relation);
    plot.ref = &out.synced.ref;
    plot.est = &out.synced.est;
    plot.series = &out.series;
    plot.plane = st.plot_plane;
    report::WriteErrorPlotSvg(st.plot_path, plot);
  }
  if (!st.aligned_out_path.empty()) {
    io::WriteTrajectory(st.aligned_out_path, out.synced.est,
                        out.synced.est.has_timestamps() ? io::TrajectoryFormat::kTum
                                                        : io::TrajectoryFormat::kKitti);
  }
}

}  // namespace

std::string EvaluationSettings::Check() const {
  if (!(association.max_diff_s >= 0)) return "--max-diff must be >= 0";
  if (plot_plane != "xy" && plot_plane != "xz" && plot_plane != "yz") {
    return "--plot-plane must be xy, xz or yz, got '" + plot_plane + "'";
  }
  if (metric == Metric::kRpe) return rpe.Check();
  return "";
}

EvaluationOutcome RunEvaluation(const EvaluationSettings& st) {
  if (const std::string m = st.Check(); !m.empty()) throw Error(m);
  Trajectory ref = io::ReadTrajectory(st.ref_path, st.ref_read);
  Trajectory est = io::ReadTrajectory(st.est_path, st.est_read);
  return RunEvaluation(st, std::move(ref), std::move(est));
}

EvaluationOutcome RunEvaluation(const EvaluationSettings& st, Trajectory ref, Trajectory est) {
  if (const std::string m = st.Check(); !m.empty()) throw Error(m);
  EvaluationOutcome out;
  out.ref_poses = ref.size();
  out.est_poses = est.size();
  out.synced = eval::Synchronize(std::move(ref), std::move(est), st.association);
  out.alignment = eval::AlignTrajectory(out.synced.ref, &out.synced.est, st.alignment);
  const std::string unit = eval::PoseRelationUnit(st.relation);
  const std::string unit_text = unit.empty() ? " (unit-less)" : " (" + unit + ")";
  if (st.metric == EvaluationSettings::Metric::kApe) {
    out.series = eval::ComputeApe(out.synced.ref, out.synced.est, st.relation);
    out.title = fmt::format("APE w.r.t. {}{}", eval::PoseRelationTitle(st.relation), unit_text);
  } else {
    eval::RpeOptions rpe = st.rpe;
    rpe.relation = st.relation;
    out.series = eval::ComputeRpe(out.synced.ref, out.synced.est, rpe);
    out.title = fmt::format("RPE w.r.t. {}{} for delta = {} ({}), {} pairs",
                            eval::PoseRelationTitle(st.relation), unit_text, rpe.delta,
                            eval::DeltaUnitName(rpe.unit), rpe.all_pairs ? "all" : "consecutive");
  }
  out.json = StatisticsJson(st, out);
  WriteOutputs(st, out);
  return out;
}

std::string FormatEvaluationTable(const EvaluationSettings& st, const EvaluationOutcome& o) {
  const eval::Statistics& s = o.series.stats;
  std::string t;
  t += o.title + "\n";
  t += fmt::format("  reference : {} ({} poses)\n", st.ref_path, o.ref_poses);
  t += fmt::format("  estimate  : {} ({} poses)\n", st.est_path, o.est_poses);
  t += fmt::format(
      "  matched   : {} of {} possible pairs{}\n", o.synced.ref.size(), o.synced.max_pairs,
      o.synced.by_index ? " (by index: no timestamps)"
                        : fmt::format(" (max diff {} s, t offset {} s)", st.association.max_diff_s,
                                      st.association.t_offset_s));
  t += fmt::format("  alignment : {}", AlignmentDescription(o.alignment, o.synced.ref.size()));
  if (st.alignment.mode == eval::AlignMode::kSim3 || st.alignment.mode == eval::AlignMode::kScale) {
    t += fmt::format(" (scale {:.6f})", o.alignment.ref_from_est.scale);
  }
  t += "\n\n";
  for (const auto& [name, value] : {std::pair{"max", s.max},
                                    {"mean", s.mean},
                                    {"median", s.median},
                                    {"min", s.min},
                                    {"rmse", s.rmse},
                                    {"sse", s.sse},
                                    {"std", s.std}}) {
    t += fmt::format("{:>10}  {:.6f}\n", name, value);
  }
  t += fmt::format("{:>10}  {}\n", "n", s.n);
  return t;
}

}  // namespace optinav::app
