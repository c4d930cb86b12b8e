// The stereo frontend: feature tracks for the backend.
//
// Per frame:
//  1. KLT (pyramidal Lucas-Kanade) tracks the previous left features into the new left image,
//     starting from a prediction by the IMU rotation when given, and keeps a track only if
//     tracking back lands within `forward_backward_px` of where it started;
//  2. geometric outlier rejection: RANSAC on the fundamental matrix of the undistorted pixel
//     coordinates (skipped when the median flow is below a pixel: no baseline to test);
//  3. new Shi-Tomasi corners fill the grid cells that lack features, away from existing ones;
//  4. keyframe selection: time since the last keyframe, fraction of its tracks still alive, and
//     mean pixel parallax since it (with the gyro rotation removed when it is given);
//  5. stereo: KLT from left to right (with a backward check, starting from the track's last
//     disparity or the median depth), accepted only when the undistorted right point lies within
//     `epipolar_px` of the epipolar line of the left one and in front of both cameras. All tracks
//     are matched at keyframes; between keyframes only tracks without a match that have failed
//     fewer than two attempts (the backend keeps only keyframe observations besides the newest
//     frame's, and new landmarks need a first stereo triangulation).
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/camera/camera.h"
#include "optinav/util/timer.h"
#include "optinav/vio/backend.h"

