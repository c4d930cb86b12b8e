#include "optinav/vio/gnss_fusion.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Cholesky>
#include <ceres/autodiff_cost_function.h>
#include <fmt/format.h>

#include "optinav/util/error.h"
#include "optinav/util/logging.h"

namespace optinav::vio {

std::optional<GnssNorm> ParseGnssNorm(const std::string& name) {
  if (name == "l2") return GnssNorm::kL2;
  if (name == "huber") return GnssNorm::kHuber;
  if (name == "tukey") return GnssNorm::kTukey;
  return std::nullopt;
}

std::string GnssNormName(GnssNorm norm) {
  switch (norm) {
    case GnssNorm::kL2:
      return "l2";
    case GnssNorm::kHuber:
      return "huber";
    case GnssNorm::kTukey:
      return "tukey";
  }
  return "?";
}

std::unique_ptr<ceres::LossFunction> MakeGnssLoss(GnssNorm norm, double parameter) {
  const double k = parameter > 0 ? parameter : DefaultGnssNormParameter(norm);
  if (norm == GnssNorm::kHuber) return std::make_unique<ceres::HuberLoss>(k);
  if (norm == GnssNorm::kTukey) return std::make_unique<ceres::TukeyLoss>(k);
  return nullptr;
}

double DefaultGnssNormParameter(GnssNorm norm) {
  // Whitened 3-D residual norms of inliers are ~1.6 (chi with 3 DoF): Huber stays quadratic for
  // nearly all of them; Tukey ignores anything beyond 5 sigma.
  return norm == GnssNorm::kTukey ? 5.0 : 2.5;
}

std::optional<GnssTimeMode> ParseGnssTimeMode(const std::string& name) {
  if (name == "exact") return GnssTimeMode::kExact;
  if (name == "frame") return GnssTimeMode::kFrameInterpolated;
  return std::nullopt;
}

std::string GnssTimeModeName(GnssTimeMode mode) {
  return mode == GnssTimeMode::kExact ? "exact" : "frame";
}

std::string GnssFusionOptions::Check() const {
  if (norm != GnssNorm::kL2 && norm_parameter == 0) return "gnss norm parameter must be > 0";
  if (!lever_arm_in_body.allFinite()) return "gnss lever arm must be finite";
  if (!(init_min_distance_m >= 0)) return "init_min_distance_m must be >= 0";
  if (!(init_max_yaw_sigma_rad > 0)) return "init_max_yaw_sigma_rad must be > 0";
  if (!(init_max_yaw_effect_m >= 0)) return "init_max_yaw_effect_m must be >= 0";
  if (init_min_samples < 3) return "init_min_samples must be >= 3";
  if (!(init_min_inlier_fraction >= 0 && init_min_inlier_fraction <= 1))
    return "init_min_inlier_fraction must be in [0, 1]";
  if (!(init_max_chi2_per_axis > 0)) return "init_max_chi2_per_axis must be > 0";
  if (!(init_settle_s >= 0)) return "init_settle_s must be >= 0";
  if (!std::isfinite(gate_chi2)) return "gate_chi2 must be finite";
  if (!(yaw_hold_speed_m_s >= 0)) return "yaw_hold_speed_m_s must be >= 0";
  if (!(drift_fraction >= 0) || !(drift_m_per_sqrt_s >= 0) || !(min_state_sigma_m > 0))
    return "VIO drift model parameters must be >= 0 (min_state_sigma_m > 0)";
  if (!(model_sigma_m >= 0)) return "model_sigma_m must be >= 0";
  if (!(factor_sigma_scale > 0) || !std::isfinite(factor_sigma_scale))
    return "factor_sigma_scale must be > 0";
  if (!(reopen_after_s > 0)) return "reopen_after_s must be > 0";
  if (!(reopen_yaw_sigma_rad >= 0)) return "reopen_yaw_sigma_rad must be >= 0";
  if (drift_window_samples < 1) return "drift_window_samples must be >= 1";
  if (!std::isfinite(drift_test_chi2)) return "drift_test_chi2 must be finite";
  if (!(max_interpolation_gap_s > 0)) return "max_interpolation_gap_s must be > 0";
  if (!(smooth_walk_scale > 0) || !std::isfinite(smooth_walk_scale))
    return "smooth_walk_scale must be > 0";
  if (!(smooth_walk_m_per_sqrt_s >= 0) || !(smooth_walk_rad_per_sqrt_s >= 0))
    return "smoother walk parameters must be >= 0";
  if (!(alignment_walk_m_per_sqrt_m >= 0) || !(alignment_walk_rad_per_sqrt_m >= 0))
    return "alignment random walk must be >= 0";
  if (!(relock_sigma_m > 0) || !(relock_yaw_sigma_rad > 0)) return "relock sigmas must be > 0";
  return "";
}

namespace {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

// The antenna at time t from the anchor state i and the IMU preintegrated from i to t, mapped
// to ENU by the alignment, minus the measurement, over sigma.
class GnssFunctor {
 public:
  GnssFunctor(const ImuPreintegration& pre, const Eigen::Vector3d& gravity,
              const Eigen::Vector3d& lever, const Eigen::Vector3d& measured, double sigma)
      : predict_(pre, gravity), lever_(lever), measured_(measured), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* pose, const T* sb, const T* align, T* residuals) const {
    Vec3<T> p_t;
    Eigen::Quaternion<T> q_t;
    predict_(pose, sb, &p_t, nullptr, &q_t);
    const Vec3<T> antenna = p_t + q_t * lever_.cast<T>();
    T enu[3];
    ApplyAlignment(align, antenna, enu);
    for (int k = 0; k < 3; ++k) residuals[k] = (enu[k] - T(measured_[k])) * T(inv_sigma_);
    return true;
  }

