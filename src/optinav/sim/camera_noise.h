// A camera sensor's noise and its 8-bit quantisation: the last step of every simulated image
// (`optinav sim`). The renderer's own image is 8-bit (its textures are); the weather is applied
// to it unrounded, in grey levels, and only this step rounds.
//
// Model: per pixel one standard normal sample n, drawn from a hash of (stream, pixel), so that
// the output depends only on the seed, the frame's time and the camera, never on the thread
// count. Each channel c becomes round(I_c + sigma(I_c) n) saturated to [0, 255], with
// sigma(I)^2 = read^2 + shot * I (read noise and photon shot noise, in grey levels). The three
// channels share n: the estimators read grey images, and the grey image's noise is then
// sigma(grey). Noise is added before the rounding, as in a camera: a low-contrast gradient (fog
// or dust over the scene) comes out dithered, not as 8-bit steps that stay put in the image
// while the scene moves through them.
//
// Default figures from a real camera: the EuRoC V1_01 clip's cam0 (MT9V034) has, by Immerkaer's
// estimator on its flattest 30 % of pixels (docs/VIO.md, "camera noise"), 0.9 grey levels below
// grey 40, 1.25 at 40-90 and 1.9 at 90-160; read 0.8 and shot 0.02 give 0.9, 1.2 and 1.8.
#pragma once

#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace optinav::sim {

struct CameraNoiseOptions {
  bool enabled = true;
  double read_sigma = 0.8;      // grey levels
  double shot_variance = 0.02;  // grey levels^2 per grey level of signal

  // Empty when valid, else the offending field and value.
  std::string Check() const;
  // "off" or "READ:SHOT" (e.g. "0.8:0.02").
  std::string ToString() const;
  // The noise's sigma (grey levels) at grey level `grey`; 0 when disabled.
  double SigmaAt(double grey) const;
};

// "on" (the defaults), "off", or "READ:SHOT" (both >= 0, READ <= 20, SHOT <= 2). Throws Error
// naming `field` otherwise.
CameraNoiseOptions ParseCameraNoise(const std::string& text, const std::string& field);

// The stream of one camera's frame: a hash of the simulation seed, the frame's time and the
// camera's index (0 left, 1 right, 2 nadir).
uint64_t CameraNoiseStream(uint64_t seed, int64_t t_ns, int camera);

// `light`: CV_32FC3 in grey levels (unrounded, any range). Returns CV_8UC3 with the noise of
// `noise` (none when disabled: only the rounding) drawn from `stream`. Throws Error on another
// image type.
cv::Mat ExposeToEightBits(const cv::Mat& light, const CameraNoiseOptions& noise, uint64_t stream);

}  // namespace optinav::sim
