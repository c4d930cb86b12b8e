// optinav eval ape|rpe REF EST [options]: trajectory evaluation with evo's definitions.
#include <cstdio>

#include <CLI/CLI.hpp>

#include "optinav/exe/commands.h"
#include "optinav/exe/evaluation.h"
#include "optinav/util/logging.h"

namespace optinav {
namespace {

struct RawOptions {
  std::string ref_format = "auto", est_format = "auto", align = "none", relation = "trans",
              unit = "frames", log_level = "info";
};

void AddCommonOptions(CLI::App* cmd, EvaluationSettings* st, RawOptions* raw) {
  cmd->add_option("ref", st->ref_path, "reference (ground-truth) trajectory file")->required();
  cmd->add_option("est", st->est_path, "estimated trajectory file")->required();
  cmd->add_option("--ref-format", raw->ref_format, "auto|tum|kitti|euroc")->capture_default_str();
  cmd->add_option("--est-format", raw->est_format, "auto|tum|kitti|euroc")->capture_default_str();
  cmd->add_option("--ref-times", st->ref_read.kitti_times_path,
                  "times file (seconds, one per line) for a KITTI reference");
  cmd->add_option("--est-times", st->est_read.kitti_times_path, "times file for a KITTI estimate");
  cmd->add_option("--max-diff", st->association.max_diff_s,
                  "max. time difference (s) for associating stamps")
      ->capture_default_str();
  cmd->add_option("--t-offset", st->association.t_offset_s,
                  "constant offset (s) added to the estimate's stamps")
      ->capture_default_str();
  cmd->add_option("--align", raw->align, "none|se3|sim3|scale|posyaw")->capture_default_str();
  cmd->add_option("--n-to-align", st->alignment.n_to_align,
                  "align on the first N pairs only (default: all)");
  cmd->add_flag("--align-origin", st->alignment.align_origin,
                "afterwards make the first poses coincide");
  cmd->add_option("--pose-relation", raw->relation, "trans|rot|full|angle_deg|angle_rad")
      ->capture_default_str();
  cmd->add_option("--json", st->json_path, "write the statistics as JSON");
  cmd->add_option("--plot", st->plot_path, "write an SVG plot (top view + error over time)");
  cmd->add_option("--plot-plane", st->plot_plane, "plane of the top view: xy|xz|yz")
      ->capture_default_str();
  cmd->add_option("--save-aligned", st->aligned_out_path,
                  "write the associated, aligned estimate (TUM; KITTI without stamps)");
  cmd->add_option("--log-level", raw->log_level, "trace|debug|info|warn|error|off")
      ->capture_default_str();
}

// Turns the raw strings into enums; returns an error message naming the flag, or "".
std::string Resolve(const RawOptions& raw, EvaluationSettings* st, bool rpe) {
  const auto rf = io::ParseTrajectoryFormat(raw.ref_format);
  if (!rf) return "--ref-format: unknown format '" + raw.ref_format + "' (auto|tum|kitti|euroc)";
  const auto ef = io::ParseTrajectoryFormat(raw.est_format);
  if (!ef) return "--est-format: unknown format '" + raw.est_format + "' (auto|tum|kitti|euroc)";
  st->ref_read.format = *rf;
  st->est_read.format = *ef;
  const auto align = eval::ParseAlignMode(raw.align);
  if (!align) return "--align: unknown mode '" + raw.align + "' (none|se3|sim3|scale|posyaw)";
  st->alignment.mode = *align;
  const auto rel = eval::ParsePoseRelation(raw.relation);
  if (!rel) {
    return "--pose-relation: unknown relation '" + raw.relation +
           "' (trans|rot|full|angle_deg|angle_rad)";
  }
  st->relation = *rel;
  if (!(st->association.max_diff_s >= 0)) return "--max-diff must be >= 0";
  if (st->plot_plane != "xy" && st->plot_plane != "xz" && st->plot_plane != "yz") {
    return "--plot-plane: must be xy, xz or yz, got '" + st->plot_plane + "'";
  }
  if (rpe) {
    const auto unit = eval::ParseDeltaUnit(raw.unit);
    if (!unit) return "--unit: unknown unit '" + raw.unit + "' (frames|m|s|rad|deg)";
    st->rpe.unit = *unit;
    if (std::string msg = st->rpe.Check(); !msg.empty()) return msg;
  }
  return "";
}

}  // namespace

int RunEval(int argc, char** argv) {
  CLI::App app{"Trajectory evaluation with evo's definitions (APE, RPE)", "optinav eval"};
  app.require_subcommand(1);
  EvaluationSettings ape_st, rpe_st;
  RawOptions ape_raw, rpe_raw;
  ape_st.metric = EvaluationSettings::Metric::kApe;
  rpe_st.metric = EvaluationSettings::Metric::kRpe;
  CLI::App* ape = app.add_subcommand("ape", "absolute pose error");
  CLI::App* rpe = app.add_subcommand("rpe", "relative pose error");
  AddCommonOptions(ape, &ape_st, &ape_raw);
  AddCommonOptions(rpe, &rpe_st, &rpe_raw);
  rpe->add_option("--delta", rpe_st.rpe.delta, "distance between the poses of a pair")
      ->capture_default_str();
  rpe->add_option("--unit", rpe_raw.unit, "unit of --delta: frames|m|s|rad|deg")
      ->capture_default_str();
  rpe->add_flag("--all-pairs", rpe_st.rpe.all_pairs,
                "use all pairs at distance delta, not consecutive non-overlapping ones");
  rpe->add_option("--rel-delta-tol", rpe_st.rpe.rel_delta_tol,
                  "relative tolerance on delta for --all-pairs (m, s, rad, deg)")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  const bool is_rpe = rpe->parsed();
  EvaluationSettings& st = is_rpe ? rpe_st : ape_st;
  const RawOptions& raw = is_rpe ? rpe_raw : ape_raw;
  try {
    SetLogLevel(raw.log_level);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  if (const std::string msg = Resolve(raw, &st, is_rpe); !msg.empty()) {
    spdlog::error("{}", msg);
    return 2;
  }
  try {
    const EvaluationOutcome outcome = RunEvaluation(st);
    std::fputs(FormatEvaluationTable(st, outcome).c_str(), stdout);
    if (!st.json_path.empty()) spdlog::info("wrote {}", st.json_path);
    if (!st.plot_path.empty()) spdlog::info("wrote {}", st.plot_path);
    if (!st.aligned_out_path.empty()) spdlog::info("wrote {}", st.aligned_out_path);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}

}  // namespace optinav
