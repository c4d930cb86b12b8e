// Sharded map builds (map build --shard I/N) joined by MergeMapParts: the same map as one build.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>

#include "optinav/maploc/frame_synth.h"
#include "optinav/maploc/locator.h"
#include "optinav/maploc/map_db.h"
#include "optinav/maploc/test_maps.h"
#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::maploc {
namespace {

void ExpectSameTiles(const MapDatabase& a, const MapDatabase& b) {
  ASSERT_EQ(a.tiles.size(), b.tiles.size());
  EXPECT_EQ(a.rows, b.rows);
  EXPECT_EQ(a.cols, b.cols);
  EXPECT_EQ(a.ortho_path, b.ortho_path);
  EXPECT_EQ(a.transform.c, b.transform.c);
  for (size_t i = 0; i < a.tiles.size(); ++i) {
    SCOPED_TRACE(i);
    const MapTile& x = a.tiles[i];
    const MapTile& y = b.tiles[i];
    EXPECT_EQ(x.index, y.index);
    EXPECT_EQ(x.px, y.px);
    EXPECT_EQ(x.centre_crs, y.centre_crs);
    ASSERT_EQ(x.keypoints, y.keypoints);
    EXPECT_EQ(x.keypoint_size, y.keypoint_size);
    EXPECT_EQ(x.keypoint_angle, y.keypoint_angle);
    ASSERT_EQ(x.descriptors.size(), y.descriptors.size());
    EXPECT_EQ(cv::norm(x.descriptors, y.descriptors, cv::NORM_INF), 0.0);
  }
}

TEST(ShardParse, IOfN) {
  EXPECT_EQ(ParseMapShard("3/4").index, 3);
  EXPECT_EQ(ParseMapShard("0/1").count, 1);
  EXPECT_ERROR(ParseMapShard("4/4"), {.field = "--shard"}, "is not I/N with 0 <= I < N");
  EXPECT_ERROR(ParseMapShard("1-4"), {.field = "--shard"}, "is not I/N");
  EXPECT_ERROR(ParseMapShard("1/4x"), {.field = "--shard"}, "is not I/N");
  // Shards cover the grid once, in order, as evenly as whole tiles allow.
  int next = 0;
  for (int i = 0; i < 4; ++i) {
    const auto [first, last] = ShardTileRange(35, {i, 4});
    EXPECT_EQ(first, next);
    EXPECT_GE(last - first, 8);
    next = last;
  }
  EXPECT_EQ(next, 35);
}

// NAIP 2009 (934 x 724 px, 35 tiles) built whole and as 4 shards: the merged map has the same
// tiles and features (the same file, byte for byte), passes --check, and locates frames from 2012
// exactly as the whole map does.
TEST(ShardedBuild, FourShardsMergeIntoTheSameMap) {
  const fs::path dir = testing::MakeTempDir("map_shards");
  testmaps::BuildNaip2009Map(dir);
  // As stored (a tile's width is read back as px1 - px0).
  const MapDatabase whole = LoadMapDatabase((dir / "naip2009_orb.db").string());
  MapBuildOptions o = whole.options;
  o.threads = 2;
  std::vector<std::string> parts;
  for (int i = 0; i < 4; ++i) {
    parts.push_back((dir / ("part_" + std::to_string(i) + ".db")).string());
    const MapDatabase part = BuildMapDatabase(testmaps::Naip("20090818"), o, parts.back(), {i, 4});
    const auto [first, last] = ShardTileRange(35, {i, 4});
    ASSERT_EQ(part.tiles.size(), static_cast<size_t>(last - first));
    EXPECT_EQ(part.tiles.front().index, first);
  }
  ASSERT_EQ(whole.tiles.size(), 35u);
  // A part is no map.
  EXPECT_ERROR(LoadMapDatabase(parts[1]), {.file = "part_1.db", .field = "shard"},
               "is part 1/4 of a sharded build, not a map; join the parts with `optinav map "
               "merge`");
  // Every shard once: missing, twice, another split.
  const std::string out = (dir / "merged.db").string();
  EXPECT_ERROR(MergeMapParts({parts[0], parts[1], parts[3]}, out), {.field = "PARTS"},
               "shards missing: 2/4");
  EXPECT_ERROR(MergeMapParts({parts[0], parts[1], parts[1], parts[3]}, out),
               {.file = "part_1.db", .field = "shard"}, "shard 1/4 is given twice");
  const std::string other = (dir / "other_0.db").string();
  BuildMapDatabase(testmaps::Naip("20090818"), o, other, {0, 3});
  EXPECT_ERROR(MergeMapParts({parts[0], other}, out), {.file = "other_0.db", .field = "shard"},
               "of another split");
  MapBuildOptions sift = o;
  sift.max_features = 500;
  const std::string other_build = (dir / "other_build_2.db").string();
  BuildMapDatabase(testmaps::Naip("20090818"), sift, other_build, {2, 4});
  EXPECT_ERROR(MergeMapParts({parts[0], parts[1], other_build, parts[3]}, out),
               {.file = "other_build_2.db", .field = "build_options"}, "another build");
  EXPECT_FALSE(fs::exists(out));

  // Any order.
  const MapMergeSummary merged = MergeMapParts({parts[2], parts[0], parts[3], parts[1]}, out);
  EXPECT_EQ(merged.tiles, 35u);
  EXPECT_EQ(merged.features, whole.FeatureCount());
  const MapCheckReport check = CheckMapDatabase(out);
  ExpectSameTiles(whole, check.db);
  EXPECT_EQ(check.features, whole.FeatureCount());
  EXPECT_EQ(testing::ReadFile(out), testing::ReadFile(dir / "naip2009_orb.db"));

  // locate: the same fixes from either map (frames cut from 2012, prior within 200 m).
  const geo::GeoRaster flight = geo::GeoRaster::Open(testmaps::Naip("20120731"));
  Locator a(whole), b(check.db);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u01(0, 1);
  int localized = 0;
  for (int i = 0; i < 8; ++i) {
    FrameSpec s;
    s.width = s.height = 256;
    s.gsd_m = 5.0;
    s.heading_deg = 360 * u01(rng);
    s.centre_px = {182 + (flight.width() - 364) * u01(rng),
                   182 + (flight.height() - 364) * u01(rng)};
    const cv::Mat frame = SynthesizeFrame(flight, 5.0, s);
    Prior prior;
    const Eigen::Vector2d near = flight.transform().PixelToCrs(s.centre_px) +
                                 Eigen::Vector2d(120 * u01(rng), -90 * u01(rng));
    prior.position = geo::CrsTransform(whole.crs_wkt).ToLatLon(near);
    prior.radius_m = 250;
    const LocateResult ra = a.Locate(frame, prior), rb = b.Locate(frame, prior);
    SCOPED_TRACE(i);
    EXPECT_EQ(ra.localized, rb.localized);
    EXPECT_EQ(ra.method, rb.method);
    EXPECT_EQ(ra.crs_xy, rb.crs_xy);
    EXPECT_EQ(ra.heading_deg, rb.heading_deg);
    EXPECT_EQ(ra.inliers, rb.inliers);
    localized += ra.localized;
  }
  std::printf("4 shards merged: %zu tiles, %zu features, %d/8 frames located identically\n",
              merged.tiles, merged.features, localized);
  EXPECT_GE(localized, 6);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace optinav::maploc
