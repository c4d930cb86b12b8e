#include "optinav/app/map_build.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "optinav/geo/raster.h"
#include "optinav/util/error.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

bool IsVsi(const std::string& path) { return path.rfind("/vsi", 0) == 0; }

std::string Absolute(const std::string& path) {
  return IsVsi(path) ? path : fs::absolute(path).lexically_normal().string();
}

// Measured (bench/RESULTS.md, "Slurm", 2026-11-26): NAIP 2012 resampled to 1 m/px, 346 px tiles
// (300 m, 60 deg, 640 px frames), ORB, 279 features per tile: 5.0 ms of CPU per tile (read,
// extract, write). Planned with twice that, for sharper imagery that fills the 1,024 features.
constexpr double kCpuSecondsPerTile = 0.010;
constexpr double kTaskTargetS = 20 * 60;
constexpr double kTaskFeatureMb = 2000;  // features a task holds before it writes its part

// Bytes per feature held: keypoint (16) + descriptor, twice (the tile and the database's copy).
double FeatureBytes(features::FeatureType type) {
  return 2 * (16 + (type == features::FeatureType::kSift ? 512 : 64));
}

}  // namespace

std::vector<std::string> ReadOrthoList(const std::string& list_path) {
  std::ifstream in(list_path);
  if (!in) throw Error("cannot read the raster list", {.file = list_path});
  const fs::path base = fs::path(list_path).parent_path();
  std::vector<std::string> out;
  std::string line;
  for (int64_t n = 1; std::getline(in, line); ++n) {
    const size_t a = line.find_first_not_of(" \t\r");
    if (a == std::string::npos || line[a] == '#') continue;
    const size_t b = line.find_last_not_of(" \t\r");
    const std::string path = line.substr(a, b - a + 1);
    if (IsVsi(path) || fs::path(path).is_absolute()) {
      out.push_back(path);
    } else {
      out.push_back((base / path).lexically_normal().string());
    }
    if (!IsVsi(out.back()) && !fs::is_regular_file(out.back()))
      throw Error("raster not found: " + out.back(), {.file = list_path, .line = n});
  }
  if (out.empty()) throw Error("the raster list names no raster", {.file = list_path});
  return out;
}

std::string ResolveOrthoInputs(const std::vector<std::string>& orthos,
                               const std::string& ortho_list, const std::string& mosaic_path) {
  std::vector<std::string> inputs = orthos;
  if (!ortho_list.empty()) {
    const std::vector<std::string> listed = ReadOrthoList(ortho_list);
    inputs.insert(inputs.end(), listed.begin(), listed.end());
  }
  if (inputs.empty()) throw Error("give --ortho or --ortho-list", {.field = "--ortho"});
  if (inputs.size() == 1) return inputs[0];
  for (std::string& p : inputs) p = Absolute(p);  // the mosaic outlives the working folder
  geo::WriteMosaicVrt(inputs, mosaic_path);
  return mosaic_path;
}

int DefaultMapShards(const maploc::MapDatabase& grid) {
  const int threads = std::max(1, grid.options.threads);
  const double work_s = grid.tiles.size() * kCpuSecondsPerTile / threads;
  const double features_mb =
      grid.tiles.size() * grid.options.max_features * FeatureBytes(grid.feature_type) / 1e6;
  const double shards = std::max(work_s / kTaskTargetS, features_mb / kTaskFeatureMb);
  return std::clamp(static_cast<int>(std::ceil(shards)), 1,
                    std::min(1000, static_cast<int>(grid.tiles.size())));
}

SlurmResources MapBuildTaskResources(const maploc::MapDatabase& grid, int shards) {
  const int threads = std::max(1, grid.options.threads);
  const double tiles = std::ceil(static_cast<double>(grid.tiles.size()) / shards);
  // Features held until the part is written (FeatureBytes, at the max_features cap); each
  // thread's tile images; GDAL's block cache, capped at 256 MB by the script (GDAL_CACHEMAX).
  const double features_mb =
      tiles * grid.options.max_features * FeatureBytes(grid.feature_type) / 1e6;
  const double tile_side = grid.tile_px * grid.map_gsd_m / grid.feature_gsd_m;
  const double images_mb =
      threads * 8 * grid.tile_px * grid.tile_px / 1e6 + threads * 4 * tile_side * tile_side / 1e6;
  SlurmResources r;
  r.cpus_per_task = threads;
  r.mem_mb = static_cast<int>(std::ceil((2 * (400 + images_mb) + features_mb + 256) / 64) * 64);
  r.time_min =
      std::max(10, static_cast<int>(std::ceil(3 * tiles * kCpuSecondsPerTile / threads / 60)));
  r.derivation = fmt::format(
      "{} CPUs (--threads); memory 2 x (400 MB + {:.0f} MB tile images) + {:.0f} MB features of "
      "{:.0f} tiles + 256 MB GDAL cache; time 3 x {:.0f} tiles x {} CPU-s / {} threads, 10 min at "
      "least",
      threads, images_mb, features_mb, tiles, tiles, kCpuSecondsPerTile, threads);
  return r;
}

