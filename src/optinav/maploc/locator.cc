#include "optinav/maploc/locator.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <unordered_map>
#include <unordered_set>

#include <fmt/format.h>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/geo/raster.h"
#include "optinav/maploc/aerial_camera.h"
#include "optinav/maploc/field_correlation.h"
#include "optinav/util/timer.h"

namespace optinav::maploc {

namespace {

constexpr double kDeg = M_PI / 180.0;
// Calibration of position_sigma_m (docs/MAPDB.md): the factors that make the true error lie
// within 2 sigma for >= 90 % of the fixes of the perspective-frame acceptance set.
constexpr double kFeatureSigmaScale = 3.0;
constexpr double kCorrelationSigmaScale = 1.0;

cv::Mat ToGray(const cv::Mat& frame) {
  if (frame.empty()) return {};
  cv::Mat gray;
  if (frame.channels() == 3) {
    cv::cvtColor(frame, gray, cv::COLOR_BGR2GRAY);
  } else if (frame.channels() == 4) {
    cv::cvtColor(frame, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = frame;
  }
  if (gray.depth() != CV_8U) gray.convertTo(gray, CV_8U);
  return gray;
}

// The adaptive method order (locator.h): correlation first after this many feature failures in
// a row, features first again on every this-many-th call.
constexpr int kFeatureFailuresForCorrelationFirst = 3;
constexpr int kFeaturesRetryEvery = 10;

// The coarse search's heading spacing in heading steps (LocateOptions::oc_heading_step_deg), and
// the distinct places then refined in heading, with a heading given and over the full circle.
// Measured on 200 bench frames each (bench/RESULTS.md): with a heading, 2x spacing and 2 places
// kept every figure (199/200 within 25 m) at 0.75x the search time; without, 3x with 4 places
// gave 198/200 within 25 m at 152 ms per frame, 2x 197/200 at 197 ms, 1x 196/200 at 341 ms.
// Map-wide (the pre-search and its fallback), 2x: on 100 frames 96/100 within 25 m as with 1x,
// at half the time; 3x gave 94/100.
constexpr int kSparseWithHeading = 2, kSparseCircle = 3, kSparseGlobal = 2;
constexpr int kRefinedPlacesWithHeading = 2, kRefinedPlacesCircle = 4;

// Up to this many placements a correlation is computed directly, not through transforms.
constexpr int kDirectPlacements = 121;

// Below this grey-level standard deviation a frame carries no structure to correlate.
constexpr double kMinFrameContrast = 1.0;

// Doubled-angle unit gradient field (complex, 2 channels), weighted down in flat areas; the
// doubling makes it invariant to contrast inversion (water darker one year, brighter the next).
cv::Mat OrientationField(const cv::Mat& gray, const cv::Mat& valid) {
  cv::Mat f, gx, gy;
  gray.convertTo(f, CV_32F);
  cv::GaussianBlur(f, f, cv::Size(0, 0), 1.0);
  cv::Sobel(f, gx, CV_32F, 1, 0, 3);
  cv::Sobel(f, gy, CV_32F, 0, 1, 3);
  cv::Mat mag2 = gx.mul(gx) + gy.mul(gy);
  cv::Mat mag;
  cv::sqrt(mag2, mag);
  // Robust gradient scale: the median magnitude over valid pixels.
  std::vector<float> m;
  m.reserve(mag.total());
  for (int y = 0; y < mag.rows; ++y) {
    const float* row = mag.ptr<float>(y);
    const uint8_t* v = valid.empty() ? nullptr : valid.ptr<uint8_t>(y);
    for (int x = 0; x < mag.cols; ++x) {
      if (!v || v[x]) m.push_back(row[x]);
    }
  }
  float g0 = 1.0f;
  if (!m.empty()) {
    std::nth_element(m.begin(), m.begin() + m.size() / 2, m.end());
    g0 = std::max(1.0f, m[m.size() / 2]);
  }
  cv::Mat out(gray.size(), CV_32FC2);
  for (int y = 0; y < gray.rows; ++y) {
    const float* px = gx.ptr<float>(y);
    const float* py = gy.ptr<float>(y);
    const float* pm2 = mag2.ptr<float>(y);
    const float* pm = mag.ptr<float>(y);
    const uint8_t* v = valid.empty() ? nullptr : valid.ptr<uint8_t>(y);
    cv::Vec2f* o = out.ptr<cv::Vec2f>(y);
    for (int x = 0; x < gray.cols; ++x) {
      if ((v && !v[x]) || pm2[x] < 1e-6f) {
        o[x] = {0, 0};
        continue;
      }
      const float w = std::min(1.0f, pm[x] / g0) / pm2[x];
      o[x] = {(px[x] * px[x] - py[x] * py[x]) * w, 2 * px[x] * py[x] * w};
    }
  }
  return out;
}

// One resolution level of the orthophoto for orientation correlation: the doubled-angle
// gradient field of the whole map at `gsd` (computed once, then cropped per frame).
struct OcLevel {
  double gsd = 0;
  cv::Mat field;  // CV_32FC2
};

// The sum of a field's magnitudes: its structure (a rotation keeps it).
double FieldEnergy(const cv::Mat& field) {
  double e = 0;
  for (int y = 0; y < field.rows; ++y) {
    const cv::Vec2f* p = field.ptr<cv::Vec2f>(y);
    for (int x = 0; x < field.cols; ++x) e += std::sqrt(p[x][0] * p[x][0] + p[x][1] * p[x][1]);
  }
  return e;
}

struct OcPeak {
  double score = -1e300, x = 0, y = 0, heading = 0, second = 0, scale = 1;
};

cv::Matx33d ToCv(const Eigen::Matrix3d& m) {
  cv::Matx33d c;
  cv::eigen2cv(m, c);
  return c;
}

Eigen::Matrix3d ToEigen(const cv::Matx33d& c) {
  Eigen::Matrix3d m;
  cv::cv2eigen(c, m);
  return m;
}

Eigen::Vector2d Apply(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  return (h * p.homogeneous()).hnormalized();
}

// Point matches between a work image and the map from block-wise orientation correlation around
// the similarity `map_from_work`: the work image is warped onto the map's level grid, cut into
// blocks, and each block's best shift within a few level pixels is kept when it is distinct.
void BlockMatches(const OcLevel& lv, const cv::Mat& gray, const cv::Mat& valid,
                  const Eigen::Matrix3d& map_from_work, double to_map, int search, int stride,
                  std::vector<Eigen::Vector2d>* work_pts, std::vector<Eigen::Vector2d>* map_pts) {
  constexpr int kBlock = 32;
  // Level pixel i covers map pixels [i, i + 1) x to_map (GDAL's convention): its centre, where
  // the level's arrays sample, is at map (i + 0.5) x to_map.
  Eigen::Matrix3d level_from_map = Eigen::Vector3d(1.0 / to_map, 1.0 / to_map, 1.0).asDiagonal();
  level_from_map.topRightCorner<2, 1>().setConstant(-0.5);
  const Eigen::Matrix3d level_from_work = level_from_map * map_from_work;
  std::vector<cv::Point2f> corners;
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(gray.cols, 0), Eigen::Vector2d(gray.cols, gray.rows),
        Eigen::Vector2d(0, gray.rows)}) {
    const Eigen::Vector2d q = Apply(level_from_work, p);
    corners.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
  }
  const cv::Rect box = cv::boundingRect(corners);
  if (box.area() <= 0 || box.area() > 4'000'000) return;
  Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
  shift(0, 2) = -box.x;
  shift(1, 2) = -box.y;
  Eigen::Matrix3d canvas_from_work = shift * level_from_work;
  canvas_from_work /= canvas_from_work(2, 2);
  const cv::Matx33d m = ToCv(canvas_from_work);
  const bool shrink = std::abs(canvas_from_work.block<2, 2>(0, 0).determinant()) < 1;
  cv::Mat warped, warped_valid;
  cv::warpPerspective(gray, warped, m, box.size(), shrink ? cv::INTER_AREA : cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT);
  cv::warpPerspective(valid, warped_valid, m, box.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  cv::erode(warped_valid, warped_valid, cv::Mat(), cv::Point(-1, -1), 2);
  const cv::Mat field = OrientationField(warped, warped_valid);
  const Eigen::Matrix3d work_from_canvas = canvas_from_work.inverse();
  cv::Mat result;
  for (int by = 0; by + kBlock <= field.rows; by += stride) {
    for (int bx = 0; bx + kBlock <= field.cols; bx += stride) {
      const cv::Rect b(bx, by, kBlock, kBlock);
      if (cv::countNonZero(warped_valid(b)) < kBlock * kBlock * 0.9) continue;
      const cv::Mat tpl = field(b);
      // The map window: the block's place on the level grid, widened by the search range.
      const cv::Rect win(box.x + bx - search, box.y + by - search, kBlock + 2 * search,
                         kBlock + 2 * search);
      if ((win & cv::Rect(0, 0, lv.field.cols, lv.field.rows)) != win) continue;
      if (FieldEnergy(tpl) < 0.15 * kBlock * kBlock) continue;  // flat: no structure to align
      CorrelateSmall(lv.field(win), tpl, &result);
      cv::Point best;
      double best_v = 0;
      cv::minMaxLoc(result, nullptr, &best_v, nullptr, &best);
      if (best.x == 0 || best.y == 0 || best.x == result.cols - 1 || best.y == result.rows - 1) {
        continue;  // at the search border: the true shift may lie beyond
      }
      double second = 0;
      for (int y = 0; y < result.rows; ++y) {
        const float* row = result.ptr<float>(y);
        for (int x = 0; x < result.cols; ++x) {
          if (std::abs(x - best.x) <= 2 && std::abs(y - best.y) <= 2) continue;
          second = std::max(second, static_cast<double>(row[x]));
        }
      }
      if (!(best_v > 1.2 * second)) continue;
      auto at = [&](int x, int y) { return static_cast<double>(result.at<float>(y, x)); };
      const double dxx = at(best.x - 1, best.y) - 2 * best_v + at(best.x + 1, best.y);
      const double dyy = at(best.x, best.y - 1) - 2 * best_v + at(best.x, best.y + 1);
      const double sx = dxx < 0 ? 0.5 * (at(best.x - 1, best.y) - at(best.x + 1, best.y)) / dxx : 0;
      const double sy = dyy < 0 ? 0.5 * (at(best.x, best.y - 1) - at(best.x, best.y + 1)) / dyy : 0;
      // Block centre in canvas px, and where the map has it (level px, then map px).
      const Eigen::Vector2d c(bx + kBlock / 2.0 - 0.5, by + kBlock / 2.0 - 0.5);
      const Eigen::Vector2d shift(best.x - search + std::clamp(sx, -0.5, 0.5),
                                  best.y - search + std::clamp(sy, -0.5, 0.5));
      work_pts->push_back(Apply(work_from_canvas, c));
      map_pts->push_back((c + Eigen::Vector2d(box.x + 0.5, box.y + 0.5) + shift) * to_map);
    }
  }
}

// The homography of block matches (work px -> map px), `scale` the expected map px per work px.
features::HomographyResult FitBlockHomography(const std::vector<Eigen::Vector2d>& work_pts,
                                              const std::vector<Eigen::Vector2d>& map_pts,
                                              double threshold_px, int min_inliers, double scale) {
  if (static_cast<int>(work_pts.size()) < std::max(8, min_inliers)) {
    features::HomographyResult none;
    none.reason = "too few block matches";
    return none;
  }
  std::vector<cv::Point2f> src, dst;
  for (size_t i = 0; i < work_pts.size(); ++i) {
    src.emplace_back(static_cast<float>(work_pts[i].x()), static_cast<float>(work_pts[i].y()));
    dst.emplace_back(static_cast<float>(map_pts[i].x()), static_cast<float>(map_pts[i].y()));
  }
  features::HomographyOptions ho;
  ho.reprojection_threshold_px = threshold_px;
  ho.min_inliers = min_inliers;
  ho.min_scale = scale / 1.5;
  ho.max_scale = scale * 1.5;
  return features::EstimateHomography(src, dst, ho);
}
}  // namespace

// A frame made ready for matching: undistorted, and rectified to a nadir view when roll and
// pitch are known. Both methods work on `gray`; `work_from_frame` takes the undistorted frame's
// pixels there, and the camera's principal point lands on the vehicle's nadir point when the
// frame was rectified.
struct PreparedFrame {
  cv::Mat gray, valid;  // work image; 255 where it holds frame content
  Eigen::Matrix3d work_from_frame = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();  // of the undistorted frame
  int width = 0, height = 0;                        // of the frame
  bool rectified = false;
  double contrast = 0;  // grey-level std of the frame as given (before any resampling)
  // Work px of the vehicle's nadir point: the principal point of the (virtual, level) camera
  // that sees the work image; the frame's principal point itself when not rectified.
  Eigen::Vector2d nadir_work = Eigen::Vector2d::Zero();
  std::string error;  // why the frame cannot be used ("" when it can)
  Eigen::Vector2d Centre() const { return {(width - 1) / 2.0, (height - 1) / 2.0}; }
  // Metres per work pixel at the nadir for a camera at `altitude_m`.
  double Gsd(double altitude_m) const { return altitude_m / K(0, 0); }
};

namespace {}  // namespace

namespace {

// The bookkeeping of one localization attempt: method, stage timing and the two exits.
struct Attempt {
  explicit Attempt(const char* method) {
    result.method = method;
    result.methods_tried = {method};
  }
  // Ends without a fix, saying why.
  LocateResult Fail(std::string reason) {
    result.reason = std::move(reason);
    result.times.total_ms = total.ElapsedSeconds() * 1e3;
    return result;
  }
  // Ends with the fix filled into `result`.
  LocateResult Done() {
    result.localized = true;
    result.reason = "ok";
    result.times.total_ms = total.ElapsedSeconds() * 1e3;
    return result;
  }
  LocateResult result;
  Timer total, stage;
};

}  // namespace

std::string LocateOptions::Check() const {
  if (!(ratio > 0 && ratio <= 1)) return "ratio must be in (0, 1]";
  if (!(xfeat_ratio > 0 && xfeat_ratio <= 1)) return "xfeat_ratio must be in (0, 1]";
  if (xfeat_threads < 0) return "xfeat_threads must be >= 0";
  if (xfeat_rotations < 1 || xfeat_rotations > 36) return "xfeat_rotations must be in [1, 36]";
  if (top_n_per_tile < 4) return "top_n_per_tile must be >= 4";
  if (max_candidate_tiles < 1) return "max_candidate_tiles must be >= 1";
  if (!(oc_heading_step_deg > 0.1)) return "oc_heading_step_deg must be > 0.1";
  if (oc_global_verify < 1) return "oc_global_verify must be >= 1";
  if (oc_min_block_inliers < 4) return "oc_min_block_inliers must be >= 4";
  if (hfov_deg != 0 && !(hfov_deg > 0 && hfov_deg < 180)) return "hfov_deg must be in (0, 180)";
  if (camera) {
    try {
      camera->Validate();
    } catch (const Error& e) {
      return std::string("camera: ") + e.what();
    }
  }
  return homography.Check();
}

struct Locator::Impl {
  const MapDatabase& db;
  LocateOptions options;
  geo::CrsTransform crs;
  std::unique_ptr<features::FeatureExtractor> extractor;
  // Global search sample of map descriptors (built on first use).
  std::once_flag index_once;
  cv::Mat all_descriptors;
  std::vector<int> descriptor_tile;
  // Orthophoto and its orientation fields for orientation correlation (built on first use).
  std::map<long, OcLevel> oc_levels;  // by gsd in mm
  std::unique_ptr<geo::GeoRaster> ortho;
  std::string ortho_error;
  bool ortho_tried = false;
  // The adaptive method order (Locator::Order::kAdaptive): features' failures in a row, calls.
  int feature_failures = 0;
  long adaptive_calls = 0;
  // Undistortion pixel maps by frame size.
  std::mutex undistort_mutex;
  std::map<std::pair<int, int>, std::pair<cv::Mat, cv::Mat>> undistort_maps;

