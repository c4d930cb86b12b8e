#include "optinav/maploc/locator.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <unordered_map>
#include <unordered_set>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "optinav/geo/raster.h"
#include "optinav/util/timer.h"

namespace optinav::maploc {

namespace {

constexpr double kDeg = M_PI / 180.0;

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

struct OcPeak {
  double score = -1e300, x = 0, y = 0, heading = 0, second = 0;
};

}  // namespace

namespace {

// The bookkeeping of one localization attempt: method, stage timing and the two exits.
struct Attempt {
  explicit Attempt(const char* method) { result.method = method; }
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
  if (top_n_per_tile < 4) return "top_n_per_tile must be >= 4";
  if (max_candidate_tiles < 1) return "max_candidate_tiles must be >= 1";
  if (!(oc_heading_step_deg > 0.1)) return "oc_heading_step_deg must be > 0.1";
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
                                                    .orb_levels = o.frame_orb_levels})) {
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

  double FrameGsd(const cv::Mat& gray, const Prior& prior) const {
    const double alt = prior.altitude_m.value_or(db.options.altitude_m);
    return 2.0 * alt * std::tan(db.options.hfov_deg * M_PI / 360.0) / gray.cols;
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
  const cv::Mat gray = ToGray(frame);
  const bool oc_possible =
      impl_->options.allow_orientation_correlation && prior.position && !gray.empty();
  const bool oc_first = oc_possible && order == Order::kCorrelationFirst;
  LocateResult first =
      oc_first ? LocateByOrientationCorrelation(gray, prior) : LocateByFeatures(gray, prior);
  if (first.localized || (!oc_first && !oc_possible)) {
    first.times.total_ms = total.ElapsedSeconds() * 1e3;
    return first;
  }
  LocateResult second =
      oc_first ? LocateByFeatures(gray, prior) : LocateByOrientationCorrelation(gray, prior);
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

LocateResult Locator::LocateByFeatures(const cv::Mat& frame, const Prior& prior) {
  Impl& im = *impl_;
  const MapDatabase& db = im.db;
  Attempt a("features");
  LocateResult& r = a.result;
  Timer& stage = a.stage;
  const cv::Mat gray = ToGray(frame);
  if (gray.empty()) return a.Fail("empty frame");
  // Bring the frame to the resolution the map's features were taken at.
  const double frame_gsd = im.FrameGsd(gray, prior);
  double to_feature = frame_gsd / db.feature_gsd_m;
  cv::Mat work = gray;
  if (prior.altitude_m && std::abs(to_feature - 1.0) > 0.15) {
    cv::resize(gray, work, cv::Size(), to_feature, to_feature,
               to_feature < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  } else {
    to_feature = 1.0;
  }
  const features::Features ff = im.extractor->Extract(work);
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
    const auto votes_m =
        features::MatchWithRatio(query, im.all_descriptors, ff.norm, im.options.ratio);
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
    const auto matches = features::MatchWithRatio(ff.descriptors, train, ff.norm, im.options.ratio);
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
  const cv::Point2d c(gray.cols / 2.0, gray.rows / 2.0);
  const cv::Point2d mc = features::ApplyHomography(h.H, c);
  const cv::Point2d up = features::ApplyHomography(h.H, c + cv::Point2d(0, -gray.rows / 4.0));
  r.map_px = {mc.x, mc.y};
  if (mc.x < 0 || mc.y < 0 || mc.x > db.width || mc.y > db.height) {
    return a.Fail("the frame centre maps outside the map");
  }
  const cv::Matx22d j = features::HomographyJacobian(h.H, c);
  r.scale = std::sqrt(std::abs(j(0, 0) * j(1, 1) - j(0, 1) * j(1, 0)));
  r.altitude_m =
      r.scale * db.map_gsd_m * gray.cols / (2.0 * std::tan(db.options.hfov_deg * M_PI / 360.0));
  r.heading_deg = PixelDirectionToHeading({up.x - mc.x, up.y - mc.y});
  r.crs_xy = db.transform.PixelToCrs(r.map_px);
  r.latlon = im.crs.ToLatLon(r.crs_xy);
  // Confidence grows with inliers (saturating) and their share of the matches.
  r.confidence = std::min(1.0, h.inliers / 60.0) * std::min(1.0, 0.5 + h.inlier_ratio);
  return a.Done();
}

LocateResult Locator::LocateByOrientationCorrelation(const cv::Mat& frame, const Prior& prior) {
  Impl& im = *impl_;
  const MapDatabase& db = im.db;
  Attempt a("orientation-correlation");
  LocateResult& r = a.result;
  Timer& stage = a.stage;
  const cv::Mat gray = ToGray(frame);
  if (gray.empty()) return a.Fail("empty frame");
  if (!prior.position) {
    return a.Fail("orientation correlation needs a prior position");
  }
  const geo::GeoRaster* ortho = im.Ortho();
  if (!ortho) {
    return a.Fail("orthophoto unavailable for orientation correlation: " + im.ortho_error);
  }
  const Eigen::Vector2d c_px = LatLonToPixel(*prior.position);
  if (c_px.x() < -db.width * 0.1 || c_px.y() < -db.height * 0.1 || c_px.x() > db.width * 1.1 ||
      c_px.y() > db.height * 1.1) {
    return a.Fail("the prior lies outside the map");
  }
  const double frame_gsd = im.FrameGsd(gray, prior);
  const double frame_extent_m = std::max(gray.cols, gray.rows) * frame_gsd;
  const double diag_m = std::hypot(gray.cols, gray.rows) * frame_gsd;
  // Coarse level: the frame about `oc_coarse_px` across; fine level: twice that resolution
  // (never finer than the map or the frame).
  const double fine_gsd =
      std::max({db.map_gsd_m, frame_gsd, frame_extent_m / (2.0 * im.options.oc_coarse_px)});
  const double coarse_gsd = 2.0 * fine_gsd;
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
  const cv::Mat ones(gray.size(), CV_8U, cv::Scalar(255));

  // Correlates the frame, rotated to each heading, with the map around `centre` (map px)
  // within `radius_px` (map px). Returns the best peak in map pixels.
  auto correlate = [&](const OcLevel& lv, const std::vector<double>& headings,
                       const Eigen::Vector2d& centre, double radius_px) {
    OcPeak best;
    const double to_map = lv.gsd / db.map_gsd_m;
    const double s = frame_gsd / lv.gsd;
    const int patch = static_cast<int>(std::ceil(diag_m / lv.gsd)) | 1;
    const double pc = patch / 2.0;
    const double radius_w = radius_px / to_map;
    const int half = static_cast<int>(std::ceil(radius_w + pc)) + 2;
    const int win = 2 * half + 1;
    const Eigen::Vector2d cw = centre / to_map;  // centre in level px
    const int wx = static_cast<int>(std::lround(cw.x())) - half;
    const int wy = static_cast<int>(std::lround(cw.y())) - half;
    const double centre_w_x = cw.x() - wx, centre_w_y = cw.y() - wy;
    const int n = cv::getOptimalDFTSize(win);
    cv::Mat padded = cv::Mat::zeros(n, n, CV_32FC2), map_spec;
    const cv::Rect src = cv::Rect(wx, wy, win, win) & cv::Rect(0, 0, lv.field.cols, lv.field.rows);
    if (src.area() > 0)
      lv.field(src).copyTo(padded(cv::Rect(src.x - wx, src.y - wy, src.width, src.height)));
    cv::dft(padded, map_spec, cv::DFT_COMPLEX_OUTPUT);
    cv::Mat patch_padded(n, n, CV_32FC2), patch_spec, prod, corr;
    const cv::Point2d fc(gray.cols / 2.0, gray.rows / 2.0);
    for (double h : headings) {
      const double a = h * kDeg + grid_rot;
      const double ca = std::cos(a), sa = std::sin(a);
      // patch (u, v) -> frame: the inverse of u = s R(a) (f - fc) + pc.
      cv::Matx23d to_frame(ca / s, sa / s, 0, -sa / s, ca / s, 0);
      to_frame(0, 2) = fc.x - (to_frame(0, 0) * pc + to_frame(0, 1) * pc);
      to_frame(1, 2) = fc.y - (to_frame(1, 0) * pc + to_frame(1, 1) * pc);
      cv::Mat warped, valid;
      cv::warpAffine(gray, warped, to_frame, cv::Size(patch, patch),
                     (s < 1 ? cv::INTER_AREA : cv::INTER_LINEAR) | cv::WARP_INVERSE_MAP,
                     cv::BORDER_CONSTANT);
      cv::warpAffine(ones, valid, to_frame, cv::Size(patch, patch),
                     cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
      cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 2);
      const cv::Mat pf = OrientationField(warped, valid);
      double weight = 0;
      for (int y = 0; y < pf.rows; ++y) {
        const cv::Vec2f* p = pf.ptr<cv::Vec2f>(y);
        for (int x = 0; x < pf.cols; ++x) weight += std::hypot(p[x][0], p[x][1]);
      }
      if (weight < 1.0 || patch > n) continue;
      patch_padded.setTo(0);
      pf.copyTo(patch_padded(cv::Rect(0, 0, patch, patch)));
      cv::dft(patch_padded, patch_spec, cv::DFT_COMPLEX_OUTPUT);
      cv::mulSpectrums(map_spec, patch_spec, prod, 0, /*conjB=*/true);
      cv::idft(prod, corr, cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
      // corr(y, x): patch top-left at (x, y), frame centre at (x + pc, y + pc).
      double best_here = -1e300, second_here = -1e300;
      int bx = 0, by = 0;
      const int x_lo = std::max(0, static_cast<int>(std::floor(centre_w_x - radius_w - pc)));
      const int x_hi = std::min(n - patch, static_cast<int>(std::ceil(centre_w_x + radius_w - pc)));
      const int y_lo = std::max(0, static_cast<int>(std::floor(centre_w_y - radius_w - pc)));
      const int y_hi = std::min(n - patch, static_cast<int>(std::ceil(centre_w_y + radius_w - pc)));
      const double r2 = radius_w * radius_w;
      for (int y = y_lo; y <= y_hi; ++y) {
        const float* row = corr.ptr<float>(y);
        for (int x = x_lo; x <= x_hi; ++x) {
          const double dx = x + pc - centre_w_x, dy = y + pc - centre_w_y;
          if (dx * dx + dy * dy > r2 || row[x] <= best_here) continue;
          best_here = row[x];
          bx = x;
          by = y;
        }
      }
      if (best_here == -1e300) continue;
      const int excl = std::max(3, patch / 8);
      for (int y = y_lo; y <= y_hi; ++y) {
        const float* row = corr.ptr<float>(y);
        for (int x = x_lo; x <= x_hi; ++x) {
          if (std::abs(x - bx) <= excl && std::abs(y - by) <= excl) continue;
          const double dx = x + pc - centre_w_x, dy = y + pc - centre_w_y;
          if (dx * dx + dy * dy > r2) continue;
          second_here = std::max(second_here, static_cast<double>(row[x]));
        }
      }
      const double score = best_here / weight;
      if (score > best.score) {
        auto at = [&](int x, int y) {
          return static_cast<double>(
              corr.at<float>(std::clamp(y, 0, n - 1), std::clamp(x, 0, n - 1)));
        };
        const double c0 = at(bx, by);
        const double dxx = at(bx - 1, by) - 2 * c0 + at(bx + 1, by);
        const double dyy = at(bx, by - 1) - 2 * c0 + at(bx, by + 1);
        const double ox = dxx < 0 ? 0.5 * (at(bx - 1, by) - at(bx + 1, by)) / dxx : 0.0;
        const double oy = dyy < 0 ? 0.5 * (at(bx, by - 1) - at(bx, by + 1)) / dyy : 0.0;
        const double px = wx + bx + std::clamp(ox, -0.5, 0.5) + pc;
        const double py = wy + by + std::clamp(oy, -0.5, 0.5) + pc;
        best = {score, px * to_map, py * to_map, h,
                second_here > -1e300 ? second_here / weight : 0};
      }
    }
    return best;
  };

  const OcLevel& coarse = level(coarse_gsd);
  const OcLevel& fine = level(fine_gsd);
  r.times.extraction_ms = stage.ElapsedSeconds() * 1e3;
  stage.Restart();
  std::vector<double> headings;
  const double step = im.options.oc_heading_step_deg;
  if (prior.heading_deg) {
    const double sigma = std::max(0.0, prior.heading_sigma_deg);
    const int k = static_cast<int>(std::ceil(sigma / step));
    for (int i = -k; i <= k; ++i)
      headings.push_back(*prior.heading_deg + i * sigma / std::max(k, 1));
  } else {
    for (double h = 0; h < 360.0 - 1e-9; h += step) headings.push_back(h);
  }
  const OcPeak c = correlate(coarse, headings, c_px, prior.radius_m / db.map_gsd_m);
  if (c.score <= 0) {
    return a.Fail("no gradient structure to correlate (textureless frame or map)");
  }
  // Refine at twice the resolution around the coarse peak and heading.
  const OcPeak f = correlate(fine, {c.heading}, {c.x, c.y}, 2.5 * coarse_gsd / db.map_gsd_m);
  const OcPeak& best = f.score > 0 ? f : c;
  r.times.matching_ms = stage.ElapsedSeconds() * 1e3;
  // Distinctiveness from the coarse search, which saw the whole prior area.
  const double peak_ratio = c.second > 0 ? c.score / c.second : 10.0;
  r.confidence = std::clamp(peak_ratio - 1.0, 0.0, 1.0);
  r.map_px = {best.x, best.y};
  r.heading_deg = std::fmod(best.heading + 720.0, 360.0);
  r.scale = frame_gsd / db.map_gsd_m;
  r.altitude_m = prior.altitude_m.value_or(db.options.altitude_m);
  if (peak_ratio < im.options.oc_min_peak_ratio) {
    return a.Fail(fmt::format("correlation peak not distinctive (ratio {:.2f} < {:.2f})",
                              peak_ratio, im.options.oc_min_peak_ratio));
  }
  r.crs_xy = db.transform.PixelToCrs(r.map_px);
  r.latlon = im.crs.ToLatLon(r.crs_xy);
  return a.Done();
}

}  // namespace optinav::maploc
