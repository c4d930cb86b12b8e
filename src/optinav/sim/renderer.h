// A CPU renderer of World meshes: textured triangles, z-buffer, perspective-correct texture
// mapping, per-pixel mip-level selection (bilinear within the level), flat Lambert shading
// baked into each triangle's tint, a sky gradient, near-plane clipping and chunk frustum
// culling. Rows are split into bands rendered in parallel; every pixel's value depends only on
// the scene, the camera and the pose, never on the thread count (bit-identical output).
// Distorted cameras (radial-tangential, equidistant) are rendered as a wider pinhole image and
// resampled through the camera's own distortion model.
#pragma once

#include <map>
#include <mutex>
#include <string>

#include <opencv2/core.hpp>

#include "optinav/camera/camera.h"
#include "optinav/geometry/lie.h"
#include "optinav/sim/world.h"

namespace optinav::sim {

class Renderer {
 public:
  explicit Renderer(const World& world) : world_(world) {}

  // bgr: CV_8UC3 image; depth (optional): CV_32F distance along the optical axis (camera z) in
  // metres, +inf where the sky is seen. Camera frame: x right, y down, z forward.
  void Render(const camera::PinholeCamera& camera, const Rigid3d& world_from_cam, cv::Mat* bgr,
              cv::Mat* depth = nullptr) const;

 private:
  struct Pinhole {
    int width, height;
    double fx, fy, cx, cy;
  };
  struct DistortionMaps {
    Pinhole render;
    cv::Mat map_x, map_y;  // CV_32F: output pixel -> pixel of the wider pinhole render
  };
  void RenderPinhole(const Pinhole& cam, const Rigid3d& cam_from_world, cv::Mat* bgr,
                     cv::Mat* inv_depth) const;
  const DistortionMaps& MapsFor(const camera::PinholeCamera& camera) const;

  const World& world_;
  mutable std::mutex mutex_;
  mutable std::map<std::string, DistortionMaps> maps_;
};

}  // namespace optinav::sim
