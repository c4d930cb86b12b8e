#include "optinav/features/xfeat.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>

#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/util/error.h"

namespace optinav::features {
namespace {

constexpr int kCells = kXFeatInputSize / 8;   // 80 cells of 8x8 px across
constexpr float kDetectionThreshold = 0.05f;  // softmax score of a keypoint pixel (XFeat's)
constexpr int kNmsRadius = 2;                 // 5x5 non-maximum suppression (XFeat's)
const char* const kOutputs[3] = {"output_feats", "output_keypoints", "output_heatmap"};

// One loaded network, shared by every extractor of the process. OpenCV's Net is not safe for
// concurrent forward passes: they take turns (the pass itself runs on OpenCV's thread pool).
struct LoadedNet {
  cv::dnn::Net net;
  std::mutex forward_mutex;
};

std::shared_ptr<LoadedNet> LoadNet(const std::string& path) {
  static std::mutex cache_mutex;
  static std::map<std::string, std::shared_ptr<LoadedNet>> cache;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(
        "XFeat model not found (give --model FILE, or set OPTINAV_SHARED_DATA to the folder "
        "holding models/xfeat_640x640.onnx)",
        {.file = path});
  }
  const std::string key = std::filesystem::canonical(path, ec).string();
  std::lock_guard<std::mutex> lock(cache_mutex);
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  auto loaded = std::make_shared<LoadedNet>();
  try {
    loaded->net = cv::dnn::readNetFromONNX(path);
  } catch (const cv::Exception& e) {
    throw Error(std::string("not an ONNX network OpenCV can read: ") + e.err, {.file = path});
  }
  if (loaded->net.empty()) throw Error("not an ONNX network OpenCV can read", {.file = path});
  loaded->net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  loaded->net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  // The export's signature: names and shapes of the outputs for a 1x1x640x640 input.
  const std::vector<std::string> outputs = loaded->net.getUnconnectedOutLayersNames();
  const cv::dnn::MatShape expected[3] = {
      {1, kCells, kCells, kXFeatDescriptorSize}, {1, kCells, kCells, 65}, {1, 1, kCells, kCells}};
  auto shape_text = [](const cv::dnn::MatShape& s) {
    std::string t;
    for (int d : s) t += (t.empty() ? "" : "x") + std::to_string(d);
    return t;
  };
  for (int k = 0; k < 3; ++k) {
    if (std::find(outputs.begin(), outputs.end(), kOutputs[k]) == outputs.end()) {
      throw Error(std::string("not the XFeat network: it has no output '") + kOutputs[k] +
                      "' (expected output_feats, output_keypoints, output_heatmap)",
                  {.file = path});
    }
    std::vector<cv::dnn::MatShape> in_shapes, out_shapes;
    try {
      loaded->net.getLayerShapes(cv::dnn::MatShape{1, 1, kXFeatInputSize, kXFeatInputSize},
                                 loaded->net.getLayerId(kOutputs[k]), in_shapes, out_shapes);
    } catch (const cv::Exception& e) {
      throw Error(std::string("not the XFeat network: it does not take a 1x1x640x640 input (") +
                      e.err + ")",
                  {.file = path});
    }
    if (out_shapes.empty() || out_shapes[0] != expected[k]) {
      throw Error(std::string("not the XFeat network: output '") + kOutputs[k] + "' is " +
                      (out_shapes.empty() ? "?" : shape_text(out_shapes[0])) +
                      " for a 1x1x640x640 input, expected " + shape_text(expected[k]),
                  {.file = path});
    }
  }
  cache.emplace(key, loaded);
  return loaded;
}

// Bilinear sample of an HxWxC (row-major, channels last) float grid at grid coordinates (u, v),
// clamped at the border; adds `weight` x the sample into out[0..C).
void SampleBilinear(const float* grid, int h, int w, int c, double u, double v, float* out) {
  u = std::clamp(u, 0.0, w - 1.0);
  v = std::clamp(v, 0.0, h - 1.0);
  const int x0 = std::min(static_cast<int>(u), w - 2), y0 = std::min(static_cast<int>(v), h - 2);
  const float fx = static_cast<float>(u - x0), fy = static_cast<float>(v - y0);
  const float w00 = (1 - fx) * (1 - fy), w01 = fx * (1 - fy), w10 = (1 - fx) * fy, w11 = fx * fy;
  const float* p00 = grid + (static_cast<size_t>(y0) * w + x0) * c;
  const float* p01 = p00 + c;
  const float* p10 = p00 + static_cast<size_t>(w) * c;
  const float* p11 = p10 + c;
  for (int k = 0; k < c; ++k) out[k] = w00 * p00[k] + w01 * p01[k] + w10 * p10[k] + w11 * p11[k];
}

void NormalizeL2(float* v, int n) {
  double s = 0;
  for (int k = 0; k < n; ++k) s += static_cast<double>(v[k]) * v[k];
  const float inv = static_cast<float>(1.0 / std::max(std::sqrt(s), 1e-12));
  for (int k = 0; k < n; ++k) v[k] *= inv;
}

class XFeatExtractor : public FeatureExtractor {
 public:
  explicit XFeatExtractor(const ExtractorOptions& o)
      : net_(LoadNet(o.model_path.empty() ? DefaultXFeatModelPath() : o.model_path)),
        max_(o.max_features),
        scale_(o.xfeat_scale) {
    if (o.threads > 0) cv::setNumThreads(o.threads);
  }

