// The evaluation plot: a top view of the reference and the aligned estimate coloured by error,
// and the error over time with its rmse, mean and median.
#pragma once

#include <string>
#include <vector>

#include "optinav/eval/metrics.h"

namespace optinav::report {

struct ErrorPlotInput {
  std::string title;                // e.g. "APE w.r.t. translation part (m)"
  std::string subtitle;             // e.g. "SE(3) Umeyama alignment, 4541 pairs"
  std::string unit;                 // error unit for the axis ("" for unit-less)
  const Trajectory* ref = nullptr;  // synchronized reference
  const Trajectory* est = nullptr;  // synchronized, aligned estimate
  const eval::ErrorSeries* series = nullptr;
  std::string plane = "xy";  // which two axes to show in the top view: xy, xz or yz
};

// Returns the SVG text. Long trajectories are decimated to a few thousand drawn samples.
std::string RenderErrorPlotSvg(const ErrorPlotInput& input);
// Renders and writes atomically; throws Error on I/O failure or a bad plane name.
void WriteErrorPlotSvg(const std::string& path, const ErrorPlotInput& input);

}  // namespace optinav::report
