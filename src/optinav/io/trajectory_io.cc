#include "optinav/io/trajectory_io.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <vector>

#include "optinav/io/text_parse.h"

namespace optinav::io {
namespace {

constexpr const char* kTumFields[] = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};
constexpr const char* kEurocFields[] = {"timestamp", "px", "py", "pz", "qw", "qx", "qy", "qz"};

Eigen::Quaterniond CheckedQuaternion(double w, double x, double y, double z,
                                     const ErrorContext& ctx) {
  const double norm = std::sqrt(w * w + x * x + y * y + z * z);
  if (norm < 1e-6) throw Error("quaternion has (near) zero norm", ctx);
  return Eigen::Quaterniond(w / norm, x / norm, y / norm, z / norm);
}

// Timestamps must not go backwards. Repeated stamps occur in real files (evo's own V102.txt
// has four), so they are accepted and counted; association then takes the first of equals.
void CheckNotBackwards(const Trajectory& traj, const ErrorContext& ctx, size_t* repeats) {
  const size_t n = traj.t_ns.size();
  if (n < 2) return;
  if (traj.t_ns[n - 1] == traj.t_ns[n - 2]) ++*repeats;
  if (traj.t_ns[n - 1] < traj.t_ns[n - 2]) {
    throw Error(fmt::format("timestamp {} s goes backwards (previous {} s)",
                            FormatNsAsSeconds(traj.t_ns[n - 1]),
                            FormatNsAsSeconds(traj.t_ns[n - 2])),
                ctx);
  }
}

void WarnRepeats(const std::string& path, size_t repeats) {
  if (repeats > 0) spdlog::warn("{}: {} repeated timestamp(s)", path, repeats);
}

Trajectory ReadTum(const std::string& path) {
  const std::string text = ReadFileToString(path);
  Trajectory traj;
  traj.Reserve(text.size() / 64 + 1, true);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  double v[8];
  size_t repeats = 0;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = path, .line = cursor.line_number()};
    SplitFields(line, ' ', &f);
    if (f.size() != 8) {
      throw Error(fmt::format("expected 8 values 't x y z qx qy qz qw' (TUM), found {}", f.size()),
                  ctx);
    }
    ctx.field = kTumFields[0];
    const int64_t t = ParseSecondsToNs(f[0], ctx);
    for (int k = 1; k < 8; ++k) {
      ctx.field = kTumFields[k];
      v[k] = ParseFiniteDouble(f[k], ctx);
    }
    ctx.field = "qx qy qz qw";
    traj.Add(t, Rigid3d(CheckedQuaternion(v[7], v[4], v[5], v[6], ctx),
                        Eigen::Vector3d(v[1], v[2], v[3])));
    ctx.field = "t";
    CheckNotBackwards(traj, ctx, &repeats);
  }
  WarnRepeats(path, repeats);
  return traj;
}

Trajectory ReadEuroc(const std::string& path) {
  const std::string text = ReadFileToString(path);
  Trajectory traj;
  traj.Reserve(text.size() / 100 + 1, true);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  double v[8];
  size_t repeats = 0;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = path, .line = cursor.line_number()};
    SplitFields(line, ',', &f);
    if (f.size() < 8) {
      throw Error(fmt::format("expected at least 8 comma-separated values "
                              "'timestamp [ns], px, py, pz, qw, qx, qy, qz' (EuRoC), found {}",
                              f.size()),
                  ctx);
    }
    ctx.field = kEurocFields[0];
    const int64_t t = ParseInt64(f[0], ctx);
    for (int k = 1; k < 8; ++k) {
      ctx.field = kEurocFields[k];
      v[k] = ParseFiniteDouble(f[k], ctx);
    }
    ctx.field = "qw qx qy qz";
    traj.Add(t, Rigid3d(CheckedQuaternion(v[4], v[5], v[6], v[7], ctx),
                        Eigen::Vector3d(v[1], v[2], v[3])));
    ctx.field = "timestamp";
    CheckNotBackwards(traj, ctx, &repeats);
  }
  WarnRepeats(path, repeats);
  return traj;
}

