#include "optinav/vio/backend.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>

#include <opencv2/calib3d.hpp>

#include "optinav/camera/camera.h"
#include "optinav/util/error.h"
#include "optinav/util/statistics.h"
#include "optinav/vio/internal/cv_pose.h"

namespace optinav::vio {

struct SlidingWindowBackend::State {
  int64_t t_ns = 0;
  bool keyframe = true;
  double pose[kPoseSize] = {0, 0, 0, 0, 0, 0, 1};
  double speed_bias[kSpeedBiasSize] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  bool has_preintegration = false;
  ImuPreintegration preintegration;  // previous state -> this one
  std::map<uint64_t, StereoObservation> observations;

  Rigid3d WorldFromBody() const {
    return {Eigen::Quaterniond(pose[6], pose[3], pose[4], pose[5]).normalized(),
            Eigen::Vector3d(pose[0], pose[1], pose[2])};
  }
  void SetPose(const Rigid3d& p) {
    const Eigen::Quaterniond q = p.rotation.normalized();
    pose[0] = p.translation.x(), pose[1] = p.translation.y(), pose[2] = p.translation.z();
    pose[3] = q.x(), pose[4] = q.y(), pose[5] = q.z(), pose[6] = q.w();
  }
  Eigen::Vector3d Velocity() const { return {speed_bias[0], speed_bias[1], speed_bias[2]}; }
  ImuBias Bias() const {
    ImuBias b;
    b.gyro = {speed_bias[3], speed_bias[4], speed_bias[5]};
    b.accel = {speed_bias[6], speed_bias[7], speed_bias[8]};
    return b;
  }
  void SetSpeedBias(const Eigen::Vector3d& v, const ImuBias& b) {
    for (int i = 0; i < 3; ++i) {
      speed_bias[i] = v[i];
      speed_bias[3 + i] = b.gyro[i];
      speed_bias[6 + i] = b.accel[i];
    }
  }
  NavState Nav() const {
    const Rigid3d p = WorldFromBody();
    return {p.rotation, p.translation, Velocity()};
  }
  StateEstimate Estimate() const { return {t_ns, WorldFromBody(), Velocity(), Bias()}; }
};

struct SlidingWindowBackend::Landmark {
  // An observation by a keyframe that left the window, its pose held fixed
  // (BackendOptions::anchored_observations_per_landmark).
  struct Anchor {
    int64_t t_ns = 0;
    Rigid3d world_from_body;
    StereoObservation observation;
  };
  double position[kPointSize] = {0, 0, 0};
  bool initialized = false;
  int num_states = 0;  // states in the window observing it
  std::vector<Anchor> anchors;
  // Constrained by the window's solve: seen by two states, or by one and an anchor.
  bool Constrained() const {
    return initialized && (num_states >= 2 || (num_states >= 1 && !anchors.empty()));
  }
};

Rigid3d WorldAlignment::EnuFromWorld() const {
  return {Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ())), translation};
}

std::string BackendOptions::Check() const {
  if (window_keyframes < 2)
    return "window_keyframes must be >= 2, got " + std::to_string(window_keyframes);
  if (!(pixel_sigma > 0)) return "pixel_sigma must be > 0";
  if (!(huber_pixels > 0)) return "huber_pixels must be > 0";
  if (!(imu_pnp_check_pixels >= 0)) return "imu_pnp_check_pixels must be >= 0 (0: off)";
  if (!(outlier_pixels > 0)) return "outlier_pixels must be > 0";
  if (!(min_depth_m > 0) || !(max_depth_m > min_depth_m))
    return "need 0 < min_depth_m < max_depth_m";
  if (!(stereo_only_outlier_pixels >= 0)) return "stereo_only_outlier_pixels must be >= 0";
  if (!(predicted_gate_pixels >= 0)) return "predicted_gate_pixels must be >= 0";
  if (!(marginalize_tracked_max_depth_m >= 0))
    return "marginalize_tracked_max_depth_m must be >= 0 (0: no limit)";
  if (!(predicted_gate_median_factor >= 0)) return "predicted_gate_median_factor must be >= 0";
  if (!(stereo_only_pnp_gate_pixels >= 0)) return "stereo_only_pnp_gate_pixels must be >= 0";
  if (!(stereo_only_pnp_gate_median_factor >= 0))
    return "stereo_only_pnp_gate_median_factor must be >= 0";
  if (anchored_observations_per_landmark < 0)
    return "anchored_observations_per_landmark must be >= 0 (0: off), got " +
           std::to_string(anchored_observations_per_landmark);
  if (!(anchored_max_age_s >= 0)) return "anchored_max_age_s must be >= 0 (0: no limit)";
  if (!(anchored_max_depth_m >= 0)) return "anchored_max_depth_m must be >= 0 (0: no limit)";
  if (anchored_observations_per_landmark > 0 && marginalize_tracked_landmarks)
    return "anchored_observations_per_landmark and marginalize_tracked_landmarks exclude each "
           "other (both keep what the oldest keyframe saw of a tracked landmark)";
  if (!(ground_vehicle_boresight_sigma_rad >= 0) ||
      !(ground_vehicle_boresight_walk_rad_per_sqrt_s >= 0))
    return "ground_vehicle_boresight_sigma_rad and ground_vehicle_boresight_walk_rad_per_sqrt_s "
           "must be >= 0";
  if (!(ground_vehicle_lateral_sigma_m_s >= 0) || !(ground_vehicle_vertical_sigma_m_s >= 0))
    return "ground_vehicle_lateral_sigma_m_s and ground_vehicle_vertical_sigma_m_s must be >= 0 "
           "(0: off)";
  if (max_iterations < 1) return "max_iterations must be >= 1";
  if (!(max_solver_time_s >= 0)) return "max_solver_time_s must be >= 0 (0: no limit)";
  if (!(initial_trust_region_radius > 0))
    return "initial_trust_region_radius must be > 0, got " +
           std::to_string(initial_trust_region_radius);
  if (!(function_tolerance > 0) || !(function_tolerance < 1))
    return "function_tolerance must be in (0, 1), got " + std::to_string(function_tolerance);
  for (double s : {prior_position_sigma_m, prior_yaw_sigma_rad, prior_tilt_sigma_rad,
                   prior_velocity_sigma_m_s, prior_gyro_bias_sigma, prior_accel_bias_sigma})
    if (!(s > 0)) return "prior sigmas must be > 0";
  for (double s : {imu_noise.gyro_noise_density, imu_noise.accel_noise_density,
                   imu_noise.gyro_random_walk, imu_noise.accel_random_walk})
    if (!(s > 0)) return "IMU noise densities and random walks must be > 0";
  return "";
}

SlidingWindowBackend::SlidingWindowBackend(const BackendOptions& options, const RigExtrinsics& rig)
    : options_(options),
      rig_(rig),
      huber_(std::make_unique<ceres::HuberLoss>(options.huber_pixels / options.pixel_sigma)),
      yaw_held_manifold_(
          std::make_unique<ceres::SubsetManifold>(kAlignmentSize, std::vector<int>{3})) {
  const std::string problem = options_.Check();
  OPTINAV_CHECK_MSG(problem.empty(), problem);
}

SlidingWindowBackend::~SlidingWindowBackend() = default;

