#include "optinav/vio/internal/frontend.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include <Eigen/Eigenvalues>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "optinav/util/error.h"

namespace optinav::vio {

namespace {

Eigen::Vector2d ToEigen(const cv::Point2f& p) { return {p.x, p.y}; }
cv::Point2f ToCv(const Eigen::Vector2d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y())};
}

// Each level of a reused pyramid emptied unless it alone owns its data: OpenCV builds a pyramid's
// first level in the input image when that is a view with a border (the caller's image), and a
// reused buffer must never be written while anything else still reads it.
void KeepIfExclusive(std::vector<cv::Mat>* pyramid) {
  for (cv::Mat& m : *pyramid)
    if (m.u == nullptr || m.u->refcount > 1) m.release();  // external memory, or shared
}

// (2h + 3)^2 bilinear samples of an 8-bit image at (x + u, y + v), u, v = -h - 1 .. h + 1, row
// by row: every sample shares the fractional part, so the four weights are computed once. The
// caller keeps the grid at least one pixel inside the image.
void SampleGrid(const cv::Mat& image, double x, double y, int h, std::vector<double>* out) {
  const int side = 2 * h + 3;
  out->resize(static_cast<size_t>(side * side));
  const int x0 = static_cast<int>(std::floor(x)) - h - 1;
  const int y0 = static_cast<int>(std::floor(y)) - h - 1;
  const double ax = x - std::floor(x), ay = y - std::floor(y);
  const double w00 = (1 - ax) * (1 - ay), w01 = ax * (1 - ay), w10 = (1 - ax) * ay, w11 = ax * ay;
  double* o = out->data();
  for (int v = 0; v < side; ++v) {
    const uchar* r0 = image.ptr<uchar>(y0 + v) + x0;
    const uchar* r1 = image.ptr<uchar>(y0 + v + 1) + x0;
    for (int u = 0; u < side; ++u)
      *o++ = w00 * r0[u] + w01 * r0[u + 1] + w10 * r1[u] + w11 * r1[u + 1];
  }
}

}  // namespace

bool AlignWithGainOffset(const cv::Mat& templ_image, const Eigen::Vector2d& t,
                         const cv::Mat& target, int h, int max_iterations, Eigen::Vector2d* p) {
  const int side = 2 * h + 1, grid = side + 2;
  const double margin = h + 3;
  auto inside = [&](const cv::Mat& image, const Eigen::Vector2d& q) {
    return q.x() >= margin && q.y() >= margin && q.x() < image.cols - margin &&
           q.y() < image.rows - margin;
  };
  OPTINAV_CHECK(templ_image.type() == CV_8UC1 && target.type() == CV_8UC1);
  if (!inside(templ_image, t) || !inside(target, *p)) return false;
  std::vector<double> templ, samples;
  SampleGrid(templ_image, t.x(), t.y(), h, &templ);
  Eigen::Vector2d q = *p;
  double gain = 1.0, offset = 0.0;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    SampleGrid(target, q.x(), q.y(), h, &samples);
    Eigen::Matrix4d hessian = Eigen::Matrix4d::Zero();
    Eigen::Vector4d gradient = Eigen::Vector4d::Zero();
    for (int v = 1; v <= side; ++v) {
      for (int u = 1; u <= side; ++u) {
        const int k = v * grid + u;
        const double r = samples[k];
        const double gx = 0.5 * (samples[k + 1] - samples[k - 1]);
        const double gy = 0.5 * (samples[k + grid] - samples[k - grid]);
        const Eigen::Vector4d j(gain * gx, gain * gy, r, 1.0);
        const double e = gain * r + offset - templ[k];
        hessian += j * j.transpose();
        gradient += j * e;
      }
    }
    // The window must constrain both directions once the gain and the offset are free: the
    // smaller eigenvalue of the position's information with them eliminated (Schur complement),
    // per pixel, at least (0.3 grey levels per pixel)^2. A window whose texture is a ramp
    // (a soft edge, the haze itself) moves as an offset does and is left to the pyramid.
    // A flat target window leaves the gain undetermined (and the photometric block singular).
    const double n = side * side, mean = hessian(2, 3) / n;
    if (!(hessian(2, 2) / n - mean * mean >= 0.01)) return false;
    const Eigen::Matrix2d photometric_inverse = hessian.bottomRightCorner<2, 2>().inverse();
    const Eigen::Matrix2d spatial =
        (hessian.topLeftCorner<2, 2>() -
         hessian.topRightCorner<2, 2>() * photometric_inverse * hessian.bottomLeftCorner<2, 2>()) /
        (gain * gain);
    const double min_eigen =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spatial, Eigen::EigenvaluesOnly)
            .eigenvalues()(0) /
        (side * side);
    if (!(min_eigen >= 0.09)) return false;
    const Eigen::Vector4d step = hessian.ldlt().solve(-gradient);
    if (!step.allFinite()) return false;
    q += step.head<2>();
    gain += step(2);
    offset += step(3);
    if (!inside(target, q) || !(gain > 0.5 && gain < 2.0)) return false;
    if (step.head<2>().norm() < 0.01) {
      *p = q;
      return true;
    }
  }
  return false;
}

