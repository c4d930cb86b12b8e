#include "optinav/report/html_report.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>

#include <fmt/format.h>

#include "optinav/io/text_parse.h"
#include "optinav/report/map_plot.h"
#include "optinav/report/svg.h"
#include "optinav/util/error.h"
#include "optinav/util/statistics.h"

#ifndef OPTINAV_LEAFLET_DIR_DEFAULT
#define OPTINAV_LEAFLET_DIR_DEFAULT ""
#endif

namespace optinav::report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Rounded so the document stays small: 1e-7 deg is 1 cm, 1e-3 m is 1 mm.
double Round(double v, double unit) { return std::isfinite(v) ? std::round(v / unit) * unit : v; }

json Number(double v, double unit) {
  return std::isfinite(v) ? json(Round(v, unit)) : json(nullptr);
}

json PointsJson(const std::vector<Eigen::Vector2d>& pts, double unit) {
  json a = json::array();
  for (const Eigen::Vector2d& p : pts) a.push_back({Round(p.x(), unit), Round(p.y(), unit)});
  return a;
}

double Unit(const std::string& frame) { return frame == "wgs84" ? 1e-7 : 1e-3; }

// Reads a member with the field path in the error ("views[0].paths[3].points").
class Reader {
 public:
  Reader(const std::string& file) : file_(file) {}

  const json& At(const json& j, const std::string& key, const std::string& path) const {
    if (!j.is_object() || !j.contains(key)) Fail(Join(path, key), "missing");
    return j.at(key);
  }
  std::string String(const json& j, const std::string& key, const std::string& path,
                     const std::string& fallback = "\x01") const {
    if (fallback != "\x01" && (!j.contains(key) || j.at(key).is_null())) return fallback;
    const json& v = At(j, key, path);
    if (!v.is_string()) Fail(Join(path, key), "expected a string");
    return v.get<std::string>();
  }
  double Double(const json& j, const std::string& key, const std::string& path,
                std::optional<double> fallback = std::nullopt) const {
    if (fallback && (!j.contains(key))) return *fallback;
    const json& v = At(j, key, path);
    if (v.is_null()) return NAN;
    if (!v.is_number()) Fail(Join(path, key), "expected a number");
    return v.get<double>();
  }
  bool Bool(const json& j, const std::string& key, const std::string& path, bool fallback) const {
    if (!j.contains(key)) return fallback;
    if (!j.at(key).is_boolean()) Fail(Join(path, key), "expected true or false");
    return j.at(key).get<bool>();
  }
  const json& Array(const json& j, const std::string& key, const std::string& path,
                    bool optional = true) const {
    static const json kEmpty = json::array();
    if (optional && !j.contains(key)) return kEmpty;
    const json& v = At(j, key, path);
    if (!v.is_array()) Fail(Join(path, key), "expected an array");
    return v;
  }
  Eigen::Vector2d Point(const json& v, const std::string& path) const {
    if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
      Fail(path, "expected a point [a, b]");
    return {v[0].get<double>(), v[1].get<double>()};
  }
  std::vector<double> Doubles(const json& j, const std::string& key,
                              const std::string& path) const {
    std::vector<double> out;
    const json& a = Array(j, key, path, false);
    for (size_t i = 0; i < a.size(); ++i) {
      if (a[i].is_null()) {
        out.push_back(NAN);
      } else if (a[i].is_number()) {
        out.push_back(a[i].get<double>());
      } else {
        Fail(fmt::format("{}[{}]", Join(path, key), i), "expected a number");
      }
    }
    return out;
  }
  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  [[noreturn]] void Fail(const std::string& field, const std::string& what) const {
    throw Error(what, {.file = file_, .field = field});
  }

 private:
  std::string file_;
};

json ChartJson(const ReportChart& c) {
  json series = json::array();
  for (const ReportSeries& s : c.series) {
    json x = json::array(), y = json::array();
    for (double v : s.x) x.push_back(Number(v, 1e-3));
    for (double v : s.y) y.push_back(Number(v, 1e-3));
    series.push_back(
        {{"name", s.name}, {"colour", s.colour_hex}, {"dots", s.dots}, {"x", x}, {"y", y}});
  }
  return {{"title", c.title}, {"x_label", c.x_label}, {"y_label", c.y_label}, {"series", series}};
}

