#include "optinav/maploc/frame_synth.h"

#include <cmath>

#include <opencv2/imgproc.hpp>

namespace optinav::maploc {

cv::Mat SynthesizeFrame(const geo::GeoRaster& raster, double map_gsd_m, const FrameSpec& s,
                        cv::Matx33d* frame_to_map) {
  const double f = s.focal_px > 0 ? s.focal_px : s.width / (2.0 * std::tan(30.0 * M_PI / 180.0));
  const double scale = s.gsd_m / map_gsd_m;  // map px per frame px at the centre
  const double h = s.heading_deg * M_PI / 180.0;
  const cv::Matx22d rot(std::cos(h), -std::sin(h), std::sin(h), std::cos(h));
  // Ray of a frame pixel, tilted camera, intersected with the ground; in "centre frame pixels".
  const double t = s.tilt_deg * M_PI / 180.0, ta = s.tilt_azimuth_deg * M_PI / 180.0;
  const Eigen::Vector3d axis(std::cos(ta), std::sin(ta), 0);  // tilt about this frame axis
  const Eigen::Matrix3d r = Eigen::AngleAxisd(t, axis).toRotationMatrix();
  auto ground = [&](double u, double v) {
    const Eigen::Vector3d ray = r * Eigen::Vector3d(u - s.width / 2.0, v - s.height / 2.0, f);
    const Eigen::Vector3d c = r * Eigen::Vector3d(0, 0, f);
    // Scale so the centre ray lands at (0, 0) with unit gsd there.
    return cv::Point2d(f * (ray.x() / ray.z() - c.x() / c.z()),
                       f * (ray.y() / ray.z() - c.y() / c.z()));
  };
  std::vector<cv::Point2f> fpts, mpts;
  for (const cv::Point2d p : {cv::Point2d(0, 0), cv::Point2d(s.width, 0),
                              cv::Point2d(s.width, s.height), cv::Point2d(0, s.height)}) {
    const cv::Point2d g = ground(p.x, p.y);
    const cv::Vec2d m = rot * cv::Vec2d(g.x, g.y) * scale;
    fpts.emplace_back(p);
    mpts.emplace_back(static_cast<float>(s.centre_px.x() + m[0]),
                      static_cast<float>(s.centre_px.y() + m[1]));
  }
  const cv::Matx33d f2m(cv::getPerspectiveTransform(fpts, mpts));
  if (frame_to_map) *frame_to_map = f2m;
  // Read the map window covering the frame (with a margin), then warp.
  const cv::Rect box = cv::boundingRect(mpts);
  const int margin = 4;
  const cv::Rect win(box.x - margin, box.y - margin, box.width + 2 * margin,
                     box.height + 2 * margin);
  // Downsample the window when the frame is much coarser than the map (anti-aliasing).
  const double down = std::max(1.0, scale);
  const int ow = std::max(1, static_cast<int>(win.width / down));
  const int oh = std::max(1, static_cast<int>(win.height / down));
  const cv::Mat img = raster.ReadGray(win.x, win.y, win.width, win.height, ow, oh);
  // frame px -> window-image px
  const cv::Matx33d to_img = cv::Matx33d(ow / static_cast<double>(win.width), 0,
                                         -win.x * ow / static_cast<double>(win.width), 0,
                                         oh / static_cast<double>(win.height),
                                         -win.y * oh / static_cast<double>(win.height), 0, 0, 1) *
                             f2m;
  cv::Mat out;
  cv::warpPerspective(img, out, to_img, cv::Size(s.width, s.height),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
  return out;
}

}  // namespace optinav::maploc