namespace optinav::vio {

struct FrontendOptions {
  int max_features = 150;  // tracks kept per frame
  int grid_cols = 8;       // detection grid over the image
  int grid_rows = 6;
  double min_distance_px = 20.0;  // between features
  double quality_level = 0.01;    // Shi-Tomasi, relative to the best corner
  int klt_window_px = 15;         // KLT window side (temporal tracking)
  int stereo_window_px = 21;      // KLT window side for left-right matching
  // Each stereo match then refined over this smaller window on the full-resolution images, with
  // a gain and an offset of the right image fitted too (0: off). The stereo window spans the
  // slanted road, whose disparity changes across it: on the simulated car route the near
  // disparities scatter by a median 0.34 px (0.57 px in dust) with 21 px, 0.13 px refined over
  // 9 px. A 9 px stereo window alone, through the pyramid, lost 40 % of the real EuRoC clip's
  // stereo matches. Off: as the default it fails the seeded stereo-inertial fog test (0.62 m mean
  // error against 0.5) and removes the premise of the in-motion start test (docs/VIO.md,
  // "2026-12-07 (night)"; the IMU-spike test does not tell it apart over 32 noise draws).
  int stereo_refine_window_px = 0;
  // Each temporal KLT track refined at full resolution over the KLT window with a gain and an
  // offset of the new frame fitted (Gauss-Newton from where the pyramid put it; a refinement that
  // does not converge or moves more than forward_backward_px keeps the track as it was). Haze
  // is a veil fixed in the image that the texture flows through; plain KLT takes its gradient
  // for part of the texture and is pulled towards no motion.
  bool klt_gain_offset = false;
  int klt_pyramid_levels = 3;
  int klt_max_iterations = 20;
  double forward_backward_px = 1.0;  // max error of the forward-backward check
  double ransac_px = 1.0;            // fundamental-matrix RANSAC threshold
  double epipolar_px = 2.0;          // stereo match distance to the epipolar line
  int border_px = 10;                // features closer to the border are dropped
  // Absolute floor of the Shi-Tomasi corner response (the smaller eigenvalue of the 3x3
  // structure tensor, OpenCV's cornerMinEigenVal scale: intensities in [0, 1]); 0: none. The
  // quality level is relative to a cell's best corner, so in fog or dust a cell holding only
  // faint, haze-blurred texture still yields corners. Off: on the foggy car route any floor
  // made the drift worse (fewer features; docs/VIO.md, weather).
  double min_corner_response = 0.0;
  // A floor of the same response that follows the camera's noise: this many times the median
  // response that the frame's noise alone would give (0: none). The noise is estimated on each
  // frame's detection image (NoiseSigma); pure white noise of sigma grey levels has a median
  // 3x3 Shi-Tomasi response of kNoiseCornerResponsePerSigma2 * sigma^2, its 99.9th percentile
  // about 5 times that. Where haze leaves texture below the noise (far fog), a cell's best
  // "corner" is noise, which KLT follows to nowhere; the quality level, relative to that best,
  // cannot tell. Not on frames prepared with CLAHE or the local normalisation, whose gain varies
  // across the image. Off here; stereo-only mode uses stereo_only_corner_noise_floor.
  double corner_noise_floor = 0.0;
  // Contrast-limited adaptive histogram equalisation of both images before detection and
  // tracking (clip limit; 0: off) over a clahe_tiles x clahe_tiles grid. In 100 % dust the
  // texture is a grey level or two deep and KLT loses most tracks every frame (every frame a
  // keyframe); CLAHE halves the drift there (docs/VIO.md, weather).
  double clahe_clip_limit = 2.0;
  int clahe_tiles = 8;
  // CLAHE only on low-contrast frames: when the left image's intensity standard deviation (grey
  // levels) is below this (0: every frame). Off again above 1.25 x this (hysteresis, so that
  // the tracked images do not flip between the two looks from one frame to the next). The car
  // route at 400x300: clear 38-43, fog 100 % 32-37, dust 100 % 12-15; on fog CLAHE did not help,
  // so clear and foggy frames stay untouched (bit-identical results). The same low-contrast
  // state selects the frames whose new corners detect_min_eigen checks.
  double clahe_below_std = 20.0;
  // Also low in contrast when the median local intensity std (over 7 x 7 pixel boxes of the left
  // image, grey levels) is below this (0: off); off again above 1.25 x this. Fog hides texture
  // without lowering the global std (the sky-to-ground gradient keeps it at 32-37): median local
  // std at 400x300, clear 3.5 (urban) / 5.5 (terrain), fog 75 % 1.9 / 1.6, fog 100 % 0.9 / 0.2,
  // dust 100 % 0.5 / 0.1. Off: CLAHE on every frame halved the terrain route's error sum but
  // moved the urban rows both ways (docs/VIO.md, weather, 2026-12-05 late).
  double clahe_below_local_std = 0.0;
  // On low-contrast frames with CLAHE off: a global contrast stretch of both images by one gain,
  // so that the left image's intensity standard deviation becomes this (grey levels; 0: off).
  // The gain follows the frames slowly (each frame moves it 10 % of the way), so consecutive
  // frames look alike to KLT. Unlike CLAHE it does not vary across the image (docs/VIO.md,
  // weather, 2026-12-02).
  double contrast_stretch_std = 0.0;
  // High-pass filter of both images before detection and tracking: image - Gaussian blur of
  // sigma highpass_sigma_px + 128 (0: off). Removes slow intensity ramps such as the haze
  // gradient of fog and dust, which changes under a feature as it approaches. Off: it made the
  // foggy car route worse (sigma 3 and 6 px).
  double highpass_sigma_px = 0.0;
  // Local contrast normalisation of both images before detection and tracking (Gaussian sigma
  // in pixels; 0: off): (I - mean) / (std + local_norm_floor) over the Gaussian neighbourhood,
  // mapped to 8 bits. Fog and dust blend a feature with the airlight by exp(-distance / L):
  // locally I = t J + (1 - t) A, so the normalised image does not change as the feature
  // approaches, where KLT on the raw image followed the brightening haze gradient: on the car
  // route in 100 % fog, KLT's displacement differs from the clear rendering's by a median 0.13
  // px (a 0.02 px per frame bias down the image) raw and 0.04 px normalised (sigma 4 px). Off:
  // over the whole route it did not lower the error (stereo 15.9 -> 15.4 m in fog, 2.2 -> 2.4 m
  // clear, 50 -> 40 m in dust; stereo-imu in fog 9.9 -> 15.2 m, and 2.0 -> 7.4 m with a 1 mrad/s
  // gyro-bias prior: features in the faint far haze;
  // docs/VIO.md, weather). On 2026-12-05 (last) with min_corner_isotropy: terrain fog's pitch
  // drift gone (terrain sum 181.6 -> 119 m) but urban no better (clear 0.87 -> 1.41 m).
  double local_norm_sigma_px = 0.0;
  double local_norm_floor = 2.0;  // grey levels added to the local std (flat areas stay flat)
  // The local contrast normalisation (local_norm_sigma_px) and the corner isotropy check
  // (min_corner_isotropy) only on the frames the low-contrast rule selects (clahe_below_std,
  // clahe_below_local_std), as CLAHE: fog's treatment, kept off clear frames.
  bool fog_treatment_low_contrast_only = false;
  // Median filter of both images before detection and tracking (odd kernel side; 0 or 1: off).
  // Removes particles of a pixel or two (dust, distant snow and rain) that would otherwise be
  // the strongest corners of a hazy image. Off: on 100 % dust 3 px helped less than CLAHE and
  // 5 px made it worse.
  int median_filter_px = 0;
  // On low-contrast frames (those clahe_below_std selects, with or without CLAHE), a new corner
  // is kept only when KLT can track it: the smaller eigenvalue of the gradient matrix over the
  // KLT window (cv::calcOpticalFlowPyrLK's minimum-eigenvalue measure, per pixel of the window)
  // must reach this (0: no check). KLT declares a track lost below its own threshold (1e-4);
  // 3e-4 is a gradient of about half a grey level per pixel in the window's weakest direction,
  // above 8-bit quantisation. Spare candidates of the same grid cell take the place of those
  // dropped. On the simulated car route in dust 40-47 % of the corners detected without the
  // check die at the next frame and count as lost tracks in the keyframe rule; with it the
  // stereo-inertial odometry in 100 % dust is better on three seeds of three (mean 8.61 -> 6.41
  // m). On every frame it made fog worse (docs/VIO.md, 2026-11-29: corners KLT can track), so
  // normal-contrast frames (clear, fog, snow: bit-identical results) are not checked.
  double detect_min_eigen = 3e-4;
  // A new corner is kept only when its gradient matrix over the KLT window is this isotropic:
  // smaller over larger eigenvalue (0: no check). A corner of the 3x3 Shi-Tomasi block can be
  // an edge over the KLT window (a kerb, a road edge fading into fog); KLT cannot see motion
  // along an edge and reports the start guess, no motion, which pulls the rotation estimate
  // toward zero in turns (docs/VIO.md, weather, "2026-12-05 (last)"). Spare candidates replace
  // those dropped.
  double min_corner_isotropy = 0.0;
  int corner_block_px = 3;  // Shi-Tomasi block size (larger: less sensitive to tiny dots)
  double keyframe_max_interval_s = 0.5;
  // Corners detected at a keyframe join its reference set (the denominator of the tracked-ratio
  // rule below) only if they are tracked into the next frame. A fresh corner that KLT cannot
  // follow for one frame is a detection failure, not a sign that the view has changed; counted
  // as a lost track it made 449 of the first 485 frames of the clear car route keyframes at
  // 400x300. Off: with it the window holds fewer keyframes, and on the car route that cost more
  // than the dead corners did (stereo-imu, fog 100 %: 2.47 -> 6.07 m; stereo-only test segment
  // 0.35 -> 0.69 m; docs/VIO.md, 2026-12-01, "tried the same day").
  bool keyframe_fresh_probation = false;
  double keyframe_min_tracked_ratio = 0.75;
  double keyframe_min_parallax_px = 15.0;
  // Stereo-only mode (VioMode::kStereo) uses these instead of the two above: without a gyro the
  // parallax includes the rotation, and on a car near ground features race through the image,
  // so the defaults above make nearly every frame a keyframe (the simulated car route: 3300 of
  // 3509 frames) and the window spans under 2 m.
  double stereo_only_keyframe_min_tracked_ratio = 0.5;
  double stereo_only_keyframe_min_parallax_px = 40.0;
  // Stereo-only mode uses these instead of local_norm_sigma_px and min_corner_isotropy when they
  // are >= 0 (-1: the same as in stereo-imu mode). Without an IMU nothing observes the tilt, and
  // the haze's pull on KLT (local_norm_sigma_px above) pitches the stereo-only odometry by degrees
  // per second on the terrain route in fog; with an IMU gravity holds the tilt. Off: with 4 px
  // and 0.05 the urban route lost its loops in leaves (3.22 -> 15.42 m) and fog 100 % (6.92 ->
  // 21.71 m; docs/VIO.md, 2026-12-06 evening).
  double stereo_only_local_norm_sigma_px = -1.0;
  double stereo_only_min_corner_isotropy = -1.0;
  // Stereo-only mode uses this instead of klt_gain_offset. Without an IMU the haze's pull on KLT
  // drifts the odometry: on the weather suite's terrain route (400x300, seed 1) 11 of 12 rows
  // better, fog 100 % 70.97 -> 21.82 m; the urban rows move both ways over three seeds, dust 100 %
  // worse (docs/VIO.md, "2026-12-07 (late)"). With the IMU it moved rows both ways on the suite
  // and moves the drone's in-motion start tests, so it is off there.
  bool stereo_only_klt_gain_offset = true;
  // Stereo-only mode uses this instead of corner_noise_floor when it is >= 0 (-1: the same). With
  // the cameras' noise (`sim --camera-noise`, the simulator's default since 2026-12-07) the
  // urban route's fog 100 % went 21.74 -> 1.85 m, its odometry alone 21.74 -> 11.12 m (docs/VIO.md,
  // "2026-12-07 (last)"). Not measured with the IMU, where it moved two seeded drone tests
  // (noise-free renderings), so off there.
  double stereo_only_corner_noise_floor = 6.0;