  // Per tile, the features in its core: the cell of points nearer to this tile's centre than
  // to any other (the whole map is covered once). Overlapping tiles detect the same map points
  // again; matching cores only never sees a map point twice.
  std::vector<cv::Mat> core_descriptors;
  std::vector<std::vector<int>> core_index;  // into the tile's keypoints

  Impl(const MapDatabase& d, const LocateOptions& o)
      : db(d),
        options(o),
        crs(d.crs_wkt),
        extractor(features::CreateFeatureExtractor({.type = d.feature_type,
                                                    .max_features = o.frame_features,
                                                    .orb_levels = o.frame_orb_levels,
                                                    .model_path = o.model_path,
                                                    .xfeat_scale = d.options.xfeat_scale,
                                                    .threads = o.xfeat_threads})) {
    core_descriptors.resize(db.tiles.size());
    core_index.resize(db.tiles.size());
    for (const MapTile& t : db.tiles) {
      const double cx = t.px.x + t.px.width / 2, cy = t.px.y + t.px.height / 2;
      const double h = db.step_px / 2;
      const double x0 = t.col == 0 ? -1e300 : cx - h, x1 = t.col == db.cols - 1 ? 1e300 : cx + h;
      const double y0 = t.row == 0 ? -1e300 : cy - h, y1 = t.row == db.rows - 1 ? 1e300 : cy + h;
      std::vector<int>& idx = core_index[t.index];
      for (size_t i = 0; i < t.keypoints.size(); ++i) {
        const auto& p = t.keypoints[i];
        if (p.x >= x0 && p.x < x1 && p.y >= y0 && p.y < y1) idx.push_back(static_cast<int>(i));
      }
      cv::Mat& d = core_descriptors[t.index];
      if (!idx.empty()) {
        d.create(static_cast<int>(idx.size()), t.descriptors.cols, t.descriptors.type());
        for (size_t k = 0; k < idx.size(); ++k)
          t.descriptors.row(idx[k]).copyTo(d.row(static_cast<int>(k)));
      }
    }
  }

