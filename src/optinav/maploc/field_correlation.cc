#include "optinav/maploc/field_correlation.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include <opencv2/core/hal/intrin.hpp>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace optinav::maploc {

namespace {

// The correlation of rows [0, tpl.rows) for every placement, with OpenCV's baseline SIMD (SSE2
// on x86-64 builds without -march).
void CorrelateSmallBaseline(const cv::Mat& image, const cv::Mat& tpl, cv::Mat* result) {
  const int rw = result->cols, rh = result->rows;
  const int len = 2 * tpl.cols;  // floats per template row
  for (int dy = 0; dy < rh; ++dy) {
    float* out = result->ptr<float>(dy);
    for (int dx = 0; dx < rw; ++dx) {
      float sum = 0;
      int k0 = 0;
#if CV_SIMD
      // Four independent accumulators: one would chain every multiply-add on the last.
      const int lanes = cv::v_float32::nlanes;
      cv::v_float32 a0 = cv::vx_setzero_f32(), a1 = a0, a2 = a0, a3 = a0;
      k0 = len - len % (4 * lanes);
      for (int y = 0; y < tpl.rows; ++y) {
        const float* m = image.ptr<float>(y + dy) + 2 * dx;
        const float* t = tpl.ptr<float>(y);
        for (int k = 0; k < k0; k += 4 * lanes) {
          a0 = cv::v_fma(cv::vx_load(m + k), cv::vx_load(t + k), a0);
          a1 = cv::v_fma(cv::vx_load(m + k + lanes), cv::vx_load(t + k + lanes), a1);
          a2 = cv::v_fma(cv::vx_load(m + k + 2 * lanes), cv::vx_load(t + k + 2 * lanes), a2);
          a3 = cv::v_fma(cv::vx_load(m + k + 3 * lanes), cv::vx_load(t + k + 3 * lanes), a3);
        }
      }
      sum = cv::v_reduce_sum((a0 + a1) + (a2 + a3));
#endif
      for (int y = 0; y < tpl.rows && k0 < len; ++y) {
        const float* m = image.ptr<float>(y + dy) + 2 * dx;
        const float* t = tpl.ptr<float>(y);
        for (int k = k0; k < len; ++k) sum += m[k] * t[k];
      }
      out[dx] = sum;
    }
  }
}

#if defined(__x86_64__) && defined(__GNUC__)
#define OPTINAV_HAVE_AVX2_PATH 1
// The same with 256-bit fused multiply-adds, chosen at run time when the CPU has them (the build
// targets baseline x86-64). Each template chunk is loaded once for up to four placements.
__attribute__((target("avx2,fma"))) void CorrelateSmallAvx2(const cv::Mat& image,
                                                            const cv::Mat& tpl, cv::Mat* result) {
  const int rw = result->cols, rh = result->rows;
  const int len = 2 * tpl.cols;
  const int k0 = len - len % 8;
  for (int dy = 0; dy < rh; ++dy) {
    float* out = result->ptr<float>(dy);
    for (int dx0 = 0; dx0 < rw; dx0 += 4) {
      const int n = std::min(4, rw - dx0);
      __m256 acc[4] = {_mm256_setzero_ps(), _mm256_setzero_ps(), _mm256_setzero_ps(),
                       _mm256_setzero_ps()};
      float tail[4] = {0, 0, 0, 0};
      for (int y = 0; y < tpl.rows; ++y) {
        const float* m = image.ptr<float>(y + dy) + 2 * dx0;
        const float* t = tpl.ptr<float>(y);
        for (int k = 0; k < k0; k += 8) {
          const __m256 tv = _mm256_loadu_ps(t + k);
          for (int j = 0; j < n; ++j) {
            acc[j] = _mm256_fmadd_ps(_mm256_loadu_ps(m + 2 * j + k), tv, acc[j]);
          }
        }
        for (int k = k0; k < len; ++k) {
          for (int j = 0; j < n; ++j) tail[j] += m[2 * j + k] * t[k];
        }
      }
      for (int j = 0; j < n; ++j) {
        // Horizontal sum of the eight lanes.
        const __m128 lo = _mm256_castps256_ps128(acc[j]), hi = _mm256_extractf128_ps(acc[j], 1);
        __m128 v = _mm_add_ps(lo, hi);
        v = _mm_add_ps(v, _mm_movehl_ps(v, v));
        v = _mm_add_ss(v, _mm_shuffle_ps(v, v, 0x55));
        out[dx0 + j] = _mm_cvtss_f32(v) + tail[j];
      }
    }
  }
}
#endif

std::atomic<bool> g_allow_avx2{true};

}  // namespace

