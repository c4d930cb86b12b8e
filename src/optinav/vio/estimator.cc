#include "optinav/vio/estimator.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <type_traits>
#include <unordered_map>
#include <variant>

#include <fmt/format.h>

#include "optinav/geometry/lie.h"
#include "optinav/util/config.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"
#include "optinav/util/statistics.h"
#include "optinav/vio/internal/vi_alignment.h"

namespace optinav::vio {

std::optional<VioMode> ParseVioMode(const std::string& name) {
  if (name == "stereo-imu") return VioMode::kStereoImu;
  if (name == "stereo") return VioMode::kStereo;
  return std::nullopt;
}

std::string VioModeName(VioMode mode) {
  return mode == VioMode::kStereoImu ? "stereo-imu" : "stereo";
}

std::string VioOptions::Check() const {
  if (std::string e = frontend.Check(); !e.empty()) return "frontend." + e;
  if (std::string e = backend.Check(); !e.empty()) return "backend." + e;
  if (std::string e = loop_closure.Check(); !e.empty()) return e;
  if (!(stereo_only_outlier_pixels >= 0)) return "backend.stereo_only_outlier_pixels must be >= 0";
  if (!(stereo_only_pnp_gate_pixels >= 0))
    return "backend.stereo_only_pnp_gate_pixels must be >= 0 (0: off)";
  if (!(stereo_only_pnp_gate_median_factor >= 0))
    return "backend.stereo_only_pnp_gate_median_factor must be >= 0 (0: off)";
  if (!(stereo_only_initial_trust_region_radius > 0) || !(stereo_only_function_tolerance > 0))
    return "backend.stereo_only_initial_trust_region_radius and function_tolerance must be > 0";
  if (stereo_only_anchored_observations_per_landmark < 0)
    return "backend.stereo_only_anchored_observations_per_landmark must be >= 0 (0: off)";
  if (!(lowcontrast_gyro_walk_scale > 0 && lowcontrast_gyro_walk_scale <= 1))
    return "backend.lowcontrast_gyro_walk_scale must be in (0, 1]";
  if (!(init_window_s > 0)) return "init_window_s must be > 0";
  if (!(still_max_gyro_std > 0) || !(still_max_accel_std > 0))
    return "still_max_gyro_std and still_max_accel_std must be > 0";
  if (!std::isfinite(still_max_image_motion_px))
    return "still_max_image_motion_px must be finite (<= 0: the IMU alone decides)";
  if (!(static_gyro_bias_min_sigma > 0)) return "static_gyro_bias_min_sigma must be > 0";
  if (!(static_gyro_bias_max_noise_ratio > 0))
    return "static_gyro_bias_max_noise_ratio must be > 0";
  if (!std::isfinite(static_gyro_bias_standard_errors))
    return "static_gyro_bias_standard_errors must be finite";
  if (min_init_stereo_features < 3) return "min_init_stereo_features must be >= 3";
  if (!(motion_init_tilt_sigma_rad > 0) || !(motion_init_velocity_sigma_m_s > 0) ||
      !(motion_init_accel_bias_sigma > 0))
    return "motion_init sigmas must be > 0";
  if (!(motion_init_window_s >= 0 && motion_init_window_s <= 2.5))
    return "motion_init_window_s must be in [0, 2.5]";
  if (!(motion_init_aligned_tilt_sigma_rad > 0) || !(motion_init_aligned_velocity_sigma_m_s > 0))
    return "motion_init_aligned sigmas must be > 0";
  if (!std::isfinite(motion_init_agreement_rad) || !std::isfinite(motion_init_agreement_sigmas))
    return "motion_init_agreement_rad and motion_init_agreement_sigmas must be finite";
  if (!(motion_init_max_whitened_residual > 0))
    return "motion_init_max_whitened_residual must be > 0";
  if (!(max_frame_gap_s > 0) || !(max_imu_gap_s > 0)) return "max gaps must be > 0";
  if (min_tracked_landmarks < 0) return "min_tracked_landmarks must be >= 0";
  if (!(max_weak_tracking_s >= 0)) return "max_weak_tracking_s must be >= 0";
  if (!(max_speed_m_s > 0) || !(max_gyro_bias > 0) || !(max_accel_bias > 0))
    return "divergence limits must be > 0";
  if (feedback_lag_frames < 1 || feedback_lag_frames > 16)
    return "pipeline.feedback_lag_frames must be in [1, 16]";
  return "";
}

namespace {

// A mapping key as a name. YAML allows a sequence or a map as a key ("? [a]: 1"); as<string>
// would throw YAML's own exception out of the loader (found by fuzz/vio_config).
std::string KeyName(const YamlFile& file, const YAML::Node& key, const std::string& prefix) {
  if (!key.IsScalar()) {
    throw Error("a key must be a plain name, not a sequence or a map",
                internal::YamlContext(file, key, prefix + "<key>"));
  }
  return key.Scalar();
}

// Every key of a config section and the field of `o` it sets; any other key is an error (a typo
// must not pass silently). The one list behind LoadVioOptions and VioOptionsYaml.
using Field = std::variant<int*, double*, bool*>;
using Section = std::vector<std::pair<const char*, Field>>;
std::map<std::string, Section> OptionSections(VioOptions& o) {
  FrontendOptions& f = o.frontend;
  BackendOptions& b = o.backend;
  LoopClosureOptions& l = o.loop_closure;
  return {
      {"frontend",
       {{"max_features", &f.max_features},
        {"grid_cols", &f.grid_cols},
        {"grid_rows", &f.grid_rows},
        {"min_distance_px", &f.min_distance_px},
        {"quality_level", &f.quality_level},
        {"klt_window_px", &f.klt_window_px},
        {"stereo_window_px", &f.stereo_window_px},
        {"stereo_refine_window_px", &f.stereo_refine_window_px},
        {"klt_gain_offset", &f.klt_gain_offset},
        {"stereo_only_klt_gain_offset", &f.stereo_only_klt_gain_offset},
        {"klt_pyramid_levels", &f.klt_pyramid_levels},
        {"klt_max_iterations", &f.klt_max_iterations},
        {"forward_backward_px", &f.forward_backward_px},
        {"ransac_px", &f.ransac_px},
        {"epipolar_px", &f.epipolar_px},
        {"border_px", &f.border_px},
        {"min_corner_response", &f.min_corner_response},
        {"corner_noise_floor", &f.corner_noise_floor},
        {"detect_min_eigen", &f.detect_min_eigen},
        {"min_corner_isotropy", &f.min_corner_isotropy},
        {"clahe_clip_limit", &f.clahe_clip_limit},
        {"clahe_tiles", &f.clahe_tiles},
        {"clahe_below_std", &f.clahe_below_std},
        {"clahe_below_local_std", &f.clahe_below_local_std},
        {"highpass_sigma_px", &f.highpass_sigma_px},
        {"local_norm_sigma_px", &f.local_norm_sigma_px},
        {"local_norm_floor", &f.local_norm_floor},
        {"fog_treatment_low_contrast_only", &f.fog_treatment_low_contrast_only},
        {"median_filter_px", &f.median_filter_px},
        {"corner_block_px", &f.corner_block_px},
        {"keyframe_max_interval_s", &f.keyframe_max_interval_s},
        {"contrast_stretch_std", &f.contrast_stretch_std},
        {"keyframe_fresh_probation", &f.keyframe_fresh_probation},
        {"keyframe_min_tracked_ratio", &f.keyframe_min_tracked_ratio},
        {"keyframe_min_parallax_px", &f.keyframe_min_parallax_px},
        {"stereo_only_keyframe_min_tracked_ratio", &f.stereo_only_keyframe_min_tracked_ratio},
        {"stereo_only_local_norm_sigma_px", &f.stereo_only_local_norm_sigma_px},
        {"stereo_only_corner_noise_floor", &f.stereo_only_corner_noise_floor},
        {"stereo_only_min_corner_isotropy", &f.stereo_only_min_corner_isotropy},
        {"stereo_only_keyframe_min_parallax_px", &f.stereo_only_keyframe_min_parallax_px}}},
      {"backend",
       {{"window_keyframes", &b.window_keyframes},
        {"pixel_sigma", &b.pixel_sigma},
        {"huber_pixels", &b.huber_pixels},
        {"outlier_pixels", &b.outlier_pixels},
        {"marginalize_tracked_landmarks", &b.marginalize_tracked_landmarks},
        {"marginalize_tracked_max_depth_m", &b.marginalize_tracked_max_depth_m},
        {"anchored_observations_per_landmark", &b.anchored_observations_per_landmark},
        {"anchored_max_age_s", &b.anchored_max_age_s},
        {"anchored_max_depth_m", &b.anchored_max_depth_m},
        {"anchored_stereo", &b.anchored_stereo},
        {"predicted_gate_pixels", &b.predicted_gate_pixels},
        {"imu_pnp_check_pixels", &b.imu_pnp_check_pixels},
        {"predicted_gate_median_factor", &b.predicted_gate_median_factor},
        {"stereo_only_pnp_gate_pixels", &o.stereo_only_pnp_gate_pixels},
        {"stereo_only_pnp_gate_median_factor", &o.stereo_only_pnp_gate_median_factor},
        {"ground_vehicle_lateral_sigma_m_s", &b.ground_vehicle_lateral_sigma_m_s},
        {"ground_vehicle_vertical_sigma_m_s", &b.ground_vehicle_vertical_sigma_m_s},
        {"ground_vehicle_boresight_sigma_rad", &b.ground_vehicle_boresight_sigma_rad},
        {"ground_vehicle_boresight_walk_rad_per_sqrt_s",
         &b.ground_vehicle_boresight_walk_rad_per_sqrt_s},
        {"stereo_only_outlier_pixels", &o.stereo_only_outlier_pixels},
        {"stereo_only_initial_trust_region_radius", &o.stereo_only_initial_trust_region_radius},
        {"stereo_only_function_tolerance", &o.stereo_only_function_tolerance},
        {"stereo_only_marginalize_tracked_landmarks", &o.stereo_only_marginalize_tracked_landmarks},
        {"stereo_only_anchored_observations_per_landmark",
         &o.stereo_only_anchored_observations_per_landmark},
        {"lowcontrast_gyro_walk_scale", &o.lowcontrast_gyro_walk_scale},
        {"min_depth_m", &b.min_depth_m},
        {"max_depth_m", &b.max_depth_m},
        {"max_iterations", &b.max_iterations},
        {"max_solver_time_s", &b.max_solver_time_s},
        {"initial_trust_region_radius", &b.initial_trust_region_radius},
        {"function_tolerance", &b.function_tolerance},
        {"relinearize_gyro_bias", &b.relinearize_gyro_bias},
        {"relinearize_accel_bias", &b.relinearize_accel_bias},
        {"prior_position_sigma_m", &b.prior_position_sigma_m},
        {"prior_yaw_sigma_rad", &b.prior_yaw_sigma_rad},
        {"prior_tilt_sigma_rad", &b.prior_tilt_sigma_rad},
        {"prior_velocity_sigma_m_s", &b.prior_velocity_sigma_m_s},
        {"prior_gyro_bias_sigma", &b.prior_gyro_bias_sigma},
        {"prior_accel_bias_sigma", &b.prior_accel_bias_sigma}}},
      {"loop_closure",
       {{"stereo_only", &l.stereo_only},
        {"stereo_imu", &l.stereo_imu},
        {"orb_features", &l.orb_features},
        {"orb_fast_threshold", &l.orb_fast_threshold},
        {"orb_retry_below_features", &l.orb_retry_below_features},
        {"orb_retry_stereo_imu", &l.orb_retry_stereo_imu},
        {"orb_retry_clahe_clip", &l.orb_retry_clahe_clip},
        {"orb_retry_clahe_tiles", &l.orb_retry_clahe_tiles},
        {"orb_retry_fast_threshold", &l.orb_retry_fast_threshold},
        {"stereo_epipolar_px", &l.stereo_epipolar_px},
        {"max_depth_baselines", &l.max_depth_baselines},
        {"min_separation_s", &l.min_separation_s},
        {"min_separation_m", &l.min_separation_m},
        {"search_radius_m", &l.search_radius_m},
        {"search_radius_fraction", &l.search_radius_fraction},
        {"max_view_angle_deg", &l.max_view_angle_deg},
        {"max_candidates", &l.max_candidates},
        {"stereo_only_search_radius_fraction", &l.stereo_only_search_radius_fraction},
        {"stereo_only_max_candidates", &l.stereo_only_max_candidates},
        {"match_ratio", &l.match_ratio},
        {"pnp_px", &l.pnp_px},
        {"min_inliers", &l.min_inliers},
        {"guided_radius_px", &l.guided_radius_px},
        {"guided_seed_inliers", &l.guided_seed_inliers},
        {"guided_max_hamming", &l.guided_max_hamming},
        {"guided_ratio", &l.guided_ratio},
        {"min_interval_s", &l.min_interval_s},
        {"support_min_path_m", &l.support_min_path_m},
        {"support_tolerance_m", &l.support_tolerance_m},
        {"support_tolerance_fraction", &l.support_tolerance_fraction},
        {"support_max_wait_s", &l.support_max_wait_s},
        {"alias_path_m", &l.alias_path_m},
        {"alias_keyframes", &l.alias_keyframes},
        {"alias_min_offset_m", &l.alias_min_offset_m},
        {"alias_drift_fraction", &l.alias_drift_fraction},
        {"alias_min_sigmas", &l.alias_min_sigmas},
        {"odometry_sigma_m_per_m", &l.odometry_sigma_m_per_m},
        {"odometry_min_sigma_m", &l.odometry_min_sigma_m},
        {"odometry_sigma_rad_per_m", &l.odometry_sigma_rad_per_m},
        {"odometry_min_sigma_rad", &l.odometry_min_sigma_rad},
        {"loop_sigma_m", &l.loop_sigma_m},
        {"loop_sigma_rad", &l.loop_sigma_rad},
        {"max_loop_residual_m", &l.max_loop_residual_m},
        {"point_sigma_px", &l.point_sigma_px},
        {"max_loop_distance_m", &l.max_loop_distance_m}}},
      {"initialization",
       {{"init_window_s", &o.init_window_s},
        {"still_max_gyro_std", &o.still_max_gyro_std},
        {"still_max_accel_std", &o.still_max_accel_std},
        {"still_max_image_motion_px", &o.still_max_image_motion_px},
        {"static_gyro_bias_standard_errors", &o.static_gyro_bias_standard_errors},
        {"static_gyro_bias_min_sigma", &o.static_gyro_bias_min_sigma},
        {"static_gyro_bias_max_noise_ratio", &o.static_gyro_bias_max_noise_ratio},
        {"min_init_stereo_features", &o.min_init_stereo_features},
        {"motion_init_tilt_sigma_rad", &o.motion_init_tilt_sigma_rad},
        {"motion_init_velocity_sigma_m_s", &o.motion_init_velocity_sigma_m_s},
        {"motion_init_accel_bias_sigma", &o.motion_init_accel_bias_sigma},
        {"motion_init_window_s", &o.motion_init_window_s},
        {"motion_init_aligned_tilt_sigma_rad", &o.motion_init_aligned_tilt_sigma_rad},
        {"motion_init_aligned_velocity_sigma_m_s", &o.motion_init_aligned_velocity_sigma_m_s},
        {"motion_init_agreement_rad", &o.motion_init_agreement_rad},
        {"motion_init_agreement_sigmas", &o.motion_init_agreement_sigmas},
        {"motion_init_max_whitened_residual", &o.motion_init_max_whitened_residual}}},
      {"failure",
       {{"max_frame_gap_s", &o.max_frame_gap_s},
        {"max_imu_gap_s", &o.max_imu_gap_s},
        {"min_tracked_landmarks", &o.min_tracked_landmarks},
        {"max_weak_tracking_s", &o.max_weak_tracking_s},
        {"max_speed_m_s", &o.max_speed_m_s},
        {"max_gyro_bias", &o.max_gyro_bias},
        {"max_accel_bias", &o.max_accel_bias}}},
      {"pipeline", {{"feedback_lag_frames", &o.feedback_lag_frames}}},
  };
}

}  // namespace

std::string VioOptionsYaml(const VioOptions& options) {
  VioOptions o = options;
  std::string text = fmt::format("mode: {}\n", VioModeName(o.mode));
  for (const auto& [section, fields] : OptionSections(o)) {
    text += section + ":\n";
    for (const auto& [name, field] : fields) {
      std::visit(
          [&, name = name](auto* value) {
            if constexpr (std::is_same_v<std::decay_t<decltype(*value)>, bool>)
              text += fmt::format("  {}: {}\n", name, *value ? "true" : "false");
            else
              text += fmt::format("  {}: {}\n", name, *value);  // shortest exact form
          },
          field);
    }
  }
  return text;
}

VioOptions LoadVioOptions(const std::string& path) {
  const YamlFile file = LoadYamlFile(path);
  VioOptions o;
  const YAML::Node& root = file.root;
  if (!root.IsMap()) throw Error("expected a map of options", {.file = path});
  const std::map<std::string, Section> sections = OptionSections(o);
  for (const auto& kv : root) {
    const std::string key = KeyName(file, kv.first, "");
    if (key == "mode") {
      const std::string mode = YamlGet<std::string>(file, root, "mode");
      const auto parsed = ParseVioMode(mode);
      if (!parsed)
        throw Error("expected stereo-imu or stereo, got '" + mode + "'",
                    internal::YamlContext(file, kv.second, "mode"));
      o.mode = *parsed;
      continue;
    }
    const auto section = sections.find(key);
    if (section == sections.end())
      throw Error("unknown key", internal::YamlContext(file, kv.first, key));
    const YAML::Node& node = kv.second;
    if (!node.IsMap())
      throw Error("expected a map of options", internal::YamlContext(file, node, key));
    for (const auto& entry : node) {
      const std::string name = KeyName(file, entry.first, key + ".");
      const auto field = std::find_if(section->second.begin(), section->second.end(),
                                      [&](const auto& p) { return name == p.first; });
      if (field == section->second.end())
        throw Error("unknown key", internal::YamlContext(file, entry.first, key + "." + name));
      std::visit(
          [&](auto* target) {
            *target = YamlGet<std::decay_t<decltype(*target)>>(file, node, name);
          },
          field->second);
    }
  }
  if (const std::string e = o.Check(); !e.empty()) throw Error(e, {.file = path});
  return o;
}

namespace {

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int r = 0; r < a.rows; ++r)
    if (std::memcmp(a.ptr(r), b.ptr(r), a.cols * a.elemSize()) != 0) return false;
  return true;
}