void SlidingWindowBackend::Reset() {
  states_.clear();
  landmarks_.clear();
  timed_factors_.clear();
  alignment_enabled_ = false;
  alignment_yaw_held_ = false;
  globals_.clear();
  boresight_ = -1;
  prior_ = LinearPrior();
  rejected_tracks_.clear();
  stats_ = BackendStats();
}

void SlidingWindowBackend::Initialize(const StateEstimate& estimate,
                                      const std::vector<StereoObservation>& observations,
                                      double tilt_sigma_rad, double velocity_sigma_m_s,
                                      double accel_bias_sigma, double gyro_bias_sigma) {
  Reset();
  auto state = std::make_unique<State>();
  state->t_ns = estimate.t_ns;
  state->SetPose(estimate.world_from_body);
  state->SetSpeedBias(estimate.velocity, estimate.bias);
  states_.push_back(std::move(state));
  SetInitialPrior(states_.back().get(),
                  tilt_sigma_rad > 0 ? tilt_sigma_rad : options_.prior_tilt_sigma_rad,
                  velocity_sigma_m_s > 0 ? velocity_sigma_m_s : options_.prior_velocity_sigma_m_s,
                  accel_bias_sigma > 0 ? accel_bias_sigma : options_.prior_accel_bias_sigma,
                  gyro_bias_sigma > 0 ? gyro_bias_sigma : options_.prior_gyro_bias_sigma);
  if (!options_.use_imu && ground_vehicle() && options_.ground_vehicle_boresight_sigma_rad > 0) {
    boresight_ = AddGlobalBlock(
        Eigen::Vector2d::Zero(),
        Eigen::Vector2d::Constant(options_.ground_vehicle_boresight_sigma_rad),
        Eigen::Vector2d::Constant(options_.ground_vehicle_boresight_walk_rad_per_sqrt_s));
  }
  AddObservations(states_.back().get(), observations);
  TriangulateNew(states_.back().get());
}

void SlidingWindowBackend::SetInitialPrior(State* state, double tilt_sigma_rad,
                                           double velocity_sigma_m_s, double accel_bias_sigma,
                                           double gyro_bias_sigma) {
  prior_ = LinearPrior();
  LinearPrior::Block pose;
  pose.values = state->pose;
  pose.ambient_size = kPoseSize;
  pose.tangent_size = kPoseTangentSize;
  pose.manifold = PoseManifold();
  pose.x0.assign(state->pose, state->pose + kPoseSize);
  prior_.blocks.push_back(pose);
  // Tangent of the pose manifold: position (3), then a rotation vector applied on the left
  // (world frame), so its z component is yaw. Without IMU the whole pose is the gauge.
  Eigen::VectorXd sigma(options_.use_imu ? 15 : 6);
  const double tilt = options_.use_imu ? tilt_sigma_rad : options_.prior_yaw_sigma_rad;
  sigma.head<6>() << Eigen::Vector3d::Constant(options_.prior_position_sigma_m), tilt, tilt,
      options_.prior_yaw_sigma_rad;
  if (options_.use_imu) {
    LinearPrior::Block sb;
    sb.values = state->speed_bias;
    sb.ambient_size = sb.tangent_size = kSpeedBiasSize;
    sb.manifold = nullptr;
    sb.x0.assign(state->speed_bias, state->speed_bias + kSpeedBiasSize);
    prior_.blocks.push_back(sb);
    sigma.tail<9>() << Eigen::Vector3d::Constant(velocity_sigma_m_s),
        Eigen::Vector3d::Constant(gyro_bias_sigma), Eigen::Vector3d::Constant(accel_bias_sigma);
  }
  prior_.J = sigma.cwiseInverse().asDiagonal();
  prior_.r0 = Eigen::VectorXd::Zero(sigma.size());
}

void SlidingWindowBackend::AddObservations(State* state,
                                           const std::vector<StereoObservation>& observations) {
  for (const StereoObservation& obs : observations) {
    if (rejected_tracks_.count(obs.track_id)) continue;
    if (!obs.left.allFinite() || (obs.right && !obs.right->allFinite())) continue;
    auto [it, inserted] = state->observations.emplace(obs.track_id, obs);
    if (!inserted) continue;
    auto& landmark = landmarks_[obs.track_id];
    if (!landmark) landmark = std::make_unique<Landmark>();
    ++landmark->num_states;
  }
}

void SlidingWindowBackend::TriangulateNew(State* state) {
  const Rigid3d body_from_world = state->WorldFromBody().Inverse();
  const Rigid3d cam0_from_world = rig_.cam0_from_body * body_from_world;
  const Rigid3d cam1_from_world = rig_.cam1_from_body * body_from_world;
  for (const auto& [id, obs] : state->observations) {
    Landmark& landmark = *landmarks_.at(id);
    if (landmark.initialized || !obs.right) continue;
    const auto point =
        camera::TriangulateTwoView(cam0_from_world, cam1_from_world, obs.left, *obs.right);
    if (!point) continue;
    const double depth = (cam0_from_world * *point).z();
    if (depth < options_.min_depth_m || depth > options_.max_depth_m) continue;
    for (int i = 0; i < 3; ++i) landmark.position[i] = (*point)[i];
    landmark.initialized = true;
  }
}

void SlidingWindowBackend::EnableAlignment(const WorldAlignment& initial,
                                           const Eigen::Matrix4d& prior_sqrt_info) {
  OPTINAV_CHECK(initialized());
  OPTINAV_CHECK(!alignment_enabled_);
  for (int i = 0; i < 3; ++i) alignment_[i] = initial.translation[i];
  alignment_[3] = initial.yaw_rad;
  alignment_enabled_ = true;
  // Append an independent block to the prior: J = diag(J_old, sqrt_info), r0 = (r0_old, 0).
  LinearPrior::Block block;
  block.values = alignment_;
  block.ambient_size = block.tangent_size = kAlignmentSize;
  block.manifold = nullptr;
  block.x0.assign(alignment_, alignment_ + kAlignmentSize);
  const Eigen::Index rows = prior_.J.rows(), cols = prior_.J.cols();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows + kAlignmentSize, cols + kAlignmentSize);
  J.topLeftCorner(rows, cols) = prior_.J;
  J.bottomRightCorner(kAlignmentSize, kAlignmentSize) = prior_sqrt_info;
  Eigen::VectorXd r0 = Eigen::VectorXd::Zero(rows + kAlignmentSize);
  r0.head(rows) = prior_.r0;
  prior_.J = std::move(J);
  prior_.r0 = std::move(r0);
  prior_.blocks.push_back(block);
}

void SlidingWindowBackend::InflateAlignment(const Eigen::Vector4d& sigma) {
  if (!alignment_enabled_) return;
  prior_ = AddRandomWalk(prior_, alignment_,
                         sigma.cwiseAbs2().cwiseMax(1e-12).asDiagonal().toDenseMatrix(),
                         options_.jacobi_scaled_marginalization);
}

WorldAlignment SlidingWindowBackend::alignment() const {
  return WorldAlignment::FromBlock(alignment_);
}

