#include "optinav/features/features.h"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/features/xfeat.h"

namespace optinav::features {
namespace {

class OrbExtractor : public FeatureExtractor {
 public:
  explicit OrbExtractor(const ExtractorOptions& o)
      : orb_(cv::ORB::create(o.max_features, 1.2f, o.orb_levels, 31, 0, 2, cv::ORB::HARRIS_SCORE,
                             31, o.orb_fast_threshold)) {}
  Features Extract(const cv::Mat& gray, const cv::Mat& mask) const override {
    Features f;
    f.norm = cv::NORM_HAMMING;
    orb_->detectAndCompute(gray, mask, f.keypoints, f.descriptors);
    return f;
  }
  std::string name() const override { return "orb"; }
  int norm() const override { return cv::NORM_HAMMING; }
  int descriptor_type() const override { return CV_8U; }
  int descriptor_size() const override { return 32; }

 private:
  cv::Ptr<cv::ORB> orb_;
};

class BriskExtractor : public FeatureExtractor {
 public:
  explicit BriskExtractor(const ExtractorOptions& o)
      : brisk_(cv::BRISK::create()), max_(o.max_features) {}
  Features Extract(const cv::Mat& gray, const cv::Mat& mask) const override {
    Features f;
    f.norm = cv::NORM_HAMMING;
    brisk_->detect(gray, f.keypoints, mask);
    cv::KeyPointsFilter::retainBest(f.keypoints, max_);
    brisk_->compute(gray, f.keypoints, f.descriptors);
    return f;
  }
  std::string name() const override { return "brisk"; }
  int norm() const override { return cv::NORM_HAMMING; }
  int descriptor_type() const override { return CV_8U; }
  int descriptor_size() const override { return 64; }

 private:
  cv::Ptr<cv::BRISK> brisk_;
  int max_;
};

class SiftExtractor : public FeatureExtractor {
 public:
  explicit SiftExtractor(const ExtractorOptions& o) : sift_(cv::SIFT::create(o.max_features)) {}
  Features Extract(const cv::Mat& gray, const cv::Mat& mask) const override {
    Features f;
    f.norm = cv::NORM_L2;
    sift_->detectAndCompute(gray, mask, f.keypoints, f.descriptors);
    return f;
  }
  std::string name() const override { return "sift"; }
  int norm() const override { return cv::NORM_L2; }
  int descriptor_type() const override { return CV_32F; }
  int descriptor_size() const override { return 128; }

