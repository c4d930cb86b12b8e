// Flag-value parsing shared by the subcommands. Every parser throws cli::UsageError (exit 2)
// naming the flag when the text is malformed or out of range.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "optinav/app/vio_run.h"
#include "optinav/geo/geo.h"

namespace optinav {

// "LAT,LON" (degrees) -> LatLon.
geo::LatLon ParseLatLon(const std::string& text, const std::string& option);

// "A,B,..." -> exactly `count` finite numbers; the message shows the expected `form` (e.g.
// "A,B,C").
std::vector<double> ParseNumbers(const std::string& text, size_t count, const std::string& form,
                                 const std::string& option);

// "A,B,C" -> three finite numbers.
Eigen::Vector3d ParseTriple(const std::string& text, const std::string& option);

// "A,B,..." -> any number of finite numbers; empty fields are skipped ("" gives none).
std::vector<double> ParseNumberList(const std::string& text, const std::string& option);

// "WxH" (pixels) -> width, height; each at least `min_side` when min_side > 0 (otherwise the
// options' Check() judges the size).
void ParseFrameSize(const std::string& text, const std::string& option, int min_side, int* width,
                    int* height);

// "auto|ground|free" -> the VIO's motion model (app::ParseVehicleModel).
app::VehicleModel ParseVehicle(const std::string& text, const std::string& option);

}  // namespace optinav
