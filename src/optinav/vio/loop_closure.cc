#include "optinav/vio/internal/loop_closure.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <ceres/ceres.h>
#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/core/hal/hal.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/video/tracking.hpp>
#include <spdlog/spdlog.h>

#include "optinav/features/features.h"
#include "optinav/geometry/angles.h"
#include "optinav/geometry/lie.h"
#include "optinav/util/error.h"
#include "optinav/vio/internal/cv_pose.h"

namespace optinav::vio {

namespace {
constexpr double kInfinity = std::numeric_limits<double>::infinity();
}  // namespace

std::string LoopClosureOptions::Check() const {
  if (orb_features < 50) return "loop_closure.orb_features must be >= 50";
  if (orb_fast_threshold < 1 || orb_fast_threshold > 255)
    return "loop_closure.orb_fast_threshold must be 1..255";
  if (orb_retry_below_features < 0) return "loop_closure.orb_retry_below_features must be >= 0";
  if (orb_retry_fast_threshold < 1 || orb_retry_fast_threshold > 255)
    return "loop_closure.orb_retry_fast_threshold must be 1..255";
  if (!(orb_retry_clahe_clip >= 0) || orb_retry_clahe_tiles < 1 || orb_retry_clahe_tiles > 64)
    return "loop_closure.orb_retry_clahe_clip must be >= 0 and orb_retry_clahe_tiles 1..64";
  if (!(stereo_epipolar_px > 0) || !(pnp_px > 0))
    return "loop_closure pixel thresholds must be > 0";
  if (!(max_depth_baselines > 1)) return "loop_closure.max_depth_baselines must be > 1";
  if (!(min_separation_s >= 0) || !(min_separation_m >= 0))
    return "loop_closure.min_separation_* must be >= 0";
  if (!(search_radius_m > 0) || !(search_radius_fraction >= 0))
    return "loop_closure.search_radius_m must be > 0, search_radius_fraction >= 0";
  if (!(max_view_angle_deg > 0 && max_view_angle_deg <= 180))
    return "loop_closure.max_view_angle_deg must be in (0, 180]";
  if (max_candidates < 1) return "loop_closure.max_candidates must be >= 1";
  if (!(stereo_only_search_radius_fraction >= 0 || stereo_only_search_radius_fraction == -1))
    return "loop_closure.stereo_only_search_radius_fraction must be >= 0 or -1 (as "
           "search_radius_fraction)";
  if (stereo_only_max_candidates < 1 && stereo_only_max_candidates != -1)
    return "loop_closure.stereo_only_max_candidates must be >= 1 or -1 (as max_candidates)";
  if (!(match_ratio > 0 && match_ratio <= 1)) return "loop_closure.match_ratio must be in (0, 1]";
  if (min_inliers < 6) return "loop_closure.min_inliers must be >= 6";
  if (!(guided_radius_px >= 0)) return "loop_closure.guided_radius_px must be >= 0";
  if (guided_seed_inliers < 6) return "loop_closure.guided_seed_inliers must be >= 6";
  if (guided_max_hamming < 0 || guided_max_hamming > 256)
    return "loop_closure.guided_max_hamming must be 0..256";
  if (!(guided_ratio > 0 && guided_ratio <= 1))
    return "loop_closure.guided_ratio must be in (0, 1]";
  if (!(min_interval_s >= 0)) return "loop_closure.min_interval_s must be >= 0";
  if (!(odometry_sigma_m_per_m >= 0) || !(odometry_min_sigma_m > 0) ||
      !(odometry_sigma_rad_per_m >= 0) || !(odometry_min_sigma_rad > 0) || !(loop_sigma_m > 0) ||
      !(loop_sigma_rad > 0))
    return "loop_closure sigmas must be > 0 (per-metre growth >= 0)";
  if (!(max_loop_residual_m >= 0)) return "loop_closure.max_loop_residual_m must be >= 0";
  if (!(point_sigma_px >= 0)) return "loop_closure.point_sigma_px must be >= 0";
  if (!(max_loop_distance_m >= 0)) return "loop_closure.max_loop_distance_m must be >= 0";
  if (!(support_min_path_m >= 0) || !(support_tolerance_m > 0) ||
      !(support_tolerance_fraction >= 0) || !(support_max_wait_s >= 0))
    return "loop_closure.support_min_path_m, support_tolerance_fraction and support_max_wait_s "
           "must be >= 0, support_tolerance_m > 0";
  if (!(alias_path_m >= 0) || alias_keyframes < 1 || !(alias_min_offset_m > 0) ||
      !(alias_drift_fraction >= 0) || !(alias_min_sigmas >= 0))
    return "loop_closure.alias_path_m, alias_drift_fraction and alias_min_sigmas must be >= 0, "
           "alias_keyframes >= 1, alias_min_offset_m > 0";
  return "";
}

namespace {

// Relative pose i -> j of the pose graph: residual in the frame of i, translation then rotation
// (twice the vector part of the quaternion error), each over its sigma.
struct RelativePoseResidual {
  RelativePoseResidual(const Rigid3d& i_from_j, double sigma_m, double sigma_rad)
      : q(i_from_j.rotation), t(i_from_j.translation), w_t(1 / sigma_m), w_r(1 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* qi_p, const T* ti_p, const T* qj_p, const T* tj_p, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> qi(qi_p), qj(qj_p);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> ti(ti_p), tj(tj_p);
    const Eigen::Quaternion<T> qi_inv = qi.conjugate();
    const Eigen::Matrix<T, 3, 1> t_est = qi_inv * (tj - ti);
    const Eigen::Quaternion<T> dq = q.template cast<T>().conjugate() * (qi_inv * qj);
    for (int k = 0; k < 3; ++k) {
      r[k] = (t_est[k] - T(t[k])) * T(w_t);
      r[3 + k] = T(2.0) * dq.vec()[k] * T(w_r);
    }
    return true;
  }