ReportChart ChartFromJson(const json& j, const std::string& path, const Reader& r) {
  ReportChart c;
  c.title = r.String(j, "title", path, "");
  c.x_label = r.String(j, "x_label", path, "");
  c.y_label = r.String(j, "y_label", path, "");
  const json& series = r.Array(j, "series", path);
  for (size_t i = 0; i < series.size(); ++i) {
    const std::string p = fmt::format("{}.series[{}]", path, i);
    ReportSeries s;
    s.name = r.String(series[i], "name", p, "");
    s.colour_hex = r.String(series[i], "colour", p, "#000000");
    s.dots = r.Bool(series[i], "dots", p, false);
    s.x = r.Doubles(series[i], "x", p);
    s.y = r.Doubles(series[i], "y", p);
    if (s.x.size() != s.y.size()) r.Fail(p + ".y", "x and y differ in length");
    c.series.push_back(std::move(s));
  }
  return c;
}

// Text inside <script>: "</script" (any case) would end the element. It can only stand in a
// string, a regular expression or a comment there, where "<\/" means the same.
std::string ScriptSafe(std::string s) {
  for (size_t k = 0; (k = s.find("</", k)) != std::string::npos; k += 3) {
    std::string tag = s.substr(k + 2, 6);
    std::transform(tag.begin(), tag.end(), tag.begin(), ::tolower);
    if (tag == "script") s.replace(k, 2, "<\\/");
  }
  return s;
}

std::string MimeOf(const std::string& file) {
  std::string ext = fs::path(file).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  throw Error("the report's map image must be .png or .jpg", {.file = file});
}

std::string DataUri(const std::string& path, const std::string& mime) {
  const std::string bytes = io::ReadFileToString(path);
  return "data:" + mime + ";base64," +
         Base64(std::vector<unsigned char>(bytes.begin(), bytes.end()));
}

// The colour of a fix: the project's colour map over [0, scale].
std::string FixColour(double error_m, double scale_m) {
  if (!std::isfinite(error_m)) return "#888888";
  return ColorMap(error_m / scale_m).Hex();
}

double FixScale(const ReportView& v) {
  if (v.fix_error_scale_m > 0) return v.fix_error_scale_m;
  std::vector<double> e;
  for (const ReportFix& f : v.fixes)
    if (std::isfinite(f.error_m)) e.push_back(f.error_m);
  if (e.empty()) return 1.0;
  const double p95 = ComputeStatistics(e).p95;
  return p95 > 0 ? p95 : 1.0;
}

// A path as both the page and ReportToJson give it.
json PathJson(const ReportPath& p, double unit) {
  return {{"layer", p.layer}, {"name", p.name},     {"colour", p.colour_hex},
          {"width", p.width}, {"dashed", p.dashed}, {"points", PointsJson(p.points, unit)}};
}

// What the page's script draws, with the image inlined and the fix colours resolved.
json ViewPageJson(const ReportView& v, const std::string& base_dir) {
  const double unit = Unit(v.frame);
  json j = {{"name", v.name}, {"frame", v.frame}};
  if (v.image) {
    const std::string path = (fs::path(base_dir) / v.image->file).string();
    if (!fs::is_regular_file(path))
      throw Error("the report's map image is missing", {.file = path});
    j["image"] = {{"url", DataUri(path, MimeOf(path))},
                  {"bounds", PointsJson({v.image->min, v.image->max}, unit)}};
  }
  json paths = json::array();
  for (const ReportPath& p : v.paths) paths.push_back(PathJson(p, unit));
  const double scale = FixScale(v);
  json fixes = json::array();
  for (const ReportFix& f : v.fixes)
    fixes.push_back({{"layer", f.layer},
                     {"name", f.name},
                     {"p", PointsJson({f.point}, unit)[0]},
                     {"t", Number(f.t_s, 1e-3)},
                     {"e", Number(f.error_m, 1e-2)},
                     {"m", f.method},
                     {"n", f.inliers},
                     {"a", f.accepted},
                     {"note", f.note},
                     {"c", FixColour(f.error_m, scale)}});
  json markers = json::array();
  for (const ReportMarker& m : v.markers)
    markers.push_back({{"layer", m.layer},
                       {"label", m.label},
                       {"kind", m.kind},
                       {"p", PointsJson({m.point}, unit)[0]}});
  j["hidden_layers"] = v.hidden_layers;
  j["paths"] = paths;
  j["fixes"] = fixes;
  j["markers"] = markers;
  j["fix_scale_m"] = scale;
  j["fix_scale_colours"] = json::array();
  for (int k = 0; k <= 10; ++k) j["fix_scale_colours"].push_back(ColorMap(k / 10.0).Hex());
  return j;
}