// A uniform (e.g. black) frame is no frozen camera: it is tracked and loses the track.
bool HasTexture(const cv::Mat& m) {
  double lo = 0, hi = 0;
  cv::minMaxLoc(m.reshape(1), &lo, &hi);
  return hi > lo;
}

RigExtrinsics MakeExtrinsics(const camera::StereoRig& rig, const Rigid3d& body_from_cam0) {
  RigExtrinsics e;
  e.cam0_from_body = body_from_cam0.Inverse();
  e.cam1_from_body = rig.right_from_left * e.cam0_from_body;
  e.focal_px = rig.left.fx;
  return e;
}

BackendOptions WithMode(BackendOptions b, const VioOptions& o, const ImuNoise& noise) {
  b.use_imu = o.mode == VioMode::kStereoImu;
  b.stereo_only_outlier_pixels = o.stereo_only_outlier_pixels;
  if (!b.use_imu) {
    b.initial_trust_region_radius = o.stereo_only_initial_trust_region_radius;
    b.function_tolerance = o.stereo_only_function_tolerance;
    b.marginalize_tracked_landmarks = o.stereo_only_marginalize_tracked_landmarks;
    b.stereo_only_pnp_gate_pixels = o.stereo_only_pnp_gate_pixels;
    b.stereo_only_pnp_gate_median_factor = o.stereo_only_pnp_gate_median_factor;
    b.anchored_observations_per_landmark =
        b.marginalize_tracked_landmarks ? 0 : o.stereo_only_anchored_observations_per_landmark;
  }
  b.imu_noise = noise;
  return b;
}