  std::string Check() const;
};

// The median 3x3 Shi-Tomasi response (cv::cornerMinEigenVal, Sobel 3) of white noise of one grey
// level (it scales with the variance); measured on 300x400 samples of Gaussian noise. For the
// default corner_block_px (3) only: other block sizes change the distribution, and the floor does
// not adjust.
inline constexpr double kNoiseCornerResponsePerSigma2 = 5.5e-6;

// The noise sigma (grey levels) of an 8-bit grey image, by Immerkaer's mask ([1 -2 1; -2 4 -2;
// 1 -2 1], which cancels planes and gains 6 on white noise): the median absolute response over
// every second row and column / (6 * 0.6745), so in steps of 0.247 grey levels. Texture inflates
// it; where most of the image is flat (haze, sky, road) the median is the noise's.
double NoiseSigma(const cv::Mat& grey);

// Standard deviation of the intensities of `grey` (CV_8UC1), grey levels.
double IntensityStd(const cv::Mat& grey);
// The median of the intensity std over 7 x 7 pixel boxes of an 8-bit grey image (grey levels;
// sampled every 4th pixel in each direction).
double MedianLocalStd(const cv::Mat& grey);
// How isotropic the texture around `p` is in an 8-bit grey image: the smaller over the larger
// eigenvalue of the gradient matrix (central differences) over the (2 half + 1)^2 window
// centred on p, clipped to the image. 1 for a corner with gradients in all directions, 0 for a
// straight edge or a flat window.
double CornerIsotropy(const cv::Mat& grey, cv::Point2f p, int half);

// `grey` (CV_8UC1) minus its Gaussian blur of `sigma_px`, plus 128 (saturated to 8 bits).
cv::Mat HighPassFilter(const cv::Mat& grey, double sigma_px);

// Local contrast normalisation of `grey` (CV_8UC1): 128 + 40 (I - m) / (s + floor), m and s the
// Gaussian-weighted mean and standard deviation of radius `sigma_px` (saturated to 8 bits).
cv::Mat LocalContrastNormalise(const cv::Mat& grey, double sigma_px, double floor);

struct FrontendStats {
  int tracked = 0, rejected_fb = 0, rejected_ransac = 0, detected = 0, stereo = 0;
  double median_flow_px = 0;
  // The measured low-contrast state (clahe_below_std > 0, and CLAHE, the stretch or the corner
  // check on) of this frame.
  bool low_contrast = false;
  // 1 when the contrast treatment switched on or off at this frame (the previous frame was then
  // prepared again to track from).
  int contrast_switches = 0;
  // Temporal tracks moved by the gain-and-offset refinement (klt_gain_offset).
  int klt_refined = 0;
  // The detection image's noise (NoiseSigma, grey levels) on frames that detect with
  // corner_noise_floor; 0 otherwise.
  double noise_sigma = 0;
};

// Gauss-Newton alignment of the (2h + 1)^2 window of `templ_image` around `t` to `target` from
// *p, with a gain a and an offset b of the target fitted: min over (p, a, b) of the sum over the
// window of (a target(p + w) + b - templ_image(t + w))^2 (8-bit images, bilinear samples). On
// convergence (a step under 0.01 px) sets *p and returns true; false, *p unchanged, when the
// window does not constrain both directions, leaves the image, or does not converge.
bool AlignWithGainOffset(const cv::Mat& templ_image, const Eigen::Vector2d& t,
                         const cv::Mat& target, int h, int max_iterations, Eigen::Vector2d* p);

struct FrontendOutput {
  int64_t t_ns = 0;
  std::vector<StereoObservation> observations;
  bool keyframe = false;
  FrontendStats stats;
};

class StereoFrontend {
 public:
  StereoFrontend(const camera::StereoRig& rig, const FrontendOptions& options);

