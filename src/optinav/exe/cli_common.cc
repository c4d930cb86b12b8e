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

Eigen::Vector3d ParseTriple(const std::string& text, const std::string& option) {
  std::vector<std::string_view> f;
  io::SplitFields(text, ',', &f);
  if (f.size() != 3) throw Error("expected three numbers A,B,C, got '" + text + "'", {.field = option});
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) v[i] = io::ParseFiniteDouble(f[i], {.field = option});
  return v;
}

}  // namespace optinav
