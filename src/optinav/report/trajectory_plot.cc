#include "optinav/report/trajectory_plot.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "optinav/io/text_parse.h"
#include "optinav/report/svg.h"

namespace optinav::report {
namespace {

constexpr double kWidth = 1100, kHeight = 560;
constexpr size_t kMaxDrawn = 4000;

struct Box {
  double x, y, w, h;
};

// Axis frame with ticks and labels mapping [x0,x1]x[y0,y1] into `box` (y up).
struct Axes {
  Box box;
  double x0, x1, y0, y1;
  double X(double v) const { return box.x + (v - x0) / (x1 - x0) * box.w; }
  double Y(double v) const { return box.y + box.h - (v - y0) / (y1 - y0) * box.h; }

  void Draw(SvgDocument* svg, const std::string& xlabel, const std::string& ylabel) const {
    svg->Rect(box.x, box.y, box.w, box.h, "none", "#444");
    const Ticks tx = NiceTicks(x0, x1, 6), ty = NiceTicks(y0, y1, 6);
    for (int i = 0; i < tx.count; ++i) {
      const double v = tx.start + i * tx.step;
      svg->Line(X(v), box.y, X(v), box.y + box.h, "#e4e4e4", 1);
      svg->Text(X(v), box.y + box.h + 16, FormatTick(v, tx.step), 11, "middle");
    }
    for (int i = 0; i < ty.count; ++i) {
      const double v = ty.start + i * ty.step;
      svg->Line(box.x, Y(v), box.x + box.w, Y(v), "#e4e4e4", 1);
      svg->Text(box.x - 6, Y(v) + 4, FormatTick(v, ty.step), 11, "end");
    }
    svg->Text(box.x + box.w / 2, box.y + box.h + 34, xlabel, 12, "middle");
    svg->Text(
        box.x - 52, box.y + box.h / 2, ylabel, 12, "middle",
        fmt::format("transform=\"rotate(-90 {:.1f} {:.1f})\"", box.x - 52, box.y + box.h / 2));
  }
};

std::pair<int, int> PlaneAxes(const std::string& plane) {
  if (plane == "xy") return {0, 1};
  if (plane == "xz") return {0, 2};
  if (plane == "yz") return {1, 2};
  throw Error("unknown plot plane '" + plane + "' (xy, xz or yz)", {.field = "--plot-plane"});
}

}  // namespace

std::string RenderErrorPlotSvg(const ErrorPlotInput& in) {
  OPTINAV_CHECK(in.ref && in.est && in.series && in.ref->size() == in.est->size());
  const auto [ax, ay] = PlaneAxes(in.plane);
  const Trajectory& ref = *in.ref;
  const Trajectory& est = *in.est;
  const eval::ErrorSeries& s = *in.series;
  SvgDocument svg(kWidth, kHeight);
  svg.Text(kWidth / 2, 24, in.title, 16, "middle", "font-weight=\"bold\"");
  svg.Text(kWidth / 2, 44, in.subtitle, 12, "middle", "fill=\"#555\"");

  // --- Top view, equal aspect ratio.
  double lo[2] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  double hi[2] = {-lo[0], -lo[1]};
  for (const Trajectory* t : {&ref, &est}) {
    for (const auto& p : t->positions) {
      lo[0] = std::min(lo[0], p[ax]);
      hi[0] = std::max(hi[0], p[ax]);
      lo[1] = std::min(lo[1], p[ay]);
      hi[1] = std::max(hi[1], p[ay]);
    }
  }
  const Box map_box{80, 70, 420, 400};
  double span = std::max({hi[0] - lo[0], (hi[1] - lo[1]) * map_box.w / map_box.h, 1e-6});
  span *= 1.08;
  const double cx = 0.5 * (lo[0] + hi[0]), cy = 0.5 * (lo[1] + hi[1]);
  const double span_y = span * map_box.h / map_box.w;
  const Axes map{map_box, cx - span / 2, cx + span / 2, cy - span_y / 2, cy + span_y / 2};
  const char* names = "xyz";
  map.Draw(&svg, fmt::format("{} (m)", names[ax]), fmt::format("{} (m)", names[ay]));

  const size_t n = ref.size();
  const size_t step = std::max<size_t>(1, (n + kMaxDrawn - 1) / kMaxDrawn);
  std::string pts;
  for (size_t i = 0; i < n; i += step) {
    pts += fmt::format("{:.1f},{:.1f} ", map.X(ref.positions[i][ax]), map.Y(ref.positions[i][ay]));
  }
  svg.Polyline(pts, "#555", 1.5, "stroke-dasharray=\"5,3\"");

  const double emin = s.stats.min, emax = s.stats.max;
  const double erange = emax > emin ? emax - emin : 1.0;
  const size_t m = s.errors.size();
  const size_t estep = std::max<size_t>(1, (m + kMaxDrawn - 1) / kMaxDrawn);
  for (size_t k = estep; k < m; k += estep) {
    const auto& a = est.positions[s.indices[k - estep]];
    const auto& b = est.positions[s.indices[k]];
    svg.Line(map.X(a[ax]), map.Y(a[ay]), map.X(b[ax]), map.Y(b[ay]),
             ColorMap((s.errors[k] - emin) / erange).Hex(), 2.2, "stroke-linecap=\"round\"");
  }
  if (m == 1) {
    const auto& a = est.positions[s.indices[0]];
    svg.Circle(map.X(a[ax]), map.Y(a[ay]), 3, ColorMap(0.5).Hex());
  }
  svg.Circle(map.X(ref.positions[0][ax]), map.Y(ref.positions[0][ay]), 4, "none", "#000");
  // Legend and colour bar.
  const double ly = map_box.y + map_box.h + 52;
  svg.Line(map_box.x, ly, map_box.x + 26, ly, "#555", 1.5, "stroke-dasharray=\"5,3\"");
  svg.Text(map_box.x + 32, ly + 4, "reference", 11);
  svg.Text(map_box.x + 100, ly + 4, "estimate (colour = error)", 11);
  svg.Circle(map_box.x + 255, ly, 4, "none", "#000");
  svg.Text(map_box.x + 263, ly + 4, "start", 11);
  const double bx = map_box.x + 310, bw = 110;
  for (int i = 0; i < 50; ++i) {
    svg.Rect(bx + i * bw / 50, ly - 6, bw / 50 + 0.3, 10, ColorMap(i / 49.0).Hex());
  }
  svg.Text(bx, ly + 17, fmt::format("{:.3g}", emin), 10, "middle");
  svg.Text(bx + bw, ly + 17, fmt::format("{:.3g} {}", emax, in.unit), 10, "middle");

  // --- Error over time (or pose index).
  const bool timed = est.has_timestamps();
  std::vector<double> xs(m);
  for (size_t k = 0; k < m; ++k) {
    xs[k] =
        timed ? (est.t_ns[s.indices[k]] - est.t_ns[0]) * 1e-9 : static_cast<double>(s.indices[k]);
  }
  const double x_max = std::max(xs.back(), xs.front() + 1e-9);
  const Axes err{
      {600, 70, 460, 400}, std::min(0.0, xs.front()), x_max, 0.0, std::max(emax * 1.08, 1e-12)};
  err.Draw(&svg, timed ? "time (s)" : "pose index",
           in.unit.empty() ? "error" : fmt::format("error ({})", in.unit));
  pts.clear();
  for (size_t k = 0; k < m; k += estep) {
    pts += fmt::format("{:.1f},{:.1f} ", err.X(xs[k]), err.Y(s.errors[k]));
  }
  if (m > 1) {
    pts += fmt::format("{:.1f},{:.1f}", err.X(xs[m - 1]), err.Y(s.errors[m - 1]));
  }
  svg.Polyline(pts, "#1f5fa8", 1.3);
  struct Ref {
    const char* name;
    double value;
    const char* colour;
  };
  double label_y = err.box.y + 14;
  for (const Ref& r : {Ref{"rmse", s.stats.rmse, "#c0392b"}, Ref{"mean", s.stats.mean, "#27ae60"},
                       Ref{"median", s.stats.median, "#8e44ad"}}) {
    svg.Line(err.box.x, err.Y(r.value), err.box.x + err.box.w, err.Y(r.value), r.colour, 1.2,
             "stroke-dasharray=\"6,3\"");
    svg.Text(err.box.x + err.box.w - 6, label_y, fmt::format("{} {:.4g}", r.name, r.value), 11,
             "end", fmt::format("fill=\"{}\"", r.colour));
    label_y += 15;
  }
  return svg.Finish();
}

void WriteErrorPlotSvg(const std::string& path, const ErrorPlotInput& input) {
  io::WriteFileAtomically(path, RenderErrorPlotSvg(input));
}

}  // namespace optinav::report