SlurmPlan WriteMapBuildPlan(const MapBuildPlanOptions& o) {
  if (o.out.empty()) throw Error("the map needs a path", {.field = "--out"});
  if (o.shards < 0) throw Error("must be >= 1 (0: derived)", {.field = "--shards"});
  SlurmPlan p;
  p.kind = "map build";
  p.dir = Absolute(o.plan_dir.empty() ? o.out + ".slurm" : o.plan_dir);
  fs::create_directories(p.dir);
  p.job_name = "optinav-map";
  const std::string ortho = Absolute(
      ResolveOrthoInputs(o.orthos, o.ortho_list, (fs::path(p.dir) / "ortho.vrt").string()));
  const maploc::MapDatabase grid = maploc::PlanMapDatabase(ortho, o.build);
  const int shards = o.shards > 0 ? o.shards : DefaultMapShards(grid);
  if (shards > static_cast<int>(grid.tiles.size()))
    throw Error(fmt::format("{} shards for {} tiles: at most one shard per tile", shards,
                            grid.tiles.size()),
                {.field = "--shards"});
  const maploc::MapBuildOptions& b = o.build;
  const std::string parts = (fs::path(p.dir) / "parts").string();
  fs::create_directories(parts);
  p.args = {"--ortho",        ortho,
            "--altitude",     fmt::format("{}", b.altitude_m),
            "--hfov",         fmt::format("{}", b.hfov_deg),
            "--frame-size",   fmt::format("{}x{}", b.frame_width, b.frame_height),
            "--scale-factor", fmt::format("{}", b.scale_factor),
            "--overlap",      fmt::format("{}", b.overlap),
            "--features",     features::FeatureTypeName(b.feature_type),
            "--max-features", std::to_string(b.max_features),
            "--threads",      std::to_string(b.threads)};
  p.task_command = {SelfExecutable(), "map", "build"};
  p.task_command.insert(p.task_command.end(), p.args.begin(), p.args.end());
  p.task_command.insert(p.task_command.end(),
                        {"--shard", fmt::format("{{task}}/{}", shards), "--out",
                         (fs::path(parts) / "part_{task}.db").string()});
  p.merge_command = {SelfExecutable(), "map",          "merge", "--plan-dir", p.dir,
                     "--out",          Absolute(o.out)};
  for (int i = 0; i < shards; ++i) {
    const auto [first, last] =
        maploc::ShardTileRange(static_cast<int>(grid.tiles.size()), {i, shards});
    p.tasks.push_back({fmt::format("shard {}/{}: tiles {}-{}", i, shards, first, last - 1),
                       {(fs::path(parts) / fmt::format("part_{}.db", i)).string()}});
  }
  p.task_resources = MapBuildTaskResources(grid, shards);
  // The merge holds the whole map's features once (and SQLite's pages): 2 x the features.
  const double all_mb = 2.0 * grid.tiles.size() * b.max_features *
                        (16 + (b.feature_type == features::FeatureType::kSift ? 512 : 64)) / 1e6;
  p.merge_resources = {1, static_cast<int>(std::ceil((1024 + all_mb) / 64) * 64),
                       std::max(30, static_cast<int>(std::ceil(grid.tiles.size() / 2000.0))),
                       "1 CPU; memory 1 GB + twice the map's features; time 30 min or 1 min "
                       "per 2,000 tiles"};
  p.env = {"GDAL_CACHEMAX=256"};
  p.slurm_args = o.slurm_args;
  WriteSlurmPlan(p);
  return p;
}

std::vector<std::string> PlannedMapParts(const std::string& plan_dir) {
  const std::optional<SlurmPlan> plan = ReadSlurmPlan(plan_dir);
  if (!plan || plan->kind != "map build")
    throw Error("holds no map build plan (plan.json; made by `map build --plan slurm`)",
                {.file = plan_dir, .field = "--plan-dir"});
  ThrowIfUnfinished(*plan);
  std::vector<std::string> parts;
  for (const PlannedTask& t : plan->tasks) parts.push_back(t.outputs.at(0));
  return parts;
}

}  // namespace optinav::app
