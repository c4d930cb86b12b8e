#include "optinav/io/trajectory_io.h"

#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "optinav/io/text_parse.h"

namespace optinav::io {
namespace {

constexpr const char* kTumFields[] = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};
constexpr const char* kEurocFields[] = {"timestamp", "px", "py", "pz", "qw", "qx", "qy", "qz"};

// Appends a pose after checking its quaternion and timestamp. Timestamps must not go
// backwards; repeated stamps occur in real files (evo's own V102.txt has four), so they are
// accepted and counted, and association then takes the first of equals.
template <typename ContextFn>
void AddChecked(int64_t t, double w, double x, double y, double z, const Eigen::Vector3d& p,
                const char* quaternion_field, const char* time_field, const ContextFn& context,
                Trajectory* traj, size_t* repeats) {
  const double norm2 = w * w + x * x + y * y + z * z;
  if (!(norm2 > 1e-12)) {
    ErrorContext ctx = context();
    ctx.field = quaternion_field;
    throw Error("quaternion has (near) zero norm", ctx);
  }
  if (!traj->t_ns.empty() && t <= traj->t_ns.back()) {
    if (t == traj->t_ns.back()) {
      ++*repeats;
    } else {
      ErrorContext ctx = context();
      ctx.field = time_field;
      throw Error(fmt::format("timestamp {} s goes backwards (previous {} s)", FormatNsAsSeconds(t),
                              FormatNsAsSeconds(traj->t_ns.back())),
                  ctx);
    }
  }
  const double inv = 1.0 / std::sqrt(norm2);
  traj->t_ns.push_back(t);
  traj->positions.push_back(p);
  traj->rotations.push_back(
      Eigen::Quaterniond(w * inv, x * inv, y * inv, z * inv).toRotationMatrix());
}

// The two timestamped one-pose-per-line layouts.
struct PoseLineFormat {
  char delim;             // ' ' (runs of blanks) or ','
  bool time_in_seconds;   // else integer nanoseconds
  bool extra_columns_ok;  // EuRoC ground truth carries velocity and biases after the pose
  bool quaternion_wxyz;   // else x y z w
  const char* const* field_names;
  const char* layout;     // for error messages
  size_t bytes_per_line;  // for reserving
};

constexpr PoseLineFormat kTumFormat{
    ' ', true, false, false, kTumFields, "8 values 't x y z qx qy qz qw' (TUM)", 64};
constexpr PoseLineFormat kEurocFormat{',',
                                      false,
                                      true,
                                      true,
                                      kEurocFields,
                                      "8 comma-separated values 'timestamp [ns], px, py, pz, qw, "
                                      "qx, qy, qz' (EuRoC)",
                                      100};

Trajectory ReadPoseLines(const std::string& path, const PoseLineFormat& lf) {
  const MappedFile file(path);
  const std::string_view text = file.view();
  Trajectory traj;
  traj.Reserve(text.size() / lf.bytes_per_line + 1, true);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  double v[8];
  size_t repeats = 0;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    int64_t t = 0;
    const bool fast = ParseNumberLine(line, lf.delim, 8, lf.time_in_seconds, !lf.time_in_seconds,
                                      &t, v, lf.extra_columns_ok ? 8 : -1);
    // The context (a string copy) is built only when needed: errors and the slow path.
    auto context = [&] { return ErrorContext{.file = path, .line = cursor.line_number()}; };
    if (!fast) {
      // Slow path: re-parse field by field to say exactly what is wrong.
      ErrorContext ctx = context();
      SplitFields(line, lf.delim, &f);
      if (f.size() < 8 || (!lf.extra_columns_ok && f.size() != 8)) {
        throw Error(fmt::format("expected {}{}, found {}", lf.extra_columns_ok ? "at least " : "",
                                lf.layout, f.size()),
                    ctx);
      }
      ctx.field = lf.field_names[0];
      t = lf.time_in_seconds ? ParseSecondsToNs(f[0], ctx) : ParseInt64(f[0], ctx);
      for (int k = 1; k < 8; ++k) {
        ctx.field = lf.field_names[k];
        v[k] = ParseFiniteDouble(f[k], ctx);
      }
    }
    const Eigen::Vector3d p(v[1], v[2], v[3]);
    if (lf.quaternion_wxyz) {
      AddChecked(t, v[4], v[5], v[6], v[7], p, "qw qx qy qz", lf.field_names[0], context, &traj,
                 &repeats);
    } else {
      AddChecked(t, v[7], v[4], v[5], v[6], p, "qx qy qz qw", lf.field_names[0], context, &traj,
                 &repeats);
    }
  }
  if (repeats > 0) spdlog::warn("{}: {} repeated timestamp(s)", path, repeats);
  return traj;
}

// Appends a KITTI pose after checking its rotation block.
void AddKittiPose(const Eigen::Matrix<double, 3, 4>& m, ErrorContext* ctx, Trajectory* traj) {
  const Eigen::Matrix3d r = m.leftCols<3>();
  if (std::abs(r.determinant()) < 1e-6) {
    ctx->field = "rotation";
    throw Error("rotation block is singular", *ctx);
  }
  // Kept as written (evo does the same); only a singular block is rejected above.
  traj->AddMatrix(r, m.col(3));
}

// Throws Error naming the row and the field when one of the `n` values is not finite.
void CheckFiniteRow(const double* v, int n, const char* const* field_names,
                    const ErrorContext& ctx) {
  for (int k = 0; k < n; ++k) {
    if (!std::isfinite(v[k])) {
      ErrorContext c = ctx;
      c.field = field_names ? field_names[k] : fmt::format("r{}c{}", k / 4, k % 4);
      throw Error(fmt::format("not a finite number: {}", v[k]), c);
    }
  }
}

