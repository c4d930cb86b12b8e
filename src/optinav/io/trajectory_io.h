// Trajectory files: TUM, KITTI and EuRoC/ASL csv.
//
//  tum    "t x y z qx qy qz qw", t in seconds, whitespace separated, '#' comments.
//  kitti  12 numbers per line: the top 3x4 of world_from_camera, row-major; no timestamps
//         unless a separate times file (one time in seconds per line) is given.
//  euroc  ASL csv "timestamp [ns], px, py, pz, qw, qx, qy, qz[, ...]" with an optional '#'
//         header; extra columns (velocity, biases of the ground-truth files) are ignored.
//         EuRoC-format estimates use the same layout; the writer emits its first 8 columns.
//
// Readers are strict: a malformed line, a non-finite value, a zero quaternion or a timestamp
// that goes backwards is an optinav::Error naming file and line. Repeated timestamps are
// accepted with a warning (they occur in real files).
#pragma once

#include <optional>
#include <string>

#include "optinav/geometry/trajectory.h"
#include "optinav/util/error.h"

namespace optinav::io {

enum class TrajectoryFormat { kAuto, kTum, kKitti, kEuroc };

// "auto" | "tum" | "kitti" | "euroc"; nullopt otherwise.
std::optional<TrajectoryFormat> ParseTrajectoryFormat(const std::string& name);
std::string TrajectoryFormatName(TrajectoryFormat format);

// Looks at the first data lines (and header) to pick a format. Throws Error with the reason
// when the content matches no format or is ambiguous.
TrajectoryFormat DetectTrajectoryFormat(const std::string& path);

struct TrajectoryReadOptions {
  TrajectoryFormat format = TrajectoryFormat::kAuto;  // kAuto: DetectTrajectoryFormat
  std::string kitti_times_path;                       // optional times file for KITTI
};

// Reads a trajectory; throws Error on any problem (file, line and field in the message).
Trajectory ReadTrajectory(const std::string& path, const TrajectoryReadOptions& options = {});

// Writes atomically (temporary file + rename). TUM and EuRoC values get 9 decimals (nm, 1e-9
// of a unit quaternion), timestamps are exact; KITTI matrices are written at full precision and
// drop timestamps (write them with WriteKittiTimes); TUM and EuRoC require timestamps.
void WriteTrajectory(const std::string& path, const Trajectory& trajectory,
                     TrajectoryFormat format);
void WriteKittiTimes(const std::string& path, const Trajectory& trajectory);

}  // namespace optinav::io
