// Direct (spatial) correlation of two-channel float fields, for the block matching of the
// orientation correlation (docs/MAPDB.md).
#pragma once

#include <opencv2/core.hpp>

namespace optinav::maploc {

// What cv::matchTemplate(image, tpl, result, TM_CCORR) gives for CV_32FC2 images: result(dy, dx)
// is the sum over the template of both channels' products (the real part of the complex
// correlation of two orientation fields), (image - tpl + 1) in each dimension. Computed directly
// with SIMD: for a 32 px template and a few pixels of search this beats OpenCV's DFT-based path,
// and so does it for a whole frame's patch over 7 x 7 placements. Uses AVX2/FMA when the CPU has
// them (chosen at run time; the build targets baseline x86-64), else OpenCV's baseline SIMD.
void CorrelateSmall(const cv::Mat& image, const cv::Mat& tpl, cv::Mat* result);
// Whether this CPU runs CorrelateSmall's AVX2/FMA path; tests switch it off to check the other.
bool CorrelateSmallHasAvx2();
void AllowCorrelateSmallAvx2(bool allow);

// An orientation field rotated into `out` (CV_32FC2, its size kept): out(u) is the bilinear sample
// of `field` at src_from_dst (u) (zero outside `field`, as cv::warpAffine with WARP_INVERSE_MAP and
// BORDER_CONSTANT), its doubled-angle vector then turned by `turn_rad` (a rotation of the image
// by a turns its doubled angles by 2a). One pass instead of a warp and a multiply: the coarse
// search does this once per heading and scale.
void RotateField(const cv::Mat& field, const cv::Matx23d& src_from_dst, double turn_rad,
                 cv::Mat* out);

}  // namespace optinav::maploc
