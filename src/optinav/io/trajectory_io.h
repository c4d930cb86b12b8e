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

// Trajectories held in memory as rows of numbers (the Python module's arrays), checked as the
// readers check file lines: finite values, a non-zero quaternion, timestamps that do not go
// backwards (repeats are accepted with a warning), a non-singular KITTI rotation, at least one
// row. Errors name `source` as the file and the 1-based row as the line ("ref array:5: ...").
//   TUM rows    n x 8, row-major: t [s] x y z qx qy qz qw. The time goes to nanoseconds through
//               its shortest decimal text, so a row loaded from a TUM file gets the stamp the
//               file reader gives that line.
//   KITTI rows  n x 12, row-major: the 3x4 world_from_camera, row-major; no timestamps.
//   EuRoC rows  t_ns[i] and n x 7 values px py pz qw qx qy qz.
Trajectory TrajectoryFromTumRows(const double* rows, size_t n, const std::string& source);
Trajectory TrajectoryFromKittiRows(const double* rows, size_t n, const std::string& source);
Trajectory TrajectoryFromEurocRows(const int64_t* t_ns, const double* rows, size_t n,
                                   const std::string& source);

}  // namespace optinav::io