  Eigen::Quaterniond q;
  Eigen::Vector3d t;
  double w_t, w_r;
};

// Yaw of a rotation about the world's z axis (Z-Y-X Euler angles): yaw(Rz(a) * R) = a + yaw(R).
double Yaw(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d r = q.toRotationMatrix();
  return std::atan2(r(1, 0), r(0, 0));
}

// Relative pose i -> j of the gravity-aligned (4-DoF) pose graph. Keyframe k's pose is
// (Rz(yaw_k) * base_k, t_k) with base_k its rotation before the solve (roll and pitch fixed).
// Residual: the translation in the frame of i, then the yaw of j against that of i composed with
// the measured rotation, each over its sigma. `yaw_offset` = yaw(base_j) - yaw(base_i * R_ij).
struct YawPositionResidual {
  YawPositionResidual(const Eigen::Quaterniond& base_i, const Eigen::Vector3d& i_t_j,
                      double yaw_offset, double sigma_m, double sigma_rad)
      : base_i(base_i), t(i_t_j), yaw_offset(yaw_offset), w_t(1 / sigma_m), w_r(1 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* yaw_i, const T* ti_p, const T* yaw_j, const T* tj_p, T* r) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> ti(ti_p), tj(tj_p);
    const Eigen::Matrix<T, 3, 1> d = tj - ti;
    const T c = cos(yaw_i[0]), s = sin(yaw_i[0]);
    // Rz(yaw_i)^T d, then base_i^T.
    const Eigen::Matrix<T, 3, 1> unyawed(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
    const Eigen::Matrix<T, 3, 1> t_est = base_i.conjugate().cast<T>() * unyawed;
    for (int k = 0; k < 3; ++k) r[k] = (t_est[k] - T(t[k])) * T(w_t);
    T e = yaw_j[0] - yaw_i[0] + T(yaw_offset);
    // Wrap into (-pi, pi]: the solve moves yaws by far less than pi per step.
    while (e > T(M_PI)) e -= T(2 * M_PI);
    while (e <= T(-M_PI)) e += T(2 * M_PI);
    r[3] = e * T(w_r);
    return true;
  }

  Eigen::Quaterniond base_i;
  Eigen::Vector3d t;
  double yaw_offset, w_t, w_r;
};

void SolvePoseGraph(ceres::Problem* problem) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = 50;
  so.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(so, problem, &summary);
}

}  // namespace

void PnpSigmas(const Rigid3d& cur_cam_from_cand_cam, const std::vector<cv::Point3f>& object,
               const std::vector<cv::Point2f>& image, double focal_px, double baseline_m,
               double sigma_px, double* sigma_m, double* sigma_rad) {
  // PnP minimises the unweighted image residuals, so its covariance is the sandwich
  // (J^T J)^-1 (J^T C J) (J^T J)^-1 with C each residual's covariance; parameters (dtheta, dt).
  Eigen::Matrix<double, 6, 6> jtj = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> jtcj = Eigen::Matrix<double, 6, 6>::Zero();
  const Eigen::Matrix3d R = cur_cam_from_cand_cam.rotation.toRotationMatrix();
  const double s_n = sigma_px / focal_px;  // in normalized coordinates
  for (size_t k = 0; k < object.size(); ++k) {
    const Eigen::Vector3d p(object[k].x, object[k].y, object[k].z);
    const Eigen::Vector3d q = cur_cam_from_cand_cam * p;
    if (q.z() <= 0 || p.z() <= 0) continue;
    Eigen::Matrix<double, 2, 3> jq;
    jq << 1 / q.z(), 0, -q.x() / (q.z() * q.z()), 0, 1 / q.z(), -q.y() / (q.z() * q.z());
    // The stereo point's covariance: along the left camera's ray (depth) and across it.
    const double s_depth = p.z() * p.z() * sigma_px / (focal_px * baseline_m);
    const double s_lateral = p.z() * s_n;
    const Eigen::Vector3d ray = p.normalized();
    const Eigen::Matrix3d cov_p =
        s_lateral * s_lateral * Eigen::Matrix3d::Identity() +
        (s_depth * s_depth - s_lateral * s_lateral) * ray * ray.transpose();
    const Eigen::Matrix2d cov_r =
        jq * R * cov_p * R.transpose() * jq.transpose() + s_n * s_n * Eigen::Matrix2d::Identity();
    Eigen::Matrix<double, 3, 6> dq;  // q = exp(dtheta) q + dt
    dq.leftCols<3>() = -Hat(q);
    dq.rightCols<3>() = Eigen::Matrix3d::Identity();
    const Eigen::Matrix<double, 2, 6> j = jq * dq;
    jtj += j.transpose() * j;
    jtcj += j.transpose() * cov_r * j;
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(jtj);
  if (!lu.isInvertible()) {
    *sigma_m = *sigma_rad = std::numeric_limits<double>::infinity();
    return;
  }
  const Eigen::Matrix<double, 6, 6> jtj_inv = lu.inverse();
  const Eigen::Matrix<double, 6, 6> cov = jtj_inv * jtcj * jtj_inv;
  // The loop edge is the inverse transform, whose translation -R^T t moves by
  // -R^T (dt - [dtheta]x t) = -R^T (dt + [t]x dtheta); R^T does not change the sizes.
  Eigen::Matrix<double, 3, 6> a;
  a.leftCols<3>() = Hat(cur_cam_from_cand_cam.translation);
  a.rightCols<3>() = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d cov_t = a * cov * a.transpose();
  const Eigen::Matrix3d cov_r = cov.topLeftCorner<3, 3>();
  *sigma_m = std::sqrt(std::max(
      0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov_t).eigenvalues().maxCoeff()));
  *sigma_rad = std::sqrt(std::max(
      0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov_r).eigenvalues().maxCoeff()));
}

