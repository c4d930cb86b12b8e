// Direct (spatial) correlation of two-channel float fields, for the block matching of the
// orientation correlation (docs/MAPDB.md).
#pragma once

#include <opencv2/core.hpp>

namespace optinav::maploc {

// What cv::matchTemplate(image, tpl, result, TM_CCORR) gives for CV_32FC2 images: result(dy, dx)
// is the sum over the template of both channels' products (the real part of the complex
// correlation of two orientation fields), (image - tpl + 1) in each dimension. Computed directly
// with SIMD: for a 32 px template and a few pixels of search this beats OpenCV's DFT-based path.
void CorrelateSmall(const cv::Mat& image, const cv::Mat& tpl, cv::Mat* result);

}  // namespace optinav::maploc