Trajectory ReadKitti(const std::string& path, const std::string& times_path) {
  const MappedFile file(path);
  const std::string_view text = file.view();
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
      throw Error(fmt::format("expected 12 values (3x4 row-major pose, KITTI), found {}", f.size()),
                  ctx);
    }
    for (int k = 0; k < 12; ++k) {
      ctx.field = fmt::format("r{}c{}", k / 4, k % 4);
      m(k / 4, k % 4) = ParseFiniteDouble(f[k], ctx);
    }
    AddKittiPose(m, &ctx, &traj);
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
    case TrajectoryFormat::kAuto:
      return "auto";
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kKitti:
      return "kitti";
    case TrajectoryFormat::kEuroc:
      return "euroc";
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
      if (t.find(',') != std::string_view::npos &&
          (t.rfind("#timestamp", 0) == 0 || t.rfind("#time", 0) == 0)) {
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
    throw Error(
        fmt::format("cannot detect format: {} columns (TUM has 8, KITTI 12)", f.size()) + hint,
        ctx);
  }
  throw Error("empty trajectory file (no data lines)", {.file = path});
}

Trajectory ReadTrajectory(const std::string& path, const TrajectoryReadOptions& options) {
  TrajectoryFormat format = options.format;
  if (format == TrajectoryFormat::kAuto) format = DetectTrajectoryFormat(path);
  Trajectory traj;
  switch (format) {
    case TrajectoryFormat::kTum:
      traj = ReadPoseLines(path, kTumFormat);
      break;
    case TrajectoryFormat::kKitti:
      traj = ReadKitti(path, options.kitti_times_path);
      break;
    case TrajectoryFormat::kEuroc:
      traj = ReadPoseLines(path, kEurocFormat);
      break;
    case TrajectoryFormat::kAuto:
      break;
  }
  if (traj.empty()) {
    throw Error("no poses in " + TrajectoryFormatName(format) + " trajectory file", {.file = path});
  }
  if (format != TrajectoryFormat::kKitti && !options.kitti_times_path.empty()) {
    throw Error("a times file only applies to KITTI trajectories", {.file = path});
  }
  return traj;
}

Trajectory TrajectoryFromTumRows(const double* rows, size_t n, const std::string& source) {
  if (n == 0) throw Error("no poses (0 rows)", {.file = source});
  Trajectory traj;
  traj.Reserve(n, true);
  size_t repeats = 0;
  for (size_t i = 0; i < n; ++i) {
    const double* v = rows + 8 * i;
    const ErrorContext ctx{.file = source, .line = static_cast<int64_t>(i + 1)};
    CheckFiniteRow(v, 8, kTumFields, ctx);
    ErrorContext tc = ctx;
    tc.field = kTumFields[0];
    // Shortest round-trip text: the decimal a TUM file held when the array was loaded from one.
    const int64_t t = ParseSecondsToNs(fmt::format("{}", v[0]), tc);
    AddChecked(
        t, v[7], v[4], v[5], v[6], Eigen::Vector3d(v[1], v[2], v[3]), "qx qy qz qw", kTumFields[0],
        [&] { return ctx; }, &traj, &repeats);
  }
  if (repeats > 0) spdlog::warn("{}: {} repeated timestamp(s)", source, repeats);
  return traj;
}

Trajectory TrajectoryFromKittiRows(const double* rows, size_t n, const std::string& source) {
  if (n == 0) throw Error("no poses (0 rows)", {.file = source});
  Trajectory traj;
  traj.Reserve(n, false);
  for (size_t i = 0; i < n; ++i) {
    ErrorContext ctx{.file = source, .line = static_cast<int64_t>(i + 1)};
    CheckFiniteRow(rows + 12 * i, 12, nullptr, ctx);
    const Eigen::Matrix<double, 3, 4> m =
        Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>>(rows + 12 * i);
    AddKittiPose(m, &ctx, &traj);
  }
  return traj;
}

Trajectory TrajectoryFromEurocRows(const int64_t* t_ns, const double* rows, size_t n,
                                   const std::string& source) {
  if (n == 0) throw Error("no poses (0 rows)", {.file = source});
  Trajectory traj;
  traj.Reserve(n, true);
  size_t repeats = 0;
  for (size_t i = 0; i < n; ++i) {
    const double* v = rows + 7 * i;
    const ErrorContext ctx{.file = source, .line = static_cast<int64_t>(i + 1)};
    CheckFiniteRow(v, 7, kEurocFields + 1, ctx);
    AddChecked(
        t_ns[i], v[3], v[4], v[5], v[6], Eigen::Vector3d(v[0], v[1], v[2]), "qw qx qy qz",
        kEurocFields[0], [&] { return ctx; }, &traj, &repeats);
  }
  if (repeats > 0) spdlog::warn("{}: {} repeated timestamp(s)", source, repeats);
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
        fmt::format_to(
            std::back_inserter(out), "{} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}\n",
            FormatNsAsSeconds(traj.t_ns[i]), p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
      }
      break;
    case TrajectoryFormat::kEuroc:
      out +=
          "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
          "q_RS_y [],q_RS_z []\n";
      for (size_t i = 0; i < traj.size(); ++i) {
        const auto& p = traj.positions[i];
        const Eigen::Quaterniond q = traj.quaternion(i);
        fmt::format_to(std::back_inserter(out),
                       "{},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f}\n", traj.t_ns[i], p.x(),
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