std::string TableHtml(const ReportTable& t) {
  std::string s = "<h3>" + XmlEscape(t.title) + "</h3>\n<table class=\"summary\">\n<tr>";
  for (const std::string& h : t.header) s += "<th>" + XmlEscape(h) + "</th>";
  s += "</tr>\n";
  for (const auto& row : t.rows) {
    s += "<tr>";
    for (const std::string& c : row) s += "<td>" + XmlEscape(c) + "</td>";
    s += "</tr>\n";
  }
  return s + "</table>\n";
}

// Leaflet's style sheet refers to images/*.png (layer icon, markers): inlined so nothing is
// loaded from disk or the network.
std::string InlineCssImages(const std::string& css, const fs::path& dir) {
  static const std::regex kUrl(R"(url\((images/[A-Za-z0-9_.-]+\.png)\))");
  std::string out;
  std::sregex_iterator it(css.begin(), css.end(), kUrl), end;
  size_t last = 0;
  for (; it != end; ++it) {
    out += css.substr(last, it->position() - last);
    const fs::path image = dir / (*it)[1].str();
    out += fs::is_regular_file(image) ? "url(" + DataUri(image.string(), "image/png") + ")"
                                      : std::string("none");
    last = it->position() + it->length();
  }
  return out + css.substr(last);
}