LoopCloser::LoopCloser(const camera::StereoRig& rig, const Rigid3d& body_from_cam0,
                       const LoopClosureOptions& options, bool gravity_aligned)
    : rig_(rig),
      body_from_cam0_(body_from_cam0),
      options_(options),
      gravity_aligned_(gravity_aligned) {
  if (const std::string e = options.Check(); !e.empty()) throw Error(e, {.field = "loop_closure"});
  if (!gravity_aligned) {
    if (options.stereo_only_search_radius_fraction >= 0)
      options_.search_radius_fraction = options.stereo_only_search_radius_fraction;
    if (options.stereo_only_max_candidates >= 0)
      options_.max_candidates = options.stereo_only_max_candidates;
  }
  // The same detector twice, differing in the FAST threshold only.
  const auto orb = [&](int fast_threshold) {
    return cv::ORB::create(options.orb_features, 1.2f, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31,
                           fast_threshold);
  };
  orb_ = orb(options.orb_fast_threshold);
  orb_retry_ = orb(options.orb_retry_fast_threshold);
  if (options.orb_retry_clahe_clip > 0)
    retry_clahe_ =
        cv::createCLAHE(options.orb_retry_clahe_clip,
                        cv::Size(options.orb_retry_clahe_tiles, options.orb_retry_clahe_tiles));
  essential_ = rig.Essential();
}

LoopCloser::Keyframe LoopCloser::Describe(const StateEstimate& state, const cv::Mat& raw_left,
                                          const cv::Mat& raw_right) const {
  cv::Mat left = raw_left, right = raw_right;
  Keyframe kf;
  kf.t_ns = state.t_ns;
  kf.track = track_;
  kf.odometry = state.world_from_body;
  std::vector<cv::KeyPoint> kl;
  cv::Mat dl;
  Timer timer;
  orb_->detectAndCompute(left, cv::noArray(), kl, dl);
  const bool retry = !gravity_aligned_ || options_.orb_retry_stereo_imu;
  const bool faded = retry && static_cast<int>(kl.size()) < options_.orb_retry_below_features;
  if (faded) {
    // A faded keyframe (fog, dust): described again with its contrast restored, both images
    // alike so that the stereo match below sees the same appearance.
    if (retry_clahe_) {
      cv::Mat eq_left, eq_right;
      retry_clahe_->apply(raw_left, eq_left);
      retry_clahe_->apply(raw_right, eq_right);
      left = eq_left;
      right = eq_right;
    }
    kl.clear();
    orb_retry_->detectAndCompute(left, cv::noArray(), kl, dl);
    kf.faded = true;
  }
  if (timing_) timing_->Add("loop_closure.orb", timer.ElapsedSeconds());
  timer.Restart();
  kf.descriptors = dl;
  kf.normalized.reserve(kl.size());
  for (const cv::KeyPoint& k : kl)
    kf.normalized.push_back(rig_.left.PixelToNormalized({k.pt.x, k.pt.y}));
  if (kl.empty()) return kf;
  // Stereo: Lucas-Kanade from the left keypoint into the right image (from zero disparity),
  // accepted on the epipolar line, in front of both cameras and not too far.
  std::vector<cv::Point2f> pl, pr;
  for (const cv::KeyPoint& k : kl) pl.push_back(k.pt);
  pr = pl;
  std::vector<uchar> ok;
  std::vector<float> err;
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03);
  cv::calcOpticalFlowPyrLK(left, right, pl, pr, ok, err, cv::Size(15, 15), 3, crit,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  const double max_line = options_.stereo_epipolar_px / rig_.right.fx;
  const double max_depth = options_.max_depth_baselines * rig_.Baseline();
  for (size_t i = 0; i < kl.size(); ++i) {
    if (!ok[i]) continue;
    const Eigen::Vector2d pix(pr[i].x, pr[i].y);
    if (!rig_.right.InImage(pix)) continue;
    const Eigen::Vector2d nr = rig_.right.PixelToNormalized(pix);
    if (camera::EpipolarDistance(essential_, kf.normalized[i], nr) > max_line) continue;
    const auto p =
        camera::TriangulateTwoView(Rigid3d::Identity(), rig_.right_from_left, kf.normalized[i], nr);
    if (!p || p->z() < 0.1 || p->z() > max_depth) continue;
    kf.points.push_back(*p);
    kf.point_descriptors.push_back(dl.row(static_cast<int>(i)));
  }
  if (timing_) timing_->Add("loop_closure.stereo", timer.ElapsedSeconds());
  spdlog::debug("vio: loop keyframe {:.3f} s: {} ORB features, {} stereo points{}", kf.t_ns * 1e-9,
                kl.size(), kf.points.size(), faded ? " (faded: described again)" : "");
  return kf;
}