double Yaw(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d r = q.toRotationMatrix();
  return std::atan2(r(1, 0), r(0, 0));
}

}  // namespace

FrontendOptions FrontendOptionsForMode(FrontendOptions f, VioMode mode) {
  if (mode == VioMode::kStereo) {
    f.keyframe_min_tracked_ratio = f.stereo_only_keyframe_min_tracked_ratio;
    f.keyframe_min_parallax_px = f.stereo_only_keyframe_min_parallax_px;
    if (f.stereo_only_local_norm_sigma_px >= 0)
      f.local_norm_sigma_px = f.stereo_only_local_norm_sigma_px;
    if (f.stereo_only_min_corner_isotropy >= 0)
      f.min_corner_isotropy = f.stereo_only_min_corner_isotropy;
    f.klt_gain_offset = f.stereo_only_klt_gain_offset;
    if (f.stereo_only_corner_noise_floor >= 0)
      f.corner_noise_floor = f.stereo_only_corner_noise_floor;
  }
  return f;
}

VioEstimator::VioEstimator(const camera::StereoRig& rig, const Rigid3d& body_from_cam0,
                           const ImuNoise& imu_noise, const VioOptions& options)
    : rig_(rig),
      body_from_cam0_(body_from_cam0),
      imu_noise_(imu_noise),
      options_(options),
      frontend_(rig, FrontendOptionsForMode(options.frontend, options.mode)),
      backend_(WithMode(options.backend, options, imu_noise), MakeExtrinsics(rig, body_from_cam0)) {
  const std::string problem = options_.Check();
  OPTINAV_CHECK_MSG(problem.empty(), problem);
  frontend_.set_timing(&timing_);
}