// The page's script: builds one Leaflet map per view from the embedded data, then records what
// it drew in #report-status (read by the browser test); script errors are recorded there too.
constexpr const char* kPageScript = R"JS(
(function () {
  'use strict';
  var D = JSON.parse(document.getElementById('report-data').textContent);
  var status = document.getElementById('report-status');
  var counts = {maps: 0, paths: 0, fixes: 0, markers: 0};
  function esc(s) {
    return String(s).replace(/[&<>"]/g, function (c) {
      return {'&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;'}[c];
    });
  }
  function fmt(v, d) { return v === null || v === undefined ? 'n/a' : Number(v).toFixed(d); }
  // Not in the fix colour map: start blue, target black, end of a missed run white.
  var markerColour = {start: '#1e5adc', target: '#111111', end: '#ffffff'};
  D.views.forEach(function (v, i) {
    var geo = v.frame === 'wgs84';
    var map = L.map('map-' + i, {
      crs: geo ? L.CRS.EPSG3857 : L.CRS.Simple, zoomSnap: 0.25,
      minZoom: geo ? 1 : -12, maxZoom: geo ? 22 : 8, attributionControl: false});
    var bounds = L.latLngBounds([]);
    var base = {}, overlays = {};
    var plain = L.layerGroup();
    if (v.image) {
      var img = L.imageOverlay(v.image.url, v.image.bounds, {className: 'optinav-image'});
      base['orthophoto'] = img;
      base['plain background'] = plain;
      img.addTo(map);
      bounds.extend(v.image.bounds);
    } else {
      base[geo ? 'plain background (no map)' : 'plain background (local frame, m)'] = plain;
      plain.addTo(map);
    }
    function group(name) {
      if (!overlays[name]) {
        overlays[name] = L.featureGroup();
        if (v.hidden_layers.indexOf(name) < 0) overlays[name].addTo(map);
      }
      return overlays[name];
    }
    v.paths.forEach(function (p) {
      if (p.points.length === 0) return;
      var line = L.polyline(p.points, {color: p.colour, weight: p.width, opacity: 0.9,
        dashArray: p.dashed ? '6 4' : null, className: 'optinav-path'});
      line.bindPopup(esc(p.name)).addTo(group(p.layer));
      bounds.extend(line.getBounds());
      counts.paths++;
    });
    v.fixes.forEach(function (f) {
      var r = v.fixes.length > 1000 ? 3 : 4;
      var dot = L.circleMarker(f.p, {radius: f.a ? r : r - 1, color: f.a ? '#222' : '#c00',
        weight: f.a ? 0.6 : 1.2, fillColor: f.c, fillOpacity: 0.9, className: 'optinav-fix'});
      dot.bindPopup('<b>' + esc(f.name) + '</b><br>time ' + fmt(f.t, 1) + ' s<br>error ' +
        fmt(f.e, 2) + ' m<br>method ' + esc(f.m) +
        (f.n >= 0 ? '<br>inliers ' + f.n : '') + '<br>' + (f.a ? 'accepted' : 'rejected') +
        (f.note ? '<br>' + esc(f.note) : ''));
      dot.addTo(group(f.layer));
      bounds.extend(f.p);
      counts.fixes++;
    });
    v.markers.forEach(function (m) {
      var c = markerColour[m.kind] || '#000';
      var mk = L.circleMarker(m.p, {radius: m.kind === 'target' ? 9 : 7,
        color: m.kind === 'end' ? '#111' : '#fff', weight: 2,
        fillColor: c, fillOpacity: 1, className: 'optinav-marker optinav-' + m.kind});
      mk.bindPopup(esc(m.label));
      if (m.label) mk.bindTooltip(esc(m.label), {direction: 'right', offset: [8, 0]});
      mk.addTo(group(m.layer));
      bounds.extend(m.p);
      counts.markers++;
    });
    L.control.layers(base, overlays, {collapsed: false}).addTo(map);
    L.control.scale({imperial: false}).addTo(map);
    if (v.fixes.length > 0) {
      var legend = L.control({position: 'bottomright'});
      legend.onAdd = function () {
        var div = L.DomUtil.create('div', 'optinav-legend');
        div.innerHTML = 'fix error (m)<div class="ramp" style="background:linear-gradient(to right,' +
          v.fix_scale_colours.join(',') + ')"></div><span>0</span><span style="float:right">&ge; ' +
          fmt(v.fix_scale_m, 1) + '</span>';
        return div;
      };
      legend.addTo(map);
    }
    if (bounds.isValid()) map.fitBounds(bounds.pad(0.05)); else map.setView([0, 0], 0);
    counts.maps++;
  });
  status.setAttribute('data-maps', counts.maps);
  status.setAttribute('data-paths', counts.paths);
  status.setAttribute('data-fixes', counts.fixes);
  status.setAttribute('data-markers', counts.markers);
  status.setAttribute('data-state', 'ready');
})();
)JS";