Trajectory ReadKitti(const std::string& path, const std::string& times_path) {
  const std::string text = ReadFileToString(path);
  Trajectory traj;
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  Eigen::Matrix<double, 3, 4> m;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = path, .line = cursor.line_number()};
    SplitFields(line, ' ', &f);
    if (f.size() != 12) {
      throw Error(fmt::format("expected 12 values (3x4 row-major pose, KITTI), found {}",
                              f.size()),
                  ctx);
    }
    for (int k = 0; k < 12; ++k) {
      ctx.field = fmt::format("r{}c{}", k / 4, k % 4);
      m(k / 4, k % 4) = ParseFiniteDouble(f[k], ctx);
    }
    const Eigen::Matrix3d r = m.leftCols<3>();
    if (std::abs(r.determinant()) < 1e-6) {
      ctx.field = "rotation";
      throw Error("rotation block is singular", ctx);
    }
    // Kept as written (evo does the same); only a singular block is rejected above.
    traj.AddMatrix(r, m.col(3));
  }
  if (times_path.empty()) return traj;

  const std::string times_text = ReadFileToString(times_path);
  LineCursor times(times_text);
  std::vector<int64_t> stamps;
  while (times.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = times_path, .line = times.line_number(), .field = "t"};
    SplitFields(line, ' ', &f);
    if (f.size() != 1) throw Error(fmt::format("expected 1 value, found {}", f.size()), ctx);
    stamps.push_back(ParseSecondsToNs(f[0], ctx));
    if (stamps.size() >= 2 && stamps.back() < stamps[stamps.size() - 2]) {
      throw Error("timestamp goes backwards", ctx);
    }
  }
  if (stamps.size() != traj.size()) {
    throw Error(fmt::format("{} timestamps for {} poses in {}", stamps.size(), traj.size(), path),
                {.file = times_path});
  }
  traj.t_ns = std::move(stamps);
  return traj;
}

}  // namespace

std::optional<TrajectoryFormat> ParseTrajectoryFormat(const std::string& name) {
  if (name == "auto") return TrajectoryFormat::kAuto;
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  if (name == "euroc" || name == "asl") return TrajectoryFormat::kEuroc;
  return std::nullopt;
}

std::string TrajectoryFormatName(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kAuto: return "auto";
    case TrajectoryFormat::kTum: return "tum";
    case TrajectoryFormat::kKitti: return "kitti";
    case TrajectoryFormat::kEuroc: return "euroc";
  }
  return "?";
}

TrajectoryFormat DetectTrajectoryFormat(const std::string& path) {
  const std::string text = ReadFileToString(path);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  bool euroc_header = false;
  while (cursor.Next(&line)) {
    const std::string_view t = Trim(line);
    if (t.empty()) continue;
    if (t.front() == '#') {
      if (t.find(',') != std::string_view::npos && (t.rfind("#timestamp", 0) == 0 ||
                                                    t.rfind("#time", 0) == 0)) {
        euroc_header = true;
      }
      continue;
    }
    const ErrorContext ctx{.file = path, .line = cursor.line_number()};
    const std::string hint = " (pass the format explicitly: tum, kitti or euroc)";
    if (t.find(',') != std::string_view::npos) {
      SplitFields(t, ',', &f);
      if (f.size() >= 8) {
        if (f[0].find_first_of(".eE") != std::string_view::npos) {
          throw Error("ambiguous format: comma-separated like EuRoC, but the first column '" +
                          std::string(f[0]) + "' is not integer nanoseconds" + hint,
                      ctx);
        }
        return TrajectoryFormat::kEuroc;
      }
      throw Error(fmt::format("cannot detect format: {} comma-separated columns", f.size()) + hint,
                  ctx);
    }
    if (euroc_header) {
      throw Error("ambiguous format: EuRoC csv header but whitespace-separated data" + hint, ctx);
    }
    SplitFields(t, ' ', &f);
    if (f.size() == 8) {
      // Seconds since the epoch are < 1e10; a 19-digit integer is nanoseconds in TUM's layout.
      if (f[0].size() >= 16 && f[0].find_first_of(".eE") == std::string_view::npos) {
        throw Error("ambiguous format: 8 columns like TUM, but the first column '" +
                        std::string(f[0]) + "' looks like nanoseconds, not seconds" + hint,
                    ctx);
      }
      return TrajectoryFormat::kTum;
    }
    if (f.size() == 12) return TrajectoryFormat::kKitti;
    throw Error(fmt::format("cannot detect format: {} columns (TUM has 8, KITTI 12)", f.size()) +
                    hint,
                ctx);
  }
  throw Error("empty trajectory file (no data lines)", {.file = path});
}