VioEstimator::~VioEstimator() = default;

void VioEstimator::AppendImu(const TimedImuSample& s, double keep_s,
                             std::deque<TimedImuSample>* imu) {
  imu->push_back(s);
  // Keep a few seconds: the initialisation window and the interval since the last frame.
  const int64_t keep_ns = static_cast<int64_t>(keep_s * 1e9);
  while (imu->size() > 2 && imu->front().t_ns < s.t_ns - keep_ns) imu->pop_front();
}

void VioEstimator::AddImu(const TimedImuSample& s) {
  if (!s.gyro.allFinite() || !s.accel.allFinite()) {
    spdlog::warn("vio: dropping non-finite IMU sample at {} ns", s.t_ns);
    return;
  }
  if (!imu_.empty() && s.t_ns <= imu_.back().t_ns) {
    spdlog::warn("vio: dropping IMU sample at {} ns (not after {} ns)", s.t_ns, imu_.back().t_ns);
    return;
  }
  AppendImu(s, options_.init_window_s + 3.0, &imu_);
  imu_for_backend_.push_back(s);
}

std::optional<std::string> VioEstimator::ImuProblem(const std::deque<TimedImuSample>& imu,
                                                    int64_t t0_ns, int64_t t1_ns) const {
  const int64_t max_gap = static_cast<int64_t>(options_.max_imu_gap_s * 1e9);
  if (imu.empty()) return "IMU gap: no IMU data (IMU stopped)";
  if (imu.back().t_ns < t1_ns - max_gap)
    return fmt::format("IMU gap: no IMU sample in the {:.3f} s before the frame (IMU stopped?)",
                       (t1_ns - imu.back().t_ns) * 1e-9);
  if (imu.front().t_ns > t0_ns + max_gap) return "IMU gap: no IMU data since the previous frame";
  int64_t prev = t0_ns;
  for (const TimedImuSample& s : imu) {
    if (s.t_ns <= t0_ns) {
      prev = s.t_ns;
      continue;
    }
    if (s.t_ns - std::max(prev, t0_ns) > max_gap)
      return fmt::format("IMU gap of {:.3f} s", (s.t_ns - std::max(prev, t0_ns)) * 1e-9);
    prev = s.t_ns;
    if (s.t_ns >= t1_ns) break;
  }
  return std::nullopt;
}

ImuPreintegration VioEstimator::Preintegrate(const std::deque<TimedImuSample>& imu, int64_t t0_ns,
                                             int64_t t1_ns, const ImuBias& bias) const {
  std::vector<TimedImuSample> window;
  for (size_t i = 0; i < imu.size(); ++i) {
    const bool next_after_t0 = i + 1 < imu.size() && imu[i + 1].t_ns > t0_ns;
    if ((imu[i].t_ns >= t0_ns || next_after_t0) && imu[i].t_ns <= t1_ns) window.push_back(imu[i]);
    if (imu[i].t_ns >= t1_ns) {
      window.push_back(imu[i]);
      break;
    }
  }
  ImuPreintegration pre(bias, imu_noise_);
  for (const ImuMeasurement& m : ImuMeasurementsBetween(window, t0_ns, t1_ns))
    pre.Integrate(m.gyro, m.accel, m.dt_s);
  return pre;
}

void VioEstimator::EnableGnss(const GnssFusionOptions& options) {
  OPTINAV_CHECK_MSG(options_.mode == VioMode::kStereoImu, "GNSS fusion needs stereo-imu mode");
  gnss_ = std::make_unique<GnssFusion>(options);
}

void VioEstimator::AddGnss(const GnssSample& sample) {
  OPTINAV_CHECK_MSG(gnss_ != nullptr, "EnableGnss first");
  gnss_->AddSample(sample);
}

void VioEstimator::Lose(int64_t t_ns, const std::string& reason) {
  if (!lost_since_ns_) {
    lost_since_ns_ = last_good_ ? last_good_->t_ns : t_ns;
    lost_reason_ = reason;
  }
  spdlog::warn("vio: tracking lost at {:.3f} s: {}", t_ns * 1e-9, reason);
  backend_.Reset();
  ResetMotionInit();
  posted_rejected_ = 0;
  if (gnss_) gnss_->OnTrackLost();
  weak_since_s_ = -1;
}

void VioEstimator::Finish() {
  if (lost_since_ns_) {
    lost_.push_back({*lost_since_ns_, last_frame_ns_.value_or(*lost_since_ns_),
                     *lost_reason_ + " (not recovered before the end)"});
    lost_since_ns_.reset();
  }
}

