#include "optinav/exe/cli_common.h"

#include <cmath>
#include <cstdio>
#include <string_view>

#include "optinav/exe/cli_runner.h"
#include "optinav/io/text_parse.h"

namespace optinav {
namespace {

// io's number parser throws a plain Error: here the number is a flag value, so a usage error.
double ParseFlagNumber(std::string_view field, const std::string& option) {
  try {
    return io::ParseFiniteDouble(field, {.field = option});
  } catch (const Error& e) {
    throw cli::UsageError(e.message(), option);
  }
}

}  // namespace

geo::LatLon ParseLatLon(const std::string& text, const std::string& option) {
  std::vector<std::string_view> f;
  io::SplitFields(text, ',', &f);
  if (f.size() != 2) throw cli::UsageError("expected LAT,LON, got '" + text + "'", option);
  const double lat = ParseFlagNumber(f[0], option);
  const double lon = ParseFlagNumber(f[1], option);
  if (std::abs(lat) > 90 || std::abs(lon) > 180) {
    throw cli::UsageError("latitude/longitude out of range: '" + text + "'", option);
  }
  return {lat, lon};
}

std::vector<double> ParseNumbers(const std::string& text, size_t count, const std::string& form,
                                 const std::string& option) {
  std::vector<std::string_view> f;
  io::SplitFields(text, ',', &f);
  if (f.size() != count) throw cli::UsageError("expected " + form + ", got '" + text + "'", option);
  std::vector<double> v;
  for (std::string_view field : f) v.push_back(ParseFlagNumber(field, option));
  return v;
}

Eigen::Vector3d ParseTriple(const std::string& text, const std::string& option) {
  const std::vector<double> v = ParseNumbers(text, 3, "three numbers A,B,C", option);
  return {v[0], v[1], v[2]};
}

std::vector<double> ParseNumberList(const std::string& text, const std::string& option) {
  std::vector<std::string_view> f;
  io::SplitFields(text, ',', &f);
  std::vector<double> v;
  for (std::string_view field : f) {
    if (!field.empty()) v.push_back(ParseFlagNumber(field, option));
  }
  return v;
}

void ParseFrameSize(const std::string& text, const std::string& option, int min_side, int* width,
                    int* height) {
  if (std::sscanf(text.c_str(), "%dx%d", width, height) != 2 ||
      (min_side > 0 && (*width < min_side || *height < min_side))) {
    throw cli::UsageError("expected WxH, e.g. 640x480, got '" + text + "'", option);
  }
}

app::VehicleModel ParseVehicle(const std::string& text, const std::string& option) {
  const std::optional<app::VehicleModel> vehicle = app::ParseVehicleModel(text);
  if (!vehicle) throw cli::UsageError("unknown vehicle '" + text + "' (auto|ground|free)", option);
  return *vehicle;
}

}  // namespace optinav