Trajectory ReadTrajectory(const std::string& path, const TrajectoryReadOptions& options) {
  TrajectoryFormat format = options.format;
  if (format == TrajectoryFormat::kAuto) format = DetectTrajectoryFormat(path);
  Trajectory traj;
  switch (format) {
    case TrajectoryFormat::kTum: traj = ReadTum(path); break;
    case TrajectoryFormat::kKitti: traj = ReadKitti(path, options.kitti_times_path); break;
    case TrajectoryFormat::kEuroc: traj = ReadEuroc(path); break;
    case TrajectoryFormat::kAuto: break;
  }
  if (traj.empty()) {
    throw Error("no poses in " + TrajectoryFormatName(format) + " trajectory file", {.file = path});
  }
  if (format != TrajectoryFormat::kKitti && !options.kitti_times_path.empty()) {
    throw Error("a times file only applies to KITTI trajectories", {.file = path});
  }
  return traj;
}

void WriteTrajectory(const std::string& path, const Trajectory& traj, TrajectoryFormat format) {
  std::string out;
  out.reserve(traj.size() * 120);
  if (format != TrajectoryFormat::kKitti && !traj.has_timestamps()) {
    throw Error("trajectory has no timestamps; " + TrajectoryFormatName(format) + " needs them",
                {.file = path});
  }
  switch (format) {
    case TrajectoryFormat::kTum:
      out += "# timestamp tx ty tz qx qy qz qw\n";
      for (size_t i = 0; i < traj.size(); ++i) {
        const auto& p = traj.positions[i];
        const Eigen::Quaterniond q = traj.quaternion(i);
        fmt::format_to(std::back_inserter(out), "{} {} {} {} {} {} {} {}\n",
                       FormatNsAsSeconds(traj.t_ns[i]), p.x(), p.y(), p.z(), q.x(), q.y(), q.z(),
                       q.w());
      }
      break;
    case TrajectoryFormat::kEuroc:
      out += "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
             "q_RS_y [],q_RS_z []\n";
      for (size_t i = 0; i < traj.size(); ++i) {
        const auto& p = traj.positions[i];
        const Eigen::Quaterniond q = traj.quaternion(i);
        fmt::format_to(std::back_inserter(out), "{},{},{},{},{},{},{},{}\n", traj.t_ns[i], p.x(),
                       p.y(), p.z(), q.w(), q.x(), q.y(), q.z());
      }
      break;
    case TrajectoryFormat::kKitti:
      for (size_t i = 0; i < traj.size(); ++i) {
        Eigen::Matrix<double, 3, 4> m;
        m << traj.rotations[i], traj.positions[i];
        fmt::format_to(std::back_inserter(out), "{} {} {} {} {} {} {} {} {} {} {} {}\n", m(0, 0),
                       m(0, 1), m(0, 2), m(0, 3), m(1, 0), m(1, 1), m(1, 2), m(1, 3), m(2, 0),
                       m(2, 1), m(2, 2), m(2, 3));
      }
      break;
    case TrajectoryFormat::kAuto:
      throw Error("cannot write format 'auto': choose tum, kitti or euroc", {.file = path});
  }
  WriteFileAtomically(path, out);
}

void WriteKittiTimes(const std::string& path, const Trajectory& traj) {
  if (!traj.has_timestamps()) throw Error("trajectory has no timestamps", {.file = path});
  std::string out;
  for (int64_t t : traj.t_ns) out += FormatNsAsSeconds(t) + "\n";
  WriteFileAtomically(path, out);
}

}  // namespace optinav::io