std::vector<std::pair<int, int>> GuidedLoopMatches(const std::vector<Eigen::Vector3d>& points,
                                                   const cv::Mat& point_descriptors,
                                                   const std::vector<Eigen::Vector2d>& normalized,
                                                   const cv::Mat& descriptors,
                                                   const Rigid3d& cur_cam_from_cand_cam,
                                                   double radius, int max_hamming, double ratio) {
  std::vector<std::pair<int, int>> out;
  if (normalized.empty() || points.empty()) return out;
  if (point_descriptors.rows != static_cast<int>(points.size()) ||
      descriptors.rows != static_cast<int>(normalized.size()) ||
      point_descriptors.cols != descriptors.cols || point_descriptors.type() != CV_8U ||
      descriptors.type() != CV_8U)
    throw Error("GuidedLoopMatches: descriptors must be 8-bit rows, one per point / feature");
  // The current features sorted by x, for the search window.
  std::vector<int> by_x(normalized.size());
  for (size_t j = 0; j < by_x.size(); ++j) by_x[j] = static_cast<int>(j);
  std::sort(by_x.begin(), by_x.end(),
            [&](int a, int b) { return normalized[a].x() < normalized[b].x(); });
  const int none = std::numeric_limits<int>::max();
  std::vector<int> best_point(normalized.size(), -1);
  std::vector<int> best_distance(normalized.size(), none);
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d q = cur_cam_from_cand_cam * points[i];
    if (q.z() <= 0) continue;
    const Eigen::Vector2d projected = q.head<2>() / q.z();
    auto it = std::lower_bound(by_x.begin(), by_x.end(), projected.x() - radius,
                               [&](int j, double x) { return normalized[j].x() < x; });
    int best = -1, d1 = none, d2 = none;
    const uchar* a = point_descriptors.ptr<uchar>(static_cast<int>(i));
    for (; it != by_x.end() && normalized[*it].x() <= projected.x() + radius; ++it) {
      if ((normalized[*it] - projected).norm() > radius) continue;
      const int d = cv::hal::normHamming(a, descriptors.ptr<uchar>(*it), descriptors.cols);
      if (d < d1) {
        d2 = d1;
        d1 = d;
        best = *it;
      } else if (d < d2) {
        d2 = d;
      }
    }
    if (best < 0 || d1 > max_hamming) continue;
    if (d2 != none && d1 >= ratio * d2) continue;
    if (d1 < best_distance[best]) {
      best_distance[best] = d1;
      best_point[best] = static_cast<int>(i);
    }
  }
  for (size_t j = 0; j < best_point.size(); ++j)
    if (best_point[j] >= 0) out.emplace_back(best_point[j], static_cast<int>(j));
  return out;
}

bool LoopCloser::Match(const Keyframe& candidate, const Keyframe& current, const Rigid3d& predicted,
                       double radius_m, LoopEdge* edge) const {
  const std::vector<cv::DMatch> matches =
      features::MatchWithRatio(candidate.point_descriptors, current.descriptors, cv::NORM_HAMMING,
                               static_cast<float>(options_.match_ratio));
  spdlog::debug("vio: loop candidate {:.3f} s for {:.3f} s: {} points, {} matches",
                candidate.t_ns * 1e-9, current.t_ns * 1e-9, candidate.points.size(),
                matches.size());
  const bool guided = options_.guided_radius_px > 0;
  const int first_min_inliers = guided ? options_.guided_seed_inliers : options_.min_inliers;
  if (static_cast<int>(matches.size()) < first_min_inliers) return false;
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (const cv::DMatch& m : matches) {
    const Eigen::Vector3d& p = candidate.points[m.queryIdx];
    const Eigen::Vector2d& n = current.normalized[m.trainIdx];
    object.emplace_back(p.x(), p.y(), p.z());
    image.emplace_back(n.x(), n.y());
  }
  cv::Mat rvec, tvec;
  std::vector<int> inlier_idx;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  const double threshold = options_.pnp_px / rig_.left.fx;
  if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 300, threshold, 0.999,
                          inlier_idx, cv::SOLVEPNP_AP3P))
    return false;
  spdlog::debug("vio: loop candidate {:.3f} s: {} PnP inliers", candidate.t_ns * 1e-9,
                inlier_idx.size());
  if (static_cast<int>(inlier_idx.size()) < first_min_inliers) return false;
  if (guided) {
    const Rigid3d guide = PoseFromRvecTvec(rvec, tvec);
    object.clear();
    image.clear();
    for (const auto& [i, j] :
         GuidedLoopMatches(candidate.points, candidate.point_descriptors, current.normalized,
                           current.descriptors, guide, options_.guided_radius_px / rig_.left.fx,
                           options_.guided_max_hamming, options_.guided_ratio)) {
      const Eigen::Vector3d& p = candidate.points[i];
      object.emplace_back(p.x(), p.y(), p.z());
      image.emplace_back(current.normalized[j].x(), current.normalized[j].y());
    }
    inlier_idx.clear();
    spdlog::debug("vio: loop candidate {:.3f} s: {} guided matches", candidate.t_ns * 1e-9,
                  object.size());
    if (static_cast<int>(object.size()) < options_.min_inliers ||
        !cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, true, 300, threshold,
                            0.999, inlier_idx, cv::SOLVEPNP_ITERATIVE))
      return false;
    spdlog::debug("vio: loop candidate {:.3f} s: {} guided matches, {} PnP inliers",
                  candidate.t_ns * 1e-9, object.size(), inlier_idx.size());
    if (static_cast<int>(inlier_idx.size()) < options_.min_inliers) return false;
  }
  std::vector<cv::Point3f> obj_in;
  std::vector<cv::Point2f> img_in;
  for (int k : inlier_idx) obj_in.push_back(object[k]), img_in.push_back(image[k]);
  cv::solvePnP(obj_in, img_in, K, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
  const Rigid3d cur_cam_from_cand_cam = PoseFromRvecTvec(rvec, tvec);
  // Count the inliers again after the refinement.
  int n = 0;
  for (size_t k = 0; k < obj_in.size(); ++k) {
    const Eigen::Vector3d q =
        cur_cam_from_cand_cam * Eigen::Vector3d(obj_in[k].x, obj_in[k].y, obj_in[k].z);
    if (q.z() <= 0) continue;
    if ((q.head<2>() / q.z() - Eigen::Vector2d(img_in[k].x, img_in[k].y)).norm() <= threshold) ++n;
  }
  if (n < options_.min_inliers) return false;
  const Rigid3d measured =
      body_from_cam0_ * cur_cam_from_cand_cam.Inverse() * body_from_cam0_.Inverse();
  double sigma_m = 0, sigma_rad = 0;
  if (options_.point_sigma_px > 0)
    PnpSigmas(cur_cam_from_cand_cam, obj_in, img_in, rig_.left.fx, rig_.Baseline(),
              options_.point_sigma_px, &sigma_m, &sigma_rad);
  // Every verified candidate, machine-readable (old and new keyframe, inliers,
  // old_body_from_new_body as tx ty tz qx qy qz qw, PnP sigmas): the input of an offline study of
  // loop selection.
  spdlog::trace(
      "loop-candidate {} {} {} {:.6f} {:.6f} {:.6f} {:.9f} {:.9f} {:.9f} {:.9f} {:.6f} {:.6f}",
      candidate.t_ns, current.t_ns, n, measured.translation.x(), measured.translation.y(),
      measured.translation.z(), measured.rotation.x(), measured.rotation.y(), measured.rotation.z(),
      measured.rotation.w(), sigma_m, sigma_rad);
  // Consistent with the odometry?
  const Rigid3d diff = predicted.Inverse() * measured;
  spdlog::debug(
      "vio: loop candidate {:.3f} s: {} refined inliers, {:.2f} m / {:.2f} deg from the "
      "odometry (radius {:.2f} m)",
      candidate.t_ns * 1e-9, n, diff.translation.norm(),
      Eigen::AngleAxisd(diff.rotation).angle() * 180 / M_PI, radius_m);
  if (options_.max_loop_distance_m > 0 &&
      measured.translation.norm() > options_.max_loop_distance_m)
    return false;
  if (diff.translation.norm() > radius_m ||
      Eigen::AngleAxisd(diff.rotation).angle() > options_.max_view_angle_deg * M_PI / 180)
    return false;
  edge->old_body_from_new_body = measured;
  edge->inliers = n;
  edge->sigma_m = sigma_m;
  edge->sigma_rad = sigma_rad;
  if (options_.point_sigma_px > 0) {
    spdlog::debug("vio: loop candidate {:.3f} s: PnP sigmas {:.3f} m, {:.4f} rad",
                  candidate.t_ns * 1e-9, edge->sigma_m, edge->sigma_rad);
  }
  return true;
}

