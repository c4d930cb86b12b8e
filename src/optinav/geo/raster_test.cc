#include "optinav/geo/raster.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/util/testing.h"

namespace optinav::geo {
namespace {

std::string Geo(const std::string& name) {
  return (testing::SharedDataDir() / "geo" / name).string();
}

TEST(GeoRaster, OpensLandsatUtm) {
  const GeoRaster r = GeoRaster::Open(Geo("RGB.byte.tif"));
  EXPECT_EQ(r.width(), 791);
  EXPECT_EQ(r.height(), 718);
  EXPECT_EQ(r.band_count(), 3);
  EXPECT_EQ(r.data_type(), "Byte");
  ASSERT_TRUE(r.nodata().has_value());
  EXPECT_EQ(*r.nodata(), 0.0);
  // gdalinfo: Origin = (101985, 2826915), Pixel Size = (300.0379..., -300.0417...)
  EXPECT_DOUBLE_EQ(r.transform().c[0], 101985.0);
  EXPECT_NEAR(r.transform().c[1], 300.037926675094809, 1e-9);
  const CrsTransform t(r.crs_wkt());
  EXPECT_EQ(t.name(), "WGS 84 / UTM zone 18N");
  // Lower-right corner pixel (791, 718) -> (339315, 2611485).
  const Eigen::Vector2d lr = r.transform().PixelToCrs({791, 718});
  EXPECT_NEAR(lr.x(), 339315.0, 1e-3);
  EXPECT_NEAR(lr.y(), 2611485.0, 1e-3);
  cv::Mat valid;
  const cv::Mat g = r.ReadGray(-10, -10, 100, 100, 0, 0, &valid);
  EXPECT_EQ(g.size(), cv::Size(100, 100));
  EXPECT_EQ(valid.at<uint8_t>(5, 5), 0);   // outside the raster
  EXPECT_EQ(valid.at<uint8_t>(50, 5), 0);  // left of x = 0
  EXPECT_EQ(cv::countNonZero(valid(cv::Rect(10, 10, 90, 90)) > 0) +
                cv::countNonZero(valid(cv::Rect(10, 10, 90, 90)) == 0),
            90 * 90);
}

TEST(GeoRaster, FourBandNaipAndWindowDownsampling) {
  const GeoRaster r = GeoRaster::Open(Geo("naip/naip_20090818.tif"));
  EXPECT_EQ(r.band_count(), 4);
  EXPECT_EQ(r.width(), 934);
  const cv::Mat full = r.ReadGray(100, 100, 256, 256);
  const cv::Mat half = r.ReadGray(100, 100, 256, 256, 128, 128);
  EXPECT_EQ(half.size(), cv::Size(128, 128));
  cv::Mat down;
  cv::resize(full, down, {128, 128}, 0, 0, cv::INTER_AREA);
  EXPECT_LT(cv::norm(down, half, cv::NORM_L1) / (128.0 * 128.0), 3.0);
  EXPECT_GT(cv::mean(full)[0], 20.0);
}

TEST(GeoRaster, Float64GeographicRaster) {
  const GeoRaster r = GeoRaster::Open(Geo("epsg4326_float64.tif"));
  EXPECT_EQ(r.data_type(), "Float64");
  EXPECT_TRUE(CrsTransform(r.crs_wkt()).is_geographic());
  const cv::Mat g = r.ReadGray(0, 0, r.width(), r.height());
  double lo, hi;
  cv::minMaxLoc(g, &lo, &hi);
  EXPECT_GT(hi, lo);  // stretched into 8 bits
}

TEST(GeoRaster, WritesAndReadsBackEpsg3857WithRotation) {
  const auto dir = testing::MakeTempDir("geotiff");
  cv::Mat img = cv::imread((testing::SharedDataDir() / "images" / "aero1.jpg").string());
  ASSERT_FALSE(img.empty());
  GeoTransform gt;
  gt.c = {-11020000.0, 0.25, 0.02, 5930000.0, 0.02, -0.25};
  const std::string path = (dir / "aero1_3857.tif").string();
  WriteGeoTiff(path, img, gt, "EPSG:3857", {.build_overviews = true});
  const GeoRaster r = GeoRaster::Open(path);
  EXPECT_EQ(r.band_count(), 3);
  EXPECT_EQ(r.overview_count(), 4);
  EXPECT_EQ(r.transform().c, gt.c);
  EXPECT_EQ(CrsTransform(r.crs_wkt()).name(), "WGS 84 / Pseudo-Mercator");
  cv::Mat gray;
  cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
  const cv::Mat back = r.ReadGray(0, 0, img.cols, img.rows);
  EXPECT_LT(cv::norm(gray, back, cv::NORM_INF), 2.0);
}

// Two halves of an image as separate GeoTIFFs, joined by a VRT mosaic: read by window, the
// mosaic gives the pixels of the whole image; a raster in another CRS is refused.
TEST(GeoRaster, MosaicOfTwoHalvesReadsAsTheWhole) {
  const auto dir = testing::MakeTempDir("mosaic");
  const cv::Mat img = cv::imread((testing::SharedDataDir() / "images" / "aero1.jpg").string());
  ASSERT_FALSE(img.empty());
  GeoTransform gt;
  gt.c = {500000.0, 0.25, 0.0, 5560000.0, 0.0, -0.25};
  const int half = img.cols / 2;
  GeoTransform right = gt;
  right.c[0] += half * 0.25;
  WriteGeoTiff((dir / "whole.tif").string(), img, gt, "EPSG:32633");
  WriteGeoTiff((dir / "left.tif").string(), img.colRange(0, half).clone(), gt, "EPSG:32633");
  WriteGeoTiff((dir / "right.tif").string(), img.colRange(half, img.cols).clone(), right,
               "EPSG:32633");
  const std::string vrt = (dir / "mosaic.vrt").string();
  WriteMosaicVrt({(dir / "left.tif").string(), (dir / "right.tif").string()}, vrt);
  const GeoRaster whole = GeoRaster::Open((dir / "whole.tif").string());
  const GeoRaster mosaic = GeoRaster::Open(vrt);
  EXPECT_EQ(mosaic.width(), img.cols);
  EXPECT_EQ(mosaic.height(), img.rows);
  EXPECT_EQ(mosaic.transform().c, gt.c);
  // A window across the seam, and one past the edge.
  for (const cv::Rect w : {cv::Rect(half - 100, 50, 200, 150), cv::Rect(img.cols - 64, 0, 128, 64)})
    EXPECT_EQ(cv::norm(whole.ReadGray(w.x, w.y, w.width, w.height),
                       mosaic.ReadGray(w.x, w.y, w.width, w.height), cv::NORM_INF),
              0.0);
  WriteGeoTiff((dir / "other_crs.tif").string(), img, gt, "EPSG:32632");
  EXPECT_ERROR(WriteMosaicVrt({(dir / "left.tif").string(), (dir / "other_crs.tif").string()},
                              (dir / "bad.vrt").string()),
               {.file = "other_crs.tif"}, "is in another CRS than");
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.vrt"));
  std::filesystem::remove_all(dir);
}

TEST(GeoRaster, BadFilesAreClearErrors) {
  const auto dir = testing::MakeTempDir("badtiff");
  // A plain TIFF without georeference.
  const std::string plain = (dir / "plain.tif").string();
  cv::imwrite(plain, cv::Mat(32, 32, CV_8UC1, cv::Scalar(7)));
  try {
    GeoRaster::Open(plain);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("georeference"), std::string::npos) << e.what();
    EXPECT_EQ(e.context().file, plain);
  }
  // A truncated GeoTIFF.
  const std::string whole = (dir / "whole.tif").string();
  GeoTransform gt;
  gt.c = {500000, 1, 0, 5000000, 0, -1};
  cv::Mat noise(512, 512, CV_8UC1);
  cv::randu(noise, 0, 255);
  WriteGeoTiff(whole, noise, gt, "EPSG:32614", {.tiled = true, .compress = "NONE"});
  const std::string cut = (dir / "cut.tif").string();
  {
    std::ifstream in(whole, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(cut, std::ios::binary).write(bytes.data(), bytes.size() / 3);
  }
  EXPECT_ERROR(GeoRaster::Open(cut).ReadGray(0, 0, 512, 512), {.file = cut},
               "read failed (truncated or corrupt file?)");
  EXPECT_ERROR(GeoRaster::Open((dir / "missing.tif").string()), {.file = "missing.tif"},
               "raster file not found");
  const std::string junk = testing::WriteFile(dir / "junk.tif", "this is not a tiff");
  EXPECT_ERROR(GeoRaster::Open(junk), {.file = junk}, "cannot open as a raster");
  EXPECT_ERROR(WriteGeoTiff((dir / "x.tif").string(), noise, gt, "EPSG:999999"), {.file = "x.tif"},
               "unknown CRS 'EPSG:999999'");
}

}  // namespace
}  // namespace optinav::geo