bool VioEstimator::TryInitialize(const FramePacket& packet) {
  const int64_t t_ns = packet.t_ns;
  const FrontendOutput& features = packet.features;
  int stereo = 0;
  for (const StereoObservation& o : features.observations) stereo += o.right ? 1 : 0;
  if (options_.mode == VioMode::kStereoImu) {
    still_frames_.emplace_back(t_ns, features.observations);
    const int64_t t0 = t_ns - static_cast<int64_t>(options_.init_window_s * 1e9);
    while (still_frames_.size() > 1 && still_frames_[1].first <= t0) still_frames_.pop_front();
  }
  // (A running in-motion alignment window tracks on through frames with fewer.)
  if (stereo < options_.min_init_stereo_features && !init_odometry_) return false;
  StateEstimate state;
  state.t_ns = t_ns;
  double tilt_sigma = -1, velocity_sigma = -1, accel_bias_sigma = -1, gyro_bias_sigma = -1;
  if (options_.mode == VioMode::kStereoImu) {
    const int64_t t0 = t_ns - static_cast<int64_t>(options_.init_window_s * 1e9);
    const std::optional<double> image_motion_px =
        ImageMotionSinceWindowStartPx(t0, t_ns, features.observations);
    std::vector<const TimedImuSample*> window;
    for (const TimedImuSample& s : backend_imu_)
      if (s.t_ns >= t0 && s.t_ns <= t_ns) window.push_back(&s);
    if (window.size() < 10 || window.front()->t_ns > t0 + (t_ns - t0) / 5 ||
        ImuProblem(backend_imu_, window.front()->t_ns, t_ns)) {
      ResetMotionInit();
      return false;
    }
    Eigen::Vector3d mg = Eigen::Vector3d::Zero(), ma = Eigen::Vector3d::Zero();
    for (const auto* s : window) mg += s->gyro, ma += s->accel;
    mg /= window.size();
    ma /= window.size();
    // Stillness on 0.1 s block means: propeller vibration averages out, motion does not.
    std::vector<Eigen::Vector3d> block_g, block_a;
    const int64_t block_ns = 100'000'000;
    for (size_t i = 0; i < window.size();) {
      Eigen::Vector3d sg = Eigen::Vector3d::Zero(), sa = Eigen::Vector3d::Zero();
      size_t j = i;
      for (; j < window.size() && window[j]->t_ns < window[i]->t_ns + block_ns; ++j)
        sg += window[j]->gyro, sa += window[j]->accel;
      block_g.push_back(sg / (j - i));
      block_a.push_back(sa / (j - i));
      i = j;
    }
    double vg = 0, va = 0;
    for (size_t k = 0; k < block_g.size(); ++k)
      vg += (block_g[k] - mg).squaredNorm(), va += (block_a[k] - ma).squaredNorm();
    const double std_g = std::sqrt(vg / block_g.size()), std_a = std::sqrt(va / block_a.size());
    // Without tracks over the whole window (a recording's or a re-start's first frame) the IMU
    // alone decides.
    const bool still = std_g < options_.still_max_gyro_std &&
                       std_a < options_.still_max_accel_std &&
                       (options_.still_max_image_motion_px <= 0 || !image_motion_px ||
                        *image_motion_px <= options_.still_max_image_motion_px);
    // Attitude: the specific force points up in the world.
    Eigen::Quaterniond world_from_body =
        Eigen::Quaterniond::FromTwoVectors(ma.normalized(), Eigen::Vector3d::UnitZ());
    const double target_yaw = last_good_ ? Yaw(last_good_->world_from_body.rotation) : 0.0;
    world_from_body =
        Eigen::AngleAxisd(target_yaw - Yaw(world_from_body), Eigen::Vector3d::UnitZ()) *
        world_from_body;
    state.world_from_body.rotation = world_from_body.normalized();
    if (still) {
      ResetMotionInit();
      state.bias.gyro = mg;
      // std_g is the RMS of the 3-vector deviations of the block means: per axis std_g /
      // sqrt(3), against gyro_noise_density / sqrt(block) from the sensor's white noise alone.
      const double axis_spread = std_g / std::sqrt(3.0);
      const double block_noise = imu_noise_.gyro_noise_density / std::sqrt(block_ns * 1e-9);
      if (options_.static_gyro_bias_standard_errors > 0 &&
          axis_spread <= options_.static_gyro_bias_max_noise_ratio * block_noise) {
        const double standard_error = axis_spread / std::sqrt(static_cast<double>(block_g.size()));
        gyro_bias_sigma = std::clamp(
            options_.static_gyro_bias_standard_errors * standard_error,
            options_.static_gyro_bias_min_sigma,
            std::max(options_.static_gyro_bias_min_sigma, options_.backend.prior_gyro_bias_sigma));
      }
      state.bias.accel =
          ma - state.world_from_body.rotation.conjugate() * -options_.backend.gravity;
      last_init_kind_ = "static";
    } else if (options_.motion_init_window_s > 0) {
      if (!MotionInitStep(packet)) return false;
      last_init_kind_ = "in-motion-aligned";
    } else {
      state.bias = last_good_ ? last_good_->bias : ImuBias{};
      tilt_sigma = options_.motion_init_tilt_sigma_rad;
      velocity_sigma = options_.motion_init_velocity_sigma_m_s;
      accel_bias_sigma = options_.motion_init_accel_bias_sigma;
      last_init_kind_ = "in-motion-priors";
    }
    // Only the loose-prior start has a transient the GNSS alignment must wait out.
    if (gnss_) gnss_->OnTrackStarted(last_init_kind_ == "in-motion-priors");
    spdlog::info(
        "vio: {} initialisation at {:.3f} s (gyro std {:.4f} rad/s, accel std {:.3f} "
        "m/s^2, image motion {} px, {} stereo features)",
        last_init_kind_, t_ns * 1e-9, std_g, std_a,
        image_motion_px ? fmt::format("{:.2f}", *image_motion_px) : "unknown", stereo);
  } else {
    if (last_good_) state.world_from_body = last_good_->world_from_body;
    last_init_kind_ = "stereo";
  }
  // (The aligned start initialised the window already, its first frame at the last good position.)
  if (last_init_kind_ != "in-motion-aligned") {
    if (last_good_) state.world_from_body.translation = last_good_->world_from_body.translation;
    backend_.Initialize(state, features.observations, tilt_sigma, velocity_sigma, accel_bias_sigma,
                        gyro_bias_sigma);
  }
  ++initializations_;
  still_frames_.clear();
  if (lost_since_ns_) {
    lost_.push_back({*lost_since_ns_, t_ns, *lost_reason_});
    spdlog::warn("vio: lost from {:.3f} s to {:.3f} s ({})", *lost_since_ns_ * 1e-9, t_ns * 1e-9,
                 *lost_reason_);
    lost_since_ns_.reset();
  }
  return true;
}