constexpr const char* kPageStyle = R"CSS(
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; margin: 12px 20px; color: #222; }
h1 { font-size: 20px; margin: 4px 0; } h2 { font-size: 17px; margin: 18px 0 6px; }
h3 { font-size: 14px; margin: 12px 0 4px; } p.note { margin: 2px 0; font-size: 13px; }
.map { height: 620px; border: 1px solid #999; background: #f4f4f0; }
.chart svg { max-width: 100%; height: auto; }
table.summary { border-collapse: collapse; font-size: 12px; margin-bottom: 8px; }
table.summary td, table.summary th { border: 1px solid #ccc; padding: 2px 7px; text-align: right; }
table.summary th { background: #eee; } table.summary td:first-child { text-align: left; }
pre.settings { font-size: 12px; background: #f6f6f6; padding: 8px; overflow: auto; }
.optinav-legend { background: #fff; padding: 4px 8px; font-size: 12px; width: 150px;
  border-radius: 4px; box-shadow: 0 0 4px rgba(0,0,0,.3); }
.optinav-legend .ramp { height: 10px; margin: 3px 0; }
#report-status { display: none; }
)CSS";

// Records script errors before anything else runs (read by the browser test).
constexpr const char* kErrorHook = R"JS(
window.addEventListener('error', function (e) {
  var s = document.getElementById('report-status');
  if (!s) return;
  s.setAttribute('data-errors', Number(s.getAttribute('data-errors') || 0) + 1);
  s.textContent += 'error: ' + e.message + '\n';
});
)JS";

}  // namespace

nlohmann::json ReportToJson(const ReportDocument& doc) {
  json views = json::array();
  for (const ReportView& v : doc.views) {
    const double unit = Unit(v.frame);
    json paths = json::array(), fixes = json::array(), markers = json::array();
    for (const ReportPath& p : v.paths) paths.push_back(PathJson(p, unit));
    for (const ReportFix& f : v.fixes)
      fixes.push_back({{"layer", f.layer},
                       {"name", f.name},
                       {"point", PointsJson({f.point}, unit)[0]},
                       {"t_s", Number(f.t_s, 1e-3)},
                       {"error_m", Number(f.error_m, 1e-3)},
                       {"method", f.method},
                       {"inliers", f.inliers},
                       {"accepted", f.accepted},
                       {"note", f.note}});
    for (const ReportMarker& m : v.markers)
      markers.push_back({{"layer", m.layer},
                         {"label", m.label},
                         {"kind", m.kind},
                         {"point", PointsJson({m.point}, unit)[0]}});
    json jv = {{"name", v.name},
               {"frame", v.frame},
               {"paths", paths},
               {"fixes", fixes},
               {"markers", markers},
               {"fix_error_scale_m", v.fix_error_scale_m},
               {"hidden_layers", v.hidden_layers}};
    if (v.image)
      jv["image"] = {{"file", v.image->file},
                     {"bounds", PointsJson({v.image->min, v.image->max}, unit)}};
    if (v.chart) jv["chart"] = ChartJson(*v.chart);
    views.push_back(jv);
  }
  json tables = json::array();
  for (const ReportTable& t : doc.tables)
    tables.push_back({{"title", t.title}, {"header", t.header}, {"rows", t.rows}});
  return {{"format", "optinav-report"}, {"version", 1},       {"kind", doc.kind},
          {"title", doc.title},         {"notes", doc.notes}, {"views", views},
          {"tables", tables},           {"text", doc.text},   {"settings", doc.settings}};
}

ReportDocument ReportFromJson(const nlohmann::json& j, const std::string& file) {
  const Reader r(file);
  if (r.String(j, "format", "") != "optinav-report")
    r.Fail("format", "not an optinav report document (expected \"optinav-report\")");
  if (r.Double(j, "version", "") != 1) r.Fail("version", "unsupported version (expected 1)");
  ReportDocument doc;
  doc.kind = r.String(j, "kind", "");
  doc.title = r.String(j, "title", "", "");
  for (const json& n : r.Array(j, "notes", ""))
    doc.notes.push_back(n.is_string() ? n.get<std::string>() : n.dump());
  const json& views = r.Array(j, "views", "", false);
  for (size_t i = 0; i < views.size(); ++i) {
    const json& jv = views[i];
    const std::string vp = fmt::format("views[{}]", i);
    ReportView v;
    v.name = r.String(jv, "name", vp, "");
    v.frame = r.String(jv, "frame", vp, "wgs84");
    if (v.frame != "wgs84" && v.frame != "local") r.Fail(vp + ".frame", "expected wgs84|local");
    v.fix_error_scale_m = r.Double(jv, "fix_error_scale_m", vp, 0.0);
    for (const json& h : r.Array(jv, "hidden_layers", vp)) {
      if (!h.is_string()) r.Fail(vp + ".hidden_layers", "expected layer names");
      v.hidden_layers.push_back(h.get<std::string>());
    }
    if (jv.contains("image")) {
      const json& im = jv.at("image");
      ReportImage image;
      image.file = r.String(im, "file", vp + ".image");
      const json& b = r.Array(im, "bounds", vp + ".image", false);
      if (b.size() != 2) r.Fail(vp + ".image.bounds", "expected [[s, w], [n, e]]");
      image.min = r.Point(b[0], vp + ".image.bounds[0]");
      image.max = r.Point(b[1], vp + ".image.bounds[1]");
      v.image = image;
    }
    const json& paths = r.Array(jv, "paths", vp);
    for (size_t k = 0; k < paths.size(); ++k) {
      const std::string p = fmt::format("{}.paths[{}]", vp, k);
      ReportPath path;
      path.layer = r.String(paths[k], "layer", p, "paths");
      path.name = r.String(paths[k], "name", p, "");
      path.colour_hex = r.String(paths[k], "colour", p, "#ff0000");
      path.width = r.Double(paths[k], "width", p, 2.0);
      path.dashed = r.Bool(paths[k], "dashed", p, false);
      const json& pts = r.Array(paths[k], "points", p, false);
      for (size_t q = 0; q < pts.size(); ++q)
        path.points.push_back(r.Point(pts[q], fmt::format("{}.points[{}]", p, q)));
      v.paths.push_back(std::move(path));
    }
    const json& fixes = r.Array(jv, "fixes", vp);
    for (size_t k = 0; k < fixes.size(); ++k) {
      const std::string p = fmt::format("{}.fixes[{}]", vp, k);
      const json& jf = fixes[k];
      ReportFix f;
      f.layer = r.String(jf, "layer", p, "fixes");
      f.name = r.String(jf, "name", p, "");
      f.point = r.Point(r.At(jf, "point", p), p + ".point");
      f.t_s = r.Double(jf, "t_s", p);
      f.error_m = r.Double(jf, "error_m", p);
      f.method = r.String(jf, "method", p, "");
      f.inliers = static_cast<int>(r.Double(jf, "inliers", p, -1.0));
      f.accepted = r.Bool(jf, "accepted", p, true);
      f.note = r.String(jf, "note", p, "");
      v.fixes.push_back(std::move(f));
    }
    const json& markers = r.Array(jv, "markers", vp);
    for (size_t k = 0; k < markers.size(); ++k) {
      const std::string p = fmt::format("{}.markers[{}]", vp, k);
      ReportMarker m;
      m.layer = r.String(markers[k], "layer", p, "start / target");
      m.label = r.String(markers[k], "label", p, "");
      m.kind = r.String(markers[k], "kind", p, "start");
      m.point = r.Point(r.At(markers[k], "point", p), p + ".point");
      v.markers.push_back(std::move(m));
    }
    if (jv.contains("chart")) v.chart = ChartFromJson(jv.at("chart"), vp + ".chart", r);
    doc.views.push_back(std::move(v));
  }
  const json& tables = r.Array(j, "tables", "");
  for (size_t i = 0; i < tables.size(); ++i) {
    const std::string p = fmt::format("tables[{}]", i);
    ReportTable t;
    t.title = r.String(tables[i], "title", p, "");
    try {
      t.header = tables[i].value("header", std::vector<std::string>{});
      t.rows = tables[i].value("rows", std::vector<std::vector<std::string>>{});
    } catch (const json::exception&) {
      r.Fail(p, "header and rows must hold strings");
    }
    doc.tables.push_back(std::move(t));
  }
  doc.text = r.String(j, "text", "", "");
  if (j.contains("settings")) doc.settings = j.at("settings");
  return doc;
}

void WriteReportDocument(const std::string& path, const ReportDocument& doc) {
  io::WriteFileAtomically(path, ReportToJson(doc).dump() + "\n");
}

ReportDocument ReadReportDocument(const std::string& path) {
  const std::string text = io::ReadFileToString(path);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    throw Error(std::string("not valid JSON: ") + e.what(), {.file = path});
  }
  return ReportFromJson(j, path);
}