bool LoopCloser::AddKeyframe(const StateEstimate& state, const cv::Mat& left,
                             const cv::Mat& right) {
  Keyframe kf = Describe(state, left, right);
  if (kf.faded) ++faded_;
  spdlog::trace("loop-keyframe {} {:.6f} {:.6f} {:.6f} {:.9f} {:.9f} {:.9f} {:.9f}", kf.t_ns,
                kf.odometry.translation.x(), kf.odometry.translation.y(),
                kf.odometry.translation.z(), kf.odometry.rotation.x(), kf.odometry.rotation.y(),
                kf.odometry.rotation.z(), kf.odometry.rotation.w());
  const bool first_of_track = keyframes_.size() == track_first_;
  if (!first_of_track) {
    const Keyframe& prev = keyframes_.back();
    kf.path_m = prev.path_m + (kf.odometry.translation - prev.odometry.translation).norm();
    kf.correction = prev.correction;
  }
  keyframes_.push_back(std::move(kf));
  if (first_of_track) return false;
  const size_t cur = keyframes_.size() - 1;
  const Keyframe& current = keyframes_[cur];

  // Candidates: the track's old keyframes near the odometry's position, similar view direction.
  // Search and check use the odometry, not the corrected poses: a wrong loop accepted for a while
  // must not steer the search toward its own family of matches.
  const Rigid3d& cur_pose = current.odometry;
  const Eigen::Vector3d cur_axis =
      (cur_pose.rotation * body_from_cam0_.rotation) * Eigen::Vector3d::UnitZ();
  std::vector<std::pair<double, size_t>> candidates;
  for (size_t j = track_first_; j < cur; ++j) {
    const Keyframe& c = keyframes_[j];
    const double since_m = current.path_m - c.path_m;
    if ((current.t_ns - c.t_ns) * 1e-9 < options_.min_separation_s ||
        since_m < options_.min_separation_m)
      break;  // later keyframes are closer in time and path
    const Rigid3d& pose = c.odometry;
    const double d = (pose.translation - cur_pose.translation).norm();
    if (d > options_.search_radius_m + options_.search_radius_fraction * since_m) continue;
    const Eigen::Vector3d axis =
        (pose.rotation * body_from_cam0_.rotation) * Eigen::Vector3d::UnitZ();
    if (AngleBetween(axis, cur_axis) > options_.max_view_angle_deg * M_PI / 180) continue;
    candidates.emplace_back(d, j);
  }
  std::sort(candidates.begin(), candidates.end());
  if (candidates.size() > static_cast<size_t>(options_.max_candidates))
    candidates.resize(options_.max_candidates);
  std::vector<PendingLoop> verified;
  for (const auto& [d, j] : candidates) {
    const Keyframe& c = keyframes_[j];
    const double radius =
        options_.search_radius_m + options_.search_radius_fraction * (current.path_m - c.path_m);
    const Rigid3d predicted = c.odometry.Inverse() * cur_pose;
    LoopEdge edge;
    if (!Match(c, current, predicted, radius, &edge)) continue;
    edge.t_old_ns = c.t_ns;
    edge.t_new_ns = current.t_ns;
    verified.push_back({edge, j, cur});
  }
  // At a place that repeats every P metres, a loop picks the copy nearest to the odometry's
  // prediction: right only when the odometry has drifted less than P / 2 since the candidate.
  // (Not looked for when no loop's drift bound reaches half the smallest repeat it can measure.)
  double longest_m = 0, shortest_m = kInfinity;
  for (const PendingLoop& p : verified) {
    longest_m = std::max(longest_m, current.path_m - keyframes_[p.old_index].path_m);
    shortest_m = std::min(shortest_m, current.path_m - keyframes_[p.old_index].path_m);
  }
  const std::vector<Repeat> repeats =
      options_.alias_drift_fraction * longest_m < 0.5 * options_.alias_min_offset_m
          ? std::vector<Repeat>{}
          : Repeats(cur, verified, 2 * options_.alias_drift_fraction * shortest_m);
  for (const PendingLoop& p : verified) {
    const double drift_m =
        options_.alias_drift_fraction * (current.path_m - keyframes_[p.old_index].path_m);
    const auto ambiguous = std::find_if(repeats.begin(), repeats.end(), [&](const Repeat& r) {
      return drift_m >= 0.5 * r.distance_m;
    });
    if (ambiguous == repeats.end()) {
      pending_.push_back(p);
      continue;
    }
    ++aliased_;
    spdlog::debug(
        "vio: loop {:.3f} s -> {:.3f} s ({} inliers) dropped: the place repeats {:.2f} m away "
        "({} inliers), the odometry may have drifted {:.2f} m since",
        p.edge.t_old_ns * 1e-9, p.edge.t_new_ns * 1e-9, p.edge.inliers, ambiguous->distance_m,
        ambiguous->inliers, drift_m);
  }
  if (pending_.empty()) return false;
  if (last_solve_ns_ && (current.t_ns - *last_solve_ns_) * 1e-9 < options_.min_interval_s)
    return false;
  return SolvePending();
}

