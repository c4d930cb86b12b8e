// The trajectory evaluation shared by `optinav eval` and `optinav demo`: read, associate, align,
// compute APE or RPE (evo's definitions, eval/metrics.h), format a table, optionally write the
// statistics as JSON, an SVG plot and the aligned estimate.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "optinav/eval/metrics.h"
#include "optinav/io/trajectory_io.h"

namespace optinav::app {

struct EvaluationSettings {
  enum class Metric { kApe, kRpe };
  Metric metric = Metric::kApe;
  std::string ref_path, est_path;
  io::TrajectoryReadOptions ref_read, est_read;
  eval::AssociationOptions association;
  eval::AlignmentOptions alignment;
  eval::PoseRelation relation = eval::PoseRelation::kTranslation;
  eval::RpeOptions rpe;  // used for kRpe (its relation is overwritten by `relation`)
  // Optional outputs (empty: not written).
  std::string json_path, plot_path, plot_plane = "xy", aligned_out_path;

  // Empty when valid, else a message that starts with the flag at fault ("--max-diff ...").
  std::string Check() const;
};

struct EvaluationOutcome {
  size_t ref_poses = 0, est_poses = 0;  // as read
  eval::SyncedPair synced;              // est aligned in place
  eval::AlignmentResult alignment;
  eval::ErrorSeries series;
  std::string title;    // "APE w.r.t. translation part (m)"
  nlohmann::json json;  // the statistics written with json_path
};

// Runs the evaluation; throws optinav::Error on invalid settings (Check()) and on bad input
// (naming the file and line). Writes the optional outputs atomically.
EvaluationOutcome RunEvaluation(const EvaluationSettings& settings);

// The same on trajectories already in memory (the Python module's arrays): ref_path and est_path
// only label them ("ref" and "est" of the JSON, null when empty; the table and the plot); the
// read options are not used.
EvaluationOutcome RunEvaluation(const EvaluationSettings& settings, Trajectory ref, Trajectory est);

// The human-readable table (as evo prints it).
std::string FormatEvaluationTable(const EvaluationSettings& settings,
                                  const EvaluationOutcome& outcome);

}  // namespace optinav::app