double MedianLocalStd(const cv::Mat& grey) {
  OPTINAV_CHECK(grey.type() == CV_8UC1);
  cv::Mat f, mean, mean_sq;
  grey.convertTo(f, CV_32F);
  cv::boxFilter(f, mean, CV_32F, cv::Size(7, 7));
  cv::boxFilter(f.mul(f), mean_sq, CV_32F, cv::Size(7, 7));
  std::vector<float> stds;
  stds.reserve(static_cast<size_t>((grey.rows / 4 + 1) * (grey.cols / 4 + 1)));
  for (int y = 0; y < grey.rows; y += 4) {
    const float* m = mean.ptr<float>(y);
    const float* m2 = mean_sq.ptr<float>(y);
    for (int x = 0; x < grey.cols; x += 4)
      stds.push_back(std::sqrt(std::max(m2[x] - m[x] * m[x], 0.0f)));
  }
  if (stds.empty()) return 0;
  std::nth_element(stds.begin(), stds.begin() + stds.size() / 2, stds.end());
  return stds[stds.size() / 2];
}

double NoiseSigma(const cv::Mat& grey) {
  OPTINAV_CHECK(grey.type() == CV_8UC1);
  // |mask response| <= 16 x 255: the median from a histogram, without a buffer per call (at
  // 800x600 a fresh 480 KB vector a frame came back as page faults).
  constexpr int kMax = 16 * 255;
  std::array<int, kMax + 1> histogram{};
  size_t n = 0;
  for (int y = 1; y + 1 < grey.rows; y += 2) {
    const uint8_t* a = grey.ptr<uint8_t>(y - 1);
    const uint8_t* m = grey.ptr<uint8_t>(y);
    const uint8_t* b = grey.ptr<uint8_t>(y + 1);
    for (int x = 1; x + 1 < grey.cols; x += 2) {
      const int v = a[x - 1] - 2 * a[x] + a[x + 1] - 2 * m[x - 1] + 4 * m[x] - 2 * m[x + 1] +
                    b[x - 1] - 2 * b[x] + b[x + 1];
      ++histogram[std::abs(v)];
      ++n;
    }
  }
  if (n == 0) return 0;
  // The (n / 2)-th smallest (0-based), the element nth_element would put at n / 2.
  size_t below = 0;
  int median = 0;
  while (below + static_cast<size_t>(histogram[median]) <= n / 2) below += histogram[median++];
  return median / (6 * 0.6745);
}

double CornerIsotropy(const cv::Mat& grey, cv::Point2f p, int half) {
  OPTINAV_CHECK(grey.type() == CV_8UC1 && half >= 1);
  const int cx = cvRound(p.x), cy = cvRound(p.y);
  const int x0 = std::max(1, cx - half), x1 = std::min(grey.cols - 2, cx + half);
  const int y0 = std::max(1, cy - half), y1 = std::min(grey.rows - 2, cy + half);
  double xx = 0, xy = 0, yy = 0;
  for (int y = y0; y <= y1; ++y) {
    const uint8_t* up = grey.ptr<uint8_t>(y - 1);
    const uint8_t* row = grey.ptr<uint8_t>(y);
    const uint8_t* down = grey.ptr<uint8_t>(y + 1);
    for (int x = x0; x <= x1; ++x) {
      const double gx = row[x + 1] - row[x - 1], gy = down[x] - up[x];
      xx += gx * gx;
      xy += gx * gy;
      yy += gy * gy;
    }
  }
  // Eigenvalues of [[xx, xy], [xy, yy]].
  const double mean = 0.5 * (xx + yy);
  const double root = std::sqrt(0.25 * (xx - yy) * (xx - yy) + xy * xy);
  const double large = mean + root;
  return large > 0 ? std::max(0.0, mean - root) / large : 0.0;
}

double IntensityStd(const cv::Mat& grey) {
  OPTINAV_CHECK(grey.type() == CV_8UC1);
  cv::Scalar mean, std;
  cv::meanStdDev(grey, mean, std);
  return std[0];
}

