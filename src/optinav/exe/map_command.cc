// optinav map build | info | locate | render: orthophoto feature databases, frame-to-map fixes
// and synthetic frames to try them on.
#include <cstdio>
#include <optional>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "optinav/app/map_build.h"
#include "optinav/app/map_info.h"
#include "optinav/app/map_locate.h"
#include "optinav/app/map_render.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/util/timer.h"

namespace optinav {
namespace {

struct BuildFlags {
  std::vector<std::string> orthos;
  std::string ortho_list, out, frame_size = "640x480", features = "orb";
  std::string shard, plan, plan_dir, slurm_args;
  int shards = 0;
  maploc::MapBuildOptions options;
};

void AddBuild(CLI::App& app, BuildFlags& f) {
  maploc::MapBuildOptions& o = f.options;
  app.add_option("--ortho", f.orthos,
                 "georeferenced orthophoto (GeoTIFF, COG, VRT, /vsi* path); repeat for a mosaic of "
                 "one CRS");
  app.add_option("--ortho-list", f.ortho_list, "file listing orthophotos, one per line");
  app.add_option("--altitude", o.altitude_m, "flight altitude above ground (m)")->required();
  app.add_option("--hfov", o.hfov_deg, "camera horizontal field of view (deg)")->required();
  app.add_option("--frame-size", f.frame_size, "camera frame size WxH (px)")->required();
  app.add_option("--scale-factor", o.scale_factor, "tile side / frame footprint")
      ->capture_default_str();
  app.add_option("--overlap", o.overlap, "fraction shared by neighbouring tiles")
      ->capture_default_str();
  app.add_option("--features", f.features, "orb|sift|brisk|xfeat")->capture_default_str();
  app.add_option("--model", o.model_path, "XFeat network (.onnx; default: shared data's)");
  app.add_option("--max-features", o.max_features, "features per tile")->capture_default_str();
  app.add_option("--threads", o.threads, "worker threads (0: all cores)")->capture_default_str();
  cli::OutputFile(app.add_option("--out", f.out, "output database (SQLite)"))->required();
  app.add_option("--shard", f.shard,
                 "I/N: build only shard I (0-based) of N, a part for `map merge`");
  app.add_option("--plan", f.plan,
                 "slurm: write a job array (one task per shard) and its merge instead of building");
  app.add_option("--plan-dir", f.plan_dir, "folder of the plan (default: OUT.slurm)");
  app.add_option("--shards", f.shards, "shards of the plan (default: about 20 min of work each)");
  app.add_option("--slurm-args", f.slurm_args, "extra sbatch options for the planned tasks");
}

int RunBuild(BuildFlags f) {
  const auto type = features::ParseFeatureType(f.features);
  if (!type)
    throw cli::UsageError("unknown feature type '" + f.features + "' (orb|sift|brisk|xfeat)",
                          "--features");
  f.options.feature_type = *type;
  if (!f.options.model_path.empty() && *type != features::FeatureType::kXFeat)
    throw cli::UsageError("--model is for --features xfeat", "--model");
  ParseFrameSize(f.frame_size, "--frame-size", 0, &f.options.frame_width, &f.options.frame_height);
  cli::ThrowIfInvalid(f.options.Check(), "");
  if (f.orthos.empty() && f.ortho_list.empty())
    throw cli::UsageError("give --ortho (one or more) or --ortho-list", "--ortho");
  if (!f.plan.empty()) {
    if (f.plan != "slurm") throw cli::UsageError("takes 'slurm'", "--plan");
    if (!f.shard.empty()) throw cli::UsageError("is not used with --plan", "--shard");
    if (f.shards < 0) throw cli::UsageError("must be >= 1 (0: derived)", "--shards");
    const app::SlurmPlan plan = app::WriteMapBuildPlan({.orthos = f.orthos,
                                                        .ortho_list = f.ortho_list,
                                                        .out = f.out,
                                                        .plan_dir = f.plan_dir,
                                                        .shards = f.shards,
                                                        .slurm_args = f.slurm_args,
                                                        .build = f.options});
    std::printf(
        "map build: planned %zu shard(s) -> %s/plan.json\n  submit: sbatch %s/submit.sbatch (the "
        "merge into %s follows when all succeed)\n  merge by hand: optinav map merge --plan-dir %s "
        "--out %s\n",
        plan.tasks.size(), plan.dir.c_str(), plan.dir.c_str(), f.out.c_str(), plan.dir.c_str(),
        f.out.c_str());
    return 0;
  }
  maploc::MapShard shard;
  if (!f.shard.empty()) {
    try {
      shard = maploc::ParseMapShard(f.shard);
    } catch (const Error& e) {
      throw cli::UsageError(e.message(), "--shard");
    }
  }
  Timer t;
  const std::string ortho = app::ResolveOrthoInputs(f.orthos, f.ortho_list, f.out + ".vrt");
  const maploc::MapDatabase db = maploc::BuildMapDatabase(ortho, f.options, f.out, shard);
  std::printf("built %s%s: %zu of %d x %d tiles, %zu features, %.1f s\n", f.out.c_str(),
              shard.whole() ? "" : (" (shard " + shard.ToString() + ")").c_str(), db.tiles.size(),
              db.cols, db.rows, db.FeatureCount(), t.ElapsedSeconds());
  return 0;
}

int RunMerge(const std::vector<std::string>& parts, const std::string& plan_dir,
             const std::string& out) {
  if (parts.empty() == plan_dir.empty())
    throw cli::UsageError("give the parts or --plan-dir (one of them)", "--plan-dir");
  Timer t;
  const maploc::MapMergeSummary m =
      maploc::MergeMapParts(parts.empty() ? app::PlannedMapParts(plan_dir) : parts, out);
  std::printf("merged %s: %d x %d = %zu tiles, %zu features, %.1f s\n", out.c_str(), m.db.cols,
              m.db.rows, m.tiles, m.features, t.ElapsedSeconds());
  return 0;
}

int RunInfo(const std::string& path, bool json, bool check) {
  // --check: the whole file (SQLite's page structure too); a damaged file throws, exit 1.
  std::optional<maploc::MapCheckReport> report;
  if (check) report = maploc::CheckMapDatabase(path);
  const maploc::MapDatabase db = report ? std::move(report->db) : maploc::LoadMapDatabase(path);
  if (json) {
    nlohmann::json j = app::MapInfoJson(db);
    if (report) j["check"] = app::MapCheckJson(*report);
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::fputs(app::MapInfoText(path, db).c_str(), stdout);
    if (report) std::fputs(app::MapCheckText(*report).c_str(), stdout);
  }
  return 0;
}

struct LocateFlags {
  std::string image, list, prior, last_fix, method = "auto", deviations = "20,40", attitude;
  bool json = false;
  app::MapLocateOptions options;
};

void AddLocate(CLI::App& app, LocateFlags& f) {
  app::MapLocateOptions& o = f.options;
  app.add_option("--map", o.map_path, "map database")->required();
  app.add_option("--image", f.image, "frame to localize");
  app.add_option("--images-from", f.list,
                 "csv 'image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg"
                 "[,altitude_m,roll_deg,pitch_deg]' (columns by the header, any order)");
  app.add_option("--prior", f.prior, "approximate position LAT,LON");
  app.add_option("--radius", o.radius_m, "prior radius (m)")->capture_default_str();
  app.add_option("--last-fix", f.last_fix, "prediction: last fix LAT,LON");
  app.add_option("--max-travel", o.max_travel_m, "prediction: distance flown since (m)");
  app.add_option("--bearing", o.bearing_deg, "prediction: bearing to the target (deg)");
  app.add_option("--deviations", f.deviations, "prediction: deviated bearings (deg)")
      ->capture_default_str();
  app.add_option("--heading", o.heading_deg, "frame heading, deg clockwise from north of frame up");
  app.add_option("--heading-sigma", o.heading_sigma_deg, "heading uncertainty (deg)")
      ->capture_default_str();
  app.add_option("--altitude", o.altitude_m, "approximate altitude above ground (m)");
  app.add_option("--attitude", f.attitude, "ROLL,PITCH (deg; roll right wing down, pitch nose up)");
  app.add_option("--attitude-sigma", o.attitude_sigma_deg, "1-sigma error of roll and pitch (deg)")
      ->capture_default_str();
  app.add_option("--hfov", o.hfov_deg, "horizontal field of view (deg; default: the map's)");
  app.add_option("--camera", o.camera_path, "EuRoC sensor.yaml: intrinsics and distortion");
  app.add_option("--ortho", o.ortho_path, "orthophoto path if moved since the build (for oc)");
  app.add_option("--model", o.model_path, "XFeat network of an xfeat map (default: shared data's)");
  app.add_option("--method", f.method, "auto|features|oc")->capture_default_str();
  app.add_flag("--json", f.json, "print the result as JSON");
}

int RunLocate(LocateFlags f) {
  app::MapLocateOptions& o = f.options;
  const auto method = app::ParseLocateMethod(f.method);
  if (!method)
    throw cli::UsageError("unknown method '" + f.method + "' (auto|features|oc)", "--method");
  o.method = *method;
  if (f.image.empty() == f.list.empty())
    throw cli::UsageError("give exactly one of --image and --images-from", "--image");
  if (!f.prior.empty()) o.prior = ParseLatLon(f.prior, "--prior");
  if (!f.last_fix.empty()) o.last_fix = ParseLatLon(f.last_fix, "--last-fix");
  o.deviations_deg = ParseNumberList(f.deviations, "--deviations");
  if (!f.attitude.empty()) {
    const std::vector<double> a = ParseNumbers(f.attitude, 2, "ROLL,PITCH", "--attitude");
    o.roll_deg = a[0];
    o.pitch_deg = a[1];
  }
  cli::ThrowIfCheckFailed(o.Check());
  app::MapLocateRun run(o);
  if (f.list.empty()) {
    const maploc::LocateResult r = run.LocateImage(f.image);
    nlohmann::json j = app::LocateResultJson(r);
    j["image"] = f.image;
    // File names are bytes, not necessarily UTF-8: invalid sequences print as U+FFFD.
    const std::string text =
        f.json ? j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n"
               : app::LocateResultText(r);
    std::fputs(text.c_str(), stdout);
    return 0;
  }
  // Many frames in one process: one JSON object per line, flushed as each frame is done.
  run.LocateList(f.list, [](const nlohmann::json& j) {
    std::printf("%s\n", j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
    std::fflush(stdout);
  });
  return 0;
}

struct RenderFlags {
  std::string at, frame_size = "640x480", out_dir;
  double altitude = 0, hfov = 0, tilt = 0;
  int set = 0;
  uint64_t seed = 1;
  app::FrameRenderOptions options;
  std::vector<CLI::Option*> single;  // flags of the one-frame mode
};

void AddRender(CLI::App& app, RenderFlags& f) {
  app::FrameRenderOptions& o = f.options;
  app.add_option("--ortho", o.ortho_path, "orthophoto (GeoTIFF)")->required();
  f.single = {
      app.add_option("--at", f.at, "vehicle position LAT,LON (with --tilt: frame centre)"),
      app.add_option("--heading", o.heading_deg, "yaw: frame up, deg clockwise from north"),
      app.add_option("--gsd", o.gsd_m, "metres per frame pixel at nadir (default: the map's)"),
      app.add_option("--roll", o.roll_deg, "roll, deg, right wing down positive"),
      app.add_option("--pitch", o.pitch_deg, "pitch, deg, nose up positive"),
      app.add_option("--tilt", f.tilt, "legacy tilt model: camera tilt from nadir (deg)"),
      app.add_option("--tilt-azimuth", o.tilt_azimuth_deg, "legacy: tilt direction in the frame"),
      cli::OutputFile(app.add_option("--out", o.out_path, "output image (PNG, JPEG)"))};
  app.add_option("--altitude", f.altitude, "height above ground (m); with --set: nominal (640)");
  app.add_option("--hfov", f.hfov, "horizontal field of view (deg, default 90)");
  app.add_option("--frame-size", f.frame_size, "WxH")->capture_default_str();
  app.add_option("--set", f.set, "write an acceptance set of N seeded frames to --out-dir");
  app.add_option("--seed", f.seed, "seed of the set")->capture_default_str();
  app.add_option("--out-dir", f.out_dir, "folder of the set (frames, frames.csv, truth.csv)");
}

int RunRenderSet(const RenderFlags& f, CLI::App& app) {
  for (const CLI::Option* opt : f.single) {
    if (opt->count() > 0)
      throw cli::UsageError(opt->get_name() + " is not used with --set", opt->get_name());
  }
  app::FrameSetOptions s{
      .ortho_path = f.options.ortho_path, .out_dir = f.out_dir, .count = f.set, .seed = f.seed};
  ParseFrameSize(f.frame_size, "--frame-size", 16, &s.frames.width, &s.frames.height);
  if (app.count("--altitude")) s.frames.altitude_m = f.altitude;
  if (app.count("--hfov")) s.frames.hfov_deg = f.hfov;
  cli::ThrowIfInvalid(s.Check(), "--set");
  const app::FrameSetSummary r = app::RenderFrameSet(s);
  std::printf("rendered %d frames into %s (given: %s, truth: %s)\n", r.count, f.out_dir.c_str(),
              r.frames_csv.c_str(), r.truth_csv.c_str());
  return 0;
}

int RunRender(RenderFlags f, CLI::App& app) {
  if (app.count("--set")) return RunRenderSet(f, app);
  app::FrameRenderOptions& o = f.options;
  if (f.at.empty()) throw cli::UsageError("--at is required (or --set)", "--at");
  if (o.out_path.empty()) throw cli::UsageError("--out is required (or --set)", "--out");
  if (app.count("--out-dir")) throw cli::UsageError("--out-dir needs --set", "--out-dir");
  ParseFrameSize(f.frame_size, "--frame-size", 16, &o.width, &o.height);
  o.at = ParseLatLon(f.at, "--at");
  if (app.count("--altitude")) o.altitude_m = f.altitude;
  if (app.count("--hfov")) o.hfov_deg = f.hfov;
  if (app.count("--tilt")) o.tilt_deg = f.tilt;
  cli::ThrowIfCheckFailed(o.Check());
  const app::RenderedFrame r = app::RenderFrame(o);
  std::printf(
      "rendered %s: %dx%d at %.3f m/px, heading %.1f deg, roll %.1f, pitch %.1f, "
      "altitude %.1f m, centre %.7f,%.7f\n",
      o.out_path.c_str(), o.width, o.height, r.gsd_m, o.heading_deg, o.roll_deg, o.pitch_deg,
      r.altitude_m, r.centre.lat_deg, r.centre.lon_deg);
  return 0;
}

}  // namespace

int RunMap(int argc, char** argv) {
  CLI::App app{"Orthophoto feature databases and frame-to-map localization", "optinav map"};
  app.require_subcommand(1);
  BuildFlags build_flags;
  CLI::App* build = app.add_subcommand("build", "build a tile/feature database from a GeoTIFF");
  AddBuild(*build, build_flags);
  std::string info_path;
  bool info_json = false, info_check = false;
  CLI::App* info = app.add_subcommand("info", "print a database's extent, CRS, tiles, features");
  info->add_option("map", info_path, "map database")->required();
  info->add_flag("--json", info_json, "machine-readable output");
  info->add_flag("--check", info_check,
                 "verify the whole file (SQLite structure, every checksum); exit 1 if damaged");
  std::vector<std::string> merge_parts;
  std::string merge_plan_dir, merge_out;
  CLI::App* merge = app.add_subcommand("merge", "join the parts of a sharded build into one map");
  merge->add_option("parts", merge_parts, "parts (map build --shard I/N)");
  merge->add_option("--plan-dir", merge_plan_dir, "the parts of this plan (map build --plan)");
  cli::OutputFile(merge->add_option("--out", merge_out, "output database"))->required();
  LocateFlags locate_flags;
  CLI::App* locate = app.add_subcommand("locate", "localize camera frames on the map");
  AddLocate(*locate, locate_flags);
  RenderFlags render_flags;
  CLI::App* render = app.add_subcommand("render", "render a synthetic camera frame from a GeoTIFF");
  AddRender(*render, render_flags);
  return cli::RunCli(app, argc, argv, [&] {
    if (build->parsed()) return RunBuild(build_flags);
    if (info->parsed()) return RunInfo(info_path, info_json, info_check);
    if (merge->parsed()) return RunMerge(merge_parts, merge_plan_dir, merge_out);
    if (locate->parsed()) return RunLocate(locate_flags);
    return RunRender(render_flags, *render);
  });
}

}  // namespace optinav