std::vector<LoopCloser::Repeat> LoopCloser::Repeats(size_t cur,
                                                    const std::vector<PendingLoop>& loops,
                                                    double enough_m) const {
  std::vector<Repeat> repeats;
  if (options_.alias_path_m <= 0) return repeats;
  const auto enough = [&] { return !repeats.empty() && repeats.back().distance_m <= enough_m; };
  const Keyframe& current = keyframes_[cur];
  // Two of its loops, to old keyframes of one earlier pass (whose odometry agrees with itself
  // there), that place the keyframe apart.
  for (size_t a = 0; a < loops.size(); ++a) {
    for (size_t b = a + 1; b < loops.size(); ++b) {
      const Keyframe &old_a = keyframes_[loops[a].old_index],
                     &old_b = keyframes_[loops[b].old_index];
      if (std::abs(old_a.path_m - old_b.path_m) > options_.alias_path_m) continue;
      const double apart_m = (old_a.odometry * loops[a].edge.old_body_from_new_body.translation -
                              old_b.odometry * loops[b].edge.old_body_from_new_body.translation)
                                 .norm();
      if (apart_m <= options_.alias_min_offset_m ||
          apart_m <=
              options_.alias_min_sigmas * std::hypot(loops[a].edge.sigma_m, loops[b].edge.sigma_m))
        continue;
      spdlog::debug(
          "vio: keyframe {:.3f} s: its loops to {:.3f} s and {:.3f} s place it {:.2f} m "
          "apart: the place repeats",
          current.t_ns * 1e-9, old_a.t_ns * 1e-9, old_b.t_ns * 1e-9, apart_m);
      repeats.push_back({apart_m, std::min(loops[a].edge.inliers, loops[b].edge.inliers)});
      if (enough()) return repeats;
    }
  }
  // Its own recent keyframes, nearest to path distances spread evenly over (lo, hi].
  const double lo = options_.alias_min_offset_m, hi = options_.alias_path_m;
  std::vector<size_t> recent;
  for (int i = options_.alias_keyframes; i >= 1 && hi > lo; --i) {
    const double target = lo + (hi - lo) * i / options_.alias_keyframes;
    // Back to the first keyframe at least `target` behind, or the farthest within the range.
    size_t k = cur;
    while (k > track_first_ && current.path_m - keyframes_[k].path_m < target &&
           current.path_m - keyframes_[k - 1].path_m <= hi + 1.0)
      --k;
    const double back = current.path_m - keyframes_[k].path_m;
    if (back > lo && std::find(recent.begin(), recent.end(), k) == recent.end())
      recent.push_back(k);
  }
  for (size_t k : recent) {
    const Keyframe& r = keyframes_[k];
    const Rigid3d predicted = r.odometry.Inverse() * current.odometry;
    LoopEdge edge;
    if (!Match(r, current, predicted, kInfinity, &edge)) continue;
    const double off_m = (predicted.Inverse() * edge.old_body_from_new_body).translation.norm();
    if (off_m <= options_.alias_min_offset_m || off_m <= options_.alias_min_sigmas * edge.sigma_m)
      continue;
    spdlog::debug(
        "vio: keyframe {:.3f} s matches its own keyframe {:.3f} s ({:.1f} m back) {:.2f} m off "
        "the odometry ({} inliers): the place repeats",
        current.t_ns * 1e-9, r.t_ns * 1e-9, current.path_m - r.path_m, off_m, edge.inliers);
    repeats.push_back({off_m, edge.inliers});
    if (enough()) return repeats;
  }
  return repeats;
}

bool LoopCloser::Supports(const PendingLoop& a, const PendingLoop& b) const {
  const Keyframe &new_a = keyframes_[a.new_index], &new_b = keyframes_[b.new_index];
  if (std::abs(new_b.path_m - new_a.path_m) < options_.support_min_path_m) return false;
  // new_b in new_a's frame: by the odometry of this pass, and through the two loops and the
  // odometry of the earlier pass.
  const Rigid3d odometry = new_a.odometry.Inverse() * new_b.odometry;
  const Rigid3d via_loops =
      (keyframes_[a.old_index].odometry * a.edge.old_body_from_new_body).Inverse() *
      (keyframes_[b.old_index].odometry * b.edge.old_body_from_new_body);
  return (via_loops.translation - odometry.translation).norm() <=
         options_.support_tolerance_m +
             options_.support_tolerance_fraction * odometry.translation.norm();
}