std::string LeafletDir() {
  if (const char* env = std::getenv("OPTINAV_LEAFLET_DIR"); env && *env) return env;
  return OPTINAV_LEAFLET_DIR_DEFAULT;
}

LeafletAssets LoadLeafletAssets() {
  const fs::path dir = LeafletDir();
  const fs::path js = dir / "leaflet.js", css = dir / "leaflet.css";
  if (dir.empty() || !fs::is_regular_file(js) || !fs::is_regular_file(css)) {
    throw Error(
        "the vendored Leaflet is missing (leaflet.js, leaflet.css); build the project (cmake "
        "--build build runs scripts/vendor_leaflet.sh build/third_party/leaflet, which needs npm), "
        "or run scripts/vendor_leaflet.sh DIR and set OPTINAV_LEAFLET_DIR=DIR",
        {.file = dir.empty() ? std::string("(no folder configured)") : dir.string()});
  }
  LeafletAssets a;
  a.js = io::ReadFileToString(js.string());
  a.css = InlineCssImages(io::ReadFileToString(css.string()), dir);
  if (fs::is_regular_file(dir / "VERSION")) {
    a.version = io::ReadFileToString((dir / "VERSION").string());
    while (!a.version.empty() && std::isspace(static_cast<unsigned char>(a.version.back())))
      a.version.pop_back();
  }
  return a;
}