  float Ratio() const {
    return db.feature_type == features::FeatureType::kXFeat ? options.xfeat_ratio : options.ratio;
  }

  std::vector<Eigen::Vector2d> PriorCentresPx(const Prior& prior, const Locator& self) const {
    std::vector<Eigen::Vector2d> centres;
    if (prior.position) centres.push_back(self.LatLonToPixel(*prior.position));
    for (const auto& c : prior.extra_centres) centres.push_back(self.LatLonToPixel(c));
    return centres;
  }

  void BuildIndex() {
    // A sample of every tile's core features: enough to vote for the right area, small enough
    // for a brute-force POPCNT search (faster here than an LSH index, and exact).
    std::vector<cv::Mat> parts;
    for (const MapTile& t : db.tiles) {
      const cv::Mat& core = core_descriptors[t.index];
      if (core.empty()) continue;
      const int k = std::min(core.rows, options.global_features_per_tile);
      parts.push_back(core.rowRange(0, k));
      descriptor_tile.insert(descriptor_tile.end(), k, t.index);
    }
    if (!parts.empty()) cv::vconcat(parts, all_descriptors);
  }

  // The frame's camera: the configured one (scaled to the frame when only its size differs),
  // else a pinhole with the configured or the map's field of view.
  std::optional<camera::PinholeCamera> CameraFor(int w, int h, std::string* error) const {
    if (options.camera) {
      const camera::PinholeCamera& c = *options.camera;
      const double k = static_cast<double>(w) / c.width;
      if (std::abs(c.height * k - h) > 1.0) {
        *error = fmt::format("the frame is {}x{}, the camera {}x{}: not the same aspect", w, h,
                             c.width, c.height);
        return std::nullopt;
      }
      return std::abs(k - 1.0) < 1e-12 ? c : c.Scaled(k);
    }
    const double hfov = options.hfov_deg > 0 ? options.hfov_deg : db.options.hfov_deg;
    return camera::PinholeCamera::FromHorizontalFov(w, h, hfov * kDeg);
  }

