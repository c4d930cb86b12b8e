// The GNSS fusion flags shared by `optinav vio --gnss` and `optinav bench gnss` (added once, so
// both commands spell, document and check them the same way).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "optinav/vio/gnss_fusion.h"

namespace optinav::cli {

// Raw flag values; "unset" values leave the GnssFusionOptions default alone.
struct GnssFusionFlags {
  std::string time = "exact";
  double norm_param = -1, gate = -1, init_distance = -1, init_yaw_sigma_deg = -1,
         factor_scale = -1, smooth_walk_scale = -1;
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