std::string RenderChartSvg(const ReportChart& c, int width, int height) {
  constexpr double kLeft = 60, kRight = 16, kTop = 44, kBottom = 36;  // title, legend: 2 lines
  double x0 = INFINITY, x1 = -INFINITY, y1 = 0;
  for (const ReportSeries& s : c.series)
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, s.x[i]);
      x1 = std::max(x1, s.x[i]);
      y1 = std::max(y1, s.y[i]);
    }
  if (!std::isfinite(x0)) x0 = 0, x1 = 1;
  if (!(x1 > x0)) x1 = x0 + 1;
  // A few wrong fixes (kilometres off) would flatten everything else: the axis ends at 1.5x the
  // 98th percentile, and what lies above is pinned to the top.
  std::vector<double> ys;
  for (const ReportSeries& s : c.series)
    for (double y : s.y)
      if (std::isfinite(y)) ys.push_back(y);
  bool pinned = false;
  if (!ys.empty()) {
    const double cap = 1.5 * Quantile(ys, 0.98);
    if (cap > 0 && cap < y1) y1 = cap, pinned = true;
  }
  if (!(y1 > 0)) y1 = 1;
  const Ticks xt = NiceTicks(x0, x1, 8), yt = NiceTicks(0, y1, 5);
  y1 = std::max(y1, yt.start + yt.step * (yt.count - 1));
  const double pw = width - kLeft - kRight, ph = height - kTop - kBottom;
  const auto X = [&](double x) { return kLeft + (x - x0) / (x1 - x0) * pw; };
  const auto Y = [&](double y) { return kTop + ph - y / y1 * ph; };
  SvgDocument svg(width, height);
  for (int k = 0; k < yt.count; ++k) {
    const double v = yt.start + k * yt.step;
    svg.Line(X(x0), Y(v), X(x1), Y(v), "#dddddd", 1);
    svg.Text(X(x0) - 6, Y(v) + 4, FormatTick(v, yt.step), 11, "end");
  }
  for (int k = 0; k < xt.count; ++k) {
    const double v = xt.start + k * xt.step;
    svg.Line(X(v), Y(0), X(v), Y(0) + 4, "#000000", 1);
    svg.Text(X(v), Y(0) + 16, FormatTick(v, xt.step), 11, "middle");
  }
  svg.Line(X(x0), Y(0), X(x1), Y(0), "#000000", 1);
  svg.Line(X(x0), Y(0), X(x0), Y(y1), "#000000", 1);
  svg.Text(kLeft, 16, c.title, 13, "start", "font-weight=\"bold\"");
  svg.Text(14, kTop + ph / 2, c.y_label, 11, "middle",
           fmt::format("transform=\"rotate(-90 14 {:.1f})\"", kTop + ph / 2));
  svg.Text(kLeft + pw / 2, height - 4, c.x_label, 11, "middle");
  if (pinned)
    svg.Text(kLeft + 6, kTop + 12,
             fmt::format("values above {} pinned to the top", FormatTick(y1, yt.step)), 10, "start",
             "fill=\"#666666\"");
  double lx = width - kRight;  // legend, right-aligned on the line under the title
  for (auto it = c.series.rbegin(); it != c.series.rend(); ++it) {
    if (it->name.empty()) continue;
    lx -= 34 + 6.5 * it->name.size();
    svg.Line(lx, 28, lx + 20, 28, it->colour_hex, it->dots ? 5 : 2);
    svg.Text(lx + 24, 32, it->name, 11);
  }
  for (const ReportSeries& s : c.series) {
    const std::string title =
        s.name.empty() ? "" : fmt::format("<title>{}</title>", XmlEscape(s.name));
    if (s.dots) {
      std::string dots;
      for (size_t i = 0; i < s.x.size(); ++i)
        if (std::isfinite(s.x[i]) && std::isfinite(s.y[i]))
          dots += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"2\"/>", X(s.x[i]),
                              Y(std::min(s.y[i], y1)));
      svg.Raw(fmt::format("<g fill=\"{}\">{}{}</g>", s.colour_hex, title, dots));
      continue;
    }
    std::string pts;
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      pts += fmt::format("{:.1f},{:.1f} ", X(s.x[i]), Y(std::min(s.y[i], y1)));
    }
    svg.Raw(
        fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.3\" "
                    "stroke-linejoin=\"round\">{}</polyline>",
                    pts, s.colour_hex, title));
  }
  return svg.Finish();
}