  PreparedFrame Prepare(const cv::Mat& frame, const Prior& prior) {
    PreparedFrame pf;
    cv::Mat gray = ToGray(frame);
    if (gray.empty()) {
      pf.error = "empty frame";
      return pf;
    }
    pf.width = gray.cols;
    pf.height = gray.rows;
    cv::Scalar mean, stddev;
    cv::meanStdDev(gray, mean, stddev);
    pf.contrast = stddev[0];
    const auto cam = CameraFor(gray.cols, gray.rows, &pf.error);
    if (!cam) return pf;
    pf.K = cam->K();
    pf.nadir_work = {pf.K(0, 2), pf.K(1, 2)};
    if (cam->distortion != camera::DistortionModel::kNone) {
      // Undistort to the same intrinsics without distortion (pixel maps cached per size).
      std::lock_guard<std::mutex> lock(undistort_mutex);
      const std::pair<int, int> key(gray.cols, gray.rows);
      auto it = undistort_maps.find(key);
      if (it == undistort_maps.end()) {
        cv::Mat mx(gray.size(), CV_32F), my(gray.size(), CV_32F);
        for (int y = 0; y < gray.rows; ++y) {
          for (int x = 0; x < gray.cols; ++x) {
            const Eigen::Vector2d d =
                cam->NormalizedToPixel({(x - cam->cx) / cam->fx, (y - cam->cy) / cam->fy});
            mx.at<float>(y, x) = static_cast<float>(d.x());
            my.at<float>(y, x) = static_cast<float>(d.y());
          }
        }
        it = undistort_maps.emplace(key, std::make_pair(mx, my)).first;
      }
      cv::Mat undistorted;
      cv::remap(gray, undistorted, it->second.first, it->second.second, cv::INTER_LINEAR,
                cv::BORDER_CONSTANT);
      gray = undistorted;
    }
    const double roll = prior.roll_deg.value_or(0.0), pitch = prior.pitch_deg.value_or(0.0);
    if (std::abs(roll) + std::abs(pitch) < 0.2) {
      pf.gray = gray;
      return pf;
    }
    // Rectify to a nadir view: the frame seen by a level camera at the same place.
    const Eigen::Matrix3d nadir = NadirFromImage(pf.K, roll, pitch);
    std::vector<cv::Point2f> corners;
    for (const Eigen::Vector2d& p :
         {Eigen::Vector2d(0, 0), Eigen::Vector2d(gray.cols, 0),
          Eigen::Vector2d(gray.cols, gray.rows), Eigen::Vector2d(0, gray.rows)}) {
      const Eigen::Vector3d q = nadir * p.homogeneous();
      if (!(q.z() > 1e-9)) {
        pf.error = "the attitude turns the camera to the horizon: the frame cannot be rectified";
        return pf;
      }
      corners.emplace_back(static_cast<float>(q.x() / q.z()), static_cast<float>(q.y() / q.z()));
    }
    cv::Rect box = cv::boundingRect(corners);
    // A steep view stretches far on one side; keep at most twice the frame around the nadir.
    const cv::Rect cap(static_cast<int>(pf.K(0, 2)) - gray.cols,
                       static_cast<int>(pf.K(1, 2)) - gray.rows, 2 * gray.cols, 2 * gray.rows);
    box &= cap;
    Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
    shift(0, 2) = -box.x;
    shift(1, 2) = -box.y;
    pf.work_from_frame = shift * nadir;
    pf.nadir_work -= Eigen::Vector2d(box.x, box.y);
    const cv::Matx33d m = ToCv(pf.work_from_frame);
    cv::warpPerspective(gray, pf.gray, m, box.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    cv::warpPerspective(cv::Mat(gray.size(), CV_8U, cv::Scalar(255)), pf.valid, m, box.size(),
                        cv::INTER_NEAREST, cv::BORDER_CONSTANT);
    cv::erode(pf.valid, pf.valid, cv::Mat(), cv::Point(-1, -1), 3);
    pf.rectified = true;
    return pf;
  }

  // The pose and every position field of `r` from the homography work px -> map px. With
  // correspondences (features), the camera pose is estimated from them (planar PnP, the prior's
  // attitude and altitude as soft constraints); without (correlation), the pose is the
  // rectification's: the given attitude, the altitude of the correlation's scale.
  // `base_sigma_m`: the position uncertainty of the correlation. False (reason in r) when the
  // result is unusable.
  bool Finish(const Locator& self, const PreparedFrame& pf, const Eigen::Matrix3d& map_from_work,
              const Prior& prior, const std::vector<Eigen::Vector2d>* work_pts,
              const std::vector<Eigen::Vector2d>* map_pts, double base_sigma_m, LocateResult* r,
              double unknown_attitude_sigma_deg = 20.0) {
    const double gsd = db.map_gsd_m;
    const Eigen::Matrix3d map_from_frame = map_from_work * pf.work_from_frame;
    const Eigen::Vector2d c = pf.Centre();
    r->centre_px = Apply(map_from_frame, c);
    if (!r->centre_px.allFinite() || r->centre_px.x() < 0 || r->centre_px.y() < 0 ||
        r->centre_px.x() > db.width || r->centre_px.y() > db.height) {
      r->reason = "the frame centre maps outside the map";
      return false;
    }
    r->scale = features::HomographyScale(ToCv(map_from_frame), {c.x(), c.y()});
    // The pose the rectification implies (a level camera sees the work image).
    AerialPose assumed;
    assumed.nadir_px = Apply(map_from_work, pf.nadir_work);
    const Eigen::Vector2d ahead =
        Apply(map_from_work, pf.nadir_work + Eigen::Vector2d(0, -10)) - assumed.nadir_px;
    assumed.altitude_m =
        features::HomographyScale(ToCv(map_from_work), {pf.nadir_work.x(), pf.nadir_work.y()}) *
        gsd * pf.K(0, 0);
    assumed.attitude = {.roll_deg = prior.roll_deg.value_or(0.0),
                        .pitch_deg = prior.pitch_deg.value_or(0.0),
                        .yaw_deg = std::atan2(ahead.x(), -ahead.y()) / kDeg};
    AerialPose pose = assumed;
    double sigma = base_sigma_m;
    if (work_pts && map_pts && work_pts->size() >= 6) {
      const Eigen::Matrix3d frame_from_work = pf.work_from_frame.inverse();
      std::vector<Eigen::Vector2d> img;
      img.reserve(work_pts->size());
      for (const auto& w : *work_pts) img.push_back(Apply(frame_from_work, w));
      const auto init = PoseFromHomography(map_from_frame, pf.K, gsd);
      // Unknown attitude: a level prior keeps a weak geometry from trading tilt for shift (weak
      // for features, firmer for the correlation, whose search assumed a near-nadir view).
      PosePriors priors{.roll_deg = prior.roll_deg.value_or(0.0),
                        .pitch_deg = prior.pitch_deg.value_or(0.0),
                        .attitude_sigma_deg = prior.roll_deg || prior.pitch_deg
                                                  ? prior.attitude_sigma_deg
                                                  : unknown_attitude_sigma_deg,
                        .altitude_m = prior.altitude_m,
                        .altitude_sigma_rel = prior.altitude_sigma_rel};
      const bool init_ok =
          init && std::abs(init->attitude.roll_deg) < 60 && std::abs(init->attitude.pitch_deg) < 60;
      const PoseEstimate est =
          RefinePose(img, *map_pts, pf.K, gsd, init_ok ? *init : assumed, priors);
      const bool plausible = est.pose.altitude_m > 0.2 * assumed.altitude_m &&
                             est.pose.altitude_m < 5.0 * assumed.altitude_m &&
                             std::abs(est.pose.attitude.roll_deg) < 60 &&
                             std::abs(est.pose.attitude.pitch_deg) < 60;
      if (plausible) {
        pose = est.pose;
        sigma = std::hypot(kFeatureSigmaScale * est.horizontal_sigma_m, gsd);
      } else {
        sigma = std::hypot(gsd, assumed.altitude_m * std::tan(prior.attitude_sigma_deg * kDeg));
      }
    }
    r->map_px = pose.nadir_px;
    if (!r->map_px.allFinite()) {
      r->reason = "no camera pose fits the match";
      return false;
    }
    r->crs_xy = db.transform.PixelToCrs(r->map_px);
    r->latlon = crs.ToLatLon(r->crs_xy);
    r->centre_latlon = crs.ToLatLon(db.transform.PixelToCrs(r->centre_px));
    const double yaw = pose.attitude.yaw_deg * kDeg;
    r->heading_deg = self.PixelDirectionToHeading({std::sin(yaw), -std::cos(yaw)});
    r->roll_deg = pose.attitude.roll_deg;
    r->pitch_deg = pose.attitude.pitch_deg;
    r->altitude_m = pose.altitude_m;
    r->position_sigma_m = sigma;
    return true;
  }

  const geo::GeoRaster* Ortho() {
    if (!ortho_tried) {
      ortho_tried = true;
      const std::string path = options.ortho_path.empty() ? db.ortho_path : options.ortho_path;
      try {
        ortho = std::make_unique<geo::GeoRaster>(geo::GeoRaster::Open(path));
      } catch (const Error& e) {
        ortho_error = e.what();
      }
    }
    return ortho.get();
  }
};

namespace {
const LocateOptions& Validated(const LocateOptions& options) {
  if (const std::string msg = options.Check(); !msg.empty()) throw Error(msg);
  return options;
}
}  // namespace

// Options are validated before anything is built from them.
Locator::Locator(const MapDatabase& db, const LocateOptions& options)
    : impl_(std::make_unique<Impl>(db, Validated(options))) {}

Locator::~Locator() = default;

geo::LatLon Locator::PixelToLatLon(const Eigen::Vector2d& px) const {
  return impl_->crs.ToLatLon(impl_->db.transform.PixelToCrs(px));
}

Eigen::Vector2d Locator::LatLonToPixel(const geo::LatLon& ll) const {
  return impl_->db.transform.CrsToPixel(impl_->crs.FromLatLon(ll));
}

double Locator::PixelDirectionToHeading(const Eigen::Vector2d& d) const {
  return impl_->db.transform.PixelDirectionToAzimuthDeg(d);
}

Eigen::Vector2d Locator::HeadingToPixelDirection(double heading_deg) const {
  return impl_->db.transform.AzimuthDegToPixelDirection(heading_deg);
}

LocateResult Locator::Locate(const cv::Mat& frame, const Prior& prior, Order order) {
  Timer total;
  const PreparedFrame pf = impl_->Prepare(frame, prior);
  // Orientation correlation also searches globally, so it backs features up with or without
  // a prior.
  const bool oc_possible = impl_->options.allow_orientation_correlation && pf.error.empty();
  Impl& im = *impl_;
  const bool adaptive_oc_first = im.feature_failures >= kFeatureFailuresForCorrelationFirst &&
                                 im.adaptive_calls % kFeaturesRetryEvery != 0;
  ++im.adaptive_calls;
  const bool oc_first = oc_possible && (order == Order::kCorrelationFirst ||
                                        (order == Order::kAdaptive && adaptive_oc_first));
  auto features = [&]() {
    LocateResult r = FeaturesOn(pf, prior);
    im.feature_failures = r.localized ? 0 : im.feature_failures + 1;
    return r;
  };
  LocateResult first = oc_first ? CorrelationOn(pf, prior) : features();
  if (first.localized || (!oc_first && !oc_possible)) {
    first.times.total_ms = total.ElapsedSeconds() * 1e3;
    return first;
  }
  LocateResult second = oc_first ? features() : CorrelationOn(pf, prior);
  second.methods_tried.insert(second.methods_tried.begin(), first.method);
  if (!second.localized) {
    const LocateResult& feat = oc_first ? second : first;
    const LocateResult& oc = oc_first ? first : second;
    second.reason = "features: " + feat.reason + "; orientation correlation: " + oc.reason;
  }
  second.times.extraction_ms += first.times.extraction_ms;
  second.times.matching_ms += first.times.matching_ms;
  second.times.estimation_ms += first.times.estimation_ms;
  second.times.total_ms = total.ElapsedSeconds() * 1e3;
  return second;
}

void Locator::ResetAdaptiveOrder() {
  impl_->feature_failures = 0;
  impl_->adaptive_calls = 0;
}

LocateResult Locator::LocateByFeatures(const cv::Mat& frame, const Prior& prior) {
  Timer total;
  const PreparedFrame pf = impl_->Prepare(frame, prior);
  LocateResult r = FeaturesOn(pf, prior);
  r.times.total_ms = total.ElapsedSeconds() * 1e3;
  return r;
}

LocateResult Locator::FeaturesOn(const PreparedFrame& pf, const Prior& prior) {
  Impl& im = *impl_;
  const MapDatabase& db = im.db;
  Attempt a("features");
  LocateResult& r = a.result;
  Timer& stage = a.stage;
  if (!pf.error.empty()) return a.Fail(pf.error);
  const cv::Mat& gray = pf.gray;
  // Bring the frame to the resolution the map's features were taken at.
  const double frame_gsd = pf.Gsd(prior.altitude_m.value_or(db.options.altitude_m));
  double to_feature = frame_gsd / db.feature_gsd_m;
  cv::Mat work = gray, work_mask = pf.valid;
  if (prior.altitude_m && std::abs(to_feature - 1.0) > 0.15) {
    cv::resize(gray, work, cv::Size(), to_feature, to_feature,
               to_feature < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
    if (!pf.valid.empty()) cv::resize(pf.valid, work_mask, work.size(), 0, 0, cv::INTER_NEAREST);
  } else {
    to_feature = 1.0;
  }
  features::Features ff;
  if (db.feature_type == features::FeatureType::kXFeat) {
    // XFeat descriptors are not rotation invariant: the frame is turned to the map's orientation
    // by the prior heading, or, without one, seen at a few rotations spread over the circle.
    const Eigen::Vector2d north_px = HeadingToPixelDirection(0.0);
    const double grid_rot = std::atan2(north_px.x(), -north_px.y());
    std::vector<double> angles;
    if (prior.heading_deg) {
      angles.push_back(*prior.heading_deg * kDeg + grid_rot);
    } else {
      for (int k = 0; k < im.options.xfeat_rotations; ++k)
        angles.push_back(grid_rot + 2 * M_PI * k / im.options.xfeat_rotations);
    }
    ff = features::ExtractRotated(*im.extractor, work, work_mask, angles);
  } else {
    ff = im.extractor->Extract(work, work_mask);
  }
  r.times.extraction_ms = stage.ElapsedSeconds() * 1e3;
  if (ff.size() < 8) {
    return a.Fail(
        fmt::format("too few features in the frame ({}): textureless, dark or blurred", ff.size()));
  }
  stage.Restart();

  // Candidate tiles.
  std::vector<int> candidates;
  const auto centres = im.PriorCentresPx(prior, *this);
  if (!centres.empty()) {
    const double radius_px = prior.radius_m / db.map_gsd_m;
    std::vector<std::pair<double, int>> by_distance;
    for (const MapTile& t : db.tiles) {
      double best = 1e300;
      for (const auto& c : centres) {
        // Distance from the centre to the tile rectangle.
        const double dx = std::max({t.px.x - c.x(), 0.0, c.x() - (t.px.x + t.px.width)});
        const double dy = std::max({t.px.y - c.y(), 0.0, c.y() - (t.px.y + t.px.height)});
        const double centre_d =
            std::hypot(t.px.x + t.px.width / 2 - c.x(), t.px.y + t.px.height / 2 - c.y());
        if (std::hypot(dx, dy) <= radius_px) best = std::min(best, centre_d);
      }
      if (best < 1e300) by_distance.emplace_back(best, t.index);
    }
    if (by_distance.empty()) {
      return a.Fail("the prior lies outside the map");
    }
    std::sort(by_distance.begin(), by_distance.end());
    for (size_t i = 0;
         i < by_distance.size() && static_cast<int>(i) < im.options.max_candidate_tiles; ++i) {
      candidates.push_back(by_distance[i].second);
    }
  } else {
    // Global search: frame descriptors vote for tiles against a sample of every tile's
    // descriptors, then the best tiles and their neighbours are verified geometrically.
    std::call_once(im.index_once, [&] { im.BuildIndex(); });
    if (im.all_descriptors.empty()) {
      return a.Fail("the map has no features");
    }
    const cv::Mat query =
        ff.descriptors.rowRange(0, std::min(ff.descriptors.rows, im.options.global_query_features));
    const auto votes_m = features::MatchWithRatio(query, im.all_descriptors, ff.norm, im.Ratio());
    std::vector<double> votes(db.tiles.size(), 0.0);
    for (const auto& m : votes_m) votes[im.descriptor_tile[m.trainIdx]] += 1.0;
    std::vector<int> order(db.tiles.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return votes[a] > votes[b]; });
    std::vector<bool> taken(db.tiles.size(), false);
    for (int k = 0; k < im.options.global_verify_tiles && k < static_cast<int>(order.size()); ++k) {
      const MapTile& t = db.tiles[order[k]];
      if (votes[t.index] <= 0) break;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = t.row + dr, cc = t.col + dc;
          if (rr < 0 || cc < 0 || rr >= db.rows || cc >= db.cols) continue;
          const int id = rr * db.cols + cc;
          if (!taken[id]) {
            taken[id] = true;
            candidates.push_back(id);
          }
        }
      }
    }
    if (candidates.empty()) {
      r.times.matching_ms = stage.ElapsedSeconds() * 1e3;
      return a.Fail("no map tile shares features with the frame");
    }
  }
  r.candidate_tiles = candidates;

