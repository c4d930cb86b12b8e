#include "optinav/io/gnss_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "optinav/io/text_parse.h"
#include "optinav/util/config.h"
#include "optinav/util/error.h"

namespace optinav::io {
namespace {

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// A non-finite value where a number belongs ("nan", "inf"): the row is dropped, not an error.
bool IsNonFiniteToken(std::string_view field) {
  const std::string f = Lower(Trim(field));
  return f == "nan" || f == "-nan" || f == "+nan" || f == "inf" || f == "-inf" || f == "+inf" ||
         f == "infinity" || f == "-infinity";
}

}  // namespace

GnssFile ReadGnssFile(const std::string& path, std::optional<GnssFileKind> kind) {
  const std::string text = ReadFileToString(path);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  GnssFile out;
  bool header_seen = false, kind_known = kind.has_value();
  if (kind) out.kind = *kind;
  int sigma_column = -1;
  const char* names_enu[] = {"timestamp", "x", "y", "z"};
  const char* names_llh[] = {"timestamp", "latitude", "longitude", "height"};
  while (cursor.Next(&line)) {
    const std::string_view trimmed = Trim(line);
    if (trimmed.empty()) continue;
    if (trimmed.front() == '#') {
      // The first comment line is the header: it names the columns.
      if (header_seen) continue;
      header_seen = true;
      SplitFields(trimmed.substr(1), ',', &f);
      for (size_t k = 0; k < f.size(); ++k) {
        const std::string name = Lower(f[k]);
        if (k == 1 && !kind_known && name.rfind("lat", 0) == 0)
          out.kind = GnssFileKind::kLatLonHeight;
        if (k >= 4 && name.rfind("sigma", 0) == 0) sigma_column = static_cast<int>(k);
      }
      kind_known = true;
      continue;
    }
    ErrorContext ctx{.file = path, .line = cursor.line_number()};
    const char* const* names = out.kind == GnssFileKind::kEnu ? names_enu : names_llh;
    SplitFields(trimmed, ',', &f);
    if (f.size() < 4) {
      throw Error(fmt::format("expected 'timestamp [ns], {}, {}, {}[, sigma]', found {} field(s)",
                              names[1], names[2], names[3], f.size()),
                  ctx);
    }
    GnssRecord r;
    r.line = cursor.line_number();
    ctx.field = "timestamp";
    r.t_ns = ParseInt64(f[0], ctx);
    bool finite = true;
    for (int k = 0; k < 3; ++k) {
      ctx.field = names[k + 1];
      if (IsNonFiniteToken(f[k + 1])) {
        finite = false;
        continue;
      }
      r.value[k] = ParseFiniteDouble(f[k + 1], ctx);
    }
    if (sigma_column >= 0 && sigma_column < static_cast<int>(f.size())) {
      ctx.field = "sigma";
      if (IsNonFiniteToken(f[sigma_column])) {
        finite = false;
      } else {
        const double s = ParseFiniteDouble(f[sigma_column], ctx);
        if (!(s > 0)) throw Error(fmt::format("sigma must be > 0, got {}", s), ctx);
        r.sigma_m = s;
      }
    }
    if (!out.records.empty() && r.t_ns <= out.records.back().t_ns) {
      ctx.field = "timestamp";
      throw Error(
          fmt::format("timestamp {} ns {} (previous {} ns at line {}): GNSS stamps must "
                      "increase strictly",
                      r.t_ns, r.t_ns == out.records.back().t_ns ? "is repeated" : "goes back",
                      out.records.back().t_ns, out.records.back().line),
          ctx);
    }
    if (!finite) {
      if (out.dropped_non_finite++ == 0) out.first_dropped_line = r.line;
      continue;
    }
    if (out.kind == GnssFileKind::kLatLonHeight) {
      if (std::abs(r.value[0]) > 90) {
        ctx.field = "latitude";
        throw Error(fmt::format("latitude {} outside [-90, 90]", r.value[0]), ctx);
      }
      if (std::abs(r.value[1]) > 180) {
        ctx.field = "longitude";
        throw Error(fmt::format("longitude {} outside [-180, 180]", r.value[1]), ctx);
      }
    }
    out.records.push_back(r);
  }
  if (out.dropped_non_finite > 0) {
    spdlog::warn("{}: dropped {} GNSS row(s) with non-finite values (first at line {})", path,
                 out.dropped_non_finite, out.first_dropped_line);
  }
  return out;
}

GnssSensorInfo ReadGnssSensorYaml(const std::string& path) {
  const YamlFile f = LoadYamlFile(path);
  GnssSensorInfo info;
  if (f.root["T_BS"]) {
    const std::vector<double> d = YamlGetNumbers(f, f.root, "T_BS", 16);
    info.lever_arm_in_body = Eigen::Vector3d(d[3], d[7], d[11]);
  }
  if (f.root["sigma_m"]) {
    const double s = YamlGet<double>(f, f.root, "sigma_m");
    if (!(s > 0) || !std::isfinite(s))
      throw Error(fmt::format("sigma_m must be > 0, got {}", s),
                  internal::YamlContext(f, f.root["sigma_m"], "sigma_m"));
    info.sigma_m = s;
  }
  if (f.root["origin_latitude_deg"] || f.root["origin_longitude_deg"]) {
    const double lat = YamlGet<double>(f, f.root, "origin_latitude_deg");
    const double lon = YamlGet<double>(f, f.root, "origin_longitude_deg");
    const double h = YamlGetOr<double>(f, f.root, "origin_height_m", 0.0);
    if (std::abs(lat) > 90 || std::abs(lon) > 180 || !std::isfinite(h))
      throw Error("origin out of range", {.file = path, .field = "origin_latitude_deg"});
    info.origin_lat_lon_height = Eigen::Vector3d(lat, lon, h);
  }
  return info;
}

}  // namespace optinav::io