  // `left`, `right`: 8-bit grey images of the calibrated size. `cur_cam_from_prev_cam`: the
  // left camera's rotation since the previous frame (from the gyro), or nullopt.
  // `match_all_stereo`: stereo-match every track even on a non-keyframe (for initialisation).
  FrontendOutput Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                         const std::optional<Eigen::Quaterniond>& cur_cam_from_prev_cam,
                         bool match_all_stereo = false);
  // Forget every track (after a tracking failure).
  void Reset();
  // Stop tracking these ids (backend outliers).
  void Drop(const std::set<uint64_t>& track_ids);
  // Records sub-stage times (frontend.pyramid, .track, .ransac, .detect, .stereo) when set.
  void set_timing(TimingStats* timing) { timing_ = timing; }

 private:
  struct Track {
    uint64_t id;
    cv::Point2f pixel;
    std::optional<cv::Point2f> stereo_offset;  // right - left pixel at the last stereo match
    int stereo_failures = 0;                   // failed attempts since the last match
  };
  // `image` as tracked: the low-contrast treatment in force (CLAHE or the contrast stretch, with
  // the left image's mean `left_mean`), then the optional filters; into `buffer` when changed.
  cv::Mat Prepare(const cv::Mat& image, double left_mean, cv::Mat* buffer);
  // New corners in `image` (the left image as tracked; `pyramid`: its KLT pyramid).
  void Detect(const cv::Mat& image, const std::vector<cv::Mat>& pyramid,
              std::vector<Track>* tracks);
  void MatchStereo(const std::vector<cv::Mat>& left_pyramid,
                   const std::vector<cv::Mat>& right_pyramid, std::vector<Track>* tracks,
                   std::vector<std::optional<cv::Point2f>>* right, bool all);
  // The stereo matches whose `matched` is set, refined over the stereo_refine_window_px window on
  // the full-resolution images (Gauss-Newton on the right position and the right image's gain
  // and offset) from where the stereo window put them; a refinement that does not converge or
  // moves a match more than forward_backward_px keeps the match as it was.
  void RefineStereo(const std::vector<cv::Mat>& left_pyramid,
                    const std::vector<cv::Mat>& right_pyramid,
                    const std::vector<cv::Point2f>& left_pts, const std::vector<uchar>& matched,
                    std::vector<cv::Point2f>* right_pts) const;
  // *p aligned to `templ` around `t` (AlignWithGainOffset over a (2h + 1)^2 window): true, *p
  // moved, when the alignment converges within forward_backward_px of where *p was.
  bool RefineWithGainOffset(const cv::Mat& templ, const cv::Point2f& t, const cv::Mat& target,
                            int h, cv::Point2f* p) const;
  // `first_new_id`: the id of the first corner detected in this frame (later ids are new too).
  bool DecideKeyframe(int64_t t_ns, const std::vector<Track>& tracks, uint64_t first_new_id);