  Features Extract(const cv::Mat& gray_in, const cv::Mat& mask) const override {
    Features f;
    f.norm = cv::NORM_L2;
    f.descriptors.create(0, kXFeatDescriptorSize, CV_32F);
    if (gray_in.empty()) return f;
    cv::Mat gray = gray_in;
    if (gray.type() != CV_8UC1) {
      if (gray.channels() == 3) cv::cvtColor(gray, gray, cv::COLOR_BGR2GRAY);
      if (gray.depth() != CV_8U) gray.convertTo(gray, CV_8U);
    }
    // 1. Network input: resampled (aspect kept), mirrored into the padding, float 0-1.
    const double fit = static_cast<double>(kXFeatInputSize) / std::max(gray.cols, gray.rows);
    const double s = scale_ > 0 ? std::min(scale_, fit) : fit;
    const int nw = std::clamp(static_cast<int>(std::lround(gray.cols * s)), 1, kXFeatInputSize);
    const int nh = std::clamp(static_cast<int>(std::lround(gray.rows * s)), 1, kXFeatInputSize);
    const double sx = static_cast<double>(nw) / gray.cols, sy = static_cast<double>(nh) / gray.rows;
    cv::Mat resized, padded, input;
    cv::resize(gray, resized, cv::Size(nw, nh), 0, 0, s < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
    cv::copyMakeBorder(resized, padded, 0, kXFeatInputSize - nh, 0, kXFeatInputSize - nw,
                       cv::BORDER_REFLECT_101);
    padded.convertTo(input, CV_32F, 1.0 / 255.0);
    const cv::Mat blob = cv::dnn::blobFromImage(input);
    std::vector<cv::Mat> out;
    {
      std::lock_guard<std::mutex> lock(net_->forward_mutex);
      net_->net.setInput(blob);
      net_->net.forward(out, std::vector<std::string>(kOutputs, kOutputs + 3));
    }
    const float* feats = out[0].ptr<float>();    // 80 x 80 x 64
    const float* logits = out[1].ptr<float>();   // 80 x 80 x 65
    const float* heatmap = out[2].ptr<float>();  // 80 x 80

    // 2. Score map: softmax per cell, dustbin dropped, pixel shuffle (cell pixel k at row k / 8,
    // column k % 8). Only the cells covering the image are needed.
    const int cells_x = std::min(kCells, (nw + 7) / 8), cells_y = std::min(kCells, (nh + 7) / 8);
    cv::Mat score(kXFeatInputSize, kXFeatInputSize, CV_32F, cv::Scalar(0));
    for (int cy = 0; cy < cells_y; ++cy) {
      for (int cx = 0; cx < cells_x; ++cx) {
        const float* l = logits + (static_cast<size_t>(cy) * kCells + cx) * 65;
        const float m = *std::max_element(l, l + 65);
        float e[65], sum = 0;
        for (int k = 0; k < 65; ++k) sum += e[k] = std::exp(l[k] - m);
        for (int k = 0; k < 64; ++k) score.at<float>(cy * 8 + k / 8, cx * 8 + k % 8) = e[k] / sum;
      }
    }
    // Non-maximum suppression (5x5) above the threshold, inside the image and the mask.
    struct Candidate {
      float score;
      int x, y;  // network px
    };
    std::vector<Candidate> candidates;
    const double to_image_x = 1.0 / sx, to_image_y = 1.0 / sy;
    for (int y = 0; y < nh; ++y) {
      const float* row = score.ptr<float>(y);
      for (int x = 0; x < nw; ++x) {
        const float v = row[x];
        if (!(v > kDetectionThreshold)) continue;
        bool is_max = true;
        for (int dy = -kNmsRadius; dy <= kNmsRadius && is_max; ++dy) {
          const int yy = y + dy;
          if (yy < 0 || yy >= kXFeatInputSize) continue;
          const float* r2 = score.ptr<float>(yy);
          for (int dx = -kNmsRadius; dx <= kNmsRadius; ++dx) {
            const int xx = x + dx;
            if (xx < 0 || xx >= kXFeatInputSize || (dx == 0 && dy == 0)) continue;
            if (r2[xx] > v) {
              is_max = false;
              break;
            }
          }
        }
        if (!is_max) continue;
        if (!mask.empty()) {
          const int ix = std::clamp(static_cast<int>((x + 0.5) * to_image_x), 0, mask.cols - 1);
          const int iy = std::clamp(static_cast<int>((y + 0.5) * to_image_y), 0, mask.rows - 1);
          if (mask.at<uint8_t>(iy, ix) == 0) continue;
        }
        // Reliability at the keypoint: the heatmap sampled as XFeat's grid_sample does
        // (align_corners = false on the 80x80 grid, the pixel scaled by 80 / 639).
        const double u = x * kCells / (kXFeatInputSize - 1.0) - 0.5;
        const double w = y * kCells / (kXFeatInputSize - 1.0) - 0.5;
        float reliability;
        SampleBilinear(heatmap, kCells, kCells, 1, u, w, &reliability);
        candidates.push_back({v * reliability, x, y});
      }
    }
    // 3. The strongest max_ (ties broken by position, for a deterministic order).
    auto stronger = [](const Candidate& a, const Candidate& b) {
      if (a.score != b.score) return a.score > b.score;
      return a.y != b.y ? a.y < b.y : a.x < b.x;
    };
    if (static_cast<int>(candidates.size()) > max_) {
      std::partial_sort(candidates.begin(), candidates.begin() + max_, candidates.end(), stronger);
      candidates.resize(max_);
    } else {
      std::sort(candidates.begin(), candidates.end(), stronger);
    }
    // Descriptors: bilinear on the unit-normalised grid, normalised again.
    cv::Mat grid(kCells * kCells, kXFeatDescriptorSize, CV_32F);
    std::memcpy(grid.data, feats, grid.total() * sizeof(float));
    for (int i = 0; i < grid.rows; ++i) NormalizeL2(grid.ptr<float>(i), kXFeatDescriptorSize);
    f.descriptors.create(static_cast<int>(candidates.size()), kXFeatDescriptorSize, CV_32F);
    f.keypoints.reserve(candidates.size());
    const float size = static_cast<float>(8.0 / s);
    for (size_t i = 0; i < candidates.size(); ++i) {
      const Candidate& c = candidates[i];
      const double u = c.x * kCells / (kXFeatInputSize - 1.0) - 0.5;
      const double w = c.y * kCells / (kXFeatInputSize - 1.0) - 0.5;
      float* d = f.descriptors.ptr<float>(static_cast<int>(i));
      SampleBilinear(grid.ptr<float>(), kCells, kCells, kXFeatDescriptorSize, u, w, d);
      NormalizeL2(d, kXFeatDescriptorSize);
      // 4. Back to the image: network pixel centre (x + 0.5) / s, OpenCV's centre convention.
      f.keypoints.emplace_back(static_cast<float>((c.x + 0.5) * to_image_x - 0.5),
                               static_cast<float>((c.y + 0.5) * to_image_y - 0.5), size, -1.0f,
                               c.score);
    }
    return f;
  }
  std::string name() const override { return "xfeat"; }
  int norm() const override { return cv::NORM_L2; }
  int descriptor_type() const override { return CV_32F; }
  int descriptor_size() const override { return kXFeatDescriptorSize; }

 private:
  std::shared_ptr<LoadedNet> net_;
  int max_;
  double scale_;
};

}  // namespace

std::string DefaultXFeatModelPath() {
  const char* env = std::getenv("OPTINAV_SHARED_DATA");
  const std::filesystem::path data = env && *env ? env : OPTINAV_SHARED_DATA_DEFAULT;
  return (data / "models" / "xfeat_640x640.onnx").string();
}

void CheckXFeatModel(const std::string& path) { LoadNet(path); }

std::unique_ptr<FeatureExtractor> CreateXFeatExtractor(const ExtractorOptions& options) {
  return std::make_unique<XFeatExtractor>(options);
}

}  // namespace optinav::features