cv::Mat HighPassFilter(const cv::Mat& grey, double sigma_px) {
  OPTINAV_CHECK(grey.type() == CV_8UC1 && sigma_px > 0);
  cv::Mat blurred, out;
  cv::GaussianBlur(grey, blurred, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::addWeighted(grey, 1.0, blurred, -1.0, 128.0, out);
  return out;
}

cv::Mat LocalContrastNormalise(const cv::Mat& grey, double sigma_px, double floor) {
  OPTINAV_CHECK(grey.type() == CV_8UC1 && sigma_px > 0 && floor > 0);
  cv::Mat f, mean, mean_sq;
  grey.convertTo(f, CV_32F);
  cv::GaussianBlur(f, mean, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::GaussianBlur(f.mul(f), mean_sq, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::Mat out(grey.size(), CV_8UC1);
  const float fl = static_cast<float>(floor);
  for (int y = 0; y < grey.rows; ++y) {
    const float* pf = f.ptr<float>(y);
    const float* pm = mean.ptr<float>(y);
    const float* pq = mean_sq.ptr<float>(y);
    uint8_t* po = out.ptr<uint8_t>(y);
    for (int x = 0; x < grey.cols; ++x) {
      const float sd = std::sqrt(std::max(pq[x] - pm[x] * pm[x], 0.0f));
      const float v = 128.0f + 40.0f * (pf[x] - pm[x]) / (sd + fl);
      po[x] = cv::saturate_cast<uint8_t>(v);
    }
  }
  return out;
}

std::string FrontendOptions::Check() const {
  if (max_features < 8) return "max_features must be >= 8";
  if (grid_cols < 1 || grid_rows < 1) return "grid_cols and grid_rows must be >= 1";
  if (!(min_distance_px > 0)) return "min_distance_px must be > 0";
  if (!(quality_level > 0 && quality_level < 1)) return "quality_level must be in (0, 1)";
  if (klt_window_px < 5) return "klt_window_px must be >= 5";
  if (stereo_window_px < 5) return "stereo_window_px must be >= 5";
  if (stereo_refine_window_px != 0 && stereo_refine_window_px < 3)
    return "stereo_refine_window_px must be 0 (off) or >= 3";
  if (klt_pyramid_levels < 0 || klt_pyramid_levels > 6) return "klt_pyramid_levels must be 0..6";
  if (klt_max_iterations < 1) return "klt_max_iterations must be >= 1";
  if (!(forward_backward_px > 0)) return "forward_backward_px must be > 0";
  if (!(ransac_px > 0)) return "ransac_px must be > 0";
  if (!(epipolar_px > 0)) return "epipolar_px must be > 0";
  if (border_px < 0) return "border_px must be >= 0";
  if (!(min_corner_response >= 0)) return "min_corner_response must be >= 0";
  if (!(corner_noise_floor >= 0)) return "corner_noise_floor must be >= 0";
  if (!(stereo_only_corner_noise_floor >= 0 || stereo_only_corner_noise_floor == -1))
    return "stereo_only_corner_noise_floor must be >= 0 or -1 (as corner_noise_floor)";
  if (!(clahe_clip_limit >= 0)) return "clahe_clip_limit must be >= 0";
  if (!(clahe_below_std >= 0)) return "clahe_below_std must be >= 0";
  if (!(clahe_below_local_std >= 0)) return "clahe_below_local_std must be >= 0";
  if (!(contrast_stretch_std >= 0)) return "contrast_stretch_std must be >= 0 (0: off)";
  if (!(highpass_sigma_px >= 0)) return "highpass_sigma_px must be >= 0";
  if (!(local_norm_sigma_px >= 0)) return "local_norm_sigma_px must be >= 0";
  if (!(local_norm_floor > 0)) return "local_norm_floor must be > 0";
  if (median_filter_px < 0 || median_filter_px > 7 ||
      (median_filter_px > 1 && median_filter_px % 2 == 0))
    return "median_filter_px must be 0, 1, 3, 5 or 7";
  if (!(detect_min_eigen >= 0)) return "detect_min_eigen must be >= 0";
  if (!(min_corner_isotropy >= 0 && min_corner_isotropy < 1))
    return "min_corner_isotropy must be in [0, 1)";
  if (corner_block_px < 3 || corner_block_px > 15) return "corner_block_px must be 3..15";
  if (clahe_tiles < 1 || clahe_tiles > 64) return "clahe_tiles must be 1..64";
  if (!(keyframe_max_interval_s > 0)) return "keyframe_max_interval_s must be > 0";
  if (!(keyframe_min_tracked_ratio >= 0 && keyframe_min_tracked_ratio <= 1))
    return "keyframe_min_tracked_ratio must be in [0, 1]";
  if (!(keyframe_min_parallax_px > 0)) return "keyframe_min_parallax_px must be > 0";
  if (!(stereo_only_local_norm_sigma_px >= 0 || stereo_only_local_norm_sigma_px == -1))
    return "stereo_only_local_norm_sigma_px must be >= 0 or -1 (as local_norm_sigma_px)";
  if (!((stereo_only_min_corner_isotropy >= 0 && stereo_only_min_corner_isotropy < 1) ||
        stereo_only_min_corner_isotropy == -1))
    return "stereo_only_min_corner_isotropy must be in [0, 1) or -1 (as min_corner_isotropy)";
  if (!(stereo_only_keyframe_min_tracked_ratio >= 0 && stereo_only_keyframe_min_tracked_ratio <= 1))
    return "stereo_only_keyframe_min_tracked_ratio must be in [0, 1]";
  if (!(stereo_only_keyframe_min_parallax_px > 0))
    return "stereo_only_keyframe_min_parallax_px must be > 0";
  return "";
}

StereoFrontend::StereoFrontend(const camera::StereoRig& rig, const FrontendOptions& options)
    : rig_(rig), options_(options) {
  const std::string problem = options_.Check();
  OPTINAV_CHECK_MSG(problem.empty(), problem);
  essential_ = rig_.Essential();
}

void StereoFrontend::Reset() {
  prev_pyramid_.clear();
  prev_left_.release();
  tracks_.clear();
  keyframe_tracks_.clear();
  has_keyframe_ = false;
}

void StereoFrontend::Drop(const std::set<uint64_t>& ids) {
  if (ids.empty()) return;
  std::erase_if(tracks_, [&](const Track& t) { return ids.count(t.id) > 0; });
}

void StereoFrontend::Detect(const cv::Mat& image, const std::vector<cv::Mat>& pyramid,
                            std::vector<Track>* tracks) {
  const int cols = options_.grid_cols, rows = options_.grid_rows;
  const int cell_w = image.cols / cols, cell_h = image.rows / rows;
  const int per_cell = (options_.max_features + cols * rows - 1) / (cols * rows);
  std::vector<int> count(cols * rows, 0);
  cv::Mat& mask = detect_mask_;
  mask.create(image.size(), CV_8UC1);
  mask.setTo(255);
  const int b = options_.border_px;
  mask.rowRange(0, std::min(b, mask.rows)).setTo(0);
  mask.rowRange(std::max(0, mask.rows - b), mask.rows).setTo(0);
  mask.colRange(0, std::min(b, mask.cols)).setTo(0);
  mask.colRange(std::max(0, mask.cols - b), mask.cols).setTo(0);
  double floor = options_.min_corner_response;
  noise_sigma_ = 0;
  // Not on images prepared with a gain that varies across them (CLAHE, local normalisation): one
  // noise figure does not describe them. The corner check (detect_min_eigen) serves CLAHE's.
  const bool local_gain = (low_contrast_ && options_.clahe_clip_limit > 0) ||
                          (options_.local_norm_sigma_px > 0 && FogTreatment());
  if (options_.corner_noise_floor > 0 && !local_gain) {
    noise_sigma_ = NoiseSigma(image);
    floor = std::max(floor, options_.corner_noise_floor * kNoiseCornerResponsePerSigma2 *
                                noise_sigma_ * noise_sigma_);
  }
  if (floor > 0) {
    // Pixels below the floor take no corner (same response as goodFeaturesToTrack's).
    cv::cornerMinEigenVal(image, corner_response_, options_.corner_block_px, 3);
    cv::compare(corner_response_, floor, corner_strong_, cv::CMP_GE);
    mask &= corner_strong_;
  }
  for (const Track& t : *tracks) {
    const int cx = std::clamp(static_cast<int>(t.pixel.x) / std::max(cell_w, 1), 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(t.pixel.y) / std::max(cell_h, 1), 0, rows - 1);
    ++count[cy * cols + cx];
    cv::circle(mask, t.pixel, static_cast<int>(options_.min_distance_px), cv::Scalar(0), -1);
  }
  const bool check = options_.detect_min_eigen > 0 && low_contrast_;
  const bool isotropy = options_.min_corner_isotropy > 0 && FogTreatment();
  int budget = options_.max_features - static_cast<int>(tracks->size());
  std::vector<cv::Point2f> corners, same;
  std::vector<uchar> status;
  std::vector<float> min_eigen;
  const cv::Size win(options_.klt_window_px, options_.klt_window_px);
  const cv::TermCriteria one(cv::TermCriteria::COUNT, 1, 0);
  for (int cy = 0; cy < rows && budget > 0; ++cy) {
    for (int cx = 0; cx < cols && budget > 0; ++cx) {
      const int want = std::min(per_cell - count[cy * cols + cx], budget);
      if (want <= 0) continue;
      const cv::Rect cell(cx * cell_w, cy * cell_h, cell_w, cell_h);
      corners.clear();
      // With the check, spare candidates replace the corners KLT could not track.
      cv::goodFeaturesToTrack(image(cell), corners, check || isotropy ? 2 * want + 2 : want,
                              options_.quality_level, options_.min_distance_px, mask(cell),
                              options_.corner_block_px);
      for (cv::Point2f& c : corners)
        c += cv::Point2f(static_cast<float>(cell.x), static_cast<float>(cell.y));
      if (check && !corners.empty()) {
        // KLT's own measure of a window's texture (the smaller eigenvalue of its gradient
        // matrix over the tracking window, per pixel): KLT declares a track lost below its
        // threshold, so a corner under it would die at the next frame.
        same = corners;
        cv::calcOpticalFlowPyrLK(pyramid, pyramid, corners, same, status, min_eigen, win, 0, one,
                                 cv::OPTFLOW_USE_INITIAL_FLOW | cv::OPTFLOW_LK_GET_MIN_EIGENVALS,
                                 0.0);
      }
      int taken = 0;
      for (size_t i = 0; i < corners.size() && taken < want; ++i) {
        const cv::Point2f& p = corners[i];
        if (check && min_eigen[i] < options_.detect_min_eigen) continue;
        if (isotropy &&
            CornerIsotropy(image, p, options_.klt_window_px / 2) < options_.min_corner_isotropy)
          continue;
        // As across cells, a spare on the rim of a taken corner's circle (at exactly
        // min_distance: goodFeaturesToTrack keeps those) is left out.
        if ((check || isotropy) && mask.at<uchar>(cv::Point(p)) == 0) continue;
        tracks->push_back({next_id_++, p, std::nullopt, 0});
        cv::circle(mask, p, static_cast<int>(options_.min_distance_px), cv::Scalar(0), -1);
        --budget;
        ++taken;
      }
    }
  }
}

void StereoFrontend::MatchStereo(const std::vector<cv::Mat>& left_pyramid,
                                 const std::vector<cv::Mat>& right_pyramid,
                                 std::vector<Track>* tracks_in_out,
                                 std::vector<std::optional<cv::Point2f>>* right, bool all) {
  std::vector<Track>& all_tracks = *tracks_in_out;
  right->assign(all_tracks.size(), std::nullopt);
  std::vector<size_t> subset;
  for (size_t i = 0; i < all_tracks.size(); ++i)
    if (all || (!all_tracks[i].stereo_offset && all_tracks[i].stereo_failures < 2))
      subset.push_back(i);
  if (subset.empty()) return;
  std::vector<Track> tracks;
  for (size_t i : subset) tracks.push_back(all_tracks[i]);
  std::vector<cv::Point2f> left_pts, right_pts, back_pts;
  // Initial guess: the track's last disparity, else the left ray at the typical depth.
  for (const Track& t : tracks) {
    left_pts.push_back(t.pixel);
    cv::Point2f guess = t.pixel;
    if (t.stereo_offset) {
      guess = t.pixel + *t.stereo_offset;
    } else {
      const Eigen::Vector3d p =
          rig_.right_from_left * (rig_.left.Unproject(ToEigen(t.pixel)) * stereo_depth_guess_m_);
      if (const auto q = rig_.right.Project(p)) guess = ToCv(*q);
    }
    right_pts.push_back(guess);
  }
  std::vector<uchar> status, back_status;
  std::vector<float> err;
  const cv::Size win(options_.stereo_window_px, options_.stereo_window_px);
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                              options_.klt_max_iterations, 0.01);
  cv::calcOpticalFlowPyrLK(left_pyramid, right_pyramid, left_pts, right_pts, status, err, win,
                           options_.klt_pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
  back_pts = left_pts;
  cv::calcOpticalFlowPyrLK(right_pyramid, left_pyramid, right_pts, back_pts, back_status, err, win,
                           options_.klt_pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<uchar> matched(tracks.size(), 0);
  for (size_t i = 0; i < tracks.size(); ++i)
    matched[i] = status[i] && back_status[i] &&
                 cv::norm(back_pts[i] - left_pts[i]) <= options_.forward_backward_px;
  if (options_.stereo_refine_window_px > 0)
    RefineStereo(left_pyramid, right_pyramid, left_pts, matched, &right_pts);
  const double focal = rig_.left.fx;
  std::vector<double> depths;
  for (size_t i = 0; i < tracks.size(); ++i) {
    all_tracks[subset[i]].stereo_offset.reset();
    ++all_tracks[subset[i]].stereo_failures;  // reset below on success
    if (!matched[i]) continue;
    if (!rig_.right.InImage(ToEigen(right_pts[i]), options_.border_px)) continue;
    const Eigen::Vector2d nl = rig_.left.PixelToNormalized(ToEigen(left_pts[i]));
    const Eigen::Vector2d nr = rig_.right.PixelToNormalized(ToEigen(right_pts[i]));
    if (camera::EpipolarDistance(essential_, nl, nr) * focal > options_.epipolar_px) continue;
    // In front of both cameras: the triangulated depth along the left ray must be positive.
    const auto point =
        camera::TriangulateTwoView(Rigid3d::Identity(), rig_.right_from_left, nl, nr);
    if (!point || point->z() <= 0) continue;
    (*right)[subset[i]] = right_pts[i];
    all_tracks[subset[i]].stereo_offset = right_pts[i] - left_pts[i];
    all_tracks[subset[i]].stereo_failures = 0;
    depths.push_back(point->z());
  }
  if (!depths.empty()) {
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
    stereo_depth_guess_m_ = depths[depths.size() / 2];
  }
}

void StereoFrontend::RefineStereo(const std::vector<cv::Mat>& left_pyramid,
                                  const std::vector<cv::Mat>& right_pyramid,
                                  const std::vector<cv::Point2f>& left_pts,
                                  const std::vector<uchar>& matched,
                                  std::vector<cv::Point2f>* right_pts) const {
  // Real stereo cameras expose and amplify on their own, and a small window around a corner is
  // mostly edges: an intensity offset between the two would shift plain KLT's match along the
  // window's mean gradient (on the EuRoC clip plain KLT over 9 px moved the 21 px matches by a
  // median 0.9 px, a tenth of them by more than 15 px).
  for (size_t i = 0; i < matched.size(); ++i) {
    if (matched[i])
      RefineWithGainOffset(left_pyramid.front(), left_pts[i], right_pyramid.front(),
                           options_.stereo_refine_window_px / 2, &(*right_pts)[i]);
  }
}

bool StereoFrontend::RefineWithGainOffset(const cv::Mat& templ, const cv::Point2f& t,
                                          const cv::Mat& target, int h, cv::Point2f* p) const {
  const Eigen::Vector2d p0 = ToEigen(*p);
  Eigen::Vector2d q = p0;
  if (!AlignWithGainOffset(templ, ToEigen(t), target, h, options_.klt_max_iterations, &q) ||
      (q - p0).norm() > options_.forward_backward_px)
    return false;
  *p = ToCv(q);
  return true;
}

bool StereoFrontend::DecideKeyframe(int64_t t_ns, const std::vector<Track>& tracks,
                                    uint64_t first_new_id) {
  bool keyframe = !has_keyframe_;
  if (!keyframe) {
    if (probation_pending_) {
      probation_pending_ = false;
      // The keyframe's own new corners that did not survive this first frame leave its
      // reference set.
      std::set<uint64_t> alive_ids;
      for (const Track& t : tracks) alive_ids.insert(t.id);
      std::erase_if(keyframe_tracks_, [&](const Track& t) {
        return t.id >= keyframe_first_new_id_ && alive_ids.count(t.id) == 0;
      });
    }
    if ((t_ns - keyframe_t_ns_) * 1e-9 >= options_.keyframe_max_interval_s) keyframe = true;
    std::map<uint64_t, cv::Point2f> at_keyframe;
    for (const Track& t : keyframe_tracks_) at_keyframe[t.id] = t.pixel;
    int alive = 0;
    double parallax = 0;
    for (const Track& t : tracks) {
      const auto it = at_keyframe.find(t.id);
      if (it == at_keyframe.end()) continue;
      ++alive;
      // Rotation-compensated: where the keyframe pixel would be after the gyro rotation alone.
      Eigen::Vector2d from = ToEigen(it->second);
      if (has_rotation_since_keyframe_) {
        const Eigen::Vector3d ray = cur_from_keyframe_ * rig_.left.Unproject(from);
        if (const auto p = rig_.left.Project(ray)) from = *p;
      }
      parallax += (ToEigen(t.pixel) - from).norm();
    }
    if (alive > 0) parallax /= alive;
    if (!keyframe_tracks_.empty() &&
        alive < options_.keyframe_min_tracked_ratio * keyframe_tracks_.size())
      keyframe = true;
    if (parallax >= options_.keyframe_min_parallax_px) keyframe = true;
  }
  if (keyframe) {
    has_keyframe_ = true;
    keyframe_t_ns_ = t_ns;
    keyframe_tracks_ = tracks;
    keyframe_first_new_id_ = first_new_id;
    probation_pending_ = options_.keyframe_fresh_probation;
    cur_from_keyframe_.setIdentity();
    has_rotation_since_keyframe_ = true;
  }
  return keyframe;
}

cv::Mat StereoFrontend::Prepare(const cv::Mat& image, double left_mean, cv::Mat* buffer) {
  cv::Mat out = image;
  if (low_contrast_ && options_.clahe_clip_limit > 0) {
    if (!clahe_)
      clahe_ = cv::createCLAHE(options_.clahe_clip_limit,
                               cv::Size(options_.clahe_tiles, options_.clahe_tiles));
    clahe_->apply(image, *buffer);
    out = *buffer;
  } else if (low_contrast_ && options_.contrast_stretch_std > 0) {
    const double g = std::max(stretch_gain_, 1.0), offset = left_mean * (1 - g);
    image.convertTo(*buffer, -1, g, offset);
    out = *buffer;
  }
  if (options_.median_filter_px > 1) {
    cv::Mat filtered;
    cv::medianBlur(out, filtered, options_.median_filter_px);
    out = filtered;
  }
  if (options_.highpass_sigma_px > 0) out = HighPassFilter(out, options_.highpass_sigma_px);
  if (options_.local_norm_sigma_px > 0 && FogTreatment())
    out = LocalContrastNormalise(out, options_.local_norm_sigma_px, options_.local_norm_floor);
  return out;
}

FrontendOutput StereoFrontend::Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                       const std::optional<Eigen::Quaterniond>& cur_from_prev,
                                       bool match_all_stereo) {
  OPTINAV_CHECK(left.type() == CV_8UC1 && right.type() == CV_8UC1);
  FrontendOutput out;
  out.t_ns = t_ns;
  const cv::Size win(options_.klt_window_px, options_.klt_window_px);
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                              options_.klt_max_iterations, 0.01);
  Timer stage;
  auto lap = [&](const char* name) {
    if (timing_) timing_->Add(name, stage.ElapsedSeconds());
    stage.Restart();
  };
  cv::Scalar left_mean, left_std;  // of the left image, when a contrast option needs them
  const bool was_low_contrast = low_contrast_;
  if (options_.clahe_clip_limit > 0 || options_.detect_min_eigen > 0 ||
      options_.contrast_stretch_std > 0 || options_.fog_treatment_low_contrast_only) {
    cv::meanStdDev(left, left_mean, left_std);
    if (options_.clahe_below_std <= 0) {
      low_contrast_ = true;
    } else {
      if (left_std[0] < options_.clahe_below_std) low_global_ = true;
      if (left_std[0] > 1.25 * options_.clahe_below_std) low_global_ = false;
      if (options_.clahe_below_local_std > 0) {
        const double local = MedianLocalStd(left);
        if (local < options_.clahe_below_local_std) low_local_ = true;
        if (local > 1.25 * options_.clahe_below_local_std) low_local_ = false;
      }
      low_contrast_ = low_global_ || low_local_;
    }
  }
  // Measured low contrast (with clahe_below_std 0, CLAHE on every frame, nothing is measured).
  out.stats.low_contrast = low_contrast_ && options_.clahe_below_std > 0;
  if (low_contrast_ && options_.clahe_clip_limit <= 0 && options_.contrast_stretch_std > 0) {
    const double want = options_.contrast_stretch_std / std::max(left_std[0], 1.0);
    stretch_gain_ = stretch_gain_ > 0 ? 0.9 * stretch_gain_ + 0.1 * want : want;
  }
  const cv::Mat left_eq = Prepare(left, left_mean[0], &left_eq_buffer_);
  const cv::Mat right_eq = Prepare(right, left_mean[0], &right_eq_buffer_);
  // The contrast treatment switched on or off: the previous frame, tracked from as it was
  // prepared, would no longer look like this one (terrain route, clear, 2026-12-05: 143 of 150
  // tracks failed the forward-backward check at such a switch). Its pyramid is built again from
  // its image prepared as this frame is.
  const bool treated =
      options_.clahe_clip_limit > 0 || options_.contrast_stretch_std > 0 ||
      (options_.fog_treatment_low_contrast_only && options_.local_norm_sigma_px > 0);
  if (treated && low_contrast_ != was_low_contrast && !tracks_.empty() && !prev_pyramid_.empty() &&
      !prev_left_.empty()) {
    cv::Mat prev_eq_buffer;
    const cv::Mat prev_eq = Prepare(prev_left_, prev_left_mean_, &prev_eq_buffer);
    KeepIfExclusive(&prev_pyramid_);
    const int pad = std::max(options_.klt_window_px, options_.stereo_window_px);
    cv::buildOpticalFlowPyramid(prev_eq, prev_pyramid_, cv::Size(pad, pad),
                                options_.klt_pyramid_levels);
    ++out.stats.contrast_switches;
  }
  if (treated && options_.clahe_below_std > 0) {
    left.copyTo(prev_left_);
    prev_left_mean_ = left_mean[0];
  }
  // Into the reused buffers: the one before the previous left pyramid, the last right one.
  std::vector<cv::Mat> left_pyramid = std::move(spare_pyramid_);
  std::vector<cv::Mat> right_pyramid = std::move(right_pyramid_);
  KeepIfExclusive(&left_pyramid);
  KeepIfExclusive(&right_pyramid);
  const int pad = std::max(options_.klt_window_px, options_.stereo_window_px);
  cv::buildOpticalFlowPyramid(left_eq, left_pyramid, cv::Size(pad, pad),
                              options_.klt_pyramid_levels);
  cv::buildOpticalFlowPyramid(right_eq, right_pyramid, cv::Size(pad, pad),
                              options_.klt_pyramid_levels);
  lap("frontend.pyramid");

  // 1. Temporal tracking with the forward-backward check.
  std::vector<Track> tracks;
  if (!tracks_.empty() && !prev_pyramid_.empty()) {
    std::vector<cv::Point2f> prev_pts, cur_pts, back_pts;
    for (const Track& t : tracks_) {
      prev_pts.push_back(t.pixel);
      cv::Point2f guess = t.pixel;
      if (cur_from_prev) {
        const Eigen::Vector3d ray = *cur_from_prev * rig_.left.Unproject(ToEigen(t.pixel));
        if (const auto p = rig_.left.Project(ray)) guess = ToCv(*p);
      }
      cur_pts.push_back(guess);
    }
    std::vector<uchar> status, back_status;
    std::vector<float> err;
    cv::calcOpticalFlowPyrLK(prev_pyramid_, left_pyramid, prev_pts, cur_pts, status, err, win,
                             options_.klt_pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    back_pts = prev_pts;
    cv::calcOpticalFlowPyrLK(left_pyramid, prev_pyramid_, cur_pts, back_pts, back_status, err, win,
                             options_.klt_pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    std::vector<Track> kept;
    std::vector<cv::Point2f> kept_prev;
    for (size_t i = 0; i < tracks_.size(); ++i) {
      if (!status[i] || !back_status[i] ||
          cv::norm(back_pts[i] - prev_pts[i]) > options_.forward_backward_px ||
          !rig_.left.InImage(ToEigen(cur_pts[i]), options_.border_px)) {
        ++out.stats.rejected_fb;
        continue;
      }
      if (options_.klt_gain_offset) {
        // Pyramidal KLT assumes constant brightness. Haze adds a veil that stays put in the image
        // while the texture flows through it: its gradient pulls the match towards no motion.
        // An offset (and gain) fitted over the window absorbs it to first order.
        if (RefineWithGainOffset(prev_pyramid_.front(), prev_pts[i], left_pyramid.front(),
                                 options_.klt_window_px / 2, &cur_pts[i]))
          ++out.stats.klt_refined;
      }
      kept.push_back(
          {tracks_[i].id, cur_pts[i], tracks_[i].stereo_offset, tracks_[i].stereo_failures});
      kept_prev.push_back(prev_pts[i]);
    }
    lap("frontend.track");
    // 2. Geometric RANSAC on undistorted pixels when there is motion to test.
    std::vector<double> flow;
    for (size_t i = 0; i < kept.size(); ++i) flow.push_back(cv::norm(kept[i].pixel - kept_prev[i]));
    if (!flow.empty()) {
      std::nth_element(flow.begin(), flow.begin() + flow.size() / 2, flow.end());
      out.stats.median_flow_px = flow[flow.size() / 2];
    }
    if (kept.size() >= 12 && out.stats.median_flow_px > 1.0) {
      // Undistorted pixels (pinhole projection of the normalised coordinates).
      std::vector<cv::Point2f> a(kept.size()), b(kept.size());
      for (size_t i = 0; i < kept.size(); ++i) {
        const Eigen::Vector2d na = rig_.left.PixelToNormalized(ToEigen(kept_prev[i]));
        const Eigen::Vector2d nb = rig_.left.PixelToNormalized(ToEigen(kept[i].pixel));
        a[i] = cv::Point2f(static_cast<float>(rig_.left.fx * na.x() + rig_.left.cx),
                           static_cast<float>(rig_.left.fy * na.y() + rig_.left.cy));
        b[i] = cv::Point2f(static_cast<float>(rig_.left.fx * nb.x() + rig_.left.cx),
                           static_cast<float>(rig_.left.fy * nb.y() + rig_.left.cy));
      }
      std::vector<uchar> inlier;
      const cv::Mat F =
          cv::findFundamentalMat(a, b, cv::FM_RANSAC, options_.ransac_px, 0.99, inlier);
      if (!F.empty() && inlier.size() == kept.size()) {
        std::vector<Track> filtered;
        for (size_t i = 0; i < kept.size(); ++i) {
          if (inlier[i])
            filtered.push_back(kept[i]);
          else
            ++out.stats.rejected_ransac;
        }
        kept = std::move(filtered);
      }
    }
    tracks = std::move(kept);
    lap("frontend.ransac");
  }
  out.stats.tracked = static_cast<int>(tracks.size());

  // 3. New corners where the grid is thin.
  const size_t before = tracks.size();
  const uint64_t first_new_id = next_id_;
  Detect(left_eq, left_pyramid, &tracks);
  out.stats.detected = static_cast<int>(tracks.size() - before);
  out.stats.noise_sigma = noise_sigma_;
  lap("frontend.detect");

  if (cur_from_prev) {
    cur_from_keyframe_ = (*cur_from_prev * cur_from_keyframe_).normalized();
  } else {
    has_rotation_since_keyframe_ = false;
  }
  // 4. Keyframe decision (on the left tracks), then stereo matching: every track at keyframes
  // (the backend keeps only keyframe observations and the newest frame's), else only tracks
  // never matched yet (new landmarks need their first stereo triangulation).
  out.keyframe = DecideKeyframe(t_ns, tracks, first_new_id);
  std::vector<std::optional<cv::Point2f>> right_pts;
  MatchStereo(left_pyramid, right_pyramid, &tracks, &right_pts, out.keyframe || match_all_stereo);
  for (size_t i = 0; i < tracks.size(); ++i) {
    StereoObservation obs;
    obs.track_id = tracks[i].id;
    obs.left = rig_.left.PixelToNormalized(ToEigen(tracks[i].pixel));
    if (right_pts[i]) {
      obs.right = rig_.right.PixelToNormalized(ToEigen(*right_pts[i]));
      ++out.stats.stereo;
    }
    out.observations.push_back(obs);
  }
  lap("frontend.stereo");
  tracks_ = std::move(tracks);
  spare_pyramid_ = std::move(prev_pyramid_);
  prev_pyramid_ = std::move(left_pyramid);
  right_pyramid_ = std::move(right_pyramid);
  return out;
}

}  // namespace optinav::vio
