#include "optinav/io/airsim_recording.h"

#include <cmath>
#include <filesystem>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "optinav/io/text_parse.h"

namespace fs = std::filesystem;

namespace optinav::io {
namespace {

// Vector conversion ENU <- NED (swap x/y, negate z); its own inverse.
const Eigen::Matrix3d& SwapEnuNed() {
  static const Eigen::Matrix3d m = (Eigen::Matrix3d() << 0, 1, 0, 1, 0, 0, 0, 0, -1).finished();
  return m;
}
// FLU <- FRD (and back): negate y and z.
const Eigen::Matrix3d& FluFrd() {
  static const Eigen::Matrix3d m = Eigen::Vector3d(1, -1, -1).asDiagonal();
  return m;
}
// Optical (x right, y down, z forward) <- AirSim camera (x forward, y right, z down).
const Eigen::Matrix3d& OpticalFromAirsimCam() {
  static const Eigen::Matrix3d m = (Eigen::Matrix3d() << 0, 1, 0, 0, 0, 1, 1, 0, 0).finished();
  return m;
}

Rigid3d Convert(const Rigid3d& pose, const Eigen::Matrix3d& world, const Eigen::Matrix3d& body) {
  // world' = W world, body' = B body: R' = W R B^-1, t' = W t.
  const Eigen::Matrix3d r = world * pose.rotation.toRotationMatrix() * body.transpose();
  return Rigid3d(Eigen::Quaterniond(r).normalized(), world * pose.translation);
}

int64_t MsToNs(std::string_view field, const ErrorContext& ctx) {
  const int64_t ms = ParseInt64(field, ctx);
  if (ms < 0 || ms > INT64_MAX / 1'000'000) throw Error("timestamp out of range", ctx);
  return ms * 1'000'000;
}

}  // namespace

Rigid3d EnuFluFromNedFrd(const Rigid3d& p) { return Convert(p, SwapEnuNed(), FluFrd()); }
Rigid3d NedFrdFromEnuFlu(const Rigid3d& p) { return Convert(p, SwapEnuNed(), FluFrd()); }
Rigid3d EnuOpticalFromNedAirsimCamera(const Rigid3d& p) {
  return Convert(p, SwapEnuNed(), OpticalFromAirsimCam());
}
Rigid3d NedAirsimCameraFromEnuOptical(const Rigid3d& p) {
  return Convert(p, SwapEnuNed(), OpticalFromAirsimCam().transpose());
}

AirsimRecording ReadAirsimRecording(const std::string& path, const AirsimReadOptions& options) {
  fs::path rec_file(path);
  if (fs::is_directory(rec_file)) rec_file /= "airsim_rec.txt";
  const fs::path dir = rec_file.parent_path();
  const std::string file = rec_file.string();
  CheckNotInProgress(dir.empty() ? "." : dir.string());
  AirsimRecording out;
  out.dir = dir.string();
  const std::string text = ReadFileToString(file);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  std::map<std::string, size_t> col;
  char delim = '\t';
  while (cursor.Next(&line)) {
    if (Trim(line).empty()) continue;
    // Tab-separated as AirSim writes it; a header without tabs means a whitespace variant.
    delim = line.find('\t') != std::string_view::npos ? '\t' : ' ';
    SplitFields(line, delim, &f);
    for (size_t i = 0; i < f.size(); ++i) col[std::string(f[i])] = i;
    break;
  }
  const ErrorContext header_ctx{.file = file, .line = cursor.line_number()};
  for (const char* required : {"TimeStamp", "ImageFile"}) {
    if (!col.count(required)) {
      throw Error(fmt::format("header lacks the column '{}'", required),
                  {.file = file, .line = header_ctx.line, .field = required});
    }
  }
  const char* pose_cols[] = {"POS_X", "POS_Y", "POS_Z", "Q_W", "Q_X", "Q_Y", "Q_Z"};
  int pose_present = 0;
  for (const char* c : pose_cols) pose_present += col.count(c);
  if (pose_present != 0 && pose_present != 7) {
    throw Error("header has some but not all of POS_X POS_Y POS_Z Q_W Q_X Q_Y Q_Z", header_ctx);
  }
  const size_t needed = [&] {
    size_t m = 0;
    for (const auto& [name, i] : col) m = std::max(m, i + 1);
    return m;
  }();
  const fs::path image_dir = dir / "images";
  while (cursor.Next(&line)) {
    if (Trim(line).empty()) continue;
    ErrorContext ctx{.file = file, .line = cursor.line_number()};
    SplitFields(line, delim, &f);
    if (f.size() != needed) {
      throw Error(fmt::format("expected {} columns as in the header, found {}", needed, f.size()),
                  ctx);
    }
    auto field = [&](const char* name) {
      ctx.field = name;
      return f[col.at(name)];
    };
    auto number = [&](const char* name, double fallback) {
      return col.count(name) ? ParseFiniteDouble(field(name), ctx) : fallback;
    };
    AirsimRecord r;
    r.t_ns = MsToNs(field("TimeStamp"), ctx);
    if (!out.records.empty() && r.t_ns <= out.records.back().t_ns) {
      throw Error(fmt::format("timestamp {} ms does not increase", r.t_ns / 1'000'000), ctx);
    }
    if (col.count("VehicleName")) r.vehicle = std::string(field("VehicleName"));
    if (pose_present) {
      double v[7];
      for (int k = 0; k < 7; ++k) v[k] = number(pose_cols[k], 0);
      ctx.field = "Q_W";
      if (Eigen::Vector4d(v[3], v[4], v[5], v[6]).norm() < 1e-6)
        throw Error("zero quaternion", ctx);
      r.world_from_body = EnuFluFromNedFrd(
          Rigid3d(QuaternionFromWxyz(v[3], v[4], v[5], v[6]), Eigen::Vector3d(v[0], v[1], v[2])));
    }
    r.throttle = number("Throttle", 0);
    r.steering = number("Steering", 0);
    r.brake = number("Brake", 0);
    const double gear = number("Gear", 0);
    if (!(std::abs(gear) <= 1000)) {  // the cast to int is undefined beyond its range (fuzz)
      ctx.field = "Gear";
      throw Error("gear out of range [-1000, 1000]", ctx);
    }
    r.gear = static_cast<int>(gear);
    r.handbrake = number("Handbrake", 0) != 0;
    r.rpm = number("RPM", 0);
    r.speed_m_s = number("Speed", 0);
    std::string_view images = field("ImageFile");
    while (!images.empty()) {
      const size_t semi = images.find(';');
      const std::string_view name = Trim(images.substr(0, semi));
      if (!name.empty()) {
        const fs::path p = image_dir / std::string(name);
        std::error_code exists_ec;  // a name the OS refuses is a missing image, not a throw
        if (options.check_images_exist && !fs::is_regular_file(p, exists_ec)) {
          throw Error("image file not found: " + p.string(), ctx);
        }
        r.image_paths.push_back(p.string());
      }
      if (semi == std::string_view::npos) break;
      images.remove_prefix(semi + 1);
    }
    if (r.image_paths.empty()) throw Error("no image listed", ctx);
    out.records.push_back(std::move(r));
  }
  if (out.records.empty()) throw Error("recording has no rows", {.file = file});

  const fs::path info = dir / "camera_info.csv";
  if (fs::is_regular_file(info)) {
    const std::string itext = ReadFileToString(info.string());
    LineCursor c2(itext);
    bool header = true;
    while (c2.Next(&line)) {
      if (Trim(line).empty()) continue;
      if (header) {
        header = false;
        continue;
      }
      ErrorContext ctx{.file = info.string(), .line = c2.line_number()};
      SplitFields(line, ',', &f);
      if (f.size() != 8) {
        throw Error(
            fmt::format("expected 8 columns (TimeStamp, POS_X..Z, Q_W..Z), found {}", f.size()),
            ctx);
      }
      ctx.field = "TimeStamp";
      AirsimCameraPose pose;
      pose.t_ns = MsToNs(f[0], ctx);
      double v[7];
      static const char* names[] = {"POS_X", "POS_Y", "POS_Z", "Q_W", "Q_X", "Q_Y", "Q_Z"};
      for (int k = 0; k < 7; ++k) {
        ctx.field = names[k];
        v[k] = ParseFiniteDouble(f[k + 1], ctx);
      }
      if (Eigen::Vector4d(v[3], v[4], v[5], v[6]).norm() < 1e-6)
        throw Error("zero quaternion", ctx);
      pose.world_from_cam = EnuOpticalFromNedAirsimCamera(
          Rigid3d(QuaternionFromWxyz(v[3], v[4], v[5], v[6]), Eigen::Vector3d(v[0], v[1], v[2])));
      out.left_camera.push_back(pose);
    }
  }
  return out;
}

void WriteAirsimRecording(const std::string& dir, const AirsimRecording& recording) {
  // AirSim stamps are milliseconds: round to the nearest.
  auto ms = [](int64_t t_ns) { return (t_ns + 500'000) / 1'000'000; };
  std::string rec =
      "VehicleName\tTimeStamp\tPOS_X\tPOS_Y\tPOS_Z\tQ_W\tQ_X\tQ_Y\tQ_Z\tThrottle\t"
      "Steering\tBrake\tGear\tHandbrake\tRPM\tSpeed\tImageFile\n";
  const std::string rec_path = (fs::path(dir) / "airsim_rec.txt").string();
  for (size_t i = 0; i < recording.records.size(); ++i) {
    const AirsimRecord& r = recording.records[i];
    if (!r.world_from_body) {
      throw Error(fmt::format("record {} (t = {} ns) has no pose to write", i, r.t_ns),
                  {.file = rec_path, .field = "POS_X"});
    }
    const Rigid3d ned_body = NedFrdFromEnuFlu(*r.world_from_body);
    const Eigen::Vector4d q = QuaternionToWxyz(ned_body.rotation);
    rec += fmt::format(
        "{}\t{}\t{:.6f}\t{:.6f}\t{:.6f}\t{:.9f}\t{:.9f}\t{:.9f}\t{:.9f}\t{:.3f}\t{:.3f}\t{:.3f}\t{}"
        "\t"
        "{}\t{:.1f}\t{:.4f}\t{}\n",
        r.vehicle, ms(r.t_ns), ned_body.translation.x(), ned_body.translation.y(),
        ned_body.translation.z(), q[0], q[1], q[2], q[3], r.throttle, r.steering, r.brake, r.gear,
        r.handbrake ? 1 : 0, r.rpm, r.speed_m_s, fmt::join(r.image_paths, ";"));
  }
  std::string cam_info;
  if (!recording.left_camera.empty()) {
    cam_info = "TimeStamp,POS_X,POS_Y,POS_Z,Q_W,Q_X,Q_Y,Q_Z\n";
    for (const AirsimCameraPose& c : recording.left_camera) {
      const Rigid3d ned_cam = NedAirsimCameraFromEnuOptical(c.world_from_cam);
      const Eigen::Vector4d q = QuaternionToWxyz(ned_cam.rotation);
      cam_info += fmt::format("{},{:.6f},{:.6f},{:.6f},{:.9f},{:.9f},{:.9f},{:.9f}\n", ms(c.t_ns),
                              ned_cam.translation.x(), ned_cam.translation.y(),
                              ned_cam.translation.z(), q[0], q[1], q[2], q[3]);
    }
  }
  WriteFileAtomically(rec_path, rec);
  if (!cam_info.empty())
    WriteFileAtomically((fs::path(dir) / "camera_info.csv").string(), cam_info);
}

}  // namespace optinav::io