bool LoopCloser::SolvePending(bool last) {
  if (pending_.empty()) return false;
  const size_t cur = keyframes_.size() - 1;
  // Loops another loop supports go in; the others wait for a partner (while young enough).
  std::vector<PendingLoop> ready, waiting;
  for (size_t a = 0; a < pending_.size(); ++a) {
    const PendingLoop& p = pending_[a];
    bool supported = options_.support_min_path_m <= 0;
    for (size_t b = 0; b < pending_.size() && !supported; ++b)
      supported = b != a && Supports(p, pending_[b]);
    for (size_t e = 0; e < loops_.size() && !supported; ++e)
      if (loop_indices_[e].first >= track_first_)
        supported = Supports(p, {loops_[e], loop_indices_[e].first, loop_indices_[e].second});
    if (supported) {
      ready.push_back(p);
    } else if (!last &&
               (keyframes_[cur].t_ns - p.edge.t_new_ns) * 1e-9 <= options_.support_max_wait_s) {
      waiting.push_back(p);
    } else {
      ++unsupported_;
      spdlog::debug("vio: loop {:.3f} s -> {:.3f} s dropped: no other loop supports it",
                    p.edge.t_old_ns * 1e-9, p.edge.t_new_ns * 1e-9);
    }
  }
  pending_ = std::move(waiting);
  if (ready.empty()) return false;
  const Rigid3d before = keyframes_[cur].correction * keyframes_[cur].odometry;
  size_t new_from = cur;  // the earliest new keyframe of the loops going in
  for (const PendingLoop& p : ready) {
    new_from = std::min(new_from, p.new_index);
    loops_.push_back(p.edge);
    loop_indices_.emplace_back(p.old_index, p.new_index);
  }
  const size_t added = ready.size();
  last_solve_ns_ = keyframes_[cur].t_ns;
  Optimize();
  // Loops the Cauchy loss down-weighted (wrong matches, e.g. on repeated texture) still disagree
  // with the solved graph: the worst and every loop within half of it go, and the graph is solved
  // again, until every loop left agrees within max_loop_residual_m. A loop kept earlier can go
  // when later ones, seen from nearer, outvote it.
  size_t dropped = 0, dropped_new = 0;
  while (options_.max_loop_residual_m > 0) {
    std::vector<double> residual(loops_.size(), 0.0);
    double worst = 0;
    for (size_t e = 0; e < loops_.size(); ++e) {
      if (loop_indices_[e].first < track_first_) continue;
      residual[e] = LoopResidualM(e);
      worst = std::max(worst, residual[e]);
    }
    if (worst <= options_.max_loop_residual_m) break;
    const double limit = std::max(options_.max_loop_residual_m, 0.5 * worst);
    size_t out = 0;
    for (size_t e = 0; e < loops_.size(); ++e) {
      if (residual[e] > limit) {
        spdlog::debug(
            "vio: loop {:.3f} s -> {:.3f} s dropped after the solve: it disagrees with the graph "
            "by {:.2f} m",
            loops_[e].t_old_ns * 1e-9, loops_[e].t_new_ns * 1e-9, residual[e]);
        ++dropped;
        if (loop_indices_[e].second >= new_from) ++dropped_new;
        continue;
      }
      loops_[out] = loops_[e];
      loop_indices_[out] = loop_indices_[e];
      ++out;
    }
    loops_.resize(out);
    loop_indices_.resize(out);
    Optimize();
  }
  const Keyframe& now = keyframes_[cur];
  const double moved_m = ((now.correction * now.odometry).translation - before.translation).norm();
  for (size_t e = 0; e < loops_.size(); ++e) {
    if (loop_indices_[e].first < track_first_) continue;
    loops_[e].residual_m = LoopResidualM(e);
    const Keyframe& k = keyframes_[loop_indices_[e].second];
    loops_[e].correction_m =
        ((k.correction * k.odometry).translation - k.odometry.translation).norm();
  }
  const size_t kept_new = added - dropped_new;
  if (kept_new > 0 || dropped > 0)
    spdlog::info(
        "vio: loop closure at {:.3f} s: {} of {} new loop(s) kept, {} dropped in all, {} in the "
        "graph; the keyframe moved {:.2f} m by this solve, {:.2f} m from the odometry",
        now.t_ns * 1e-9, kept_new, added, dropped, loops_.size(), moved_m,
        ((now.correction * now.odometry).translation - now.odometry.translation).norm());
  return kept_new > 0 || dropped > 0;
}

bool LoopCloser::Finish() { return SolvePending(true); }

void LoopCloser::AddLoop(const LoopEdge& edge) {
  const auto index = [&](int64_t t_ns) {
    const auto it = std::lower_bound(keyframes_.begin(), keyframes_.end(), t_ns,
                                     [](const Keyframe& k, int64_t t) { return k.t_ns < t; });
    if (it == keyframes_.end() || it->t_ns != t_ns ||
        static_cast<size_t>(it - keyframes_.begin()) < track_first_)
      throw Error(fmt::format("loop closure: no keyframe at {} ns in the current track", t_ns));
    return static_cast<size_t>(it - keyframes_.begin());
  };
  pending_.push_back({edge, index(edge.t_old_ns), index(edge.t_new_ns)});
}

