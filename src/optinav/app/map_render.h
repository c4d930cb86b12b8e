// Synthetic camera frames cut from an orthophoto (`optinav map render`): frames to try
// `map locate` on, for tests and demos. Two kinds:
//  - one frame: a true perspective view from a vehicle at a position, altitude and attitude
//    (aerospace convention, maploc/aerial_camera.h), or the legacy tilt model (--tilt);
//  - an acceptance set (issue 18): seeded frames from maploc::MakePerspectiveFrames written as
//    JPEG files with the `--images-from` CSV of what locate is given, and the truth beside it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "optinav/geo/geo.h"
#include "optinav/maploc/frame_synth.h"

namespace optinav::app {

struct FrameRenderOptions {
  std::string ortho_path;  // georeferenced orthophoto (GeoTIFF)
  std::string out_path;    // image to write (PNG, JPEG: by extension)
  // The vehicle's position (its nadir point). With the legacy tilt model: the ground point
  // under the frame centre.
  geo::LatLon at;
  int width = 640, height = 480;
  double heading_deg = 0;  // yaw: frame up, clockwise from north
  double gsd_m = 0;        // metres per frame pixel at nadir; 0: the orthophoto's at `at`
  // True perspective: altitude above ground (m; default: gsd_m x the focal length), roll and
  // pitch (deg), horizontal field of view (deg; default 90).
  std::optional<double> altitude_m;
  double roll_deg = 0, pitch_deg = 0;
  std::optional<double> hfov_deg;
  // Legacy tilt model (maploc::SynthesizeFrame, 60 deg field of view): set, it replaces the
  // perspective camera and `at` is the frame centre's ground point.
  std::optional<double> tilt_deg;
  double tilt_azimuth_deg = 0;  // tilt direction in the frame (0: towards frame up)
  // "" when valid, else a message starting with the flag at fault.
  std::string Check() const;
};

struct RenderedFrame {
  double gsd_m = 0;       // metres per frame pixel at nadir (legacy: at the centre)
  double altitude_m = 0;  // 0 for the legacy model
  geo::LatLon centre;     // ground point under the frame centre
};

// Renders and writes the frame. Throws Error when the orthophoto cannot be read or has no
// georeference, `at` lies outside it (field "--at"), the camera sees the horizon, or the image
// cannot be written.
RenderedFrame RenderFrame(const FrameRenderOptions& options);

struct FrameSetOptions {
  std::string ortho_path;
  std::string out_dir;  // created if missing; frame_NNN.jpg, frames.csv, truth.csv
  int count = 50;
  uint64_t seed = 1;
  maploc::PerspectiveFrameOptions frames;  // size, field of view, nominal altitude, ranges
  std::string Check() const;
};

struct FrameSetSummary {
  int count = 0;
  std::string frames_csv, truth_csv;
};

// Writes the acceptance set: DIR/frame_NNN.jpg (the frame's own JPEG compression, written
// once; a frame without compression is written at quality 100), DIR/frames.csv with the header
// image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg,altitude_m,roll_deg,pitch_deg
// (the values given to locate; image paths absolute) and DIR/truth.csv with
// image,lat,lon,center_lat,center_lon,altitude_m,roll_deg,pitch_deg,heading_deg (the vehicle's
// nadir point, the image centre's ground point, the true altitude and attitude).
FrameSetSummary RenderFrameSet(const FrameSetOptions& options);

}  // namespace optinav::app
