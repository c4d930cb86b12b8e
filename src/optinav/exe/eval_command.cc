// optinav eval ape|rpe REF EST [options]: trajectory evaluation with evo's definitions. Parses the
// flags into app::EvaluationSettings, runs app::RunEvaluation and prints evo's table.
#include <cstdio>

#include <CLI/CLI.hpp>

#include "optinav/app/evaluation.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/util/logging.h"

namespace optinav {
namespace {

using app::EvaluationSettings;

// The flags that are names of enums, resolved after parsing.
struct NamedFlags {
  std::string ref_format = "auto", est_format = "auto", align = "none", relation = "trans",
              unit = "frames";
};

void AddCommonOptions(CLI::App* cmd, EvaluationSettings* st, NamedFlags* named) {
  cmd->add_option("ref", st->ref_path, "reference (ground-truth) trajectory file")->required();
  cmd->add_option("est", st->est_path, "estimated trajectory file")->required();
  cmd->add_option("--ref-format", named->ref_format, "auto|tum|kitti|euroc")->capture_default_str();
  cmd->add_option("--est-format", named->est_format, "auto|tum|kitti|euroc")->capture_default_str();
  cmd->add_option("--ref-times", st->ref_read.kitti_times_path,
                  "times file (seconds, one per line) for a KITTI reference");
  cmd->add_option("--est-times", st->est_read.kitti_times_path, "times file for a KITTI estimate");
  cmd->add_option("--max-diff", st->association.max_diff_s,
                  "max. time difference (s) for associating stamps")
      ->capture_default_str();
  cmd->add_option("--t-offset", st->association.t_offset_s,
                  "constant offset (s) added to the estimate's stamps")
      ->capture_default_str();
  cmd->add_option("--align", named->align, "none|se3|sim3|scale|posyaw")->capture_default_str();
  cmd->add_option("--n-to-align", st->alignment.n_to_align,
                  "align on the first N pairs only (default: all)");
  cmd->add_flag("--align-origin", st->alignment.align_origin,
                "afterwards make the first poses coincide");
  cmd->add_option("--pose-relation", named->relation, "trans|rot|full|angle_deg|angle_rad")
      ->capture_default_str();
  cli::OutputFile(cmd->add_option("--json", st->json_path, "write the statistics as JSON"));
  cli::OutputFile(
      cmd->add_option("--plot", st->plot_path, "write an SVG plot (top view + error over time)"));
  cmd->add_option("--plot-plane", st->plot_plane, "plane of the top view: xy|xz|yz")
      ->capture_default_str();
  cli::OutputFile(
      cmd->add_option("--save-aligned", st->aligned_out_path,
                      "write the associated, aligned estimate (TUM; KITTI without stamps)"));
}

void AddRpeOptions(CLI::App* rpe, EvaluationSettings* st, NamedFlags* named) {
  rpe->add_option("--delta", st->rpe.delta, "distance between the poses of a pair")
      ->capture_default_str();
  rpe->add_option("--unit", named->unit, "unit of --delta: frames|m|s|rad|deg")
      ->capture_default_str();
  rpe->add_flag("--all-pairs", st->rpe.all_pairs,
                "use all pairs at distance delta, not consecutive non-overlapping ones");
  rpe->add_option("--rel-delta-tol", st->rpe.rel_delta_tol,
                  "relative tolerance on delta for --all-pairs (m, s, rad, deg)")
      ->capture_default_str();
}

// Turns the named flags into enums and checks the settings; throws cli::UsageError naming the
// flag at fault.
void Resolve(const NamedFlags& named, EvaluationSettings* st) {
  const auto rf = io::ParseTrajectoryFormat(named.ref_format);
  if (!rf) {
    throw cli::UsageError("unknown format '" + named.ref_format + "' (auto|tum|kitti|euroc)",
                          "--ref-format");
  }
  const auto ef = io::ParseTrajectoryFormat(named.est_format);
  if (!ef) {
    throw cli::UsageError("unknown format '" + named.est_format + "' (auto|tum|kitti|euroc)",
                          "--est-format");
  }
  st->ref_read.format = *rf;
  st->est_read.format = *ef;
  const auto align = eval::ParseAlignMode(named.align);
  if (!align) {
    throw cli::UsageError("unknown mode '" + named.align + "' (none|se3|sim3|scale|posyaw)",
                          "--align");
  }
  st->alignment.mode = *align;
  const auto relation = eval::ParsePoseRelation(named.relation);
  if (!relation) {
    throw cli::UsageError(
        "unknown relation '" + named.relation + "' (trans|rot|full|angle_deg|angle_rad)",
        "--pose-relation");
  }
  st->relation = *relation;
  if (st->metric == EvaluationSettings::Metric::kRpe) {
    const auto unit = eval::ParseDeltaUnit(named.unit);
    if (!unit)
      throw cli::UsageError("unknown unit '" + named.unit + "' (frames|m|s|rad|deg)", "--unit");
    st->rpe.unit = *unit;
  }
  cli::ThrowIfCheckFailed(st->Check());
}

}  // namespace

int RunEval(int argc, char** argv) {
  CLI::App command{"Trajectory evaluation with evo's definitions (APE, RPE)", "optinav eval"};
  command.require_subcommand(1);
  EvaluationSettings ape_st, rpe_st;
  NamedFlags ape_named, rpe_named;
  ape_st.metric = EvaluationSettings::Metric::kApe;
  rpe_st.metric = EvaluationSettings::Metric::kRpe;
  CLI::App* ape = command.add_subcommand("ape", "absolute pose error");
  CLI::App* rpe = command.add_subcommand("rpe", "relative pose error");
  AddCommonOptions(ape, &ape_st, &ape_named);
  AddCommonOptions(rpe, &rpe_st, &rpe_named);
  AddRpeOptions(rpe, &rpe_st, &rpe_named);
  return cli::RunCli(command, argc, argv, [&] {
    const bool is_rpe = rpe->parsed();
    EvaluationSettings& st = is_rpe ? rpe_st : ape_st;
    Resolve(is_rpe ? rpe_named : ape_named, &st);
    const app::EvaluationOutcome outcome = app::RunEvaluation(st);
    std::fputs(app::FormatEvaluationTable(st, outcome).c_str(), stdout);
    if (!st.json_path.empty()) spdlog::info("wrote {}", st.json_path);
    if (!st.plot_path.empty()) spdlog::info("wrote {}", st.plot_path);
    if (!st.aligned_out_path.empty()) spdlog::info("wrote {}", st.aligned_out_path);
    return 0;
  });
}

}  // namespace optinav