void LoopCloser::Optimize() {
  if (gravity_aligned_) return OptimizeYawAndPosition();
  std::vector<Rigid3d> poses = TrackOdometry();
  const size_t n = poses.size();
  std::vector<std::array<double, 4>> q(n);  // x y z w (Eigen's storage)
  std::vector<std::array<double, 3>> t(n);
  for (size_t k = 0; k < n; ++k) {
    const Rigid3d& pose = poses[k];
    const Eigen::Quaterniond r = pose.rotation.normalized();
    q[k] = {r.x(), r.y(), r.z(), r.w()};
    t[k] = {pose.translation.x(), pose.translation.y(), pose.translation.z()};
  }
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  ceres::EigenQuaternionManifold manifold;
  auto add = [&](size_t i, size_t j, const Rigid3d& i_from_j, double sm, double sr,
                 ceres::LossFunction* loss) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<RelativePoseResidual, 6, 4, 3, 4, 3>(
                                 new RelativePoseResidual(i_from_j, sm, sr)),
                             loss, q[i].data(), t[i].data(), q[j].data(), t[j].data());
  };
  AddEdges(add);
  for (size_t k = 0; k < n; ++k) problem.SetManifold(q[k].data(), &manifold);
  problem.SetParameterBlockConstant(q[0].data());
  problem.SetParameterBlockConstant(t[0].data());
  SolvePoseGraph(&problem);
  for (size_t k = 0; k < n; ++k)
    poses[k] = Rigid3d(Eigen::Quaterniond(q[k][3], q[k][0], q[k][1], q[k][2]).normalized(),
                       Eigen::Vector3d(t[k][0], t[k][1], t[k][2]));
  SetTrackPoses(poses);
}

void LoopCloser::OptimizeYawAndPosition() {
  std::vector<Rigid3d> poses = TrackOdometry();
  const size_t n = poses.size();
  std::vector<Eigen::Quaterniond> base(n);
  std::vector<double> yaw(n, 0.0);
  std::vector<std::array<double, 3>> t(n);
  for (size_t k = 0; k < n; ++k) {
    const Rigid3d& pose = poses[k];
    base[k] = pose.rotation.normalized();
    t[k] = {pose.translation.x(), pose.translation.y(), pose.translation.z()};
  }
  ceres::Problem problem;
  auto add = [&](size_t i, size_t j, const Rigid3d& i_from_j, double sm, double sr,
                 ceres::LossFunction* loss) {
    const double offset = WrapRadPi(Yaw(base[j]) - Yaw(base[i] * i_from_j.rotation));
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<YawPositionResidual, 4, 1, 3, 1, 3>(
            new YawPositionResidual(base[i], i_from_j.translation, offset, sm, sr)),
        loss, &yaw[i], t[i].data(), &yaw[j], t[j].data());
  };
  AddEdges(add);
  problem.SetParameterBlockConstant(&yaw[0]);
  problem.SetParameterBlockConstant(t[0].data());
  SolvePoseGraph(&problem);
  for (size_t k = 0; k < n; ++k)
    poses[k] = Rigid3d(Eigen::AngleAxisd(yaw[k], Eigen::Vector3d::UnitZ()) * base[k],
                       Eigen::Vector3d(t[k][0], t[k][1], t[k][2]));
  SetTrackPoses(poses);
}

std::vector<Rigid3d> LoopCloser::TrackOdometry() const {
  std::vector<Rigid3d> poses;
  for (size_t k = track_first_; k < keyframes_.size(); ++k) poses.push_back(keyframes_[k].odometry);
  return poses;
}

void LoopCloser::SetTrackPoses(const std::vector<Rigid3d>& poses) {
  for (size_t k = 0; k < poses.size(); ++k) {
    Keyframe& kf = keyframes_[track_first_ + k];
    kf.correction = poses[k] * kf.odometry.Inverse();
  }
}

void LoopCloser::AddEdges(const EdgeAdder& add) const {
  const size_t n = keyframes_.size() - track_first_;
  for (size_t k = 0; k + 1 < n; ++k) {
    const Keyframe& a = keyframes_[track_first_ + k];
    const Keyframe& b = keyframes_[track_first_ + k + 1];
    const double dist = b.path_m - a.path_m;
    add(k, k + 1, a.odometry.Inverse() * b.odometry,
        std::max(options_.odometry_min_sigma_m, options_.odometry_sigma_m_per_m * dist),
        std::max(options_.odometry_min_sigma_rad, options_.odometry_sigma_rad_per_m * dist),
        nullptr);
  }
  for (size_t e = 0; e < loops_.size(); ++e) {
    const auto [i, j] = loop_indices_[e];
    if (i < track_first_) continue;
    add(i - track_first_, j - track_first_, loops_[e].old_body_from_new_body,
        std::max(options_.loop_sigma_m, loops_[e].sigma_m),
        std::max(options_.loop_sigma_rad, loops_[e].sigma_rad), new ceres::CauchyLoss(1.0));
  }
}

double LoopCloser::LoopResidualM(size_t e) const {
  const auto [i, j] = loop_indices_[e];
  const Rigid3d pi = keyframes_[i].correction * keyframes_[i].odometry;
  const Rigid3d pj = keyframes_[j].correction * keyframes_[j].odometry;
  return ((pi.Inverse() * pj).translation - loops_[e].old_body_from_new_body.translation).norm();
}

void LoopCloser::NewTrack(int64_t t_ns) {
  SolvePending(true);
  last_solve_ns_.reset();
  ++track_;
  track_starts_ns_.push_back(t_ns);
  track_first_ = keyframes_.size();
}

Rigid3d LoopCloser::CorrectionAt(int64_t t_ns) const {
  const auto it = std::upper_bound(keyframes_.begin(), keyframes_.end(), t_ns,
                                   [](int64_t t, const Keyframe& k) { return t < k.t_ns; });
  if (it == keyframes_.begin()) return Rigid3d::Identity();
  const Keyframe& k = *std::prev(it);
  // The frame's track: the number of track starts at or before it. A frame of a track before
  // that track's first keyframe gets no correction.
  const int track =
      static_cast<int>(std::upper_bound(track_starts_ns_.begin(), track_starts_ns_.end(), t_ns) -
                       track_starts_ns_.begin());
  return k.track == track ? k.correction : Rigid3d::Identity();
}

}  // namespace optinav::vio