 private:
  TimedStatePredictor predict_;
  Eigen::Vector3d lever_, measured_;
  double inv_sigma_;
};

class GnssFactor : public TimedFactor {
 public:
  GnssFactor(const GnssSample& s, const Eigen::Vector3d& lever, const ceres::LossFunction* loss)
      : sample_(s), lever_(lever), loss_(loss) {}
  int64_t t_ns() const override { return sample_.t_ns; }
  ceres::CostFunction* Create(const ImuPreintegration& anchor_to_t, const Eigen::Vector3d& gravity,
                              bool uses_speed_bias) const override {
    OPTINAV_CHECK_MSG(uses_speed_bias, "GNSS factors need the IMU (stereo-imu mode)");
    return new ceres::AutoDiffCostFunction<GnssFunctor, 3, kPoseSize, kSpeedBiasSize,
                                           kAlignmentSize>(
        new GnssFunctor(anchor_to_t, gravity, lever_, sample_.position_enu_m, sample_.sigma_m));
  }
  const ceres::LossFunction* loss() const override { return loss_; }
  bool uses_alignment() const override { return true; }

 private:
  GnssSample sample_;
  Eigen::Vector3d lever_;
  const ceres::LossFunction* loss_;
};

Eigen::Vector3d Apply(const WorldAlignment& a, const Eigen::Vector3d& p_world) {
  const Eigen::Vector4d block = a.Block();
  Eigen::Vector3d out;
  ApplyAlignment(block.data(), p_world, out.data());
  return out;
}

// d(enu)/d[tx, ty, tz, yaw] at p_world.
Eigen::Matrix<double, 3, 4> AlignmentJacobian(const WorldAlignment& a,
                                              const Eigen::Vector3d& p_world) {
  Eigen::Matrix<double, 3, 4> J = Eigen::Matrix<double, 3, 4>::Zero();
  J.leftCols<3>().setIdentity();
  const double c = std::cos(a.yaw_rad), s = std::sin(a.yaw_rad);
  J(0, 3) = -s * p_world.x() - c * p_world.y();
  J(1, 3) = c * p_world.x() - s * p_world.y();
  return J;
}

}  // namespace