bool CorrelateSmallHasAvx2() {
#ifdef OPTINAV_HAVE_AVX2_PATH
  static const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return avx2;
#else
  return false;
#endif
}

void AllowCorrelateSmallAvx2(bool allow) { g_allow_avx2.store(allow); }

void CorrelateSmall(const cv::Mat& image, const cv::Mat& tpl, cv::Mat* result) {
  CV_Assert(image.type() == CV_32FC2 && tpl.type() == CV_32FC2);
  const int rw = image.cols - tpl.cols + 1, rh = image.rows - tpl.rows + 1;
  CV_Assert(rw > 0 && rh > 0);
  result->create(rh, rw, CV_32F);
#ifdef OPTINAV_HAVE_AVX2_PATH
  if (g_allow_avx2.load(std::memory_order_relaxed) && CorrelateSmallHasAvx2()) {
    CorrelateSmallAvx2(image, tpl, result);
    return;
  }
#endif
  CorrelateSmallBaseline(image, tpl, result);
}

void RotateField(const cv::Mat& field, const cv::Matx23d& src_from_dst, double turn_rad,
                 cv::Mat* out) {
  CV_Assert(field.type() == CV_32FC2 && out->type() == CV_32FC2);
  const float c2 = static_cast<float>(std::cos(turn_rad));
  const float s2 = static_cast<float>(std::sin(turn_rad));
  const int w = field.cols, h = field.rows;
  // Sample positions are offset by kShift so that truncation is the floor (positions below
  // -kShift lie far outside anyway).
  constexpr double kShift = 4096.0;
  constexpr double kFar = 1e9;  // beyond any field; keeps the int conversion defined
  auto tap = [&](int x, int y) -> cv::Vec2f {
    if (x < 0 || y < 0 || x >= w || y >= h) return {0, 0};
    return field.at<cv::Vec2f>(y, x);
  };
  // Positions in double: a float carries only ~5e-4 px at the shifted magnitude.
  const double dxu = src_from_dst(0, 0), dyu = src_from_dst(1, 0);
  for (int v = 0; v < out->rows; ++v) {
    cv::Vec2f* o = out->ptr<cv::Vec2f>(v);
    const double qx0 = src_from_dst(0, 1) * v + src_from_dst(0, 2) + kShift;
    const double qy0 = src_from_dst(1, 1) * v + src_from_dst(1, 2) + kShift;
    for (int u = 0; u < out->cols; ++u) {
      // From the row's start each time: no drift along long rows.
      const double qx = qx0 + dxu * u;
      const double qy = qy0 + dyu * u;
      if (!(qx >= 0 && qy >= 0 && qx < kFar && qy < kFar)) {  // also NaN: outside
        o[u] = {0, 0};
        continue;
      }
      const int xs = static_cast<int>(qx), ys = static_cast<int>(qy);
      const float ax = static_cast<float>(qx - xs), ay = static_cast<float>(qy - ys);
      const int x0 = xs - static_cast<int>(kShift), y0 = ys - static_cast<int>(kShift);
      float s0, s1;
      if (static_cast<unsigned>(x0) < static_cast<unsigned>(w - 1) &&
          static_cast<unsigned>(y0) < static_cast<unsigned>(h - 1)) {
        const float* r0 = field.ptr<float>(y0) + 2 * x0;
        const float* r1 = field.ptr<float>(y0 + 1) + 2 * x0;
        const float w00 = (1 - ax) * (1 - ay), w01 = ax * (1 - ay), w10 = (1 - ax) * ay,
                    w11 = ax * ay;
        s0 = r0[0] * w00 + r0[2] * w01 + r1[0] * w10 + r1[2] * w11;
        s1 = r0[1] * w00 + r0[3] * w01 + r1[1] * w10 + r1[3] * w11;
      } else if (x0 < -1 || y0 < -1 || x0 >= w || y0 >= h) {
        o[u] = {0, 0};
        continue;
      } else {
        const cv::Vec2f t = (tap(x0, y0) * (1 - ax) + tap(x0 + 1, y0) * ax) * (1 - ay) +
                            (tap(x0, y0 + 1) * (1 - ax) + tap(x0 + 1, y0 + 1) * ax) * ay;
        s0 = t[0];
        s1 = t[1];
      }
      o[u] = {s0 * c2 - s1 * s2, s0 * s2 + s1 * c2};
    }
  }
}

}  // namespace optinav::maploc
