#include "optinav/io/waypoints.h"

#include <fmt/format.h>

#include "optinav/io/text_parse.h"

namespace optinav::io {

std::vector<WaypointRow> ReadWaypointsFile(const std::string& path) {
  const std::string text = ReadFileToString(path);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  std::vector<WaypointRow> out;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = path, .line = cursor.line_number()};
    SplitFields(line, line.find(',') != std::string_view::npos ? ',' : ' ', &f);
    if (f.size() != 3 && f.size() != 4) {
      throw Error(fmt::format("expected 'x, y, altitude[, yaw_deg]', found {} fields", f.size()),
                  ctx);
    }
    WaypointRow w;
    ctx.field = "x";
    w.x_m = ParseFiniteDouble(f[0], ctx);
    ctx.field = "y";
    w.y_m = ParseFiniteDouble(f[1], ctx);
    ctx.field = "altitude";
    w.altitude_m = ParseFiniteDouble(f[2], ctx);
    if (f.size() == 4) {
      ctx.field = "yaw_deg";
      w.yaw_deg = ParseFiniteDouble(f[3], ctx);
    }
    out.push_back(w);
  }
  if (out.size() < 2) throw Error("a drone route needs at least 2 waypoints", {.file = path});
  return out;
}

}  // namespace optinav::io