  // Match against the union of the candidates' core features (2-NN + ratio over the union),
  // keep the best top_n_per_tile per tile, lift to map pixels, de-duplicate on a grid.
  std::vector<cv::Mat> parts;
  std::vector<std::pair<int, int>> owner;  // (tile, keypoint index) per union row
  for (int id : candidates) {
    if (im.core_descriptors[id].empty()) continue;
    parts.push_back(im.core_descriptors[id]);
    for (int k : im.core_index[id]) owner.emplace_back(id, k);
  }
  std::vector<cv::Point2f> src, dst;
  if (!parts.empty()) {
    cv::Mat train;
    cv::vconcat(parts, train);
    const auto matches =
        features::MatchFeatures(db.feature_type, ff.descriptors, train, im.Ratio());
    std::unordered_map<int, int> per_tile;
    // Several frame features (e.g. one corner at two pyramid levels) can match map features at
    // the same place: keep the best match per map grid cell.
    std::unordered_set<int64_t> seen;
    const double cell = im.options.dedupe_cell_px * db.feature_gsd_m / db.map_gsd_m;
    for (const auto& m : matches) {  // sorted by distance: best first
      const auto [tile, k] = owner[m.trainIdx];
      if (++per_tile[tile] > im.options.top_n_per_tile) continue;
      const cv::Point2f mp = db.tiles[tile].keypoints[k];
      const int64_t key = (static_cast<int64_t>(std::floor(mp.x / cell)) << 32) ^
                          static_cast<int64_t>(std::floor(mp.y / cell));
      if (!seen.insert(key).second) continue;
      src.push_back(ff.keypoints[m.queryIdx].pt * static_cast<float>(1.0 / to_feature));
      dst.push_back(mp);
    }
  }
  r.times.matching_ms = stage.ElapsedSeconds() * 1e3;
  stage.Restart();

  features::HomographyOptions ho = im.options.homography;
  ho.reprojection_threshold_px *= db.feature_gsd_m / db.map_gsd_m;  // threshold in map pixels
  // Scale is map px per frame px: allow the plausible range around the expected one.
  const double expected = frame_gsd / db.map_gsd_m;
  ho.min_scale = expected / 3.0;
  ho.max_scale = expected * 3.0;
  const features::HomographyResult h = features::EstimateHomography(src, dst, ho);
  r.times.estimation_ms = stage.ElapsedSeconds() * 1e3;
  r.inliers = h.inliers;
  r.inlier_ratio = h.inlier_ratio;
  if (!h.ok) {
    return a.Fail(h.reason);
  }
  std::vector<Eigen::Vector2d> work_pts, map_pts;
  for (size_t i = 0; i < src.size(); ++i) {
    if (i < h.inlier_mask.size() && !h.inlier_mask[i]) continue;
    work_pts.emplace_back(src[i].x, src[i].y);
    map_pts.emplace_back(dst[i].x, dst[i].y);
  }
  if (!im.Finish(*this, pf, ToEigen(h.H), prior, &work_pts, &map_pts, 0.0, &r)) {
    return a.Fail(r.reason);
  }
  // Confidence grows with inliers (saturating) and their share of the matches.
  r.confidence = std::min(1.0, h.inliers / 60.0) * std::min(1.0, 0.5 + h.inlier_ratio);
  return a.Done();
}

LocateResult Locator::LocateByOrientationCorrelation(const cv::Mat& frame, const Prior& prior) {
  Timer total;
  const PreparedFrame pf = impl_->Prepare(frame, prior);
  LocateResult r = CorrelationOn(pf, prior);
  r.times.total_ms = total.ElapsedSeconds() * 1e3;
  return r;
}

