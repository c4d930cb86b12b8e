#include "optinav/exe/gnss_flags.h"

#include <cmath>
#include <vector>

#include <fmt/format.h>

#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"

namespace optinav::cli {

void AddGnssFusionFlags(CLI::App& app, GnssFusionFlags* f) {
  const vio::GnssFusionOptions d;
  app.add_option("--gnss-time", f->time,
                 "exact (factor at the sample time) | frame (GNSS interpolated to frame times)")
      ->capture_default_str();
  app.add_option("--gnss-norm-param", f->norm_param,
                 "norm parameter in sigmas (default huber 2.5, tukey 5)");
  app.add_option(
      "--gnss-gate", f->gate,
      fmt::format("chi-square gate, 3 DoF (default {:g} = 99.9 %; 0: off)", d.gate_chi2));
  app.add_option("--gnss-init-yaw-sigma", f->init_yaw_sigma_deg,
                 fmt::format("yaw sigma (deg) the ENU alignment waits for (default {:g}; smaller: "
                             "a later but steadier alignment)",
                             d.init_max_yaw_sigma_rad * 180 / M_PI));
  app.add_option("--gnss-init-distance", f->init_distance,
                 fmt::format("horizontal distance before the ENU alignment is initialised, m "
                             "(default {:g})",
                             d.init_min_distance_m));
  app.add_option("--gnss-factor-scale", f->factor_scale,
                 fmt::format("GNSS factor sigma x this (the gate is not scaled; default {:g})",
                             d.factor_sigma_scale));
  app.add_option("--gnss-walk", f->walk,
                 fmt::format("VIO drift vs ENU as a random walk of the alignment per metre "
                             "travelled: M_PER_SQRT_M,RAD_PER_SQRT_M (default {:g},{:g})",
                             d.alignment_walk_m_per_sqrt_m, d.alignment_walk_rad_per_sqrt_m));
  app.add_option("--gnss-drift-test", f->drift_test,
                 fmt::format("drift detection on the mean innovation: SAMPLES,CHI2 (CHI2 0: off; "
                             "default {},{:g})",
                             d.drift_window_samples, d.drift_test_chi2));
  app.add_flag("--gnss-no-smooth", f->no_smooth,
               "output the live estimate (each frame through the ENU alignment known right after "
               "it) instead of the one smoothed over the whole run");
  app.add_option("--gnss-smooth-walk-scale", f->smooth_walk_scale,
                 fmt::format("the smoother's random walk = the alignment walk (--gnss-walk) x this "
                             "(default {:g}; raise it for a VIO that drifts more)",
                             d.smooth_walk_scale));
}

void GnssFusionFlags::ApplyTo(vio::GnssFusionOptions* g) const {
  const std::optional<vio::GnssTimeMode> time_mode = vio::ParseGnssTimeMode(time);
  if (!time_mode) throw UsageError("unknown mode '" + time + "' (exact|frame)", "--gnss-time");
  g->time_mode = *time_mode;
  if (norm_param) {
    if (!(*norm_param > 0))
      throw UsageError(fmt::format("must be > 0, got {}", *norm_param), "--gnss-norm-param");
    g->norm_parameter = *norm_param;
  }
  if (gate) {
    if (!(*gate >= 0)) throw UsageError(fmt::format("must be >= 0, got {}", *gate), "--gnss-gate");
    g->gate_chi2 = *gate;
  }
  if (init_distance) {
    if (!(*init_distance >= 0))
      throw UsageError(fmt::format("must be >= 0, got {}", *init_distance), "--gnss-init-distance");
    g->init_min_distance_m = *init_distance;
  }
  if (init_yaw_sigma_deg) {
    if (!(*init_yaw_sigma_deg > 0))
      throw UsageError("must be > 0 (degrees)", "--gnss-init-yaw-sigma");
    g->init_max_yaw_sigma_rad = *init_yaw_sigma_deg * M_PI / 180;
  }
  if (factor_scale) {
    if (!(*factor_scale > 0) || !std::isfinite(*factor_scale))
      throw UsageError(fmt::format("must be > 0, got {}", *factor_scale), "--gnss-factor-scale");
    g->factor_sigma_scale = *factor_scale;
  }
  if (smooth_walk_scale) {
    if (!(*smooth_walk_scale > 0) || !std::isfinite(*smooth_walk_scale))
      throw UsageError(fmt::format("must be > 0, got {}", *smooth_walk_scale),
                       "--gnss-smooth-walk-scale");
    g->smooth_walk_scale = *smooth_walk_scale;
  }
  g->smooth = !no_smooth;
  if (!drift_test.empty()) {  // ParseNumbers throws UsageError naming the flag
    const std::vector<double> v = ParseNumbers(drift_test, 2, "SAMPLES,CHI2", "--gnss-drift-test");
    if (v[0] != std::floor(v[0]) || !(v[0] >= 1))
      throw UsageError(fmt::format("SAMPLES must be a whole number >= 1, got {}", v[0]),
                       "--gnss-drift-test");
    g->drift_window_samples = static_cast<int>(v[0]);
    g->drift_test_chi2 = v[1];
  }
  if (!walk.empty()) {
    const std::vector<double> v =
        ParseNumbers(walk, 2, "M_PER_SQRT_M,RAD_PER_SQRT_M", "--gnss-walk");
    if (v[0] < 0 || v[1] < 0) throw UsageError("must be >= 0", "--gnss-walk");
    g->alignment_walk_m_per_sqrt_m = v[0];
    g->alignment_walk_rad_per_sqrt_m = v[1];
  }
  // Every flag was checked above; what Check() still finds is in the options given by the code.
  ThrowIfInvalid(g->Check(), "--gnss");
}

}  // namespace optinav::cli