struct GnssFusion::Evidence {
  GnssSample sample;
  Eigen::Vector3d antenna_world;
};

GnssFusion::GnssFusion(const GnssFusionOptions& options) : options_(options) {
  const std::string problem = options_.Check();
  OPTINAV_CHECK_MSG(problem.empty(), problem);
  loss_ = MakeGnssLoss(options_.norm, options_.norm_parameter);
}

GnssFusion::~GnssFusion() = default;

void GnssFusion::Reject(const GnssSample& s, const std::string& reason, double innovation_m) {
  rejected_.push_back({s.t_ns, s.position_enu_m, reason, innovation_m});
  ++stats_.rejected;
}

void GnssFusion::AddSample(const GnssSample& sample) {
  ++stats_.received;
  if (last_sample_ns_ && sample.t_ns <= *last_sample_ns_) {
    Reject(sample, "timestamp not after the previous sample");
    return;
  }
  if (!sample.position_enu_m.allFinite() || !(sample.sigma_m > 0)) {
    Reject(sample, "non-finite position or sigma <= 0");
    return;
  }
  last_sample_ns_ = sample.t_ns;
  GnssSample s = sample;
  s.sigma_m = std::hypot(sample.sigma_m, options_.model_sigma_m);
  pending_.push_back(s);
}

void GnssFusion::OnTrackLost() {
  history_.clear();
  track_start_ns_.reset();
  evidence_.clear();
  evidence_tried_ = 0;
  frames_waiting_.clear();
  last_ready_.reset();
  rejecting_since_ns_.reset();
  relock_ = alignment_.has_value();
}

std::optional<Rigid3d> GnssFusion::WorldPoseAt(int64_t t_ns) const {
  if (history_.empty() || t_ns < history_.front().t_ns || t_ns > history_.back().t_ns)
    return std::nullopt;
  for (size_t k = history_.size(); k-- > 0;) {
    const StateEstimate& a = history_[k];
    if (a.t_ns > t_ns) continue;
    if (a.t_ns == t_ns || k + 1 == history_.size()) return a.world_from_body;
    const StateEstimate& b = history_[k + 1];
    const double u = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
    return Rigid3d(a.world_from_body.rotation.slerp(u, b.world_from_body.rotation),
                   (1 - u) * a.world_from_body.translation + u * b.world_from_body.translation);
  }
  return std::nullopt;
}

