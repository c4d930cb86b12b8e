// The GNSS fusion flags shared by `optinav vio --gnss` and `optinav bench gnss` (added once, so
// both commands spell, document and check them the same way).
#pragma once

#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "optinav/vio/gnss_fusion.h"

namespace optinav::cli {

// Raw flag values; flags not given leave the GnssFusionOptions default alone.
struct GnssFusionFlags {
  std::string time = "exact";
  std::optional<double> norm_param, gate, init_distance, init_yaw_sigma_deg, factor_scale,
      smooth_walk_scale;
  std::string walk, drift_test;
  bool no_smooth = false;

  // Applies the flags that were given over `o`, then o->Check(); throws UsageError naming the
  // flag at fault.
  void ApplyTo(vio::GnssFusionOptions* o) const;
};

// --gnss-time --gnss-norm-param --gnss-gate --gnss-init-yaw-sigma --gnss-init-distance
// --gnss-factor-scale --gnss-walk --gnss-drift-test --gnss-no-smooth --gnss-smooth-walk-scale.
// (--gnss-norm is the command's own: one norm in vio, a list in bench gnss.)
void AddGnssFusionFlags(CLI::App& app, GnssFusionFlags* flags);

}  // namespace optinav::cli
