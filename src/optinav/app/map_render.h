// Synthetic camera frames cut from an orthophoto (`optinav map render`): frames to try
// `map locate` on, for tests and demos.
#pragma once

#include <string>

#include "optinav/geo/geo.h"

namespace optinav::app {

struct FrameRenderOptions {
  std::string ortho_path;  // georeferenced orthophoto (GeoTIFF)
  std::string out_path;    // image to write (PNG, JPEG: by extension)
  geo::LatLon at;          // ground point under the frame centre
  int width = 640, height = 480;
  double heading_deg = 0;       // frame up, clockwise from north
  double gsd_m = 0;             // metres per frame pixel; 0: the orthophoto's at `at`
  double tilt_deg = 0;          // camera tilt from nadir
  double tilt_azimuth_deg = 0;  // tilt direction in the frame (0: towards frame up)
};

struct RenderedFrame {
  double gsd_m = 0;  // metres per frame pixel used
};

// Renders and writes the frame. Throws Error when the orthophoto cannot be read or has no
// georeference, `at` lies outside it (field "--at"), or the image cannot be written.
RenderedFrame RenderFrame(const FrameRenderOptions& options);

}  // namespace optinav::app
