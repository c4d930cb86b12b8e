#include "optinav/exe/cli_common.h"

#include <cmath>
#include <filesystem>
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

void PrepareOutputDir(const std::string& dir, bool force, const std::string& option) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) {
      throw Error("exists and is not a directory", {.file = dir, .field = option});
    }
    if (!force && !fs::is_empty(dir, ec)) {
      throw Error("output folder exists and is not empty (use --force to write into it)",
                  {.file = dir, .field = option});
    }
  }
  fs::create_directories(dir, ec);
  if (ec) throw Error("cannot create output folder: " + ec.message(), {.file = dir});
}

}  // namespace optinav