std::optional<double> VioEstimator::ImageMotionSinceWindowStartPx(
    int64_t t0_ns, int64_t t_ns, const std::vector<StereoObservation>& now) const {
  // The first frame must be at (or before) the window's start, as the IMU window's first sample.
  if (still_frames_.empty() || still_frames_.front().first > t0_ns + (t_ns - t0_ns) / 5)
    return std::nullopt;
  std::unordered_map<uint64_t, Eigen::Vector2d> then;
  for (const StereoObservation& o : still_frames_.front().second) then.emplace(o.track_id, o.left);
  std::vector<double> moved;
  for (const StereoObservation& o : now)
    if (const auto it = then.find(o.track_id); it != then.end())
      moved.push_back((o.left - it->second).norm() * rig_.left.fx);
  if (moved.size() < 10) return std::nullopt;
  return Median(std::move(moved));
}

void VioEstimator::ResetMotionInit() {
  init_odometry_.reset();
  init_frames_.clear();
  pending_alignment_.reset();
  init_attempt_front_ = 0;
}

void VioEstimator::HoldGyroBiasIf(bool low_contrast, ImuPreintegration* pre) const {
  if (low_contrast && options_.lowcontrast_gyro_walk_scale != 1.0)
    pre->ScaleGyroBiasWalk(options_.lowcontrast_gyro_walk_scale);
}

bool VioEstimator::MotionInitStep(const FramePacket& packet) {
  const Timer timer;
  struct AddTime {
    TimingStats& timing;
    const Timer& timer;
    ~AddTime() { timing.Add("init_odometry", timer.ElapsedSeconds()); }
  } add_time{timing_, timer};
  const int64_t t_ns = packet.t_ns;
  const FrontendOutput& features = packet.features;
  if (packet.problem) ResetMotionInit();
  if (init_odometry_) {
    const StateEstimate e = init_odometry_->AddFrame(t_ns, ImuPreintegration(ImuBias{}, imu_noise_),
                                                     features.observations, features.keyframe);
    const bool finite = e.world_from_body.translation.allFinite() &&
                        e.world_from_body.rotation.coeffs().allFinite();
    if (finite &&
        init_odometry_->stats().newest_constrained_landmarks >= options_.min_tracked_landmarks) {
      init_frames_.push_back({t_ns, e.world_from_body, features.observations, features.keyframe,
                              features.stats.low_contrast});
    } else {
      spdlog::debug("vio: in-motion alignment odometry lost at {:.3f} s, restarting", t_ns * 1e-9);
      ResetMotionInit();
    }
  }
  if (!init_odometry_) {
    int stereo = 0;
    for (const StereoObservation& o : features.observations) stereo += o.right ? 1 : 0;
    if (stereo < options_.min_init_stereo_features) return false;
    BackendOptions odometry = options_.backend;
    odometry.use_imu = false;
    // The ground vehicle's velocity constraint is the window's, with the IMU.
    odometry.ground_vehicle_lateral_sigma_m_s = odometry.ground_vehicle_vertical_sigma_m_s = 0;
    init_odometry_ =
        std::make_unique<SlidingWindowBackend>(odometry, MakeExtrinsics(rig_, body_from_cam0_));
    StateEstimate first;
    first.t_ns = t_ns;
    init_odometry_->Initialize(first, features.observations);
    init_frames_.push_back(
        {t_ns, first.world_from_body, features.observations, true, features.stats.low_contrast});
    return false;
  }
  // This attempt's window: from init_frames_[init_attempt_front_] (the front itself unless an
  // alignment awaits its confirmation) to the newest frame.
  const int64_t window_start_ns = init_frames_[init_attempt_front_].t_ns;
  if ((t_ns - window_start_ns) * 1e-9 < options_.motion_init_window_s) return false;
  // The IMU between consecutive odometry frames, at the prior bias.
  const ImuBias prior = last_good_ ? last_good_->bias : ImuBias{};
  if (const auto problem = ImuProblem(backend_imu_, init_frames_.front().t_ns, t_ns)) {
    spdlog::debug("vio: in-motion alignment window has an IMU problem ({}), restarting", *problem);
    ResetMotionInit();
    return false;
  }
  // The alignment of init_frames_ from index `from` on (times and poses kept for the start).
  std::vector<int64_t> times;
  std::vector<Rigid3d> poses;
  ViAlignmentOptions alignment_options;
  alignment_options.accel_bias_sigma = options_.motion_init_accel_bias_sigma;
  alignment_options.max_whitened_residual = options_.motion_init_max_whitened_residual;
  auto align_from = [&](size_t from) {
    times.clear();
    poses.clear();
    std::vector<ImuPreintegration> pre;
    for (size_t k = from; k < init_frames_.size(); ++k) {
      const MotionInitFrame& f = init_frames_[k];
      if (!times.empty()) pre.push_back(Preintegrate(backend_imu_, times.back(), f.t_ns, prior));
      times.push_back(f.t_ns);
      poses.push_back(f.vo_from_body);
    }
    return SolveViAlignment(times, poses, std::move(pre), alignment_options);
  };
  ViAlignmentResult r = align_from(init_attempt_front_);
  // The next window starts half-way into this one.
  const size_t next_front = init_attempt_front_ + (init_frames_.size() - init_attempt_front_) / 2;
  if (!r.ok) {
    spdlog::info("vio: in-motion alignment at {:.3f} s failed: {}; sliding on", t_ns * 1e-9,
                 r.failure);
    init_frames_.erase(init_frames_.begin(), init_frames_.begin() + next_front);
    pending_alignment_.reset();
    init_attempt_front_ = 0;
    return false;
  }
  if (options_.motion_init_agreement_rad > 0 || options_.motion_init_agreement_sigmas > 0) {
    // The angle by which this alignment confirms the pending one, if it does.
    std::optional<double> agreement;
    if (pending_alignment_) {
      const double angle = AngleBetween(pending_alignment_->gravity_vo, r.gravity_vo);
      const double limit =
          std::max(options_.motion_init_agreement_rad,
                   options_.motion_init_agreement_sigmas *
                       std::hypot(pending_alignment_->tilt_sigma_rad, r.tilt_sigma_rad));
      if (angle <= limit) {
        agreement = angle;
      } else {
        spdlog::info(
            "vio: in-motion alignment at {:.3f} s disagrees with the one before by {:.2f} deg; "
            "sliding on",
            t_ns * 1e-9, angle * 180 / M_PI);
      }
    }
    if (!agreement) {
      // Unconfirmed: this alignment waits for the next window's (its frames from this window's
      // first on).
      init_frames_.erase(init_frames_.begin(), init_frames_.begin() + init_attempt_front_);
      init_attempt_front_ = next_front - init_attempt_front_;
      pending_alignment_ = std::move(r);
      return false;
    }
    // Confirmed: one alignment over both windows (init_frames_ from the earlier one's first
    // frame), or the earlier one's alone when the two together fail the residual test.
    r = align_from(0);
    spdlog::info(
        "vio: in-motion alignment confirmed at {:.3f} s (gravity within {:.2f} deg of the one "
        "before){}",
        t_ns * 1e-9, *agreement * 180 / M_PI,
        r.ok ? ""
             : fmt::format("; both windows together fail ({}), the earlier one starts", r.failure));
    if (!r.ok) r = std::move(*pending_alignment_);
  }
  const int64_t first_ns = times.front();
  // world_from_vo: gravity down, the first odometry frame at the last good position and yaw
  // (the origin and yaw 0 on the first start).
  Eigen::Quaterniond rotation = r.world_from_vo;
  const double target_yaw = last_good_ ? Yaw(last_good_->world_from_body.rotation) : 0.0;
  rotation = Eigen::AngleAxisd(target_yaw - Yaw(rotation * poses.front().rotation),
                               Eigen::Vector3d::UnitZ()) *
             rotation;
  const Eigen::Vector3d origin =
      last_good_ ? last_good_->world_from_body.translation : Eigen::Vector3d::Zero();
  const Rigid3d world_from_vo(rotation.normalized(), origin - rotation * poses.front().translation);
  ImuBias bias = prior;
  bias.gyro = r.gyro_bias;
  StateEstimate first;
  first.t_ns = times.front();
  first.world_from_body = world_from_vo * poses.front();
  first.velocity = world_from_vo.rotation * r.velocities_vo.front();
  first.bias = bias;
  const double tilt_sigma = std::max(options_.motion_init_aligned_tilt_sigma_rad, r.tilt_sigma_rad);
  const double velocity_sigma =
      std::max(options_.motion_init_aligned_velocity_sigma_m_s, r.first_velocity_sigma_m_s);
  spdlog::info(
      "vio: in-motion alignment over {:.2f} s ({} frames): free gravity norm {:.3f} m/s^2, "
      "tilt sigma {:.2f} deg, gyro bias [{:.4f} {:.4f} {:.4f}] rad/s, first speed {:.2f} m/s "
      "(sigma {:.2f}), whitened residual RMS {:.2f}",
      (t_ns - first_ns) * 1e-9, times.size(), r.unconstrained_gravity_norm, tilt_sigma * 180 / M_PI,
      bias.gyro.x(), bias.gyro.y(), bias.gyro.z(), first.velocity.norm(), velocity_sigma,
      r.whitened_rms);
  // The window from the run's first frame, then the run's frames again, now with the IMU.
  backend_.Initialize(first, init_frames_.front().observations, tilt_sigma, velocity_sigma,
                      options_.motion_init_accel_bias_sigma);
  delayed_.push_back(FrameEstimate{backend_.Newest(), true, std::nullopt});
  for (size_t k = 1; k < init_frames_.size(); ++k) {
    const MotionInitFrame& f = init_frames_[k];
    ImuPreintegration pre =
        Preintegrate(backend_imu_, times[k - 1], f.t_ns, backend_.Newest().bias);
    HoldGyroBiasIf(f.low_contrast, &pre);
    const StateEstimate e =
        backend_.AddFrame(f.t_ns, pre, f.observations, f.keyframe || k + 1 == init_frames_.size());
    if (k + 1 < init_frames_.size()) delayed_.push_back(FrameEstimate{e, f.keyframe, std::nullopt});
  }
  ResetMotionInit();
  return true;
}

