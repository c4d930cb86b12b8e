#include "optinav/exe/cli_common.h"

#include <cmath>
#include <string_view>
#include <vector>

#include "optinav/io/text_parse.h"

namespace optinav {

geo::LatLon ParseLatLon(const std::string& text, const std::string& option) {
  std::vector<std::string_view> f;
  io::SplitFields(text, ',', &f);
  if (f.size() != 2) throw Error("expected LAT,LON, got '" + text + "'", {.field = option});
  const double lat = io::ParseFiniteDouble(f[0], {.field = option});
  const double lon = io::ParseFiniteDouble(f[1], {.field = option});
  if (std::abs(lat) > 90 || std::abs(lon) > 180) {
    throw Error("latitude/longitude out of range: '" + text + "'", {.field = option});
  }
  return {lat, lon};
}

std::vector<double> ParseNumbers(const std::string& text, size_t count, const std::string& form,
                                 const std::string& option) {
  std::vector<std::string_view> f;
  io::SplitFields(text, ',', &f);
  if (f.size() != count)
    throw Error("expected " + form + ", got '" + text + "'", {.field = option});
  std::vector<double> v;
  for (std::string_view field : f) v.push_back(io::ParseFiniteDouble(field, {.field = option}));
  return v;
}

Eigen::Vector3d ParseTriple(const std::string& text, const std::string& option) {
  const std::vector<double> v = ParseNumbers(text, 3, "three numbers A,B,C", option);
  return {v[0], v[1], v[2]};
}

}  // namespace optinav