std::vector<double*> SlidingWindowBackend::TimedFactorBlocks(const TimedFactor& factor,
                                                             State* anchor) const {
  if (factor.uses_alignment() && !alignment_enabled_) return {};
  std::vector<double*> blocks{anchor->pose};
  if (options_.use_imu) blocks.push_back(anchor->speed_bias);
  if (factor.uses_alignment()) blocks.push_back(const_cast<double*>(alignment_));
  for (int id : factor.global_blocks()) {
    OPTINAV_CHECK_MSG(id >= 0 && id < static_cast<int>(globals_.size()),
                      "timed factor names global block " + std::to_string(id));
    blocks.push_back(globals_[id]->values.data());
  }
  return blocks;
}

int SlidingWindowBackend::AddGlobalBlock(const Eigen::VectorXd& initial,
                                         const Eigen::VectorXd& prior_sigma,
                                         const Eigen::VectorXd& walk_per_sqrt_s) {
  OPTINAV_CHECK(initialized());
  const Eigen::Index n = initial.size();
  OPTINAV_CHECK(n > 0 && prior_sigma.size() == n && walk_per_sqrt_s.size() == n);
  OPTINAV_CHECK((prior_sigma.array() > 0).all() && (walk_per_sqrt_s.array() >= 0).all());
  auto global = std::make_unique<Global>();
  global->values.assign(initial.data(), initial.data() + n);
  global->walk_per_sqrt_s = walk_per_sqrt_s;
  // Append an independent block to the prior, as EnableAlignment does.
  LinearPrior::Block block;
  block.values = global->values.data();
  block.ambient_size = block.tangent_size = static_cast<int>(n);
  block.manifold = nullptr;
  block.x0 = global->values;
  const Eigen::Index rows = prior_.J.rows(), cols = prior_.J.cols();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows + n, cols + n);
  J.topLeftCorner(rows, cols) = prior_.J;
  J.bottomRightCorner(n, n) = prior_sigma.cwiseInverse().asDiagonal();
  Eigen::VectorXd r0 = Eigen::VectorXd::Zero(rows + n);
  r0.head(rows) = prior_.r0;
  prior_.J = std::move(J);
  prior_.r0 = std::move(r0);
  prior_.blocks.push_back(block);
  globals_.push_back(std::move(global));
  return static_cast<int>(globals_.size()) - 1;
}

