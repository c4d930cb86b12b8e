#include "optinav/maploc/field_correlation.h"

#include <opencv2/core/hal/intrin.hpp>

namespace optinav::maploc {

void CorrelateSmall(const cv::Mat& image, const cv::Mat& tpl, cv::Mat* result) {
  CV_Assert(image.type() == CV_32FC2 && tpl.type() == CV_32FC2);
  const int rw = image.cols - tpl.cols + 1, rh = image.rows - tpl.rows + 1;
  CV_Assert(rw > 0 && rh > 0);
  result->create(rh, rw, CV_32F);
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

}  // namespace optinav::maploc