std::string RenderHtmlReport(const ReportDocument& doc, const LeafletAssets& leaflet,
                             const std::string& base_dir) {
  json page = {{"views", json::array()}};
  for (const ReportView& v : doc.views) page["views"].push_back(ViewPageJson(v, base_dir));
  std::string body;
  body += "<h1>" + XmlEscape(doc.title) + "</h1>\n";
  for (const std::string& n : doc.notes) body += "<p class=\"note\">" + XmlEscape(n) + "</p>\n";
  for (size_t i = 0; i < doc.views.size(); ++i) {
    const ReportView& v = doc.views[i];
    if (!v.name.empty()) body += "<h2>" + XmlEscape(v.name) + "</h2>\n";
    body += fmt::format("<div class=\"map\" id=\"map-{}\"></div>\n", i);
    if (v.chart && !v.chart->series.empty()) {
      std::string svg = RenderChartSvg(*v.chart, 1100, 260);
      svg.erase(0, svg.find("<svg"));  // inline: no XML declaration
      body += "<div class=\"chart\">" + svg + "</div>\n";
    }
  }
  if (!doc.tables.empty()) body += "<h2>Summary</h2>\n";
  for (const ReportTable& t : doc.tables) body += TableHtml(t);
  if (!doc.text.empty()) body += "<pre class=\"settings\">" + XmlEscape(doc.text) + "</pre>\n";
  body += "<h2>Run settings</h2>\n<pre class=\"settings\">" + XmlEscape(doc.settings.dump(2)) +
          "</pre>\n";
  body += fmt::format(
      "<p class=\"note\">Made by optinav ({}); map by Leaflet {} (BSD-2-Clause), inlined: this "
      "file needs no network.</p>\n",
      XmlEscape(doc.kind), XmlEscape(leaflet.version));
  return fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      "<title>{}</title>\n<script>{}</script>\n<style>\n{}\n</style>\n<style>{}</style>\n"
      "</head>\n<body>\n<div id=\"report-status\" data-state=\"loading\" data-errors=\"0\"></div>\n"
      "{}<script type=\"application/json\" id=\"report-data\">{}</script>\n"
      "<script>\n{}\n</script>\n<script>{}</script>\n</body>\n</html>\n",
      XmlEscape(doc.title), kErrorHook, leaflet.css, kPageStyle, body, ScriptSafe(page.dump()),
      ScriptSafe(leaflet.js), kPageScript);
}

}  // namespace optinav::report