std::optional<FrameEstimate> VioEstimator::ProcessFrame(int64_t t_ns, const cv::Mat& left,
                                                        const cv::Mat& right) {
  std::optional<FramePacket> packet = RunFrontend(t_ns, left, right);
  if (!packet) return std::nullopt;
  return RunBackend(std::move(*packet));
}

std::optional<FramePacket> VioEstimator::RunFrontend(int64_t t_ns, const cv::Mat& left,
                                                     const cv::Mat& right) {
  const Timer work;
  if (prev_frame_ns_ && t_ns <= *prev_frame_ns_) {
    spdlog::warn("vio: skipping frame at {} ns (not after the previous one)", t_ns);
    timing_.Add("total", work.ElapsedSeconds());
    return std::nullopt;
  }
  // A frozen camera repeats its last images with new stamps: tracking them would tell the
  // estimator the vehicle stood still. Skipped, the IMU bridges the time as for a dropped frame
  // (and a long freeze becomes a frame-time jump, a lost interval).
  if (!prev_left_.empty() && SameImage(left, prev_left_) && SameImage(right, prev_right_) &&
      HasTexture(left)) {
    if (frozen_frames_++ % 20 == 0)
      spdlog::warn("vio: skipping frame at {} ns: identical to the previous frame (frozen camera)",
                   t_ns);
    timing_.Add("total", work.ElapsedSeconds());
    return std::nullopt;
  }
  left.copyTo(prev_left_);
  right.copyTo(prev_right_);
  // The backend's feedback after packet n - lag (waiting for it when the backend is behind).
  const uint64_t lag = static_cast<uint64_t>(options_.feedback_lag_frames);
  double wait_s = 0;
  if (packets_ >= lag) {
    const Timer wait;
    std::optional<BackendFeedback> feedback = feedback_mailbox_.WaitFor(packets_ - lag);
    wait_s = wait.ElapsedSeconds();
    timing_.Add("frontend_wait", wait_s);
    if (!feedback) throw Error("vio: the backend stopped (feedback cancelled)");
    if (feedback->rejected_tracks) frontend_.Drop(*feedback->rejected_tracks);
    feedback->rejected_tracks.reset();
    feedback_ = std::move(*feedback);
  }
  FramePacket packet;
  packet.number = packets_++;
  packet.t_ns = t_ns;
  packet.prev_t_ns = prev_frame_ns_;
  std::optional<Eigen::Quaterniond> cur_from_prev;
  if (prev_frame_ns_) {
    const double gap_s = (t_ns - *prev_frame_ns_) * 1e-9;
    if (gap_s > options_.max_frame_gap_s) {
      packet.problem = fmt::format("frame time jump of {:.3f} s", gap_s);
    } else if (options_.mode == VioMode::kStereoImu) {
      packet.problem = ImuProblem(imu_, *prev_frame_ns_, t_ns);
      if (!packet.problem) {
        packet.pre_bias = feedback_.initialized ? feedback_.bias : ImuBias{};
        packet.pre = Preintegrate(imu_, *prev_frame_ns_, t_ns, packet.pre_bias);
        const Eigen::Quaterniond cam_from_body = body_from_cam0_.rotation.conjugate();
        cur_from_prev =
            cam_from_body * packet.pre->delta_R().conjugate() * body_from_cam0_.rotation;
      }
    }
  }
  {
    ScopedTimer timer(timing_, "frontend");
    packet.features = frontend_.Process(t_ns, left, right, cur_from_prev, !feedback_.initialized);
  }
  prev_frame_ns_ = t_ns;
  packet.imu = std::move(imu_for_backend_);
  imu_for_backend_.clear();
  packet.frontend_s = work.ElapsedSeconds() - wait_s;  // work only
  return packet;
}

