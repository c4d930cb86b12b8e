#include "optinav/eval/metrics.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include <fmt/format.h>

#include "optinav/geometry/alignment.h"
#include "optinav/io/text_parse.h"

namespace optinav::eval {
namespace {

int64_t SecondsToNs(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

// The double evo would hold for a stamp: the correctly rounded value of its decimal text.
double EvoSeconds(int64_t t_ns) {
  const std::string text = io::FormatNsAsSeconds(t_ns);
  double v = 0;
  std::from_chars(text.data(), text.data() + text.size(), v);
  return v;
}

// Association compares exact integer nanoseconds. Where the outcome hinges on differences
// below double resolution at epoch-sized stamps (~0.2 us), it is decided as evo decides it,
// on doubles, so results match evo exactly even at (near-)ties.
constexpr int64_t kNearTieNs = 2000;

// First index in [begin, end) of the run of values equal to v[k] (v sorted non-decreasing).
size_t FirstOfRun(const std::vector<int64_t>& v, size_t begin, size_t k) {
  return static_cast<size_t>(std::lower_bound(v.begin() + begin, v.begin() + k + 1, v[k]) -
                             v.begin());
}

// A pose as evo holds it: the matrices of the file. Inverse = transpose (evo's se3_inverse).
struct MatPose {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  MatPose Inverse() const { return {r.transpose(), -(r.transpose() * t)}; }
  MatPose operator*(const MatPose& o) const { return {r * o.r, r * o.t + t}; }
};

MatPose At(const Trajectory& traj, size_t i) { return {traj.rotations[i], traj.positions[i]}; }

double AngleOf(const Eigen::Matrix3d& r) {
  return RotationAngle(Eigen::Quaterniond(r).normalized());
}

double RelationError(const MatPose& e, PoseRelation relation) {
  switch (relation) {
    case PoseRelation::kTranslation:
      return e.t.norm();
    case PoseRelation::kRotation:
      return (e.r - Eigen::Matrix3d::Identity()).norm();
    case PoseRelation::kFull:
      return std::sqrt((e.r - Eigen::Matrix3d::Identity()).squaredNorm() + e.t.squaredNorm());
    case PoseRelation::kAngleRad:
      return AngleOf(e.r);
    case PoseRelation::kAngleDeg:
      return AngleOf(e.r) * 180.0 / M_PI;
  }
  return 0;
}

}  // namespace

SyncedPair Synchronize(Trajectory ref, Trajectory est, const AssociationOptions& options) {
  if (ref.empty() || est.empty()) throw Error("cannot associate an empty trajectory");
  SyncedPair out;
  out.max_pairs = std::min(ref.size(), est.size());
  if (!ref.has_timestamps() || !est.has_timestamps()) {
    if (ref.size() != est.size()) {
      throw Error(
          fmt::format("trajectories without timestamps are matched by index and need the "
                      "same number of poses (reference {}, estimate {})",
                      ref.size(), est.size()));
    }
    out.by_index = true;
    out.ref_indices.resize(ref.size());
    for (size_t i = 0; i < ref.size(); ++i) out.ref_indices[i] = i;
    out.est_indices = out.ref_indices;
    out.ref = std::move(ref);
    out.est = std::move(est);
    return out;
  }
  if (!(options.max_diff_s >= 0) || !std::isfinite(options.t_offset_s)) {
    throw Error("max_diff must be >= 0 and t_offset finite", {.field = "--max-diff"});
  }
  // As evo: the trajectory with fewer poses drives; ties make the estimate the shorter one.
  const bool est_longer = est.size() > ref.size();
  const Trajectory& lng = est_longer ? est : ref;
  const Trajectory& shrt = est_longer ? ref : est;
  const int64_t offset = SecondsToNs(options.t_offset_s);
  const int64_t max_diff = SecondsToNs(options.max_diff_s);
  // |t_long + off_long - t_short| with the offset applied to the estimate's side.
  const int64_t off_long = est_longer ? offset : -offset;
  const double off_long_s = est_longer ? options.t_offset_s : -options.t_offset_s;
  const std::vector<int64_t>& L = lng.t_ns;
  std::vector<size_t> idx_short, idx_long;
  idx_short.reserve(shrt.size());
  idx_long.reserve(shrt.size());
  size_t lo = 0;
  for (size_t s = 0; s < shrt.size(); ++s) {
    const int64_t target = shrt.t_ns[s] - off_long;
    // Short stamps never go backwards, so the first stamp >= target only moves forward: a
    // linear walk is amortised O(n + m) and cache friendly.
    size_t k = lo;
    while (k < L.size() && L[k] < target) ++k;
    lo = k;
    auto evo_diff = [&](size_t j) {
      return std::abs((EvoSeconds(L[j]) + off_long_s) - EvoSeconds(shrt.t_ns[s]));
    };
    size_t best;
    if (k == L.size()) {
      best = FirstOfRun(L, 0, k - 1);
    } else if (k == 0) {
      best = 0;
    } else {
      const int64_t d_left = target - L[k - 1];
      const int64_t d_right = L[k] - target;
      const size_t left = FirstOfRun(L, 0, k - 1);
      if (std::llabs(d_left - d_right) <= kNearTieNs) {
        best = evo_diff(left) <= evo_diff(k) ? left : k;  // argmin: first of equals
      } else {
        best = d_left < d_right ? left : k;
      }
    }
    const int64_t d_best = std::llabs(L[best] - target);
    const bool accept = std::llabs(d_best - max_diff) <= kNearTieNs
                            ? evo_diff(best) <= options.max_diff_s
                            : d_best <= max_diff;
    if (accept) {
      idx_short.push_back(s);
      idx_long.push_back(best);
    }
  }
  if (idx_short.empty()) {
    throw Error(
        fmt::format("found no matching timestamps between reference and estimate with "
                    "max. time diff {} s and time offset {} s (reference {}..{} s, "
                    "estimate {}..{} s)",
                    options.max_diff_s, options.t_offset_s, ref.t_ns.front() * 1e-9,
                    ref.t_ns.back() * 1e-9, est.t_ns.front() * 1e-9, est.t_ns.back() * 1e-9));
  }
  out.ref_indices = est_longer ? idx_short : idx_long;
  out.est_indices = est_longer ? idx_long : idx_short;
  ref.KeepOnly(out.ref_indices);
  est.KeepOnly(out.est_indices);
  out.ref = std::move(ref);
  out.est = std::move(est);
  return out;
}

std::optional<AlignMode> ParseAlignMode(const std::string& name) {
  if (name == "none") return AlignMode::kNone;
  if (name == "se3") return AlignMode::kSe3;
  if (name == "sim3") return AlignMode::kSim3;
  if (name == "scale") return AlignMode::kScale;
  if (name == "posyaw") return AlignMode::kPosYaw;
  return std::nullopt;
}

std::string AlignModeName(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kSe3:
      return "se3";
    case AlignMode::kSim3:
      return "sim3";
    case AlignMode::kScale:
      return "scale";
    case AlignMode::kPosYaw:
      return "posyaw";
  }
  return "?";
}

Eigen::Matrix4d AlignmentResult::Total() const {
  Eigen::Matrix4d m = ref_from_est.ToMatrix();
  if (origin_correction) m = origin_correction->ToMatrix() * m;
  return m;
}

AlignmentResult AlignTrajectory(const Trajectory& ref, Trajectory* est,
                                const AlignmentOptions& options) {
  OPTINAV_CHECK(est != nullptr && ref.size() == est->size());
  AlignmentResult result;
  result.options = options;
  const size_t n = options.n_to_align;
  switch (options.mode) {
    case AlignMode::kNone:
      break;
    case AlignMode::kSe3:
      result.ref_from_est = UmeyamaAlignment(est->positions, ref.positions, false, n);
      break;
    case AlignMode::kSim3:
      result.ref_from_est = UmeyamaAlignment(est->positions, ref.positions, true, n);
      break;
    case AlignMode::kScale:
      // evo's --correct_scale without --align: only the Umeyama scale is applied.
      result.ref_from_est = Sim3d{};
      result.ref_from_est.scale = UmeyamaAlignment(est->positions, ref.positions, true, n).scale;
      break;
    case AlignMode::kPosYaw:
      result.ref_from_est = PositionYawAlignment(est->positions, ref.positions, n);
      break;
  }
  if (options.mode != AlignMode::kNone) est->Transform(result.ref_from_est);
  if (options.align_origin) {
    // evo: ref_0 * se3_inverse(est_0), on the matrices as they are.
    const MatPose c = At(ref, 0) * At(*est, 0).Inverse();
    est->Transform(1.0, c.r, c.t);
    result.origin_correction = Rigid3d(QuaternionFromMatrix(c.r), c.t);
  }
  return result;
}

std::optional<PoseRelation> ParsePoseRelation(const std::string& name) {
  if (name == "trans" || name == "trans_part") return PoseRelation::kTranslation;
  if (name == "rot" || name == "rot_part") return PoseRelation::kRotation;
  if (name == "full") return PoseRelation::kFull;
  if (name == "angle_rad") return PoseRelation::kAngleRad;
  if (name == "angle_deg") return PoseRelation::kAngleDeg;
  return std::nullopt;
}

std::string PoseRelationName(PoseRelation r) {
  switch (r) {
    case PoseRelation::kTranslation:
      return "trans";
    case PoseRelation::kRotation:
      return "rot";
    case PoseRelation::kFull:
      return "full";
    case PoseRelation::kAngleRad:
      return "angle_rad";
    case PoseRelation::kAngleDeg:
      return "angle_deg";
  }
  return "?";
}

std::string PoseRelationTitle(PoseRelation r) {
  switch (r) {
    case PoseRelation::kTranslation:
      return "translation part";
    case PoseRelation::kRotation:
      return "rotation part";
    case PoseRelation::kFull:
      return "full transformation";
    case PoseRelation::kAngleRad:
      return "rotation angle in radians";
    case PoseRelation::kAngleDeg:
      return "rotation angle in degrees";
  }
  return "?";
}

std::string PoseRelationUnit(PoseRelation r) {
  switch (r) {
    case PoseRelation::kTranslation:
      return "m";
    case PoseRelation::kAngleRad:
      return "rad";
    case PoseRelation::kAngleDeg:
      return "deg";
    default:
      return "";
  }
}

ErrorSeries ComputeApe(const Trajectory& ref, const Trajectory& est, PoseRelation relation) {
  if (ref.size() != est.size()) throw Error("APE needs synchronized trajectories of equal size");
  if (ref.empty()) throw Error("APE of empty trajectories");
  ErrorSeries out;
  out.errors.resize(ref.size());
  out.indices.resize(ref.size());
  for (size_t i = 0; i < ref.size(); ++i) {
    out.indices[i] = i;
    if (relation == PoseRelation::kTranslation) {
      out.errors[i] = (est.positions[i] - ref.positions[i]).norm();
    } else {
      out.errors[i] = RelationError(At(est, i).Inverse() * At(ref, i), relation);
    }
  }
  out.stats = ComputeStatistics(out.errors);
  return out;
}

double MeanErrorAfterStartPose(const Trajectory& ref, const Trajectory& est) {
  if (ref.size() != est.size())
    throw Error("the start-pose error needs synchronized trajectories of equal size");
  if (ref.empty()) throw Error("the start-pose error of empty trajectories");
  Trajectory aligned = est;
  AlignTrajectory(ref, &aligned, {.mode = AlignMode::kNone, .align_origin = true});
  return ComputeApe(ref, aligned, PoseRelation::kTranslation).stats.mean;
}

std::optional<DeltaUnit> ParseDeltaUnit(const std::string& name) {
  if (name == "frames" || name == "f") return DeltaUnit::kFrames;
  if (name == "m") return DeltaUnit::kMeters;
  if (name == "s") return DeltaUnit::kSeconds;
  if (name == "rad") return DeltaUnit::kRadians;
  if (name == "deg") return DeltaUnit::kDegrees;
  return std::nullopt;
}

std::string DeltaUnitName(DeltaUnit u) {
  switch (u) {
    case DeltaUnit::kFrames:
      return "frames";
    case DeltaUnit::kMeters:
      return "m";
    case DeltaUnit::kSeconds:
      return "s";
    case DeltaUnit::kRadians:
      return "rad";
    case DeltaUnit::kDegrees:
      return "deg";
  }
  return "?";
}

std::string RpeOptions::Check() const {
  if (!(delta > 0) || !std::isfinite(delta)) {
    return fmt::format("--delta must be a positive number, got {}", delta);
  }
  if (unit == DeltaUnit::kFrames && delta != std::floor(delta)) {
    return fmt::format("--delta must be a whole number of frames, got {}", delta);
  }
  if (unit == DeltaUnit::kRadians && delta > M_PI) return "--delta in rad must be within (0, pi]";
  if (unit == DeltaUnit::kDegrees && delta > 180.0) return "--delta in deg must be within (0, 180]";
  if (!(rel_delta_tol >= 0)) return "--rel-delta-tol must be >= 0";
  return "";
}

std::vector<std::pair<size_t, size_t>> SelectRpePairs(const Trajectory& est, const RpeOptions& o) {
  std::vector<std::pair<size_t, size_t>> pairs;
  const size_t n = est.size();
  if (n < 2) return pairs;
  switch (o.unit) {
    case DeltaUnit::kFrames: {
      const size_t d = static_cast<size_t>(o.delta);
      if (o.all_pairs) {
        for (size_t i = 0; i + d < n; ++i) pairs.emplace_back(i, i + d);
      } else {
        for (size_t i = 0; i + d < n; i += d) pairs.emplace_back(i, i + d);
      }
      break;
    }
    case DeltaUnit::kMeters: {
      if (o.all_pairs) {
        std::vector<double> dist(n, 0.0);
        for (size_t i = 1; i < n; ++i) {
          dist[i] = dist[i - 1] + (est.positions[i] - est.positions[i - 1]).norm();
        }
        const double tol = o.delta * o.rel_delta_tol;
        for (size_t i = 0; i + 1 < n; ++i) {
          // argmin over j > i of |(dist[j] - dist[i]) - delta|, first of equals.
          auto cost = [&](size_t j) { return std::abs((dist[j] - dist[i]) - o.delta); };
          size_t k = static_cast<size_t>(
              std::lower_bound(dist.begin() + i + 1, dist.end(), dist[i] + o.delta) - dist.begin());
          size_t best = std::min(k, n - 1);
          if (k > i + 1 && (k == n || cost(k - 1) <= cost(k))) best = k - 1;
          best = static_cast<size_t>(
              std::lower_bound(dist.begin() + i + 1, dist.begin() + best + 1, dist[best]) -
              dist.begin());
          if (cost(best) <= tol) pairs.emplace_back(i, best);
        }
      } else {
        // evo: a pose is a pair boundary once the path since the previous boundary >= delta;
        // the first boundary is where the path from pose 0 first reaches delta.
        std::vector<size_t> ids;
        double path = 0;
        for (size_t i = 1; i < n; ++i) {
          path += (est.positions[i] - est.positions[i - 1]).norm();
          if (path >= o.delta) {
            ids.push_back(i);
            path = 0;
          }
        }
        for (size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
      }
      break;
    }
    case DeltaUnit::kRadians:
    case DeltaUnit::kDegrees: {
      const double scale = o.unit == DeltaUnit::kDegrees ? M_PI / 180.0 : 1.0;
      const double delta = o.delta * scale;
      const double tol = o.delta * o.rel_delta_tol * scale;
      if (o.all_pairs) {
        for (size_t i = 0; i + 1 < n; ++i) {
          const Eigen::Matrix3d inv = est.rotations[i].transpose();
          for (size_t j = i + 1; j < n; ++j) {
            const double a = AngleOf(inv * est.rotations[j]);
            if (a >= delta - tol && a <= delta + tol) pairs.emplace_back(i, j);
          }
        }
      } else {
        double acc = 0;
        size_t start = 0;
        for (size_t i = 0; i + 1 < n; ++i) {
          acc += AngleOf(est.rotations[i].transpose() * est.rotations[i + 1]);
          if (acc >= delta) {
            pairs.emplace_back(start, i + 1);
            acc = 0;
            start = i + 1;
          }
        }
      }
      break;
    }
    case DeltaUnit::kSeconds: {
      if (!est.has_timestamps()) throw Error("--unit s needs trajectories with timestamps");
      const int64_t delta = SecondsToNs(o.delta);
      const std::vector<int64_t>& t = est.t_ns;
      if (o.all_pairs) {
        const int64_t tol = SecondsToNs(o.delta * o.rel_delta_tol);
        for (size_t i = 0; i + 1 < n; ++i) {
          const int64_t target = t[i] + delta;
          const size_t k =
              static_cast<size_t>(std::lower_bound(t.begin() + i + 1, t.end(), target) - t.begin());
          size_t best = std::min(k, n - 1);
          if (k > i + 1 && (k == n || target - t[k - 1] <= t[k] - target)) {
            best = FirstOfRun(t, i + 1, k - 1);
          }
          if (std::llabs(t[best] - target) <= tol) pairs.emplace_back(i, best);
        }
      } else {
        size_t start = 0;
        for (size_t j = 1; j < n; ++j) {
          if (t[j] - t[start] >= delta) {
            pairs.emplace_back(start, j);
            start = j;
          }
        }
      }
      break;
    }
  }
  return pairs;
}

ErrorSeries ComputeRpe(const Trajectory& ref, const Trajectory& est, const RpeOptions& options) {
  if (const std::string msg = options.Check(); !msg.empty()) throw Error(msg);
  if (ref.size() != est.size()) throw Error("RPE needs synchronized trajectories of equal size");
  const auto pairs = SelectRpePairs(est, options);
  if (pairs.empty()) {
    throw Error(
        fmt::format("delta = {} ({}) produced no pose pairs among {} poses: try a smaller "
                    "delta{}",
                    options.delta, DeltaUnitName(options.unit), est.size(),
                    options.all_pairs ? " or a larger --rel-delta-tol" : ""));
  }
  ErrorSeries out;
  out.errors.reserve(pairs.size());
  out.indices.reserve(pairs.size());
  for (const auto& [i, j] : pairs) {
    const MatPose q_rel = At(ref, i).Inverse() * At(ref, j);
    const MatPose p_rel = At(est, i).Inverse() * At(est, j);
    out.errors.push_back(RelationError(q_rel.Inverse() * p_rel, options.relation));
    out.indices.push_back(j);
  }
  out.stats = ComputeStatistics(out.errors);
  return out;
}

}  // namespace optinav::eval