  camera::StereoRig rig_;
  FrontendOptions options_;
  Eigen::Matrix3d essential_;  // right_x^T E left_x = 0 for normalised points
  std::vector<cv::Mat> prev_pyramid_;
  // Buffers reused from frame to frame (the next left pyramid is built in the one before the
  // previous; the right pyramid and the contrast-normalised images in their own): an image or
  // pyramid allocated anew each frame costs its page faults each frame (at 800x600 about 6 MB
  // a frame; a tenth of `optinav vio`'s time on these VMs, bench/RESULTS.md). A pyramid level is
  // written only when nothing else references it (KeepIfExclusive), so a caller's image is never
  // changed; the contrast-normalised images are ours alone (a pyramid copies them).
  std::vector<cv::Mat> spare_pyramid_, right_pyramid_;
  cv::Mat left_eq_buffer_, right_eq_buffer_, detect_mask_;
  cv::Mat corner_response_, corner_strong_;  // the corner floor's, kept as the mask is
  std::vector<Track> tracks_;
  uint64_t next_id_ = 1;
  // The last keyframe: its time and its tracks' pixels.
  int64_t keyframe_t_ns_ = 0;
  std::vector<Track> keyframe_tracks_;
  bool has_keyframe_ = false;
  // keyframe_fresh_probation: ids >= this in keyframe_tracks_ were detected at the keyframe,
  // and their probation is still to be decided (at the first frame after the keyframe).
  uint64_t keyframe_first_new_id_ = 0;
  bool probation_pending_ = false;
  double stereo_depth_guess_m_ = 3.0;
  // Gyro rotation accumulated since the last keyframe (parallax is measured without it).
  Eigen::Quaterniond cur_from_keyframe_ = Eigen::Quaterniond::Identity();
  bool has_rotation_since_keyframe_ = false;
  cv::Ptr<cv::CLAHE> clahe_;   // when clahe_clip_limit > 0
  bool low_contrast_ = false;  // the low-contrast state (clahe_below_std or the local one)
  double noise_sigma_ = 0;     // the last Detect's NoiseSigma (corner_noise_floor), else 0
  // Whether this frame gets the fog treatment (local normalisation, isotropy check).
  bool FogTreatment() const { return low_contrast_ || !options_.fog_treatment_low_contrast_only; }
  bool low_global_ = false, low_local_ = false;  // each measure's own state (hysteresis)
  double stretch_gain_ = 0;  // contrast_stretch_std's current gain (0: none yet)
  // The previous left image as given and its mean (kept when the contrast treatment can switch,
  // to prepare it again as the next frame is prepared).
  cv::Mat prev_left_;
  double prev_left_mean_ = 0;
  TimingStats* timing_ = nullptr;  // median depth of the last stereo matches
};

}  // namespace optinav::vio
