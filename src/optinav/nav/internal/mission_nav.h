// `optinav mission --estimator nav`: one closed-loop mission flown with MapAidedNavigator
// (MissionOptions::estimator, nav/mission.h). Called by Mission::Run after its checks.
#pragma once

#include <string>

#include "optinav/geo/raster.h"
#include "optinav/maploc/locator.h"
#include "optinav/nav/mission.h"

namespace optinav::nav {

// What the nav estimator needs of the options beyond Mission::Check ("" when valid).
std::string CheckNavMission(const maploc::MapDatabase& db, const MissionOptions& options);

// `frames`: the orthophoto the nadir frames are rendered from, `frames_gsd_m` its ground
// sample distance.
MissionResult RunNavMission(const maploc::MapDatabase& db, const geo::GeoRaster& frames,
                            double frames_gsd_m, const maploc::LocateOptions& locate_options,
                            const MissionOptions& options);

}  // namespace optinav::nav