 private:
  cv::Ptr<cv::SIFT> sift_;
};

}  // namespace

std::optional<FeatureType> ParseFeatureType(const std::string& name) {
  if (name == "orb") return FeatureType::kOrb;
  if (name == "sift") return FeatureType::kSift;
  if (name == "brisk") return FeatureType::kBrisk;
  if (name == "xfeat") return FeatureType::kXFeat;
  return std::nullopt;
}

std::string FeatureTypeName(FeatureType type) {
  switch (type) {
    case FeatureType::kOrb:
      return "orb";
    case FeatureType::kSift:
      return "sift";
    case FeatureType::kBrisk:
      return "brisk";
    case FeatureType::kXFeat:
      return "xfeat";
  }
  return "?";
}

DescriptorFormat DescriptorFormatOf(FeatureType type) {
  switch (type) {
    case FeatureType::kOrb:
      return {CV_8U, 32, cv::NORM_HAMMING};
    case FeatureType::kBrisk:
      return {CV_8U, 64, cv::NORM_HAMMING};
    case FeatureType::kSift:
      return {CV_32F, 128, cv::NORM_L2};
    case FeatureType::kXFeat:
      return {CV_32F, kXFeatDescriptorSize, cv::NORM_L2};
  }
  return {};
}

std::string ExtractorOptions::Check() const {
  if (max_features < 4 || max_features > 100000) {
    return "max_features must be in [4, 100000], got " + std::to_string(max_features);
  }
  if (orb_fast_threshold < 1 || orb_fast_threshold > 100)
    return "orb_fast_threshold must be in [1, 100]";
  if (orb_levels < 1 || orb_levels > 16) return "orb_levels must be in [1, 16]";
  if (!(xfeat_scale >= 0 && xfeat_scale <= 8)) return "xfeat_scale must be in [0, 8]";
  if (threads < 0) return "threads must be >= 0";
  return "";
}

std::unique_ptr<FeatureExtractor> CreateFeatureExtractor(const ExtractorOptions& options) {
  if (options.type == FeatureType::kSift) return std::make_unique<SiftExtractor>(options);
  if (options.type == FeatureType::kBrisk) return std::make_unique<BriskExtractor>(options);
  if (options.type == FeatureType::kXFeat) return CreateXFeatExtractor(options);
  return std::make_unique<OrbExtractor>(options);
}

Features ExtractAffineSimulated(const FeatureExtractor& extractor, const cv::Mat& gray,
                                double max_tilt) {
  Features out;
  out.norm = extractor.norm();
  std::vector<cv::Mat> descriptors;
  for (double t = 1.0; t <= max_tilt + 1e-9; t *= std::sqrt(2.0)) {
    const double step_deg = t == 1.0 ? 180.0 : 72.0 / t;
    for (double phi = 0; phi < 180.0 - 1e-9; phi += step_deg) {
      // view_from_image: rotate by phi into a canvas holding the whole image, squeeze x by t.
      cv::Matx23d a(1, 0, 0, 0, 1, 0);
      cv::Mat view = gray;
      if (phi != 0) {
        const double c = std::cos(phi * CV_PI / 180), s = std::sin(phi * CV_PI / 180);
        std::vector<cv::Point2f> corners = {
            {0, 0},
            {static_cast<float>(gray.cols), 0},
            {static_cast<float>(gray.cols), static_cast<float>(gray.rows)},
            {0, static_cast<float>(gray.rows)}};
        for (auto& p : corners) p = cv::Point2f(c * p.x - s * p.y, s * p.x + c * p.y);
        const cv::Rect box = cv::boundingRect(corners);
        a = cv::Matx23d(c, -s, -box.x, s, c, -box.y);
        cv::warpAffine(gray, view, a, box.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
      }
      if (t != 1.0) {
        cv::Mat blurred;
        cv::GaussianBlur(view, blurred, cv::Size(0, 0), 0.8 * std::sqrt(t * t - 1), 0.01);
        cv::resize(blurred, view, cv::Size(0, 0), 1.0 / t, 1.0, cv::INTER_NEAREST);
        for (int k = 0; k < 3; ++k) a(0, k) /= t;
      }
      Features f = extractor.Extract(view);
      cv::Matx23d inv;
      cv::invertAffineTransform(a, inv);
      for (auto& kp : f.keypoints) {
        const cv::Point2f p = kp.pt;
        kp.pt = cv::Point2f(inv(0, 0) * p.x + inv(0, 1) * p.y + inv(0, 2),
                            inv(1, 0) * p.x + inv(1, 1) * p.y + inv(1, 2));
      }
      out.keypoints.insert(out.keypoints.end(), f.keypoints.begin(), f.keypoints.end());
      if (!f.descriptors.empty()) descriptors.push_back(f.descriptors);
    }
  }
  if (!descriptors.empty()) cv::vconcat(descriptors, out.descriptors);
  return out;
}

Features ExtractRotated(const FeatureExtractor& extractor, const cv::Mat& gray, const cv::Mat& mask,
                        const std::vector<double>& angles_rad) {
  Features out;
  out.norm = extractor.norm();
  std::vector<cv::Mat> descriptors;
  const cv::Mat valid = mask.empty() ? cv::Mat(gray.size(), CV_8U, cv::Scalar(255)) : mask;
  const cv::Point2d centre((gray.cols - 1) / 2.0, (gray.rows - 1) / 2.0);
  for (const double angle : angles_rad) {
    const double c = std::cos(angle), s = std::sin(angle);
    const int w = static_cast<int>(std::ceil(std::abs(c) * gray.cols + std::abs(s) * gray.rows));
    const int h = static_cast<int>(std::ceil(std::abs(s) * gray.cols + std::abs(c) * gray.rows));
    // view = R (image - centre) + view centre.
    const cv::Point2d vc((w - 1) / 2.0, (h - 1) / 2.0);
    const cv::Matx23d a(c, -s, vc.x - (c * centre.x - s * centre.y), s, c,
                        vc.y - (s * centre.x + c * centre.y));
    cv::Mat view, view_mask;
    cv::warpAffine(gray, view, a, cv::Size(w, h), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    cv::warpAffine(valid, view_mask, a, cv::Size(w, h), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
    // Keep detections off the rotated border, where the edge itself looks like structure.
    cv::erode(view_mask, view_mask, cv::Mat(), cv::Point(-1, -1), 3);
    Features f = extractor.Extract(view, view_mask);
    cv::Matx23d inv;
    cv::invertAffineTransform(a, inv);
    for (auto& kp : f.keypoints) {
      const cv::Point2f p = kp.pt;
      kp.pt = cv::Point2f(static_cast<float>(inv(0, 0) * p.x + inv(0, 1) * p.y + inv(0, 2)),
                          static_cast<float>(inv(1, 0) * p.x + inv(1, 1) * p.y + inv(1, 2)));
    }
    out.keypoints.insert(out.keypoints.end(), f.keypoints.begin(), f.keypoints.end());
    if (!f.descriptors.empty()) descriptors.push_back(f.descriptors);
  }
  if (!descriptors.empty()) cv::vconcat(descriptors, out.descriptors);
  return out;
}

namespace {

// Brute-force 2-NN for binary descriptors whose width is a multiple of 8 bytes: XOR + POPCNT on
// 64-bit words (every x86-64 CPU since 2008 has POPCNT; the attribute enables it here only).
__attribute__((target("popcnt"))) void Hamming2Nn(const cv::Mat& query, const cv::Mat& train,
                                                  float ratio, std::vector<cv::DMatch>* out) {
  const int words = query.cols / 8;
  for (int q = 0; q < query.rows; ++q) {
    const uint64_t* a = query.ptr<uint64_t>(q);
    int best = INT32_MAX, second = INT32_MAX, best_idx = -1;
    for (int t = 0; t < train.rows; ++t) {
      const uint64_t* b = train.ptr<uint64_t>(t);
      int d;
      if (words == 4) {  // ORB: 256 bits
        d = __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
            __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
      } else {
        d = 0;
        for (int w = 0; w < words; ++w) d += __builtin_popcountll(a[w] ^ b[w]);
      }
      if (d < second) {
        if (d < best) {
          second = best;
          best = d;
          best_idx = t;
        } else {
          second = d;
        }
      }
    }
    if (best_idx < 0) continue;
    if (train.rows == 1 || best < ratio * second) {
      out->emplace_back(q, best_idx, static_cast<float>(best));
    }
  }
}

}  // namespace

std::vector<cv::DMatch> MatchWithRatio(const cv::Mat& query, const cv::Mat& train, int norm,
                                       float ratio) {
  std::vector<cv::DMatch> out;
  if (query.empty() || train.empty()) return out;
  if (norm == cv::NORM_HAMMING && query.type() == CV_8U && train.type() == CV_8U &&
      query.cols == train.cols && query.cols % 8 == 0 && query.isContinuous() &&
      train.isContinuous()) {
    Hamming2Nn(query, train, ratio, &out);
    std::sort(out.begin(), out.end(),
              [](const cv::DMatch& a, const cv::DMatch& b) { return a.distance < b.distance; });
    return out;
  }
  cv::BFMatcher matcher(norm, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, train, knn, 2);
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance) {
      out.push_back(m[0]);
    } else if (m.size() == 1) {
      out.push_back(m[0]);  // a single candidate cannot be ambiguous
    }
  }
  std::sort(out.begin(), out.end(),
            [](const cv::DMatch& a, const cv::DMatch& b) { return a.distance < b.distance; });
  return out;
}

std::vector<cv::DMatch> MatchMutual(const cv::Mat& query, const cv::Mat& train, float ratio,
                                    float max_distance) {
  std::vector<cv::DMatch> out;
  if (query.empty() || train.empty()) return out;
  CV_Assert(query.type() == CV_32F && train.type() == CV_32F && query.cols == train.cols);
  // Unit vectors: |a - b|^2 = 2 - 2 a.b, so one matrix product gives every distance.
  cv::Mat sim;
  cv::gemm(query, train, 1.0, cv::noArray(), 0.0, sim, cv::GEMM_2_T);
  std::vector<int> best_query(train.rows, -1);
  std::vector<float> best_query_sim(train.rows, -2.f);
  for (int q = 0; q < sim.rows; ++q) {
    const float* row = sim.ptr<float>(q);
    for (int t = 0; t < sim.cols; ++t) {
      if (row[t] > best_query_sim[t]) {
        best_query_sim[t] = row[t];
        best_query[t] = q;
      }
    }
  }
  auto distance = [](float s) { return std::sqrt(std::max(0.f, 2.f - 2.f * s)); };
  for (int q = 0; q < sim.rows; ++q) {
    const float* row = sim.ptr<float>(q);
    float s1 = -2.f, s2 = -2.f;
    int t1 = -1;
    for (int t = 0; t < sim.cols; ++t) {
      if (row[t] > s2) {
        if (row[t] > s1) {
          s2 = s1;
          s1 = row[t];
          t1 = t;
        } else {
          s2 = row[t];
        }
      }
    }
    if (t1 < 0 || best_query[t1] != q) continue;
    const float d1 = distance(s1);
    if (d1 > max_distance) continue;
    if (sim.cols > 1 && !(d1 < ratio * distance(s2))) continue;
    out.emplace_back(q, t1, d1);
  }
  std::sort(out.begin(), out.end(),
            [](const cv::DMatch& a, const cv::DMatch& b) { return a.distance < b.distance; });
  return out;
}

std::vector<cv::DMatch> MatchFeatures(FeatureType type, const cv::Mat& query, const cv::Mat& train,
                                      float ratio) {
  if (type == FeatureType::kXFeat) return MatchMutual(query, train, ratio);
  return MatchWithRatio(query, train, DescriptorFormatOf(type).norm, ratio);
}

std::string HomographyOptions::Check() const {
  if (!(reprojection_threshold_px > 0)) return "reprojection_threshold_px must be > 0";
  if (min_inliers < 4) return "min_inliers must be >= 4";
  if (!(min_scale > 0 && max_scale > min_scale)) return "need 0 < min_scale < max_scale";
  if (!(max_anisotropy >= 1)) return "max_anisotropy must be >= 1";
  return "";
}

cv::Matx22d HomographyJacobian(const cv::Matx33d& H, const cv::Point2d& p) {
  const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
  const double w2 = v[2] * v[2];
  return {(H(0, 0) * v[2] - H(2, 0) * v[0]) / w2, (H(0, 1) * v[2] - H(2, 1) * v[0]) / w2,
          (H(1, 0) * v[2] - H(2, 0) * v[1]) / w2, (H(1, 1) * v[2] - H(2, 1) * v[1]) / w2};
}

double HomographyScale(const cv::Matx33d& H, const cv::Point2d& p) {
  const cv::Matx22d j = HomographyJacobian(H, p);
  return std::sqrt(std::abs(j(0, 0) * j(1, 1) - j(0, 1) * j(1, 0)));
}

cv::Point2d ApplyHomography(const cv::Matx33d& H, const cv::Point2d& p) {
  const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
  return {v[0] / v[2], v[1] / v[2]};
}

HomographyResult EstimateHomography(const std::vector<cv::Point2f>& src,
                                    const std::vector<cv::Point2f>& dst,
                                    const HomographyOptions& o) {
  HomographyResult r;
  if (src.size() != dst.size()) {
    r.reason = "source and destination point counts differ";
    return r;
  }
  if (static_cast<int>(src.size()) < std::max(4, o.min_inliers)) {
    r.reason = "too few matches (" + std::to_string(src.size()) + ", need " +
               std::to_string(std::max(4, o.min_inliers)) + ")";
    return r;
  }
  cv::Mat mask;
  cv::Mat h = cv::findHomography(src, dst, cv::USAC_MAGSAC, o.reprojection_threshold_px, mask,
                                 o.max_iterations, o.confidence);
  if (h.empty()) {
    r.reason = "no homography found by the robust estimator";
    return r;
  }
  r.H = cv::Matx33d(h);
  r.inlier_mask.assign(mask.begin<uint8_t>(), mask.end<uint8_t>());
  // Refine on the inliers by least squares (Levenberg-Marquardt on the reprojection error),
  // then take the inliers of the refined model.
  {
    std::vector<cv::Point2f> in_src, in_dst;
    for (size_t i = 0; i < src.size(); ++i) {
      if (r.inlier_mask[i]) {
        in_src.push_back(src[i]);
        in_dst.push_back(dst[i]);
      }
    }
    if (in_src.size() >= 8) {
      cv::Mat refined = cv::findHomography(in_src, in_dst, 0);
      if (!refined.empty()) {
        const cv::Matx33d hr(refined);
        std::vector<uint8_t> m2(src.size(), 0);
        const double t2 = o.reprojection_threshold_px * o.reprojection_threshold_px;
        int count = 0;
        for (size_t i = 0; i < src.size(); ++i) {
          const cv::Point2d p = ApplyHomography(hr, src[i]);
          const double dx = p.x - dst[i].x, dy = p.y - dst[i].y;
          m2[i] = dx * dx + dy * dy <= t2;
          count += m2[i];
        }
        if (count >= cv::countNonZero(mask)) {
          r.H = hr;
          r.inlier_mask = m2;
          mask = cv::Mat(m2, true);
        }
      }
    }
  }
  r.inliers = cv::countNonZero(mask);
  r.inlier_ratio = static_cast<double>(r.inliers) / src.size();
  if (r.inliers < o.min_inliers) {
    r.reason = "too few inliers (" + std::to_string(r.inliers) + " < " +
               std::to_string(o.min_inliers) + ")";
    return r;
  }
  if (r.inlier_ratio < o.min_inlier_ratio) {
    r.reason = "inlier ratio too low";
    return r;
  }
  // Degeneracy checks on the local linear map (Jacobian) at the inliers' centroid and at the
  // corners of their bounding box: no fold-over or mirror anywhere, plausible scale and shear
  // at the centre, and bounded perspective (local scale varies by at most `max_anisotropy`).
  cv::Point2d centre(0, 0);
  cv::Point2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (size_t i = 0; i < src.size(); ++i) {
    if (!r.inlier_mask[i]) continue;
    centre += cv::Point2d(src[i]);
    lo = {std::min(lo.x, static_cast<double>(src[i].x)),
          std::min(lo.y, static_cast<double>(src[i].y))};
    hi = {std::max(hi.x, static_cast<double>(src[i].x)),
          std::max(hi.y, static_cast<double>(src[i].y))};
  }
  centre *= 1.0 / r.inliers;
  double centre_scale = 0;
  for (const cv::Point2d& p : {centre, lo, hi, cv::Point2d(lo.x, hi.y), cv::Point2d(hi.x, lo.y)}) {
    const cv::Matx22d j = HomographyJacobian(r.H, p);
    const double det = j(0, 0) * j(1, 1) - j(0, 1) * j(1, 0);
    if (!(det > 0)) {
      r.reason = "degenerate homography (mirror or fold-over)";
      return r;
    }
    if (p == centre) {
      cv::Mat w;
      cv::SVD::compute(cv::Mat(j), w, cv::SVD::NO_UV);
      const double s1 = w.at<double>(0), s2 = w.at<double>(1);
      if (s2 < o.min_scale || s1 > o.max_scale) {
        r.reason = "implausible scale in homography";
        return r;
      }
      if (s1 / s2 > o.max_anisotropy) {
        r.reason = "implausible shear in homography";
        return r;
      }
      centre_scale = std::sqrt(det);
    } else if (std::sqrt(det) / centre_scale > o.max_anisotropy ||
               centre_scale / std::sqrt(det) > o.max_anisotropy) {
      r.reason = "implausible perspective in homography";
      return r;
    }
  }
  r.ok = true;
  return r;
}

}  // namespace optinav::features
