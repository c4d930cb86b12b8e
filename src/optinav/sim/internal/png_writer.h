// Fast PNG encoding for the simulator's image streams (libpng directly): one fixed "sub" row
// filter and zlib's RLE strategy at level 1 encode about twice as fast as OpenCV's adaptive
// filtering at a similar size, and the encoding dominates writing a dataset. Deterministic:
// the same image gives the same bytes.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace optinav::sim {

// `image`: CV_8UC3 (BGR) or CV_8UC1. compression_level 0 (store) .. 9. Throws Error on failure.
std::vector<uint8_t> EncodePng(const cv::Mat& image, int compression_level = 1);

}  // namespace optinav::sim
