// AirSim recordings (the weather-dataset document's format), converted to the project's frames.
//
// A sequence folder holds:
//   airsim_rec.txt   tab-separated, a header row naming the columns; AirSim's car recorder
//                    writes VehicleName TimeStamp POS_X POS_Y POS_Z Q_W Q_X Q_Y Q_Z Throttle
//                    Steering Brake Gear Handbrake RPM Speed ImageFile. TimeStamp in
//                    milliseconds; POS in NED metres; Q (w x y z) = NED_from_vehicle with the
//                    vehicle frame x forward, y right, z down; ImageFile lists the images of the
//                    row joined by ';'. The two-column variant "TimeStamp ImageFile" is accepted.
//   camera_info.csv  (optional) comma-separated with a header: TimeStamp, POS_X, POS_Y, POS_Z,
//                    Q_W, Q_X, Q_Y, Q_Z of the left camera (NED; camera frame x forward, y right,
//                    z down, AirSim's camera convention).
//   images/          the image files.
// The reader converts at the boundary (docs/ARCHITECTURE.md: NED only inside this file): poses
// come out as world_from_body in ENU (x east, y north, z up) with the body x forward, y left,
// z up, and cameras as world_from_cam with the optical frame x right, y down, z forward.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "optinav/geometry/lie.h"
#include "optinav/util/error.h"

namespace optinav::io {

struct AirsimRecord {
  int64_t t_ns = 0;
  std::string vehicle;
  std::optional<Rigid3d> world_from_body;  // ENU / FLU; absent in the two-column variant
  double throttle = 0, steering = 0, brake = 0, rpm = 0, speed_m_s = 0;
  int gear = 0;
  bool handbrake = false;
  std::vector<std::string> image_paths;  // resolved against <dir>/images
};

struct AirsimCameraPose {
  int64_t t_ns = 0;
  Rigid3d world_from_cam;  // ENU / optical frame
};

struct AirsimRecording {
  std::string dir;
  std::vector<AirsimRecord> records;
  std::vector<AirsimCameraPose> left_camera;  // empty without camera_info.csv
};

struct AirsimReadOptions {
  bool check_images_exist = true;
};

// `path`: the sequence folder or its airsim_rec.txt. Throws Error naming the file, line and
// column on any problem (missing required column, malformed number, zero quaternion,
// timestamps going backwards, a listed image that does not exist).
AirsimRecording ReadAirsimRecording(const std::string& path, const AirsimReadOptions& options = {});

// Writes <dir>/airsim_rec.txt (the car recorder's 17 columns) and, when `recording.left_camera`
// is not empty, <dir>/camera_info.csv, atomically; the inverse of ReadAirsimRecording. Records
// need world_from_body (ENU / FLU; converted to NED here) and their image_paths are written as
// given (names relative to <dir>/images). Stamps are rounded to milliseconds, positions written
// with 6 decimals (µm), quaternions with 9. Throws Error naming the record without a pose.
void WriteAirsimRecording(const std::string& dir, const AirsimRecording& recording);

// Frame conversions used by the reader and by writers of the format.
// NED_from_FRD (AirSim vehicle) <-> ENU_from_FLU (project body).
Rigid3d EnuFluFromNedFrd(const Rigid3d& ned_from_frd);
Rigid3d NedFrdFromEnuFlu(const Rigid3d& enu_from_flu);
// NED_from_AirSim-camera (x forward, y right, z down) <-> ENU_from_optical (x right, y down,
// z forward).
Rigid3d EnuOpticalFromNedAirsimCamera(const Rigid3d& ned_from_camera);
Rigid3d NedAirsimCameraFromEnuOptical(const Rigid3d& enu_from_optical);

}  // namespace optinav::io
