#include "optinav/report/map_plot.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "optinav/report/geo_export.h"
#include "optinav/util/testing.h"

namespace optinav::report {
namespace {

TEST(MapPlot, Base64MatchesKnownVectors) {
  auto b = [](const std::string& s) {
    return Base64(std::vector<unsigned char>(s.begin(), s.end()));
  };
  EXPECT_EQ(b(""), "");
  EXPECT_EQ(b("f"), "Zg==");
  EXPECT_EQ(b("fo"), "Zm8=");
  EXPECT_EQ(b("foo"), "Zm9v");
  EXPECT_EQ(b("foobar"), "Zm9vYmFy");
}

TEST(MapPlot, DrawsPathsOverTheBackgroundAndWritesPngAndSvg) {
  MapPlot p;
  p.background = cv::Mat(200, 300, CV_8U, cv::Scalar(128));
  p.title = "test & <plot>";
  p.notes = {"one note"};
  p.paths.push_back({"truth", {0, 160, 0}, {{10, 10}, {290, 190}}, 3});
  p.markers.push_back({"target", {220, 30, 30}, {150, 100}, '*'});
  const cv::Mat img = RenderMapPlotImage(p);
  ASSERT_EQ(img.cols, 300);
  ASSERT_GT(img.rows, 200);
  const int band = img.rows - 200;
  // The path's colour is on the diagonal, the background elsewhere.
  const cv::Vec3b on = img.at<cv::Vec3b>(band + 42, 60);  // (60, 42.1) is on the line
  const cv::Vec3b off = img.at<cv::Vec3b>(band + 180, 20);
  EXPECT_GT(on[1], 140);
  EXPECT_LT(on[0], 100);
  EXPECT_EQ(off, cv::Vec3b(128, 128, 128));
  const auto dir = testing::MakeTempDir("map_plot");
  WriteMapPlot((dir / "plot").string(), p);
  EXPECT_EQ(cv::imread((dir / "plot.png").string()).size(), img.size());
  const std::string svg = testing::ReadFile(dir / "plot.svg");
  EXPECT_NE(svg.find("data:image/png;base64,iVBOR"), std::string::npos);
  EXPECT_NE(svg.find("test &amp; &lt;plot&gt;"), std::string::npos);
  EXPECT_NE(svg.find("<polyline"), std::string::npos);
}

TEST(GeoExport, GeoJsonIsLonLatAndKmlHasAbgrColours) {
  const std::vector<GeoLine> lines = {
      {"true path", {{47.1, -97.2}, {47.2, -97.3}}, "#112233", {{"run", "3"}}}};
  const std::vector<GeoPoint> points = {{"target", {47.25, -97.35}}};
  const nlohmann::json j = nlohmann::json::parse(ToGeoJson(lines, points));
  EXPECT_EQ(j["type"], "FeatureCollection");
  ASSERT_EQ(j["features"].size(), 2u);
  EXPECT_EQ(j["features"][0]["geometry"]["type"], "LineString");
  EXPECT_DOUBLE_EQ(j["features"][0]["geometry"]["coordinates"][0][0].get<double>(), -97.2);
  EXPECT_DOUBLE_EQ(j["features"][0]["geometry"]["coordinates"][0][1].get<double>(), 47.1);
  EXPECT_EQ(j["features"][0]["properties"]["run"], "3");
  EXPECT_EQ(j["features"][1]["geometry"]["type"], "Point");
  const std::string kml = ToKml("mission", lines, points);
  EXPECT_NE(kml.find("<color>ff332211</color>"), std::string::npos);
  EXPECT_NE(kml.find("-97.20000000,47.10000000,0"), std::string::npos);
  EXPECT_NE(kml.find("<Point><coordinates>-97.35000000,47.25000000,0"), std::string::npos);
}

}  // namespace
}  // namespace optinav::report
