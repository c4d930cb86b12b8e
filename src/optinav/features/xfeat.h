// XFeat (Potje et al., CVPR 2024, "XFeat: Accelerated Features for Lightweight Image Matching"):
// a learned detector and 64-d float descriptor, run on the CPU through OpenCV's DNN module from
// the ONNX export in the project's shared data (models/xfeat_640x640.onnx).
//
// The network takes one 640x640 grey image (float 0-1) and returns, on an 80x80 grid of 8x8
// cells: `output_keypoints` (1x80x80x65 logits: the 64 pixels of the cell and a "no keypoint"
// dustbin), `output_heatmap` (1x1x80x80 reliability, 0-1) and `output_feats` (1x80x80x64 dense
// descriptors). Extraction:
//  1. the image is resampled by `xfeat_scale` (or to fit 640), keeping its aspect, and padded to
//     640x640 by mirroring (the network normalises its input per image: a black border would
//     change the statistics of the content);
//  2. a softmax over the 65 logits of each cell, the dustbin dropped, the 64 pixel scores put back
//     in place (pixel shuffle) give a 640x640 score map; a keypoint is a 5x5 local maximum above
//     0.05; its score is that times the reliability heatmap (bilinear) at its place;
//  3. the strongest `max_features` inside the image (and the mask) are kept; descriptors are
//     sampled bilinearly from the L2-normalised descriptor grid and L2-normalised again;
//  4. positions go back to image pixels (pixel-centre convention of OpenCV keypoints).
// The keypoint size is the cell (8 network px) in image px; keypoints have no orientation (-1).
#pragma once

#include <memory>
#include <string>

#include "optinav/features/features.h"

namespace optinav::features {

constexpr int kXFeatInputSize = 640;  // the export's fixed input side
constexpr int kXFeatDescriptorSize = 64;

// The network file used when none is given: $OPTINAV_SHARED_DATA/models/xfeat_640x640.onnx when
// that variable is set, else the shared data folder beside the source checkout
// (../shared/data/models/xfeat_640x640.onnx).
std::string DefaultXFeatModelPath();

// Checks that `path` holds the expected network (loads it through the process-wide cache).
// Throws Error naming the file: missing, not an ONNX network OpenCV reads, or not XFeat
// (inputs 1x1x640x640, outputs output_feats 1x80x80x64, output_keypoints 1x80x80x65,
// output_heatmap 1x1x80x80).
void CheckXFeatModel(const std::string& path);

// The extractor behind CreateFeatureExtractor({.type = FeatureType::kXFeat, ...}).
std::unique_ptr<FeatureExtractor> CreateXFeatExtractor(const ExtractorOptions& options);

}  // namespace optinav::features