void VioEstimator::PostFeedback(bool with_rejected_tracks) {
  pending_feedback_.initialized = backend_.initialized();
  pending_feedback_.bias = pending_feedback_.initialized ? backend_.Newest().bias : ImuBias{};
  // The rejected set only grows between resets (Lose resets posted_rejected_). Kept until sent:
  // a later update of the same packet without a set does not erase it.
  if (with_rejected_tracks && backend_.rejected_tracks().size() != posted_rejected_) {
    pending_feedback_.rejected_tracks = backend_.rejected_tracks();
    posted_rejected_ = backend_.rejected_tracks().size();
  }
}

std::optional<FrameEstimate> VioEstimator::RunBackend(FramePacket packet) {
  // "total": this frame's work in both steps (queue waits between threads excluded).
  struct TotalTimer {
    TimingStats& timing;
    double frontend_s;
    Timer timer;
    ~TotalTimer() { timing.Add("total", frontend_s + timer.ElapsedSeconds()); }
  } total{timing_, packet.frontend_s, Timer()};
  const int64_t t_ns = packet.t_ns;
  for (const TimedImuSample& s : packet.imu)
    AppendImu(s, options_.init_window_s + 3.0, &backend_imu_);
  last_frame_ns_ = t_ns;
  std::optional<FrameEstimate> result = [&]() -> std::optional<FrameEstimate> {
    if (backend_.initialized() && packet.problem) Lose(t_ns, *packet.problem);
    if (!backend_.initialized()) {
      if (!TryInitialize(packet)) return std::nullopt;
      last_good_ = backend_.Newest();
      if (gnss_) gnss_->OnFrame(*last_good_, &backend_);
      return FrameEstimate{*last_good_, true, gnss_ ? gnss_->alignment() : std::nullopt};
    }
    // The frontend preintegrated at the bias it knew; redo it at the current one if that
    // differs (never when the steps run in order).
    ImuPreintegration pre =
        packet.pre ? std::move(*packet.pre) : ImuPreintegration(ImuBias{}, imu_noise_);
    if (packet.pre && packet.prev_t_ns) {
      const ImuBias bias = backend_.Newest().bias;
      if (bias.gyro != packet.pre_bias.gyro || bias.accel != packet.pre_bias.accel)
        pre = Preintegrate(backend_imu_, *packet.prev_t_ns, t_ns, bias);
    }
    const FrontendOutput& features = packet.features;
    HoldGyroBiasIf(features.stats.low_contrast, &pre);
    StateEstimate estimate;
    {
      const Timer timer;
      estimate = backend_.AddFrame(t_ns, pre, features.observations, features.keyframe);
      const double s = timer.ElapsedSeconds();
      timing_.Add("backend", s);
      // Keyframes carry the window solve (and the marginalisation): the per-keyframe cost.
      if (features.keyframe) timing_.Add("backend_keyframe", s);
    }
    PostFeedback(/*with_rejected_tracks=*/true);
    if (spdlog::should_log(spdlog::level::trace)) {
      const FrontendStats& fs = features.stats;
      const BackendStats& bs = backend_.stats();
      spdlog::trace(
          "vio frame {:.3f}: kf {} tracked {} fb {} refined {} ransac {} detected {} stereo {} "
          "flow {:.1f} constrained {} landmarks {} outliers {} gated {} median {:.3f} "
          "iterations {} shift {:.3f} deg {:.3f} m gyro_bias {:.6f} {:.6f} {:.6f}",
          t_ns * 1e-9, features.keyframe ? 1 : 0, fs.tracked, fs.rejected_fb, fs.klt_refined,
          fs.rejected_ransac, fs.detected, fs.stereo, fs.median_flow_px,
          bs.newest_constrained_landmarks, bs.num_landmarks, bs.num_outliers_removed, bs.num_gated,
          bs.median_reprojection_px, bs.solver_iterations, bs.window_shift_deg, bs.window_shift_m,
          estimate.bias.gyro.x(), estimate.bias.gyro.y(), estimate.bias.gyro.z());
    }
    // Divergence.
    const bool use_imu = options_.mode == VioMode::kStereoImu;
    const bool finite = estimate.world_from_body.translation.allFinite() &&
                        estimate.world_from_body.rotation.coeffs().allFinite() &&
                        estimate.velocity.allFinite();
    if (!finite || estimate.velocity.norm() > options_.max_speed_m_s ||
        (use_imu && (estimate.bias.gyro.norm() > options_.max_gyro_bias ||
                     estimate.bias.accel.norm() > options_.max_accel_bias))) {
      Lose(t_ns, "estimate diverged (speed or bias out of bounds)");
      return std::nullopt;
    }
    // Weak tracking for too long.
    const double t_s = t_ns * 1e-9;
    if (backend_.stats().newest_constrained_landmarks < options_.min_tracked_landmarks) {
      if (weak_since_s_ < 0) weak_since_s_ = t_s;
      if (t_s - weak_since_s_ > options_.max_weak_tracking_s) {
        Lose(t_ns, fmt::format("fewer than {} tracked landmarks for {:.2f} s",
                               options_.min_tracked_landmarks, t_s - weak_since_s_));
        return std::nullopt;
      }
    } else {
      weak_since_s_ = -1;
      last_good_ = estimate;  // lost intervals start at the last well-tracked frame
    }
    if (gnss_) gnss_->OnFrame(estimate, &backend_);
    return FrameEstimate{estimate, features.keyframe, gnss_ ? gnss_->alignment() : std::nullopt};
  }();
  PostFeedback(/*with_rejected_tracks=*/false);
  feedback_mailbox_.Post(packet.number, std::exchange(pending_feedback_, {}));
  return result;
}

}  // namespace optinav::vio
