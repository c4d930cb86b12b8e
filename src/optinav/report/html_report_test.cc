#include "optinav/report/html_report.h"

#include <cmath>
#include <cstdlib>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/report/map_overlay.h"
#include "optinav/util/testing.h"

namespace optinav::report {
namespace {

namespace fs = std::filesystem;

ReportDocument SampleDocument() {
  ReportDocument d;
  d.kind = "mission";
  d.title = "two runs </script> & more";
  d.notes = {"a note"};
  ReportView v;
  v.name = "map";
  v.image = ReportImage{"map.jpg", {47.0, -99.2}, {47.1, -99.1}};
  v.paths.push_back({"true paths",
                     "true path 1",
                     "#14a03c",
                     2.5,
                     false,
                     {{47.01, -99.15}, {47.02, -99.14}, {47.03, -99.13}}});
  v.paths.push_back({"estimated paths",
                     "estimated path 1",
                     "#e66e14",
                     1.5,
                     true,
                     {{47.011, -99.151}, {47.021, -99.141}}});
  v.fixes.push_back({"fixes", "run 1", {47.02, -99.14}, 12.5, 3.25, "features", 57, true, ""});
  v.fixes.push_back(
      {"fixes", "run 1", {47.03, -99.13}, 13.5, NAN, "orientation-correlation", -1, false, "gate"});
  v.markers.push_back({"start / target", "start 1", "start", {47.01, -99.15}});
  v.markers.push_back({"start / target", "target 1", "target", {47.03, -99.13}});
  v.chart = ReportChart{"error over time",
                        "time (s)",
                        "error (m)",
                        {{"estimate", "#e66e14", {0, 1, 2}, {1, 2, 1.5}, false},
                         {"fixes", "#c828c8", {1, 2}, {3.25, NAN}, true}}};
  d.views.push_back(v);
  d.tables.push_back({"runs", {"run", "reached"}, {{"1", "yes"}}});
  d.settings = {{"speed_m_s", 20}};
  return d;
}

TEST(HtmlReport, DocumentRoundTripsThroughJson) {
  const fs::path dir = testing::MakeTempDir("html_report");
  const std::string path = (dir / "report.json").string();
  WriteReportDocument(path, SampleDocument());
  const ReportDocument d = ReadReportDocument(path);
  EXPECT_EQ(d.kind, "mission");
  EXPECT_EQ(d.title, "two runs </script> & more");
  ASSERT_EQ(d.views.size(), 1u);
  const ReportView& v = d.views[0];
  ASSERT_TRUE(v.image);
  EXPECT_EQ(v.image->file, "map.jpg");
  EXPECT_DOUBLE_EQ(v.image->max.y(), -99.1);
  ASSERT_EQ(v.paths.size(), 2u);
  EXPECT_EQ(v.paths[1].points.size(), 2u);
  EXPECT_TRUE(v.paths[1].dashed);
  EXPECT_NEAR(v.paths[0].points[2].x(), 47.03, 1e-9);
  ASSERT_EQ(v.fixes.size(), 2u);
  EXPECT_EQ(v.fixes[0].inliers, 57);
  EXPECT_DOUBLE_EQ(v.fixes[0].error_m, 3.25);
  EXPECT_TRUE(std::isnan(v.fixes[1].error_m));
  EXPECT_FALSE(v.fixes[1].accepted);
  EXPECT_EQ(v.fixes[1].note, "gate");
  ASSERT_EQ(v.markers.size(), 2u);
  EXPECT_EQ(v.markers[1].kind, "target");
  ASSERT_TRUE(v.chart);
  ASSERT_EQ(v.chart->series.size(), 2u);
  EXPECT_TRUE(std::isnan(v.chart->series[1].y[1]));
  ASSERT_EQ(d.tables.size(), 1u);
  EXPECT_EQ(d.tables[0].rows[0][1], "yes");
  EXPECT_EQ(d.settings.at("speed_m_s"), 20);
}

TEST(HtmlReport, BadDocumentsNameTheFileAndField) {
  const fs::path dir = testing::MakeTempDir("html_report_bad");
  const std::string not_json = testing::WriteFile(dir / "a.json", "{\"format\": ");
  EXPECT_ERROR(ReadReportDocument(not_json), {.file = "a.json"}, "not valid JSON");
  const std::string no_kind =
      testing::WriteFile(dir / "k.json", "{\"format\": \"optinav-report\", \"version\": 1}");
  EXPECT_ERROR(ReadReportDocument(no_kind), {.file = "k.json", .field = "kind"}, "missing");
  const std::string other = testing::WriteFile(dir / "b.json", "{\"format\": \"x\"}");
  EXPECT_ERROR(ReadReportDocument(other), {.file = "b.json", .field = "format"},
               "not an optinav report");
  nlohmann::json j = ReportToJson(SampleDocument());
  j["views"][0]["paths"][0]["points"][1] = {1.0};
  EXPECT_ERROR(ReportFromJson(j, "c.json"),
               {.file = "c.json", .field = "views[0].paths[0].points[1]"}, "expected a point");
  j = ReportToJson(SampleDocument());
  j["views"][0]["fixes"][0]["t_s"] = "soon";
  EXPECT_ERROR(ReportFromJson(j, "d.json"), {.file = "d.json", .field = "views[0].fixes[0].t_s"},
               "expected a number");
}

TEST(HtmlReport, MissingLeafletSaysWhatToRun) {
  const fs::path dir = testing::MakeTempDir("no_leaflet");
  ASSERT_EQ(setenv("OPTINAV_LEAFLET_DIR", dir.c_str(), 1), 0);
  EXPECT_ERROR(LoadLeafletAssets(), {.file = dir.string()}, "scripts/vendor_leaflet.sh");
  unsetenv("OPTINAV_LEAFLET_DIR");
}

TEST(HtmlReport, PageInlinesLeafletTheImageAndTheData) {
  const fs::path dir = testing::MakeTempDir("html_page");
  // A stand-in Leaflet: this test checks the inlining; the browser test (report/browser) loads
  // the real library.
  const fs::path lf = dir / "leaflet";
  testing::WriteFile(lf / "leaflet.js", "var L = {marker: '</script>'};");
  testing::WriteFile(lf / "leaflet.css", ".x{background-image:url(images/layers.png)}");
  fs::create_directories(lf / "images");
  ASSERT_TRUE(cv::imwrite((lf / "images" / "layers.png").string(),
                          cv::Mat(2, 2, CV_8UC3, cv::Scalar(1, 2, 3))));
  testing::WriteFile(lf / "VERSION", "1.9.4\n");
  ASSERT_EQ(setenv("OPTINAV_LEAFLET_DIR", lf.c_str(), 1), 0);
  const LeafletAssets a = LoadLeafletAssets();
  unsetenv("OPTINAV_LEAFLET_DIR");
  EXPECT_EQ(a.version, "1.9.4");
  EXPECT_NE(a.css.find("url(data:image/png;base64,"), std::string::npos);
  EXPECT_EQ(a.css.find("images/layers.png"), std::string::npos);

  const ReportDocument doc = SampleDocument();
  EXPECT_ERROR(RenderHtmlReport(doc, a, dir.string()), {.file = "map.jpg"}, "missing");
  WriteJpeg((dir / "map.jpg").string(), cv::Mat(8, 8, CV_8U, cv::Scalar(100)));
  const std::string html = RenderHtmlReport(doc, a, dir.string());
  EXPECT_NE(html.find("data:image/jpeg;base64,"), std::string::npos);
  EXPECT_NE(html.find("var L = {marker: '<\\/script>'};"), std::string::npos);
  // The title is escaped in the page and in the data, so no element ends early.
  EXPECT_NE(html.find("two runs &lt;/script&gt; &amp; more"), std::string::npos);
  EXPECT_EQ(html.find("two runs </script>"), std::string::npos);
  EXPECT_NE(html.find("id=\"map-0\""), std::string::npos);
  EXPECT_NE(html.find("<svg"), std::string::npos);   // the chart, inline
  EXPECT_EQ(html.find("<?xml"), std::string::npos);  // without the XML declaration
  EXPECT_EQ(html.find("http://"), html.find("http://www.w3.org/2000/svg"));  // nothing fetched
  EXPECT_EQ(html.find("https://"), std::string::npos);
}

TEST(HtmlReport, ChartScalesToTheData) {
  const ReportChart c{"t", "time (s)", "error (m)", {{"e", "#ff0000", {0, 10}, {0, 4}, false}}};
  const std::string svg = RenderChartSvg(c, 400, 200);
  // Left end at the axis origin (x = 60, y = 200 - 36), right end at the top-right of the plot.
  EXPECT_NE(svg.find("points=\"60.0,164.0 384.0,44.0 \""), std::string::npos) << svg;
}

// A picture in UTM zone 14N, 2 m pixels, rotated grid-north-up: the Mercator image's pixel at a
// lat/lon shows the picture's pixel at the same lat/lon.
TEST(MapOverlay, MercatorImageKeepsEveryPointInPlace) {
  const geo::CrsTransform utm("EPSG:32614");
  const Eigen::Vector2d origin(486000, 5208000);  // top-left corner, near 47.0 N, -99.2
  const double gsd = 2.0;
  cv::Mat picture(500, 600, CV_8U);
  for (int y = 0; y < picture.rows; ++y)
    for (int x = 0; x < picture.cols; ++x)
      picture.at<uchar>(y, x) = static_cast<uchar>((x / 25 + y / 25) % 2 ? 200 : 40);
  const auto to_px = [&](const geo::LatLon& ll) {
    const Eigen::Vector2d xy = utm.FromLatLon(ll);
    return Eigen::Vector2d((xy.x() - origin.x()) / gsd, (origin.y() - xy.y()) / gsd);
  };
  const auto to_ll = [&](const Eigen::Vector2d& px) {
    return utm.ToLatLon({origin.x() + px.x() * gsd, origin.y() - px.y() * gsd});
  };
  const MercatorImage m = ToMercatorImage(picture, to_px, to_ll, 400);
  ASSERT_LE(std::max(m.image.cols, m.image.rows), 400);
  EXPECT_LT(m.south_west.lat_deg, m.north_east.lat_deg);
  const auto merc_y = [](double lat) { return std::log(std::tan(M_PI / 4 + lat * M_PI / 360)); };
  int checked = 0;
  for (int k = 0; k < 40; ++k) {
    // Square centres: away from the edges between squares, where resampling blurs.
    const Eigen::Vector2d px(25 * (2 + k % 20) + 12.5, 25 * (2 + (k * 7) % 16) + 12.5);
    const geo::LatLon ll = to_ll(px);
    const double u = (ll.lon_deg - m.south_west.lon_deg) /
                     (m.north_east.lon_deg - m.south_west.lon_deg) * m.image.cols;
    const double v = (merc_y(m.north_east.lat_deg) - merc_y(ll.lat_deg)) /
                     (merc_y(m.north_east.lat_deg) - merc_y(m.south_west.lat_deg)) * m.image.rows;
    const int got = m.image.at<uchar>(static_cast<int>(v), static_cast<int>(u));
    EXPECT_NEAR(got, picture.at<uchar>(static_cast<int>(px.y()), static_cast<int>(px.x())), 40)
        << "at picture px " << px.transpose();
    ++checked;
  }
  EXPECT_EQ(checked, 40);
}

}  // namespace
}  // namespace optinav::report
