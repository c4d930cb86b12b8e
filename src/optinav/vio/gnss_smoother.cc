#include "optinav/vio/gnss_smoother.h"

#include <algorithm>
#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "optinav/geometry/lie.h"
#include "optinav/util/logging.h"
#include "optinav/util/timer.h"

namespace optinav::vio {
namespace {

// The alignment's change between consecutive frames, measured where the VIO is (a yaw change
// about the current position moves nothing there).
struct WalkCost {
  WalkCost(const Eigen::Vector3d& p, double sigma_t, double sigma_yaw)
      : p_(p), inv_t_(1.0 / sigma_t), inv_yaw_(1.0 / sigma_yaw) {}
  template <typename T>
  bool operator()(const T* a0, const T* a1, T* r) const {
    T e0[3], e1[3];
    ApplyAlignment(a0, p_, e0);
    ApplyAlignment(a1, p_, e1);
    for (int k = 0; k < 3; ++k) r[k] = (e1[k] - e0[k]) * inv_t_;
    r[3] = (a1[3] - a0[3]) * inv_yaw_;
    return true;
  }
  Eigen::Vector3d p_;
  double inv_t_, inv_yaw_;
};

struct SampleCost {
  SampleCost(const Eigen::Vector3d& antenna_world, const Eigen::Vector3d& z, double sigma)
      : p_(antenna_world), z_(z), inv_(1.0 / sigma) {}
  template <typename T>
  bool operator()(const T* a, T* r) const {
    T e[3];
    ApplyAlignment(a, p_, e);
    for (int k = 0; k < 3; ++k) r[k] = (e[k] - z_[k]) * inv_;
    return true;
  }
  Eigen::Vector3d p_, z_;
  double inv_;
};

// A weak pull to the live alignment, only so that a direction no sample observes (the yaw of a
// track flown in a straight line at one point) stays defined.
struct WeakPriorCost {
  WeakPriorCost(const Eigen::Vector4d& a0) : a0_(a0) {}
  template <typename T>
  bool operator()(const T* a, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = (a[k] - a0_[k]) * 1e-3;  // 1 km
    r[3] = (a[3] - a0_[3]) * 1.0;                               // 1 rad
    return true;
  }
  Eigen::Vector4d a0_;
};

}  // namespace

std::vector<std::optional<WorldAlignment>> LiveAlignments(
    const std::vector<FrameEstimate>& estimates) {
  std::vector<std::optional<WorldAlignment>> out(estimates.size());
  const auto first = std::find_if(estimates.begin(), estimates.end(), [](const FrameEstimate& e) {
    return e.enu_from_world.has_value();
  });
  if (first == estimates.end()) return out;
  WorldAlignment live = *first->enu_from_world;
  for (size_t i = 0; i < estimates.size(); ++i) {
    if (estimates[i].enu_from_world) live = *estimates[i].enu_from_world;
    out[i] = live;
  }
  return out;
}

GnssSmoothing SmoothGnssAlignment(const std::vector<FrameEstimate>& estimates,
                                  const std::vector<size_t>& track_starts,
                                  const std::vector<GnssSample>& used_in,
                                  const std::vector<AlignmentInflation>& inflations,
                                  const GnssFusionOptions& options) {
  GnssSmoothing out;
  const size_t n = estimates.size();
  out.enu_from_world = LiveAlignments(estimates);  // the initial values
  if (!options.smooth || n == 0 || !out.enu_from_world.front()) return out;
  Timer timer;
  std::vector<GnssSample> used = used_in;
  std::stable_sort(used.begin(), used.end(),
                   [](const GnssSample& a, const GnssSample& b) { return a.t_ns < b.t_ns; });

  // VIO tracks: [begin, end) index ranges.
  std::vector<std::pair<size_t, size_t>> tracks;
  size_t begin = 0;
  for (size_t i = 1; i <= n; ++i) {
    const bool split =
        i == n || std::find(track_starts.begin(), track_starts.end(), i) != track_starts.end();
    if (split) tracks.emplace_back(begin, i), begin = i;
  }

  for (const auto& [b, e] : tracks) {
    if (e - b < 2) continue;
    const int64_t t_begin = estimates[b].state.t_ns, t_end = estimates[e - 1].state.t_ns;
    const auto s_begin =
        std::lower_bound(used.begin(), used.end(), t_begin,
                         [](const GnssSample& s, int64_t t) { return s.t_ns < t; });
    const auto s_end = std::upper_bound(used.begin(), used.end(), t_end,
                                        [](int64_t t, const GnssSample& s) { return t < s.t_ns; });
    if (s_end - s_begin < 3) continue;

    std::vector<Eigen::Vector4d> params(e - b);
    for (size_t i = b; i < e; ++i) params[i - b] = out.enu_from_world[i]->Block();
    ceres::Problem problem;
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<WeakPriorCost, 4, 4>(new WeakPriorCost(params.front())),
        nullptr, params.front().data());
    auto inflation = inflations.begin();
    for (size_t i = b; i + 1 < e; ++i) {
      const StateEstimate& s0 = estimates[i].state;
      const StateEstimate& s1 = estimates[i + 1].state;
      const double dist = (s1.world_from_body.translation - s0.world_from_body.translation).norm();
      const double dt = (s1.t_ns - s0.t_ns) * 1e-9;
      const double k2 = options.smooth_walk_scale * options.smooth_walk_scale;
      double var_t =
          k2 * options.alignment_walk_m_per_sqrt_m * options.alignment_walk_m_per_sqrt_m * dist +
          options.smooth_walk_m_per_sqrt_s * options.smooth_walk_m_per_sqrt_s * dt;
      double var_yaw = k2 * options.alignment_walk_rad_per_sqrt_m *
                           options.alignment_walk_rad_per_sqrt_m * dist +
                       options.smooth_walk_rad_per_sqrt_s * options.smooth_walk_rad_per_sqrt_s * dt;
      // An inflation made while fusing a sample in [t_i+1, t_i+2) loosens the step into frame
      // i+1, the frame that sample constrains.
      while (inflation != inflations.end() && inflation->t_ns < s1.t_ns) ++inflation;
      const int64_t t_next = i + 2 < e ? estimates[i + 2].state.t_ns : INT64_MAX;
      for (; inflation != inflations.end() && inflation->t_ns < t_next; ++inflation) {
        var_t += inflation->sigma.head<3>().squaredNorm() / 3.0;
        var_yaw += inflation->sigma[3] * inflation->sigma[3];
      }
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<WalkCost, 4, 4, 4>(new WalkCost(
                                   s0.world_from_body.translation, std::sqrt(std::max(var_t, 1e-8)),
                                   std::sqrt(std::max(var_yaw, 1e-12)))),
                               nullptr, params[i - b].data(), params[i + 1 - b].data());
    }
    size_t frame = b;
    for (auto it = s_begin; it != s_end; ++it) {
      while (frame + 1 < e && estimates[frame + 1].state.t_ns <= it->t_ns) ++frame;
      const StateEstimate& a = estimates[frame].state;
      Rigid3d pose = a.world_from_body;
      if (frame + 1 < e && a.t_ns < it->t_ns) {
        const StateEstimate& c = estimates[frame + 1].state;
        const double u =
            static_cast<double>(it->t_ns - a.t_ns) / static_cast<double>(c.t_ns - a.t_ns);
        pose = InterpolatePose(a.world_from_body, c.world_from_body, u);
      }
      const Eigen::Vector3d antenna = pose.translation + pose.rotation * options.lever_arm_in_body;
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SampleCost, 3, 4>(
                                   new SampleCost(antenna, it->position_enu_m, it->sigma_m)),
                               MakeGnssLoss(options.norm, options.norm_parameter).release(),
                               params[frame - b].data());
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    so.max_num_iterations = 50;
    so.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    if (!summary.IsSolutionUsable()) {
      spdlog::warn("gnss smoother: track at {:.3f} s not solved ({}); the live alignment is kept",
                   t_begin * 1e-9, summary.message);
      continue;
    }
    for (size_t i = b; i < e; ++i)
      out.enu_from_world[i] = WorldAlignment::FromBlock(params[i - b].data());
    ++out.tracks_smoothed;
    out.samples += static_cast<size_t>(s_end - s_begin);
    spdlog::debug(
        "gnss smoother: track {:.3f}-{:.3f} s, {} frames, {} samples: {} iterations, cost "
        "{:.1f} -> {:.1f}",
        t_begin * 1e-9, t_end * 1e-9, e - b, s_end - s_begin, summary.iterations.size(),
        summary.initial_cost, summary.final_cost);
  }
  out.solve_s = timer.ElapsedSeconds();
  return out;
}

Trajectory EstimatesToEnuTrajectory(
    const std::vector<FrameEstimate>& estimates,
    const std::vector<std::optional<WorldAlignment>>& enu_from_world,
    const std::optional<Rigid3d>& body_from_cam) {
  Trajectory t;
  t.Reserve(estimates.size(), true);
  for (size_t i = 0; i < estimates.size() && i < enu_from_world.size(); ++i) {
    if (!enu_from_world[i]) continue;
    const Rigid3d& world_from_body = estimates[i].state.world_from_body;
    t.Add(estimates[i].state.t_ns,
          enu_from_world[i]->EnuFromWorld() *
              (body_from_cam ? world_from_body * *body_from_cam : world_from_body));
  }
  return t;
}

}  // namespace optinav::vio