Eigen::VectorXd SlidingWindowBackend::GlobalBlock(int id) const {
  OPTINAV_CHECK(id >= 0 && id < static_cast<int>(globals_.size()));
  const std::vector<double>& v = globals_[id]->values;
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

std::vector<std::unique_ptr<ResidualSpec>> SlidingWindowBackend::BuildStateResiduals() const {
  std::vector<std::unique_ptr<ResidualSpec>> specs;
  if (options_.use_imu) {
    for (size_t k = 1; k < states_.size(); ++k) {
      const State& a = *states_[k - 1];
      const State& b = *states_[k];
      if (!b.has_preintegration || b.preintegration.dt_s() <= 0) continue;
      auto spec = std::make_unique<ResidualSpec>();
      spec->cost.reset(CreateImuFactor(b.preintegration, options_.gravity));
      spec->blocks = {const_cast<double*>(a.pose), const_cast<double*>(a.speed_bias),
                      const_cast<double*>(b.pose), const_cast<double*>(b.speed_bias)};
      specs.push_back(std::move(spec));
    }
  }
  for (const auto& state : states_)
    if (auto spec = GroundVehicleSpec(*state)) specs.push_back(std::move(spec));
  for (size_t k = 1; k < states_.size(); ++k)
    if (auto spec = GroundVehiclePairSpec(*states_[k - 1], *states_[k]))
      specs.push_back(std::move(spec));
  if (auto spec = PriorSpec()) specs.push_back(std::move(spec));
  for (const auto& factor : timed_factors_)
    if (auto spec = TimedFactorSpec(*factor, nullptr)) specs.push_back(std::move(spec));
  return specs;
}

std::unique_ptr<ResidualSpec> SlidingWindowBackend::GroundVehicleSpec(const State& state) const {
  if (!ground_vehicle() || !options_.use_imu) return nullptr;
  auto spec = std::make_unique<ResidualSpec>();
  spec->cost.reset(CreateGroundVehicleFactor(options_.ground_vehicle_lateral_sigma_m_s,
                                             options_.ground_vehicle_vertical_sigma_m_s));
  spec->blocks = {const_cast<double*>(state.pose), const_cast<double*>(state.speed_bias)};
  return spec;
}

std::unique_ptr<ResidualSpec> SlidingWindowBackend::GroundVehiclePairSpec(const State& a,
                                                                          const State& b) const {
  if (!ground_vehicle() || options_.use_imu || b.t_ns <= a.t_ns) return nullptr;
  auto spec = std::make_unique<ResidualSpec>();
  const double dt = (b.t_ns - a.t_ns) * 1e-9, lateral = options_.ground_vehicle_lateral_sigma_m_s,
               vertical = options_.ground_vehicle_vertical_sigma_m_s;
  spec->blocks = {const_cast<double*>(a.pose), const_cast<double*>(b.pose)};
  if (boresight_ >= 0) {
    spec->cost.reset(CreateGroundVehiclePairFactorWithBoresight(dt, lateral, vertical));
    spec->blocks.push_back(globals_[boresight_]->values.data());
  } else {
    spec->cost.reset(CreateGroundVehiclePairFactor(dt, lateral, vertical));
  }
  return spec;
}

std::unique_ptr<ResidualSpec> SlidingWindowBackend::PriorSpec() const {
  if (prior_.empty()) return nullptr;
  auto spec = std::make_unique<ResidualSpec>();
  spec->cost.reset(prior_.CreateCostFunction());
  for (const auto& b : prior_.blocks) spec->blocks.push_back(b.values);
  return spec;
}

std::unique_ptr<ResidualSpec> SlidingWindowBackend::TimedFactorSpec(const TimedFactor& factor,
                                                                    const State* only) const {
  ImuPreintegration anchor_to_t;
  State* anchor = AnchorFor(factor.t_ns(), &anchor_to_t);
  if (!anchor || (only && anchor != only)) return nullptr;
  std::vector<double*> blocks = TimedFactorBlocks(factor, anchor);
  if (blocks.empty()) return nullptr;
  auto spec = std::make_unique<ResidualSpec>();
  spec->cost.reset(factor.Create(anchor_to_t, options_.gravity, options_.use_imu));
  spec->loss = factor.loss();
  spec->blocks = std::move(blocks);
  return spec;
}

Eigen::MatrixXd SlidingWindowBackend::NewestCovariance() const {
  OPTINAV_CHECK(initialized());
  // Every block but the newest state's is marginalised out; the prior left on the newest state
  // is the square root of its marginal information.
  std::vector<std::unique_ptr<ResidualSpec>> owned = BuildStateResiduals();
  for (auto& spec :
       BuildResiduals([](const State*) { return true; }, [](const Landmark*) { return true; }))
    owned.push_back(std::move(spec));
  const State& newest = *states_.back();
  std::set<const double*> keep{newest.pose};
  if (options_.use_imu) keep.insert(newest.speed_bias);
  std::vector<double*> marginalize;
  std::set<const double*> seen;
  for (const auto& spec : owned)
    for (double* b : spec->blocks)
      if (!keep.count(b) && seen.insert(b).second) marginalize.push_back(b);
  std::vector<const ResidualSpec*> specs;
  for (const auto& s : owned) specs.push_back(s.get());
  const LinearPrior left = Marginalize(
      specs, marginalize, [&](const double* b) { return ManifoldOf(b); },
      [&](const double* b) { return SizeOf(b); }, options_.jacobi_scaled_marginalization);
  const int n = options_.use_imu ? kPoseTangentSize + kSpeedBiasSize : kPoseTangentSize;
  // The kept blocks in the prior's order -> pose first, then speed-bias.
  Eigen::MatrixXd info = Eigen::MatrixXd::Zero(n, n);
  if (!left.empty()) {
    std::vector<int> to(left.J.cols());
    int col = 0;
    for (const auto& b : left.blocks) {
      const int base = b.values == newest.pose ? 0 : kPoseTangentSize;
      for (int i = 0; i < b.tangent_size; ++i) to[col++] = base + i;
    }
    const Eigen::MatrixXd h = left.J.transpose() * left.J;
    for (Eigen::Index i = 0; i < h.rows(); ++i)
      for (Eigen::Index j = 0; j < h.cols(); ++j) info(to[i], to[j]) += h(i, j);
  }
  // An unconstrained direction (no information) gets a huge variance rather than a failure.
  info.diagonal().array() += 1e-12;
  return info.ldlt().solve(Eigen::MatrixXd::Identity(n, n));
}

void SlidingWindowBackend::AddTimedFactor(std::unique_ptr<TimedFactor> factor) {
  OPTINAV_CHECK(factor != nullptr);
  timed_factors_.push_back(std::move(factor));
}

SlidingWindowBackend::State* SlidingWindowBackend::AnchorFor(int64_t t_ns,
                                                             ImuPreintegration* anchor_to_t) const {
  for (size_t k = states_.size(); k-- > 0;) {
    const State& s = *states_[k];
    if (s.t_ns > t_ns) continue;
    const ImuBias bias = s.Bias();
    if (s.t_ns == t_ns) {
      *anchor_to_t = ImuPreintegration(bias, options_.imu_noise);
      return states_[k].get();
    }
    if (k + 1 == states_.size()) return nullptr;  // after the newest state: not yet usable
    if (!options_.use_imu) {
      *anchor_to_t = ImuPreintegration(bias, options_.imu_noise);
    } else {
      *anchor_to_t = states_[k + 1]->preintegration.Prefix((t_ns - s.t_ns) * 1e-9);
    }
    return states_[k].get();
  }
  return nullptr;
}

void SlidingWindowBackend::DropNewestIfNotKeyframe(ImuPreintegration* next) {
  if (states_.size() < 2 || states_.back()->keyframe) return;
  State& newest = *states_.back();
  if (options_.use_imu && newest.has_preintegration) {
    ImuPreintegration merged = newest.preintegration;
    merged.Append(*next);
    *next = std::move(merged);
  }
  for (const auto& [id, obs] : newest.observations) {
    auto it = landmarks_.find(id);
    if (it != landmarks_.end() && --it->second->num_states <= 0) landmarks_.erase(it);
  }
  states_.pop_back();
}

StateEstimate SlidingWindowBackend::AddFrame(int64_t t_ns, const ImuPreintegration& preintegration,
                                             const std::vector<StereoObservation>& observations,
                                             bool keyframe) {
  OPTINAV_CHECK(initialized());
  OPTINAV_CHECK(t_ns > states_.back()->t_ns);
  ImuPreintegration pre = preintegration;
  DropNewestIfNotKeyframe(&pre);
  const State& last = *states_.back();
  auto state = std::make_unique<State>();
  state->t_ns = t_ns;
  state->keyframe = keyframe;
  if (options_.use_imu) {
    pre.Reintegrate(last.Bias());
    const NavState predicted = pre.Predict(last.Nav(), last.Bias(), options_.gravity);
    state->SetPose({predicted.world_from_body_rotation, predicted.position});
    state->SetSpeedBias(predicted.velocity, last.Bias());
    state->preintegration = std::move(pre);
    state->has_preintegration = true;
  } else {
    // Constant velocity: the last relative motion, scaled to this interval.
    Rigid3d predicted = last.WorldFromBody();
    if (states_.size() >= 2) {
      const State& before = *states_[states_.size() - 2];
      const Rigid3d delta = before.WorldFromBody().Inverse() * last.WorldFromBody();
      const double ratio =
          static_cast<double>(t_ns - last.t_ns) / static_cast<double>(last.t_ns - before.t_ns);
      Vector6d xi = LogSE3(delta) * std::clamp(ratio, 0.0, 3.0);
      predicted = last.WorldFromBody() * ExpSE3(xi);
    }
    state->SetPose(predicted);
  }
  states_.push_back(std::move(state));
  State* added = states_.back().get();
  AddObservations(added, observations);
  // The IMU check first: the prediction gate then judges against the corrected pose.
  if (options_.use_imu && options_.imu_pnp_check_pixels > 0) CheckImuAgainstPnp(added);
  if (options_.use_imu && options_.predicted_gate_pixels > 0) GateOnPrediction(*added);
  if (!options_.use_imu && options_.stereo_only_pnp_gate_pixels > 0) GateOnPnp(*added);
  TriangulateNew(added);
  if (keyframe || states_.size() < 3) {
    Optimize();
  } else {
    OptimizeNewest();
  }
  RemoveOutliers();
  TriangulateNew(added);
  if (options_.use_imu) RelinearizeBiases();
  int keyframes = 0;
  for (const auto& s : states_) keyframes += s->keyframe ? 1 : 0;
  if (keyframes > options_.window_keyframes) MarginalizeOldest();

  stats_.num_states = static_cast<int>(states_.size());
  stats_.num_keyframes = std::min(keyframes, options_.window_keyframes);
  int constrained = 0;
  for (const auto& [id, obs] : added->observations) {
    const auto it = landmarks_.find(id);
    if (it != landmarks_.end() && it->second->Constrained()) ++constrained;
  }
  stats_.newest_constrained_landmarks = constrained;
  return Newest();
}

StateEstimate SlidingWindowBackend::Newest() const {
  OPTINAV_CHECK(initialized());
  return states_.back()->Estimate();
}

int64_t SlidingWindowBackend::oldest_t_ns() const {
  OPTINAV_CHECK(initialized());
  return states_.front()->t_ns;
}

std::vector<std::unique_ptr<ResidualSpec>> SlidingWindowBackend::BuildResiduals(
    const std::function<bool(const State*)>& state_filter,
    const std::function<bool(const Landmark*)>& landmark_filter, bool with_anchors) const {
  std::vector<std::unique_ptr<ResidualSpec>> specs;
  const double focal = rig_.focal_px;
  std::set<const Landmark*> used;  // landmarks with a residual, for their anchors
  for (const auto& state : states_) {
    if (!state_filter(state.get())) continue;
    for (const auto& [id, obs] : state->observations) {
      Landmark* landmark = landmarks_.at(id).get();
      if (!landmark->Constrained() || !landmark_filter(landmark)) continue;
      auto add = [&](const Rigid3d& cam_from_body, const Eigen::Vector2d& observed) {
        auto spec = std::make_unique<ResidualSpec>();
        spec->cost.reset(
            CreateReprojectionFactor(cam_from_body, observed, focal, options_.pixel_sigma));
        spec->loss = huber_.get();
        spec->blocks = {state->pose, landmark->position};
        specs.push_back(std::move(spec));
      };
      add(rig_.cam0_from_body, obs.left);
      if (obs.right) add(rig_.cam1_from_body, *obs.right);
      if (with_anchors && !landmark->anchors.empty()) used.insert(landmark);
    }
  }
  // In id order (deterministic).
  for (const auto& [id, landmark_ptr] : landmarks_) {
    Landmark* landmark = landmark_ptr.get();
    if (!used.count(landmark)) continue;
    for (const Landmark::Anchor& anchor : landmark->anchors) {
      auto add = [&](const Rigid3d& cam_from_body, const Eigen::Vector2d& observed) {
        auto spec = std::make_unique<ResidualSpec>();
        spec->cost.reset(CreateFixedPoseReprojectionFactor(anchor.world_from_body, cam_from_body,
                                                           observed, focal, options_.pixel_sigma));
        spec->loss = huber_.get();
        spec->blocks = {landmark->position};
        specs.push_back(std::move(spec));
      };
      add(rig_.cam0_from_body, anchor.observation.left);
      if (anchor.observation.right) add(rig_.cam1_from_body, *anchor.observation.right);
    }
  }
  return specs;
}

const ceres::Manifold* SlidingWindowBackend::ManifoldOf(const double* block) const {
  for (const auto& s : states_)
    if (block == s->pose) return PoseManifold();
  return nullptr;  // speed-bias, landmarks and the alignment are Euclidean
}

int SlidingWindowBackend::SizeOf(const double* block) const {
  if (block == alignment_) return kAlignmentSize;
  for (const auto& g : globals_)
    if (block == g->values.data()) return static_cast<int>(g->values.size());
  for (const auto& s : states_) {
    if (block == s->pose) return kPoseSize;
    if (block == s->speed_bias) return kSpeedBiasSize;
  }
  return kPointSize;
}

namespace {

// Problems own their cost functions; losses and manifolds are shared and outlive them.
ceres::Problem::Options ProblemOptions() {
  ceres::Problem::Options o;
  o.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return o;
}

// Single-threaded Levenberg-Marquardt within the per-frame iteration budget (deterministic unless
// a wall-clock limit is set).
ceres::Solver::Options SolverOptions(const BackendOptions& options) {
  ceres::Solver::Options o;
  o.max_num_iterations = options.max_iterations;
  o.initial_trust_region_radius = options.initial_trust_region_radius;
  o.function_tolerance = options.function_tolerance;
  if (options.max_solver_time_s > 0) o.max_solver_time_in_seconds = options.max_solver_time_s;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  return o;
}

}  // namespace

void SlidingWindowBackend::RecordSummary(const ceres::Solver::Summary& summary) {
  stats_.solver_iterations = static_cast<int>(summary.iterations.size());
  stats_.initial_cost = summary.initial_cost;
  stats_.final_cost = summary.final_cost;
  stats_.solver_usable = summary.IsSolutionUsable();
}

void SlidingWindowBackend::OptimizeNewest() {
  // Between keyframes: only the newest state moves, against the previous state and the
  // landmarks held fixed (motion-only tracking; the full window is solved at keyframes).
  ceres::Problem problem(ProblemOptions());
  State& newest = *states_.back();
  State& previous = *states_[states_.size() - 2];
  for (State* s : {&previous, &newest}) {
    problem.AddParameterBlock(s->pose, kPoseSize, const_cast<ceres::Manifold*>(PoseManifold()));
    if (options_.use_imu) problem.AddParameterBlock(s->speed_bias, kSpeedBiasSize);
  }
  problem.SetParameterBlockConstant(previous.pose);
  if (options_.use_imu) {
    problem.SetParameterBlockConstant(previous.speed_bias);
    if (newest.has_preintegration && newest.preintegration.dt_s() > 0)
      problem.AddResidualBlock(CreateImuFactor(newest.preintegration, options_.gravity), nullptr,
                               previous.pose, previous.speed_bias, newest.pose, newest.speed_bias);
    if (auto spec = GroundVehicleSpec(newest))
      problem.AddResidualBlock(spec->cost.release(), nullptr, spec->blocks);
  }
  if (auto spec = GroundVehiclePairSpec(previous, newest)) {
    if (spec->blocks.size() > 2) {  // the boresight, held
      problem.AddParameterBlock(spec->blocks[2], 2);
      problem.SetParameterBlockConstant(spec->blocks[2]);
    }
    problem.AddResidualBlock(spec->cost.release(), nullptr, spec->blocks);
  }
  int num_observations = 0;
  for (auto& spec : BuildResiduals([&](const State* s) { return s == &newest; },
                                   [](const Landmark*) { return true; }, /*with_anchors=*/false)) {
    if (!problem.HasParameterBlock(spec->blocks[1])) {
      problem.AddParameterBlock(spec->blocks[1], kPointSize);
      problem.SetParameterBlockConstant(spec->blocks[1]);
    }
    problem.AddResidualBlock(spec->cost.release(), const_cast<ceres::LossFunction*>(spec->loss),
                             spec->blocks);
    ++num_observations;
  }
  ceres::Solver::Options solver_options = SolverOptions(options_);
  solver_options.linear_solver_type = ceres::DENSE_QR;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  stats_.num_observations = num_observations;
  stats_.window_shift_deg = stats_.window_shift_m = 0;
  RecordSummary(summary);
  Eigen::Map<Eigen::Quaterniond>(newest.pose + 3).normalize();
}

void SlidingWindowBackend::Optimize() {
  // The solve runs on a packed copy of the window's values: landmarks (in order of first
  // observation), then each state's pose and speed-bias in window order, then the alignment.
  // The elimination ordering puts exactly the landmarks in the first group. Ceres orders the
  // blocks of a group by address, so packing makes that order the window's order (deterministic:
  // same input, same output). Without an explicit ordering Ceres picks the elimination set
  // greedily by degree, which also takes some speed-bias blocks; the mixed block sizes then
  // send it from its fixed-size Schur kernels (2x3x6) to the slower dynamic-size ones.
  auto reprojection =
      BuildResiduals([](const State*) { return true; }, [](const Landmark*) { return true; });
  std::vector<double*> live;  // blocks in packed order
  std::vector<int> sizes;
  std::vector<const ceres::Manifold*> manifolds;
  std::map<const double*, size_t> index;  // live block -> position in `live`
  auto add_block = [&](double* block, int size, const ceres::Manifold* manifold) {
    if (index.emplace(block, live.size()).second) {
      live.push_back(block);
      sizes.push_back(size);
      manifolds.push_back(manifold);
    }
  };
  for (const auto& spec : reprojection) add_block(spec->blocks.back(), kPointSize, nullptr);
  const size_t num_landmarks = live.size();
  for (const auto& s : states_) {
    add_block(s->pose, kPoseSize, PoseManifold());
    if (options_.use_imu) add_block(s->speed_bias, kSpeedBiasSize, nullptr);
  }
  if (alignment_enabled_) add_block(alignment_, kAlignmentSize, nullptr);
  for (const auto& g : globals_)
    add_block(g->values.data(), static_cast<int>(g->values.size()), nullptr);
  std::vector<size_t> offset(live.size() + 1, 0);
  for (size_t i = 0; i < live.size(); ++i) offset[i + 1] = offset[i] + sizes[i];
  std::vector<double> packed(offset.back());
  for (size_t i = 0; i < live.size(); ++i)
    std::copy_n(live[i], sizes[i], packed.data() + offset[i]);
  auto packed_of = [&](const double* block) { return packed.data() + offset[index.at(block)]; };
  auto packed_blocks = [&](const std::vector<double*>& blocks) {
    std::vector<double*> out;
    out.reserve(blocks.size());
    for (const double* b : blocks) out.push_back(packed_of(b));
    return out;
  };

  ceres::Problem problem(ProblemOptions());
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (size_t i = 0; i < live.size(); ++i) {
    double* block = packed.data() + offset[i];
    problem.AddParameterBlock(block, sizes[i], const_cast<ceres::Manifold*>(manifolds[i]));
    ordering->AddElementToGroup(block, i < num_landmarks ? 0 : 1);
  }
  if (options_.use_imu) {
    for (size_t k = 1; k < states_.size(); ++k) {
      State& a = *states_[k - 1];
      State& b = *states_[k];
      if (!b.has_preintegration || b.preintegration.dt_s() <= 0) continue;
      problem.AddResidualBlock(CreateImuFactor(b.preintegration, options_.gravity), nullptr,
                               packed_of(a.pose), packed_of(a.speed_bias), packed_of(b.pose),
                               packed_of(b.speed_bias));
    }
    for (const auto& state : states_)
      if (auto spec = GroundVehicleSpec(*state))
        problem.AddResidualBlock(spec->cost.release(), nullptr, packed_blocks(spec->blocks));
  }
  for (size_t k = 1; k < states_.size(); ++k)
    if (auto spec = GroundVehiclePairSpec(*states_[k - 1], *states_[k]))
      problem.AddResidualBlock(spec->cost.release(), nullptr, packed_blocks(spec->blocks));
  int num_observations = 0;
  for (auto& spec : reprojection) {
    problem.AddResidualBlock(spec->cost.release(), const_cast<ceres::LossFunction*>(spec->loss),
                             packed_blocks(spec->blocks));
    ++num_observations;
  }
  if (!prior_.empty()) {
    std::vector<double*> blocks;
    for (const auto& b : prior_.blocks) blocks.push_back(b.values);
    problem.AddResidualBlock(prior_.CreateCostFunction(), nullptr, packed_blocks(blocks));
  }
  for (const auto& factor : timed_factors_) {
    ImuPreintegration anchor_to_t;
    State* anchor = AnchorFor(factor->t_ns(), &anchor_to_t);
    if (!anchor) continue;
    const std::vector<double*> blocks = TimedFactorBlocks(*factor, anchor);
    if (blocks.empty()) continue;
    problem.AddResidualBlock(factor->Create(anchor_to_t, options_.gravity, options_.use_imu),
                             const_cast<ceres::LossFunction*>(factor->loss()),
                             packed_blocks(blocks));
  }
  if (alignment_enabled_ && alignment_yaw_held_)
    problem.SetManifold(packed_of(alignment_), yaw_held_manifold_.get());

  ceres::Solver::Options solver_options = SolverOptions(options_);
  if (num_landmarks > 0) {
    solver_options.linear_solver_type = ceres::DENSE_SCHUR;
    solver_options.linear_solver_ordering = ordering;
  } else {
    solver_options.linear_solver_type = ceres::DENSE_QR;
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  stats_.window_shift_deg = stats_.window_shift_m = 0;
  for (size_t k = 0; k + 1 < states_.size(); ++k) {
    const double* before = states_[k]->pose;
    const double* after = packed_of(before);
    const Eigen::Map<const Eigen::Quaterniond> q0(before + 3), q1(after + 3);
    stats_.window_shift_deg = std::max(
        stats_.window_shift_deg, q0.angularDistance(q1.normalized()) * 180.0 / std::numbers::pi);
    stats_.window_shift_m = std::max(
        stats_.window_shift_m,
        (Eigen::Map<const Eigen::Vector3d>(before) - Eigen::Map<const Eigen::Vector3d>(after))
            .norm());
  }
  for (size_t i = 0; i < live.size(); ++i)
    std::copy_n(packed.data() + offset[i], sizes[i], live[i]);
  stats_.num_landmarks = static_cast<int>(num_landmarks);
  stats_.num_observations = num_observations;
  RecordSummary(summary);
  // Keep quaternions normalised (the manifold keeps them on the sphere up to rounding).
  for (auto& s : states_) {
    Eigen::Map<Eigen::Quaterniond> q(s->pose + 3);
    q.normalize();
  }
}

double SlidingWindowBackend::ReprojectionErrorPx(const Rigid3d& body_from_world,
                                                 const Landmark& landmark,
                                                 const StereoObservation& obs) const {
  const Eigen::Vector3d p_world(landmark.position[0], landmark.position[1], landmark.position[2]);
  const Eigen::Vector3d p_body = body_from_world * p_world;
  auto error_px = [&](const Rigid3d& cam_from_body, const Eigen::Vector2d& observed) {
    const Eigen::Vector3d p = cam_from_body * p_body;
    if (p.z() < options_.min_depth_m) return 1e9;
    return rig_.focal_px * (p.head<2>() / p.z() - observed).norm();
  };
  double error = error_px(rig_.cam0_from_body, obs.left);
  if (obs.right) error = std::max(error, error_px(rig_.cam1_from_body, *obs.right));
  return error;
}

void SlidingWindowBackend::RejectLandmarks(const std::set<uint64_t>& ids) {
  for (uint64_t id : ids) {
    for (auto& state : states_) state->observations.erase(id);
    landmarks_.erase(id);
    rejected_tracks_.insert(id);
  }
}

std::vector<std::pair<uint64_t, double>> SlidingWindowBackend::ErrorsAtPose(
    const State& state, bool constrained_only) const {
  const Rigid3d body_from_world = state.WorldFromBody().Inverse();
  std::vector<std::pair<uint64_t, double>> errors;
  for (const auto& [id, obs] : state.observations) {
    const Landmark& landmark = *landmarks_.at(id);
    if (constrained_only ? landmark.Constrained() : landmark.initialized)
      errors.emplace_back(id, ReprojectionErrorPx(body_from_world, landmark, obs));
  }
  return errors;
}

namespace {

double MedianError(const std::vector<std::pair<uint64_t, double>>& errors) {
  std::vector<double> values;
  values.reserve(errors.size());
  for (const auto& [id, e] : errors) values.push_back(e);
  return Median(std::move(values));
}

}  // namespace

void SlidingWindowBackend::GateOnPrediction(const State& state) {
  RejectAboveGate(ErrorsAtPose(state, /*constrained_only=*/false), options_.predicted_gate_pixels,
                  options_.predicted_gate_median_factor);
}

void SlidingWindowBackend::RejectAboveGate(const std::vector<std::pair<uint64_t, double>>& errors,
                                           double gate, double median_factor) {
  if (median_factor > 0 && !errors.empty())
    gate = std::max(gate, median_factor * MedianError(errors));
  std::set<uint64_t> bad;
  for (const auto& [id, e] : errors)
    if (e > gate) bad.insert(id);
  RejectLandmarks(bad);
  stats_.num_gated = static_cast<int>(bad.size());
}

std::optional<SlidingWindowBackend::PnpFit> SlidingWindowBackend::FitPnp(const State& state,
                                                                         double gate) const {
  std::vector<uint64_t> ids;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;  // normalised left-camera coordinates
  for (const auto& [id, obs] : state.observations) {
    const Landmark& landmark = *landmarks_.at(id);
    if (!landmark.Constrained()) continue;
    ids.push_back(id);
    object.emplace_back(landmark.position[0], landmark.position[1], landmark.position[2]);
    image.emplace_back(obs.left.x(), obs.left.y());
  }
  constexpr size_t kMinLandmarks = 12;
  if (ids.size() < kMinLandmarks) return std::nullopt;
  // Seeded by the predicted pose; the camera matrix is the identity on normalised coordinates.
  cv::Mat rvec, tvec;
  RvecTvecFromPose(rig_.cam0_from_body * state.WorldFromBody().Inverse(), &rvec, &tvec);
  std::vector<int> inliers;
  if (!cv::solvePnPRansac(object, image, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec,
                          true, 100, static_cast<float>(gate / rig_.focal_px), 0.99, inliers,
                          cv::SOLVEPNP_P3P) ||
      2 * inliers.size() < ids.size())
    return std::nullopt;
  // The landmarks' errors (pixels, left and right camera) from a camera pose (Rodrigues vector,
  // translation), and how many are within the gate.
  auto fit_at = [&](const cv::Mat& rv, const cv::Mat& tv) {
    PnpFit fit;
    fit.body_from_world = rig_.cam0_from_body.Inverse() * PoseFromRvecTvec(rv, tv);
    for (uint64_t id : ids) {
      const double e =
          ReprojectionErrorPx(fit.body_from_world, *landmarks_.at(id), state.observations.at(id));
      fit.errors.emplace_back(id, e);
      fit.within += e <= gate ? 1 : 0;
    }
    return fit;
  };
  // OpenCV refines the RANSAC model with EPnP on the inliers; Levenberg-Marquardt from there
  // minimises the reprojection error the gate measures. It can also slide off (a road's
  // self-similar texture), so the refinement is kept only when it keeps more landmarks.
  const cv::Mat ransac_rvec = rvec.clone(), ransac_tvec = tvec.clone();
  {
    std::vector<cv::Point3d> inlier_object;
    std::vector<cv::Point2d> inlier_image;
    for (int i : inliers) {
      inlier_object.push_back(object[i]);
      inlier_image.push_back(image[i]);
    }
    cv::solvePnP(inlier_object, inlier_image, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec,
                 true, cv::SOLVEPNP_ITERATIVE);
  }
  PnpFit fit = fit_at(rvec, tvec);
  PnpFit ransac_fit = fit_at(ransac_rvec, ransac_tvec);
  if (ransac_fit.within > fit.within) fit = std::move(ransac_fit);
  // A pose that keeps fewer than half of the landmarks is not trusted to judge them.
  if (2 * fit.within < ids.size()) return std::nullopt;
  return fit;
}

void SlidingWindowBackend::GateOnPnp(const State& state) {
  stats_.num_gated = 0;
  const double gate = options_.stereo_only_pnp_gate_pixels;
  if (const std::optional<PnpFit> fit = FitPnp(state, gate))
    RejectAboveGate(fit->errors, gate, options_.stereo_only_pnp_gate_median_factor);
}

void SlidingWindowBackend::CheckImuAgainstPnp(State* state) {
  if (!state->has_preintegration) return;  // (AddFrame: `state` follows at least one state)
  const double check = options_.imu_pnp_check_pixels;
  const std::vector<std::pair<uint64_t, double>> predicted =
      ErrorsAtPose(*state, /*constrained_only=*/true);
  if (predicted.empty() || MedianError(predicted) <= check) return;
  const std::optional<PnpFit> fit = FitPnp(*state, 0.5 * check);
  if (!fit || MedianError(fit->errors) > 0.5 * check) return;
  // The frame's own landmarks agree on a pose the IMU prediction misses by more than `check`
  // pixels (median). Its difference from the prediction, in the preintegration's error terms
  // (phi = Log(R_predicted^T R_pnp), the position error in the previous state's body frame),
  // against their joint preintegrated covariance (the previous state taken as known) gives how
  // much larger the interval's white noise must have been.
  const State& previous = *states_[states_.size() - 2];
  const Rigid3d world_from_pnp = fit->body_from_world.Inverse();
  const Rigid3d predicted_pose = state->WorldFromBody();
  Vector6d error;
  error.head<3>() = LogSO3(predicted_pose.rotation.conjugate() * world_from_pnp.rotation);
  error.tail<3>() = previous.WorldFromBody().rotation.conjugate() *
                    (world_from_pnp.translation - predicted_pose.translation);
  const Matrix9d& cov = state->preintegration.covariance();
  Eigen::Matrix<double, 6, 6> joint;
  joint << cov.block<3, 3>(0, 0), cov.block<3, 3>(0, 6), cov.block<3, 3>(6, 0),
      cov.block<3, 3>(6, 6);
  const double m2 = error.dot(joint.ldlt().solve(error));
  constexpr double kChi2Six = 16.8;  // 99 % of chi-square with 6 degrees of freedom
  constexpr double kMaxScale = 1e4;
  const double scale = std::sqrt(m2 / kChi2Six);
  if (!(scale > 1)) return;
  state->preintegration.ScaleWhiteNoise(std::min(scale, kMaxScale));
  state->SetPose(world_from_pnp);
  ++imu_inflations_;
}

void SlidingWindowBackend::RemoveOutliers() {
  stats_.num_outliers_removed = 0;
  std::set<uint64_t> bad;
  const double limit = !options_.use_imu && options_.stereo_only_outlier_pixels > 0
                           ? options_.stereo_only_outlier_pixels
                           : options_.outlier_pixels;
  std::vector<double> errors;
  for (const auto& state : states_) {
    const Rigid3d body_from_world = state->WorldFromBody().Inverse();
    for (const auto& [id, obs] : state->observations) {
      const Landmark& landmark = *landmarks_.at(id);
      if (!landmark.initialized) continue;
      const double e = ReprojectionErrorPx(body_from_world, landmark, obs);
      errors.push_back(e);
      if (e > limit) bad.insert(id);
    }
  }
  if (!errors.empty()) {
    std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
    stats_.median_reprojection_px = errors[errors.size() / 2];
  }
  RejectLandmarks(bad);
  stats_.num_outliers_removed = static_cast<int>(bad.size());
  // An anchored observation that disagrees is dropped, the landmark kept (its fixed pose cannot
  // move to meet it).
  for (auto& [id, landmark] : landmarks_) {
    if (!landmark->initialized || landmark->anchors.empty()) continue;
    std::erase_if(landmark->anchors, [&](const Landmark::Anchor& a) {
      return ReprojectionErrorPx(a.world_from_body.Inverse(), *landmark, a.observation) > limit;
    });
  }
}

void SlidingWindowBackend::RelinearizeBiases() {
  for (size_t k = 1; k < states_.size(); ++k) {
    State& b = *states_[k];
    if (!b.has_preintegration) continue;
    const ImuBias bias = states_[k - 1]->Bias();
    const ImuBias& lin = b.preintegration.linearization_bias();
    if ((bias.gyro - lin.gyro).norm() > options_.relinearize_gyro_bias ||
        (bias.accel - lin.accel).norm() > options_.relinearize_accel_bias)
      b.preintegration.Reintegrate(bias);
  }
}

void SlidingWindowBackend::MarginalizeOldest() {
  OPTINAV_CHECK(states_.size() >= 3);
  State* oldest = states_.front().get();
  const State* newest = states_.back().get();
  // Landmarks of the oldest state that are no longer tracked go with it.
  // (In id order: the block order of the marginalisation must not depend on addresses.)
  // With marginalize_tracked_landmarks, the landmarks the newest frame still tracks are split:
  // their observations by the other states go into the prior with them (`split`).
  const Rigid3d cam0_from_world = rig_.cam0_from_body * newest->WorldFromBody().Inverse();
  std::set<const Landmark*> leaving;
  std::vector<uint64_t> leaving_ids, split_ids;
  std::vector<double*> leaving_blocks;
  for (const auto& [id, obs] : oldest->observations) {
    Landmark* l = landmarks_.at(id).get();
    if (!l->Constrained()) continue;
    const bool tracked = newest->observations.count(id) > 0;
    if (tracked && !options_.marginalize_tracked_landmarks) {
      // Dropped from the window; with anchoring kept against the oldest keyframe's fixed pose.
      if (options_.anchored_max_age_s > 0)
        std::erase_if(l->anchors, [&](const Landmark::Anchor& a) {
          return (newest->t_ns - a.t_ns) * 1e-9 > options_.anchored_max_age_s;
        });
      const auto near = [&] {
        const Eigen::Vector3d p(l->position[0], l->position[1], l->position[2]);
        return options_.anchored_max_depth_m <= 0 ||
               (cam0_from_world * p).z() < options_.anchored_max_depth_m;
      };
      if (static_cast<int>(l->anchors.size()) < options_.anchored_observations_per_landmark &&
          near()) {
        l->anchors.push_back({oldest->t_ns, oldest->WorldFromBody(), obs});
        if (!options_.anchored_stereo) l->anchors.back().observation.right.reset();
      }
      continue;
    }
    if (tracked && options_.marginalize_tracked_max_depth_m > 0) {
      const Eigen::Vector3d p =
          cam0_from_world * Eigen::Vector3d(l->position[0], l->position[1], l->position[2]);
      if (p.z() > options_.marginalize_tracked_max_depth_m) continue;
    }
    leaving.insert(l);
    (tracked ? split_ids : leaving_ids).push_back(id);
    leaving_blocks.push_back(l->position);
  }
  // (The newest state observes no leaving landmark; it keeps its observations of split ones. It
  // is the keyframe just added: only a new keyframe makes the window overflow, so the prior never
  // involves a state that DropNewestIfNotKeyframe removes later.)
  std::vector<std::unique_ptr<ResidualSpec>> owned =
      BuildResiduals([&](const State* s) { return s != newest; },
                     [&](const Landmark* l) { return leaving.count(l) > 0; });
  if (options_.use_imu && states_[1]->has_preintegration) {
    auto spec = std::make_unique<ResidualSpec>();
    spec->cost.reset(CreateImuFactor(states_[1]->preintegration, options_.gravity));
    spec->blocks = {oldest->pose, oldest->speed_bias, states_[1]->pose, states_[1]->speed_bias};
    owned.push_back(std::move(spec));
  }
  if (auto spec = GroundVehicleSpec(*oldest)) owned.push_back(std::move(spec));
  if (auto spec = GroundVehiclePairSpec(*oldest, *states_[1])) owned.push_back(std::move(spec));
  if (auto spec = PriorSpec()) owned.push_back(std::move(spec));
  const int64_t next_t = states_[1]->t_ns;
  for (const auto& factor : timed_factors_) {
    if (factor->t_ns() >= next_t) continue;
    if (auto spec = TimedFactorSpec(*factor, oldest)) owned.push_back(std::move(spec));
  }
  std::vector<double*> marginalize{oldest->pose};
  if (options_.use_imu) marginalize.push_back(oldest->speed_bias);
  marginalize.insert(marginalize.end(), leaving_blocks.begin(), leaving_blocks.end());
  std::vector<const ResidualSpec*> specs;
  for (const auto& s : owned) specs.push_back(s.get());
  prior_ = Marginalize(
      specs, marginalize, [&](const double* b) { return ManifoldOf(b); },
      [&](const double* b) { return SizeOf(b); }, options_.jacobi_scaled_marginalization);
  if (alignment_enabled_ && (alignment_walk_translation_ > 0 || alignment_walk_yaw_ > 0)) {
    const double d =
        (states_[1]->WorldFromBody().translation - oldest->WorldFromBody().translation).norm();
    // The VIO's heading drifts where the vehicle is, not about the world origin: the yaw part of
    // the walk turns the alignment about the current position (the translation compensates, so
    // far from the origin a yaw step does not move the current position by yaw x distance).
    const Eigen::Vector3d c = states_[1]->WorldFromBody().translation;
    const double cy = std::cos(alignment_[3]), sy = std::sin(alignment_[3]);
    const Eigen::Vector2d rc(cy * c.x() - sy * c.y(), sy * c.x() + cy * c.y());
    const Eigen::Vector4d g(rc.y(), -rc.x(), 0.0, 1.0);
    Eigen::Matrix4d q = alignment_walk_yaw_ * alignment_walk_yaw_ * d * g * g.transpose();
    q.diagonal().head<3>().array() +=
        std::max(alignment_walk_translation_ * alignment_walk_translation_ * d, 1e-12);
    q(3, 3) = std::max(q(3, 3), 1e-12);
    prior_ = AddRandomWalk(prior_, alignment_, q, options_.jacobi_scaled_marginalization);
  }
  const double dt_s = (states_[1]->t_ns - oldest->t_ns) * 1e-9;
  for (const auto& g : globals_) {
    if (!(g->walk_per_sqrt_s.array() > 0).any() || !prior_.Involves(g->values.data())) continue;
    const Eigen::VectorXd var = (g->walk_per_sqrt_s.array().square() * dt_s).max(1e-12).matrix();
    prior_ = AddRandomWalk(prior_, g->values.data(), var.asDiagonal().toDenseMatrix(),
                           options_.jacobi_scaled_marginalization);
  }

  // Remove what left the window. A split landmark keeps its block (eliminated from the prior,
  // so free again) at its current position, observed by the newest state only.
  for (uint64_t id : leaving_ids) {
    for (auto& state : states_) state->observations.erase(id);
    landmarks_.erase(id);
  }
  for (uint64_t id : split_ids) {
    for (auto& state : states_)
      if (state.get() != newest) state->observations.erase(id);
    landmarks_.at(id)->num_states = 1;
  }
  for (const auto& [id, obs] : oldest->observations) {
    auto it = landmarks_.find(id);
    if (it != landmarks_.end() && --it->second->num_states <= 0) landmarks_.erase(it);
  }
  std::erase_if(timed_factors_, [&](const auto& f) { return f->t_ns() < next_t; });
  states_.pop_front();
  states_.front()->has_preintegration = false;
}

}  // namespace optinav::vio