LocateResult Locator::CorrelationOn(const PreparedFrame& pf, const Prior& prior) {
  Impl& im = *impl_;
  const MapDatabase& db = im.db;
  Attempt a("orientation-correlation");
  LocateResult& r = a.result;
  Timer& stage = a.stage;
  if (!pf.error.empty()) return a.Fail(pf.error);
  const cv::Mat& gray = pf.gray;
  // A frame without contrast (a blank frame, a lens cap, a white-out) has no orientation field
  // to correlate, but the borders of its rectification do: refuse it rather than match them.
  // The contrast of the frame as given, and over the rectified frame's own pixels: resampling
  // (undistortion, rectification) blends the frame's edge with the border, which left a std of
  // 1.2-1.8 inside the valid area of blank 640x480 frames of the simulator's nadir camera.
  cv::Scalar mean, stddev;
  if (pf.valid.empty()) {
    cv::meanStdDev(gray, mean, stddev);
  } else {
    cv::meanStdDev(gray, mean, stddev, pf.valid);
  }
  const double contrast = std::min(pf.contrast, stddev[0]);
  if (contrast < kMinFrameContrast) {
    return a.Fail(fmt::format("textureless frame: contrast (grey-level std) {:.2f} < {}", contrast,
                              kMinFrameContrast));
  }
  const geo::GeoRaster* ortho = im.Ortho();
  if (!ortho) {
    return a.Fail("orthophoto unavailable for orientation correlation: " + im.ortho_error);
  }
  // Search area: around the prior's centres, or (no prior) the whole map.
  const auto centres = im.PriorCentresPx(prior, *this);
  const bool global = centres.empty();
  Eigen::Vector2d c_px(db.width / 2.0, db.height / 2.0);
  double radius_px = 0.5 * std::hypot(db.width, db.height);
  if (!global) {
    c_px = Eigen::Vector2d::Zero();
    for (const auto& c : centres) c_px += c / static_cast<double>(centres.size());
    radius_px = 0;
    for (const auto& c : centres) radius_px = std::max(radius_px, (c - c_px).norm());
    radius_px += prior.radius_m / db.map_gsd_m;
    if (c_px.x() < -db.width * 0.1 || c_px.y() < -db.height * 0.1 || c_px.x() > db.width * 1.1 ||
        c_px.y() > db.height * 1.1) {
      return a.Fail("the prior lies outside the map");
    }
  }
  // Scales searched (frame gsd factors): +-25 % when the altitude is unknown, else its 1-sigma
  // uncertainty (an altitude 10 % off still peaks at the coarse level, but less reliably on a
  // map years older than the frame); the fine level and the blocks find the exact scale.
  std::vector<double> scales = {1.0};
  if (!prior.altitude_m) {
    scales = {0.82, 1.0, 1.2};
  } else if (prior.altitude_sigma_rel >= 0.05) {
    // With a heading, two scales at +-s/2 (at most s/2 of scale error over [1 - s, 1 + s], as
    // with three at 1 - s, 1, 1 + s; the fine level refines the scale by +-5 %). Over the full
    // circle of headings the weaker peaks of that residual error lose to look-alikes more often
    // (prior only: 26/30 frames within 25 m against 30/30 with three), so three there.
    const double s = std::min(0.25, prior.altitude_sigma_rel);
    if (prior.heading_deg) {
      scales = {1.0 - s / 2, 1.0 + s / 2};
    } else {
      scales = {1.0 - s, 1.0, 1.0 + s};
    }
  }
  const double max_scale = *std::max_element(scales.begin(), scales.end());
  const double frame_gsd = pf.Gsd(prior.altitude_m.value_or(db.options.altitude_m));
  const double frame_extent_m = std::max(pf.width, pf.height) * frame_gsd;
  // The frame's valid part, as wide as the rectified view can be.
  const double diag_m = std::hypot(gray.cols, gray.rows) * frame_gsd * max_scale;
  // The levels sit on a fixed ladder, rung k at map gsd x 2^(k/4), so that frames from other
  // altitudes reuse them: each level is the whole map's field, computed once (keyed by the exact
  // gsd, every frame of a flight made a new one: 3 map-sized fields per fix, and the memory grew
  // with them). Fine level: the rung nearest the frame ~2 x `oc_coarse_px` across (never finer
  // than the map, nor much finer than the frame); coarse: 4 rungs up (twice the gsd); blocks: 4
  // rungs down (not below the map).
  auto rung = [&](int k) { return db.map_gsd_m * std::exp2(k / 4.0); };
  const double fine_wanted = std::max(frame_gsd, frame_extent_m / (2.0 * im.options.oc_coarse_px));
  const int fine_k =
      static_cast<int>(std::lround(4.0 * std::log2(std::max(1.0, fine_wanted / db.map_gsd_m))));
  const double fine_gsd = rung(fine_k), coarse_gsd = rung(fine_k + 4);
  auto level = [&](double gsd) -> const OcLevel& {
    const long key = std::lround(gsd * 1000.0);
    auto it = im.oc_levels.find(key);
    if (it != im.oc_levels.end()) return it->second;
    OcLevel l;
    l.gsd = gsd;
    const double k = db.map_gsd_m / gsd;
    const int w = std::max(8, static_cast<int>(std::lround(db.width * k)));
    const int h = std::max(8, static_cast<int>(std::lround(db.height * k)));
    cv::Mat valid;
    const cv::Mat img = ortho->ReadGray(0, 0, db.width, db.height, w, h, &valid);
    cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 2);
    l.field = OrientationField(img, valid);
    return im.oc_levels.emplace(key, std::move(l)).first->second;
  };
  const Eigen::Vector2d north_px = HeadingToPixelDirection(0.0);
  const double grid_rot = std::atan2(north_px.x(), -north_px.y());  // map north vs -y
  const cv::Mat frame_valid =
      pf.valid.empty() ? cv::Mat(gray.size(), CV_8U, cv::Scalar(255)) : pf.valid;
  const cv::Point2d fc(gray.cols / 2.0, gray.rows / 2.0);
  // The search finds the work image's centre; the prior is the vehicle's (nadir) position. A
  // tilted view's centre lies ahead of (or beside) the vehicle: move the search area by that
  // offset in the prior heading's direction, widened by what the heading and altitude leave open
  // (the whole circle when the heading is unknown).
  if (!global) {
    const Eigen::Vector2d offset_w = Eigen::Vector2d(fc.x, fc.y) - pf.nadir_work;
    const double offset_px = offset_w.norm() * frame_gsd / db.map_gsd_m;
    if (prior.heading_deg) {
      const double ang = *prior.heading_deg * kDeg + grid_rot;
      const Eigen::Matrix2d rot =
          (Eigen::Matrix2d() << std::cos(ang), -std::sin(ang), std::sin(ang), std::cos(ang))
              .finished();
      c_px += rot * offset_w * (frame_gsd / db.map_gsd_m);
      radius_px += offset_px * (prior.heading_sigma_deg * kDeg + (max_scale - 1.0) + 0.05);
    } else {
      radius_px += offset_px * max_scale;
    }
  }

  // Correlates the frame, rotated to each heading and scaled by each factor, with the map
  // around `centre` (map px) within `radius_px` (map px). Returns the best peak (map pixels of
  // the work image's centre) of each heading and scale, best first.
  const auto by_score = [](const OcPeak& x, const OcPeak& y) { return x.score > y.score; };
  auto correlate = [&](const OcLevel& lv, const std::vector<double>& headings,
                       const std::vector<double>& factors, const Eigen::Vector2d& centre,
                       double radius_px) {
    std::vector<OcPeak> peaks;
    const double to_map = lv.gsd / db.map_gsd_m;
    const int patch = static_cast<int>(std::ceil(diag_m / lv.gsd)) | 1;
    const double pc = patch / 2.0;
    const double radius_w = radius_px / to_map;
    // Centre in level px (level pixel i's centre is at map (i + 0.5) x to_map).
    const Eigen::Vector2d cw = centre / to_map - Eigen::Vector2d(0.5, 0.5);
    // Patch placements searched: top-left corners T in [t0, t0 + span] (level px), the work
    // image's centre then at T + pc. The FFT block holds the map from t0 to t0 + span + patch,
    // so the correlation is exact (no wrap-around) at every placement searched, and a local
    // search costs a block little larger than the patch.
    const int tx0 = static_cast<int>(std::floor(cw.x() - radius_w - pc));
    const int ty0 = static_cast<int>(std::floor(cw.y() - radius_w - pc));
    const int span_x = static_cast<int>(std::ceil(cw.x() + radius_w - pc)) - tx0;
    const int span_y = static_cast<int>(std::ceil(cw.y() + radius_w - pc)) - ty0;
    // A rectangular block: the whole map is wider than high.
    const int nx = cv::getOptimalDFTSize(span_x + patch + 1);
    const int ny = cv::getOptimalDFTSize(span_y + patch + 1);
    const cv::Rect want(tx0, ty0, span_x + patch, span_y + patch);
    const cv::Rect src = want & cv::Rect(0, 0, lv.field.cols, lv.field.rows);
    // A few placements (the refinement around a peak) are cheaper to correlate directly than
    // through transforms of the whole block: 49 placements of a 191 px patch cost a third of one
    // 200 x 200 transform.
    const bool direct = (span_x + 1) * (span_y + 1) <= kDirectPlacements;
    cv::Mat padded = cv::Mat::zeros(ny, nx, CV_32FC2), map_spec;
    if (src.area() > 0) {
      lv.field(src).copyTo(padded(cv::Rect(src.x - tx0, src.y - ty0, src.width, src.height)));
    }
    if (!direct) cv::dft(padded, map_spec, cv::DFT_COMPLEX_OUTPUT);
    // The best placement of one heading and scale within the search disc, and the best one
    // outside its neighbourhood (the distinctness of the peak).
    auto add_peak = [&](const cv::Mat& corr, double h, double factor, double weight) {
      // corr(j, i): the patch's top-left corner at level px (tx0 + i, ty0 + j).
      auto at = [&](int x, int y) {
        return static_cast<double>(
            corr.at<float>(std::clamp(y, 0, span_y), std::clamp(x, 0, span_x)));
      };
      auto inside = [&](int x, int y) {
        const double dx = tx0 + x + pc - cw.x(), dy = ty0 + y + pc - cw.y();
        return dx * dx + dy * dy <= radius_w * radius_w;
      };
      double best_here = -1e300, second_here = -1e300;
      int bx = 0, by = 0;
      for (int y = 0; y <= span_y; ++y) {
        const float* row = corr.ptr<float>(y);
        for (int x = 0; x <= span_x; ++x) {
          if (row[x] <= best_here || !inside(x, y)) continue;
          best_here = row[x];
          bx = x;
          by = y;
        }
      }
      if (best_here == -1e300) return;
      const int excl = std::max(3, patch / 8);
      for (int y = 0; y <= span_y; ++y) {
        const float* row = corr.ptr<float>(y);
        for (int x = 0; x <= span_x; ++x) {
          if (std::abs(x - bx) <= excl && std::abs(y - by) <= excl) continue;
          if (row[x] <= second_here || !inside(x, y)) continue;
          second_here = row[x];
        }
      }
      const double c0 = at(bx, by);
      const double dxx = at(bx - 1, by) - 2 * c0 + at(bx + 1, by);
      const double dyy = at(bx, by - 1) - 2 * c0 + at(bx, by + 1);
      const double sx = dxx < 0 ? 0.5 * (at(bx - 1, by) - at(bx + 1, by)) / dxx : 0.0;
      const double sy = dyy < 0 ? 0.5 * (at(bx, by - 1) - at(bx, by + 1)) / dyy : 0.0;
      const double px = tx0 + bx + std::clamp(sx, -0.5, 0.5) + pc;
      const double py = ty0 + by + std::clamp(sy, -0.5, 0.5) + pc;
      peaks.push_back({best_here / weight, (px + 0.5) * to_map, (py + 0.5) * to_map, h,
                       second_here > -1e300 ? second_here / weight : 0, factor});
    };
    // The correlation surface is Re(IDFT(M conj(P))). Two of them share one complex inverse:
    // with H(k) = (X(k) + conj(X(-k))) / 2, IDFT(H) is the real part of IDFT(X), so
    // IDFT(H_a + i H_b) holds surface a in its real and b in its imaginary channel.
    struct Pending {
      cv::Mat spec;
      double heading, factor, weight;
    };
    std::vector<Pending> pending;
    cv::Mat packed(ny, nx, CV_32FC2), both, surfaces[2], spec_buffers[2];
    auto flush = [&]() {
      if (pending.empty()) return;
      const cv::Mat& a = pending[0].spec;
      const cv::Mat& b = pending.size() == 2 ? pending[1].spec : pending[0].spec;
      const float bw = pending.size() == 2 ? 0.5f : 0.f;
      for (int r = 0; r < ny; ++r) {
        const cv::Vec2f* ar = a.ptr<cv::Vec2f>(r);
        const cv::Vec2f* am = a.ptr<cv::Vec2f>(r == 0 ? 0 : ny - r);
        const cv::Vec2f* br = b.ptr<cv::Vec2f>(r);
        const cv::Vec2f* bm = b.ptr<cv::Vec2f>(r == 0 ? 0 : ny - r);
        cv::Vec2f* o = packed.ptr<cv::Vec2f>(r);
        for (int c = 0; c < nx; ++c) {
          const int cm = c == 0 ? 0 : nx - c;
          // H_a = (a + conj(a_m)) / 2, H_b likewise; packed = H_a + i H_b.
          const float har = 0.5f * (ar[c][0] + am[cm][0]), hai = 0.5f * (ar[c][1] - am[cm][1]);
          const float hbr = bw * (br[c][0] + bm[cm][0]), hbi = bw * (br[c][1] - bm[cm][1]);
          o[c] = {har - hbi, hai + hbr};
        }
      }
      cv::idft(packed, both, cv::DFT_SCALE | cv::DFT_COMPLEX_OUTPUT);
      cv::split(both, surfaces);
      for (size_t i = 0; i < pending.size(); ++i) {
        add_peak(surfaces[i], pending[i].heading, pending[i].factor, pending[i].weight);
      }
      pending.clear();
    };
    cv::Mat patch_padded = cv::Mat::zeros(ny, nx, CV_32FC2), patch_spec, direct_corr;
    for (double factor : factors) {
      // The frame's field once per scale, on a canvas at the level's resolution: canvas
      // q = s (f - fc) + qc. Each heading rotates that field instead of re-deriving it from a
      // rotated image: a rotation by a turns the doubled-angle vectors by 2a.
      const double s = frame_gsd * factor / lv.gsd;
      const int qw = static_cast<int>(std::ceil(gray.cols * s)) + 4;
      const int qh = static_cast<int>(std::ceil(gray.rows * s)) + 4;
      const cv::Point2d qc(qw / 2.0, qh / 2.0);
      const cv::Matx23d to_canvas(s, 0, qc.x - s * fc.x, 0, s, qc.y - s * fc.y);
      cv::Mat scaled, scaled_valid;
      cv::warpAffine(gray, scaled, to_canvas, cv::Size(qw, qh),
                     s < 1 ? cv::INTER_AREA : cv::INTER_LINEAR, cv::BORDER_CONSTANT);
      cv::warpAffine(frame_valid, scaled_valid, to_canvas, cv::Size(qw, qh), cv::INTER_NEAREST,
                     cv::BORDER_CONSTANT);
      cv::erode(scaled_valid, scaled_valid, cv::Mat(), cv::Point(-1, -1), 2);
      const cv::Mat field = OrientationField(scaled, scaled_valid);
      // The field's total magnitude, which a rotation keeps (the patch holds the whole canvas).
      const double weight = FieldEnergy(field);
      if (weight < 1.0) continue;  // no structure at this scale
      for (double h : headings) {
        const double ang = h * kDeg + grid_rot;
        const double ca = std::cos(ang), sa = std::sin(ang);
        // patch u = R(a) (q - qc) + pc; RotateField takes the inverse map u -> q.
        cv::Matx23d to_q(ca, sa, 0, -sa, ca, 0);
        to_q(0, 2) = qc.x - (to_q(0, 0) * pc + to_q(0, 1) * pc);
        to_q(1, 2) = qc.y - (to_q(1, 0) * pc + to_q(1, 1) * pc);
        // The warped field turned by e^(2ia) into the block (outside the patch: zeros, never
        // written).
        cv::Mat patch_roi = patch_padded(cv::Rect(0, 0, patch, patch));
        RotateField(field, to_q, 2 * ang, &patch_roi);
        if (direct) {
          CorrelateSmall(padded(cv::Rect(0, 0, span_x + patch, span_y + patch)), patch_roi,
                         &direct_corr);
          add_peak(direct_corr, h, factor, weight);
          continue;
        }
        cv::dft(patch_padded, patch_spec, cv::DFT_COMPLEX_OUTPUT, patch);  // rows >= patch are 0
        // Two spectrum buffers, reused: a fresh map-sized allocation per heading costs page
        // faults comparable to the transform itself.
        cv::Mat& spec = spec_buffers[pending.size()];
        cv::mulSpectrums(map_spec, patch_spec, spec, 0, /*conjB=*/true);
        pending.push_back({spec, h, factor, weight});
        if (pending.size() == 2) flush();
      }
    }
    flush();
    std::sort(peaks.begin(), peaks.end(), by_score);
    return peaks;
  };

  const OcLevel& coarse = level(coarse_gsd);
  r.times.extraction_ms = stage.ElapsedSeconds() * 1e3;
  stage.Restart();
  std::vector<double> headings;
  const double step = im.options.oc_heading_step_deg;
  // The transform search steps kSparseWithHeading (kSparseCircle over the full circle around a
  // prior, kSparseGlobal map-wide) times the heading step; the best few distinct places are then
  // refined at +-half that spacing by direct correlation (a few placements: a tenth of a
  // transform each). The global pre-search's seeds get the same refinement at the coarse level.
  double spacing = step;
  if (prior.heading_deg) {
    const double sigma = std::max(0.0, prior.heading_sigma_deg);
    const int k = static_cast<int>(std::ceil(sigma / (step * kSparseWithHeading)));
    spacing = sigma / std::max(k, 1);
    for (int i = -k; i <= k; ++i) headings.push_back(*prior.heading_deg + i * spacing);
  } else {
    spacing = step * (global ? kSparseGlobal : kSparseCircle);
    for (double h = 0; h < 360.0 - 1e-9; h += spacing) headings.push_back(h);
  }
  const bool refine_headings = spacing > step && !headings.empty();
  const double exclusion_px = 0.25 * diag_m / db.map_gsd_m;
  auto distinct_places = [&](const std::vector<OcPeak>& peaks, int count) {
    std::vector<OcPeak> out;
    for (const OcPeak& p : peaks) {
      bool distinct = true;
      for (const OcPeak& q : out)
        distinct = distinct && std::hypot(p.x - q.x, p.y - q.y) > exclusion_px;
      if (distinct) out.push_back(p);
      if (static_cast<int>(out.size()) >= count) break;
    }
    return out;
  };
  // The similarity work px -> map px of a peak: map = centre + k R(a) (w - fc).
  auto similarity = [&](const OcPeak& p) {
    const double ang = p.heading * kDeg + grid_rot;
    const double k = frame_gsd * p.scale / db.map_gsd_m;
    Eigen::Matrix3d m;
    m << k * std::cos(ang), -k * std::sin(ang), 0, k * std::sin(ang), k * std::cos(ang), 0, 0, 0, 1;
    m.block<2, 1>(0, 2) =
        Eigen::Vector2d(p.x, p.y) - m.block<2, 2>(0, 0) * Eigen::Vector2d(fc.x, fc.y);
    return m;
  };
  const double block_gsd = rung(std::max(0, fine_k - 4));
  const OcLevel& block_level = level(block_gsd);
  const OcLevel& fine_level = level(fine_gsd);
  struct Candidate {
    OcPeak peak;  // refined at the fine level
    Eigen::Matrix3d map_from_work;
    std::vector<Eigen::Vector2d> work_pts, map_pts;  // inliers
    features::HomographyResult h;
  };
  // Verification and refinement. Each candidate place (the best coarse peak; globally the best
  // few distinct ones, since a map-wide search meets look-alikes) is refined by block matching:
  // the frame, warped by the peak's similarity, is cut into blocks, each correlated with the map
  // around its predicted place. Consistent block shifts (a homography) carry what a similarity
  // cannot (the tilt left by an attitude error, perspective, the exact scale), so the camera
  // pose comes from the image as with features; their number verifies the place.
  auto verify = [&](const OcPeak& p) {
    Candidate c;
    // Two passes: wide shifts on the fine level from the peak's similarity, then small ones at
    // the blocks' resolution from the homography of the first.
    std::vector<Eigen::Vector2d> work_pts, map_pts;
    // The peak refined at the fine level over scale (+-5 %, the coarse search steps 10 % when the
    // altitude is known to ~10 %); the heading is left to the blocks' homography (refining it here
    // too, 9 correlations instead of 3, changed no acceptance figure).
    const std::vector<OcPeak> f =
        correlate(fine_level, {p.heading}, {p.scale * 0.95, p.scale, p.scale * 1.05}, {p.x, p.y},
                  1.5 * coarse_gsd / db.map_gsd_m);
    c.peak = !f.empty() && f[0].score > 0 ? f[0] : p;
    Eigen::Matrix3d predicted = similarity(c.peak);
    const double k = frame_gsd * p.scale / db.map_gsd_m;
    BlockMatches(fine_level, gray, frame_valid, predicted, fine_gsd / db.map_gsd_m, 5, 24,
                 &work_pts, &map_pts);
    const features::HomographyResult h1 =
        FitBlockHomography(work_pts, map_pts, 1.2 * fine_gsd / db.map_gsd_m, 6, k);
    if (h1.ok) predicted = ToEigen(h1.H);
    work_pts.clear();
    map_pts.clear();
    BlockMatches(block_level, gray, frame_valid, predicted, block_gsd / db.map_gsd_m, 3, 24,
                 &work_pts, &map_pts);
    c.h = FitBlockHomography(work_pts, map_pts, 1.0 * block_gsd / db.map_gsd_m, 8, k);
    if (c.h.ok) {
      for (size_t i = 0; i < work_pts.size(); ++i) {
        if (!c.h.inlier_mask[i]) continue;
        c.work_pts.push_back(work_pts[i]);
        c.map_pts.push_back(map_pts[i]);
      }
      c.map_from_work = ToEigen(c.h.H);
    }
    return c;
  };
  // Map-wide without a heading, the full circle is searched first on a level 1.41x coarser (half
  // the transform per heading and scale), and the best few distinct places of that search are
  // correlated again at the coarse level around their heading and scale; only when none of them
  // is confirmed is the coarse level searched itself. Measured (bench/RESULTS.md): the pre-search
  // alone confirms 57/60 frames within 25 m against 58/60 for the coarse search, at 0.4x the
  // time (twice as coarse lost 5 of 20). With a prior the search stays at the coarse level (a
  // pre-search there gave 2 wrong fixes of 50 without a heading). `search_peaks` is the full
  // search, whose best and second-best place give the peak's distinctness.
  // The best `places` distinct places of a search, each correlated again at the coarse level
  // (directly: a few placements within `radius_px` map px) at its scale and at its heading +-
  // half the search's spacing; best first.
  auto refine_at_coarse = [&](const std::vector<OcPeak>& peaks, int places, double radius_px) {
    std::vector<OcPeak> out;
    for (const OcPeak& seed : distinct_places(peaks, places)) {
      const double d = spacing / 2;
      const std::vector<OcPeak> refined =
          correlate(coarse, {seed.heading - d, seed.heading, seed.heading + d}, {seed.scale},
                    {seed.x, seed.y}, radius_px);
      if (!refined.empty()) out.push_back(refined[0]);
    }
    std::sort(out.begin(), out.end(), by_score);
    return out;
  };
  std::vector<OcPeak> search_peaks;
  std::vector<Candidate> candidates;
  size_t bi = 0, runner_up = 0;
  bool confirmed = false;
  const bool with_pre_search = global && !prior.heading_deg;
  for (const bool pre_search : {true, false}) {
    if (pre_search && !with_pre_search) continue;  // one search, at the coarse level
    std::vector<OcPeak> coarse_peaks;
    if (pre_search) {
      const double coarser_gsd = rung(fine_k + 6);
      search_peaks = correlate(level(coarser_gsd), headings, scales, c_px, radius_px);
      coarse_peaks = refine_at_coarse(search_peaks, 2 * im.options.oc_global_verify,
                                      1.5 * coarser_gsd / db.map_gsd_m);
    } else {
      coarse_peaks = search_peaks = correlate(coarse, headings, scales, c_px, radius_px);
      if (refine_headings) {
        coarse_peaks = refine_at_coarse(
            search_peaks, prior.heading_deg ? kRefinedPlacesWithHeading : kRefinedPlacesCircle,
            1.5 * coarse_gsd / db.map_gsd_m);
      }
    }
    if (coarse_peaks.empty() || coarse_peaks[0].score <= 0) {
      if (pre_search) continue;
      return a.Fail("no gradient structure to correlate (textureless frame or map)");
    }
    candidates.clear();
    for (const OcPeak& p : distinct_places(coarse_peaks, im.options.oc_global_verify)) {
      candidates.push_back(verify(p));
      // With a prior the best peak is usually right: the next places are verified only when
      // the blocks do not confirm it clearly (globally every place is, to compare them).
      if (!global && candidates.back().work_pts.size() >= 2u * im.options.oc_min_block_inliers)
        break;
    }
    bi = 0;
    for (size_t i = 1; i < candidates.size(); ++i)
      if (candidates[i].work_pts.size() > candidates[bi].work_pts.size()) bi = i;
    runner_up = 0;
    for (size_t i = 0; i < candidates.size(); ++i)
      if (i != bi) runner_up = std::max(runner_up, candidates[i].work_pts.size());
    // Distinct: the blocks confirm one place far better than any other candidate (globally the
    // coarse peaks of look-alike places are close in score), or (below) the coarse peak stands
    // out.
    const size_t n = candidates[bi].work_pts.size();
    confirmed = n >= static_cast<size_t>(im.options.oc_min_block_inliers) && n >= 2 * runner_up;
    if (confirmed) break;
  }
  r.times.matching_ms = stage.ElapsedSeconds() * 1e3;
  stage.Restart();
  const Candidate& best = candidates[bi];
  const OcPeak& c0 = search_peaks[0];
  const double peak_ratio = c0.second > 0 ? c0.score / c0.second : 10.0;
  const size_t verified = best.work_pts.size();
  r.inliers = static_cast<int>(verified);
  r.inlier_ratio = best.h.inlier_ratio;
  r.confidence =
      std::clamp(std::max(peak_ratio - 1.0,
                          confirmed ? verified / (2.0 * im.options.oc_min_block_inliers) : 0),
                 0.0, 1.0);
  if (!confirmed && (global || im.options.oc_require_blocks || prior.require_confirmed ||
                     peak_ratio < im.options.oc_min_peak_ratio)) {
    r.times.estimation_ms = stage.ElapsedSeconds() * 1e3;
    return a.Fail(
        global ? fmt::format("no place confirmed: {} consistent block matches (need {} and twice "
                             "the next place's {})",
                             verified, im.options.oc_min_block_inliers, runner_up)
               : fmt::format("correlation peak not distinctive (ratio {:.2f} < {:.2f}, {} block "
                             "matches, next place {})",
                             peak_ratio, im.options.oc_min_peak_ratio, verified, runner_up));
  }
  // Position error without the blocks: the coarse level's resolution, and the attitude's error
  // over the altitude (the nadir comes from the given roll/pitch; level assumed when none given).
  const double alt = prior.altitude_m.value_or(db.options.altitude_m);
  const double att_sigma = prior.roll_deg || prior.pitch_deg ? prior.attitude_sigma_deg : 5.0;
  const double sigma =
      std::hypot(kCorrelationSigmaScale * coarse_gsd, alt * std::tan(att_sigma * kDeg));
  const bool ok = confirmed
                      ? im.Finish(*this, pf, best.map_from_work, prior, &best.work_pts,
                                  &best.map_pts, sigma, &r, /*unknown_attitude_sigma_deg=*/3.0)
                      : im.Finish(*this, pf, similarity(candidates[0].peak), prior, nullptr,
                                  nullptr, sigma, &r);
  r.times.estimation_ms = stage.ElapsedSeconds() * 1e3;
  if (!ok) return a.Fail(r.reason);
  return a.Done();
}

}  // namespace optinav::maploc