void GnssFusion::OnFrame(const StateEstimate& estimate, SlidingWindowBackend* backend) {
  // The model of the VIO position uncertainty grows with the motion since the previous frame.
  if (!history_.empty()) {
    const double dist =
        (estimate.world_from_body.translation - history_.back().world_from_body.translation).norm();
    const double dt = (estimate.t_ns - history_.back().t_ns) * 1e-9;
    state_var_m2_ += std::pow(options_.drift_fraction * dist, 2) +
                     options_.drift_m_per_sqrt_s * options_.drift_m_per_sqrt_s * dt;
  }
  history_.push_back(estimate);
  if (!track_start_ns_) track_start_ns_ = estimate.t_ns;
  while (history_.size() > 2 && history_[1].t_ns < estimate.t_ns - 2'000'000'000)
    history_.pop_front();

  // After a VIO re-initialisation the world frame continues from the last good pose: the old
  // alignment holds approximately; re-lock it with a loose prior and a wide gate.
  if (relock_ && alignment_ && backend->initialized() && !backend->alignment_enabled()) {
    Eigen::Matrix4d sqrt_info = Eigen::Matrix4d::Zero();
    sqrt_info.diagonal() << Eigen::Vector3d::Constant(1.0 / options_.relock_sigma_m),
        1.0 / options_.relock_yaw_sigma_rad;
    backend->EnableAlignment(*alignment_, sqrt_info);
    backend->SetAlignmentRandomWalk(options_.alignment_walk_m_per_sqrt_m,
                                    options_.alignment_walk_rad_per_sqrt_m);
    state_var_m2_ = options_.relock_sigma_m * options_.relock_sigma_m;
    state_var_floor_m2_ = 0;
    innovation_mean_.setZero();
    innovation_mean_var_ = 0;
    relock_ = false;
    ++stats_.alignments;
    spdlog::info("gnss: alignment re-locked after a VIO re-initialisation at {:.3f} s",
                 estimate.t_ns * 1e-9);
  }
  if (backend->alignment_enabled()) {
    alignment_ = backend->alignment();
    if (spdlog::should_log(spdlog::level::debug) && estimate.t_ns >= next_debug_ns_) {
      spdlog::debug(
          "gnss: alignment at {:.3f} s: translation ({:.3f}, {:.3f}, {:.3f}) m, yaw "
          "{:.3f} deg; mean innovation ({:.3f}, {:.3f}, {:.3f}) m",
          estimate.t_ns * 1e-9, alignment_->translation.x(), alignment_->translation.y(),
          alignment_->translation.z(), alignment_->yaw_rad * 180 / M_PI, innovation_mean_.x(),
          innovation_mean_.y(), innovation_mean_.z());
      next_debug_ns_ = estimate.t_ns + 5'000'000'000;
    }
    backend->SetAlignmentYawHeld(estimate.velocity.head<2>().norm() < options_.yaw_hold_speed_m_s);
  }

  // Samples up to this frame are ready.
  while (!pending_.empty() && pending_.front().t_ns <= estimate.t_ns) {
    const GnssSample s = pending_.front();
    pending_.pop_front();
    if (options_.time_mode == GnssTimeMode::kExact) {
      Use(s, backend);
      continue;
    }
    // The baseline of the Kimera-VIO GNSS study (SEEDS.md part 2): measurements linearly
    // interpolated to the frame times between this sample and the previous one.
    if (last_ready_ && (s.t_ns - last_ready_->t_ns) * 1e-9 <= options_.max_interpolation_gap_s) {
      for (int64_t t : frames_waiting_) {
        if (t < last_ready_->t_ns || t > s.t_ns) continue;
        const double u = static_cast<double>(t - last_ready_->t_ns) /
                         static_cast<double>(s.t_ns - last_ready_->t_ns);
        GnssSample at_frame;
        at_frame.t_ns = t;
        at_frame.position_enu_m = (1 - u) * last_ready_->position_enu_m + u * s.position_enu_m;
        at_frame.sigma_m = (1 - u) * last_ready_->sigma_m + u * s.sigma_m;
        Use(at_frame, backend);
      }
    }
    std::erase_if(frames_waiting_, [&](int64_t t) { return t <= s.t_ns; });
    last_ready_ = s;
  }
  if (options_.time_mode == GnssTimeMode::kFrameInterpolated)
    frames_waiting_.push_back(estimate.t_ns);
  if (!backend->alignment_enabled() && !relock_) TryInitialize(backend);
}

void GnssFusion::Use(const GnssSample& s, SlidingWindowBackend* backend) {
  const std::optional<Rigid3d> pose = WorldPoseAt(s.t_ns);
  if (!pose) {
    Reject(s, "no VIO pose at its time (before the first frame or while tracking is lost)");
    return;
  }
  const Eigen::Vector3d antenna = pose->translation + pose->rotation * options_.lever_arm_in_body;
  if (!backend->alignment_enabled()) {
    if (relock_) {
      Reject(s, "VIO re-initialising");
      return;
    }
    if ((s.t_ns - *track_start_ns_) * 1e-9 < settle_s_) {
      Reject(s, "before the alignment: VIO start-up transient");
      return;
    }
    evidence_.push_back({s, antenna});
    return;
  }
  // Chi-square gate on the innovation.
  const Eigen::Vector3d innovation = s.position_enu_m - Apply(*alignment_, antenna);
  const double var = s.sigma_m * s.sigma_m + state_var_m2_;
  const double d2 = innovation.squaredNorm() / var;
  if (options_.gate_chi2 > 0 && d2 > options_.gate_chi2) {
    Reject(s,
           fmt::format("gate: innovation {:.2f} m, chi2 {:.1f} > {:.2f}", innovation.norm(), d2,
                       options_.gate_chi2),
           innovation.norm());
    if (!rejecting_since_ns_) rejecting_since_ns_ = s.t_ns;
    if ((s.t_ns - *rejecting_since_ns_) * 1e-9 > options_.reopen_after_s) {
      // Everything rejected for a while: the VIO drifted more than modelled. Widen the gate.
      state_var_m2_ *= 4;
      state_var_floor_m2_ = state_var_m2_;
      rejecting_since_ns_ = s.t_ns;
      // The window's prior on the alignment is as overconfident as the model: loosen it too (the
      // next factors start loose as well: their sigma includes the widened floor, which halves
      // per accepted sample).
      const Eigen::Vector4d sigma(std::sqrt(state_var_m2_), std::sqrt(state_var_m2_),
                                  std::sqrt(state_var_m2_), options_.reopen_yaw_sigma_rad);
      backend->InflateAlignment(sigma);
      inflations_.push_back({s.t_ns, sigma});
      spdlog::info("gnss: {:.1f} s of rejected samples at {:.3f} s, gate widened to {:.1f} m",
                   options_.reopen_after_s, s.t_ns * 1e-9, std::sqrt(state_var_m2_));
    }
    return;
  }
  rejecting_since_ns_.reset();
  // Drift detection on the mean innovation (see drift_window_samples).
  const double alpha = 1.0 / options_.drift_window_samples;
  innovation_mean_ = (1 - alpha) * innovation_mean_ + alpha * innovation;
  innovation_mean_var_ = (1 - alpha) * (1 - alpha) * innovation_mean_var_ + alpha * alpha * var;
  if (options_.drift_test_chi2 > 0 &&
      innovation_mean_.squaredNorm() > options_.drift_test_chi2 * innovation_mean_var_) {
    // The offset may be a translation or a yaw error of the VIO world (the yaw converging after
    // an in-motion start): loosen both, the yaw by the angle the offset subtends at the
    // antenna's distance from the world origin (the alignment's centre of rotation).
    const double offset = innovation_mean_.norm();
    const double reach = std::max(10.0, (*pose).translation.head<2>().norm());
    const Eigen::Vector4d sigma(offset, offset, offset, offset / reach);
    backend->InflateAlignment(sigma);
    inflations_.push_back({s.t_ns, sigma});
    ++stats_.drift_inflations;
    spdlog::debug(
        "gnss: mean innovation {:.2f} m at {:.3f} s: VIO drift beyond the model, "
        "alignment loosened",
        offset, s.t_ns * 1e-9);
    innovation_mean_.setZero();
    innovation_mean_var_ = 0;
  }
  AddFactor(s, state_var_m2_, backend);
  state_var_floor_m2_ *= 0.5;
  state_var_m2_ =
      std::max({1.0 / (1.0 / state_var_m2_ + 1.0 / (s.sigma_m * s.sigma_m)),
                options_.min_state_sigma_m * options_.min_state_sigma_m, state_var_floor_m2_});
}

void GnssFusion::AddFactor(const GnssSample& sample, double state_var_m2,
                           SlidingWindowBackend* backend) {
  // The factor is weighted by the innovation's sigma, the one the gate used: the sample's with
  // the modelled VIO uncertainty. The window's VIO is overconfident; this keeps a sample the
  // gate accepted inside the norm's threshold (Tukey would otherwise ignore every sample once
  // the VIO drifted past k sample sigmas, and never recover).
  GnssSample s = sample;
  s.sigma_m = options_.factor_sigma_scale * std::sqrt(s.sigma_m * s.sigma_m + state_var_m2);
  backend->AddTimedFactor(std::make_unique<GnssFactor>(s, options_.lever_arm_in_body, loss_.get()));
  ++stats_.factors;
  used_.push_back(sample);
}

void GnssFusion::TryInitialize(SlidingWindowBackend* backend) {
  const int n = static_cast<int>(evidence_.size());
  if (n < options_.init_min_samples || evidence_.size() == evidence_tried_) return;
  evidence_tried_ = evidence_.size();
  double span = 0;
  for (const Evidence& e : evidence_)
    span = std::max(span, (e.antenna_world - evidence_.front().antenna_world).head<2>().norm());
  if (span < options_.init_min_distance_m) return;

  // RANSAC over pairs of samples far enough apart (fixed seed: deterministic).
  const double gate = options_.gate_chi2 > 0 ? std::sqrt(options_.gate_chi2) : 4.0;
  // The VIO's own error across the span adds to each sample's sigma here.
  const double vio_var = std::pow(options_.drift_fraction * span, 2);
  auto var_of = [&](const Evidence& e) { return e.sample.sigma_m * e.sample.sigma_m + vio_var; };
  auto inliers_of = [&](const WorldAlignment& a) {
    std::vector<int> in;
    for (int i = 0; i < n; ++i) {
      const Evidence& e = evidence_[i];
      if ((e.sample.position_enu_m - Apply(a, e.antenna_world)).squaredNorm() <
          gate * gate * var_of(e))
        in.push_back(i);
    }
    return in;
  };
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<int> best;
  WorldAlignment best_a;
  for (int trial = 0, tried = 0; trial < 2000 && tried < 300; ++trial) {
    const int i = pick(rng), j = pick(rng);
    const Eigen::Vector2d dw = (evidence_[j].antenna_world - evidence_[i].antenna_world).head<2>();
    const Eigen::Vector2d de =
        (evidence_[j].sample.position_enu_m - evidence_[i].sample.position_enu_m).head<2>();
    if (dw.norm() < 0.5 * span) continue;
    ++tried;
    WorldAlignment a;
    a.yaw_rad = std::atan2(de.y(), de.x()) - std::atan2(dw.y(), dw.x());
    a.translation =
        0.5 * (evidence_[i].sample.position_enu_m + evidence_[j].sample.position_enu_m) -
        Apply(a, 0.5 * (evidence_[i].antenna_world + evidence_[j].antenna_world));
    std::vector<int> in = inliers_of(a);
    if (in.size() > best.size()) best = std::move(in), best_a = a;
  }
  if (static_cast<int>(best.size()) < std::max(options_.init_min_samples / 2, 3)) return;

  // Weighted Gauss-Newton on the inliers (twice: re-select inliers with the refined estimate).
  WorldAlignment a = best_a;
  Eigen::Matrix4d info = Eigen::Matrix4d::Zero();
  for (int round = 0; round < 2; ++round) {
    for (int it = 0; it < 5; ++it) {
      info.setZero();
      Eigen::Vector4d g = Eigen::Vector4d::Zero();
      for (int i : best) {
        const Evidence& e = evidence_[i];
        const Eigen::Matrix<double, 3, 4> J = AlignmentJacobian(a, e.antenna_world);
        const Eigen::Vector3d r = Apply(a, e.antenna_world) - e.sample.position_enu_m;
        const double w = 1.0 / var_of(e);
        info += w * J.transpose() * J;
        g += w * J.transpose() * r;
      }
      const Eigen::Vector4d step = info.ldlt().solve(-g);
      if (!step.allFinite()) return;
      a.translation += step.head<3>();
      a.yaw_rad += step[3];
    }
    best = inliers_of(a);
  }
  // The VIO track must agree with the GNSS (see init_min_inlier_fraction); if not, the older
  // half of the evidence goes (it holds the VIO's start-up transient) and the next frames add more.
  double chi2 = 0;
  for (int i : best) {
    const Evidence& e = evidence_[i];
    chi2 += (Apply(a, e.antenna_world) - e.sample.position_enu_m).squaredNorm() / var_of(e);
  }
  const double chi2_per_axis = best.empty() ? INFINITY : chi2 / (3.0 * best.size());
  if (static_cast<double>(best.size()) < options_.init_min_inlier_fraction * n ||
      !(chi2_per_axis <= options_.init_max_chi2_per_axis)) {
    spdlog::debug("gnss: alignment deferred at {:.3f} s: {} of {} inliers, chi2 per axis {:.2f}",
                  history_.back().t_ns * 1e-9, best.size(), n, chi2_per_axis);
    evidence_.erase(evidence_.begin(), evidence_.begin() + n / 2);
    evidence_tried_ = evidence_.size();
    return;
  }
  const Eigen::Matrix4d cov = info.inverse();
  // The yaw must be known (or its effect across the track negligible): wait for more motion.
  const double yaw_sigma = std::sqrt(cov(3, 3));
  if (!(yaw_sigma <= options_.init_max_yaw_sigma_rad ||
        yaw_sigma * span <= options_.init_max_yaw_effect_m))
    return;
  const size_t before = rejected_.size();
  std::vector<bool> inlier(n, false);
  for (int i : best) inlier[i] = true;
  for (int i = 0; i < n; ++i)
    if (!inlier[i]) Reject(evidence_[i].sample, "outlier of the alignment initialisation");

  // Samples older than the window go into the alignment's prior; the others become factors.
  const int64_t window_start = backend->oldest_t_ns();
  Eigen::Matrix4d prior_info = Eigen::Matrix4d::Zero();
  for (int i : best) {
    const Evidence& e = evidence_[i];
    if (e.sample.t_ns >= window_start) continue;
    used_.push_back(e.sample);
    const Eigen::Matrix<double, 3, 4> J = AlignmentJacobian(a, e.antenna_world);
    prior_info += J.transpose() * J / (e.sample.sigma_m * e.sample.sigma_m);
  }
  // A weak regulariser keeps the prior full rank (yaw within pi, translation within 1 km).
  prior_info.diagonal() += Eigen::Vector4d(1e-6, 1e-6, 1e-6, 1.0 / (M_PI * M_PI));
  const Eigen::Matrix4d sqrt_info = prior_info.llt().matrixU();
  backend->EnableAlignment(a, sqrt_info);
  backend->SetAlignmentRandomWalk(options_.alignment_walk_m_per_sqrt_m,
                                  options_.alignment_walk_rad_per_sqrt_m);
  alignment_ = a;
  for (int i : best)
    if (evidence_[i].sample.t_ns >= window_start)
      AddFactor(evidence_[i].sample, options_.min_state_sigma_m * options_.min_state_sigma_m,
                backend);
  // The gate starts from the alignment's uncertainty at the newest position.
  const Eigen::Matrix<double, 3, 4> J =
      AlignmentJacobian(a, history_.back().world_from_body.translation);
  state_var_m2_ = std::max((J * cov * J.transpose()).trace() / 3.0,
                           options_.min_state_sigma_m * options_.min_state_sigma_m);
  if (!stats_.aligned_at_ns) stats_.aligned_at_ns = history_.back().t_ns;
  ++stats_.alignments;
  spdlog::info(
      "gnss: ENU alignment at {:.3f} s from {} of {} samples over {:.1f} m: yaw {:.2f} deg "
      "(sigma {:.2f}), translation ({:.2f}, {:.2f}, {:.2f}) m; {} outlier(s)",
      history_.back().t_ns * 1e-9, best.size(), n, span, a.yaw_rad * 180 / M_PI,
      std::sqrt(cov(3, 3)) * 180 / M_PI, a.translation.x(), a.translation.y(), a.translation.z(),
      rejected_.size() - before);
  evidence_.clear();
  evidence_tried_ = 0;
  state_var_floor_m2_ = 0;
  innovation_mean_.setZero();
  innovation_mean_var_ = 0;
}

}  // namespace optinav::vio
