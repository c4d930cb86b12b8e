#include "optinav/vio/pipeline.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <functional>
#include <mutex>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "optinav/io/airsim_recording.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"
#include "optinav/util/stages.h"
#include "optinav/util/timer.h"

namespace optinav::vio {

namespace {

struct Packet {
  int64_t t_ns = 0;
  cv::Mat left, right;
  std::vector<TimedImuSample> imu;  // samples to add before the frame
  std::vector<GnssSample> gnss;     // samples up to the frame time
};

cv::Mat LoadGrey(const std::string& path, const camera::PinholeCamera& calibration, bool* missing) {
  cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty()) {
    *missing = true;
    return image;
  }
  if (image.cols != calibration.width || image.rows != calibration.height)
    throw Error("image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                    " but the calibration says " + std::to_string(calibration.width) + "x" +
                    std::to_string(calibration.height),
                {.file = path, .field = "resolution"});
  return image;
}

}  // namespace

Trajectory EstimatesToTrajectory(const std::vector<FrameEstimate>& estimates,
                                 const std::optional<Rigid3d>& body_from_cam) {
  Trajectory t;
  t.Reserve(estimates.size(), true);
  for (const FrameEstimate& e : estimates)
    t.Add(e.state.t_ns,
          body_from_cam ? e.state.world_from_body * *body_from_cam : e.state.world_from_body);
  return t;
}

Trajectory EstimatesToEnuTrajectory(const std::vector<FrameEstimate>& estimates,
                                    const std::optional<Rigid3d>& body_from_cam) {
  return EstimatesToEnuTrajectory(estimates, LiveAlignments(estimates), body_from_cam);
}

namespace {

struct StereoPair {
  int64_t t_ns;
  std::string left, right;
};

// What the frontend thread hands to the backend thread: the GNSS samples up to the frame (in
// time order, before it) and the frame's packet (none when the frame was skipped).
struct TrackedPacket {
  Timer since_frame_in;  // started when the frontend step took the frame
  std::vector<GnssSample> gnss;
  std::optional<FramePacket> frame;
  cv::Mat left, right;  // for loop closure
};

// The run loop shared by the dataset formats.
VioRunResult RunOnPairs(const camera::StereoRig& rig, const Rigid3d& body_from_cam0,
                        const ImuNoise& noise, const std::vector<TimedImuSample>& imu,
                        std::vector<StereoPair> pairs, const VioRunOptions& options,
                        VioRunResult result) {
  if (options.max_frames > 0 && pairs.size() > options.max_frames) pairs.resize(options.max_frames);
  result.frames_total = pairs.size();
  result.body_from_cam0 = body_from_cam0;
  // The loader: builds packets in order; `emit` returns false to stop.
  auto load = [&](const std::function<bool(Packet)>& emit) {
    size_t imu_next = 0, gnss_next = 0;
    for (const StereoPair& p : pairs) {
      Packet packet;
      packet.t_ns = p.t_ns;
      bool missing = false;
      packet.left = LoadGrey(p.left, rig.left, &missing);
      if (!missing) packet.right = LoadGrey(p.right, rig.right, &missing);
      if (missing) {
        if (!options.skip_missing_images)
          throw Error("cannot read image", {.file = packet.left.empty() ? p.left : p.right});
        spdlog::warn("vio: cannot read image of frame {} ns, frame skipped", p.t_ns);
        packet.left.release();
      }
      // IMU up to a little after the frame (interpolation at the frame time needs the next one).
      while (imu_next < imu.size() && imu[imu_next].t_ns <= p.t_ns + 20'000'000)
        packet.imu.push_back(imu[imu_next++]);
      while (options.gnss && gnss_next < options.gnss_samples.size() &&
             options.gnss_samples[gnss_next].t_ns <= p.t_ns)
        packet.gnss.push_back(options.gnss_samples[gnss_next++]);
      if (!emit(std::move(packet))) return;
    }
  };

  VioEstimator estimator(rig, body_from_cam0, noise, options.vio);
  if (options.gnss) estimator.EnableGnss(*options.gnss);
  const LoopClosureOptions& lc = options.vio.loop_closure;
  std::optional<LoopCloser> closer;
  if (options.vio.mode == VioMode::kStereo ? lc.stereo_only : lc.stereo_imu) {
    if (options.gnss)
      spdlog::warn("vio: loop closure is not run with GNSS fusion");
    else
      closer.emplace(rig, body_from_cam0, lc,
                     /*gravity_aligned=*/options.vio.mode == VioMode::kStereoImu);
  }
  TimingStats loop_timing;  // loop closure and the per-frame latency
  if (closer) closer->set_timing(&loop_timing);
  int track_initializations = 0;
  auto record = [&](std::optional<FrameEstimate> e, const cv::Mat& left, const cv::Mat& right,
                    const Timer& since_frame_in) {
    // Earlier frames first (an in-motion alignment window, output when it succeeds).
    std::vector<FrameEstimate> delayed = estimator.TakeDelayedEstimates();
    const FrameEstimate* first = !delayed.empty() ? &delayed.front() : e ? &*e : nullptr;
    if (first && estimator.initializations() != track_initializations) {
      if (track_initializations > 0) {
        result.track_starts.push_back(result.estimates.size());
        if (closer) closer->NewTrack(first->state.t_ns);
      }
      track_initializations = estimator.initializations();
    }
    for (FrameEstimate& d : delayed) result.estimates.push_back(d);
    if (!e) return;
    if (result.first_init_kind.empty()) result.first_init_kind = estimator.last_init_kind();
    if (closer && e->keyframe && !left.empty()) {
      ScopedTimer timer(loop_timing, "loop_closure");
      closer->AddKeyframe(e->state, left, right);
    }
    result.estimates.push_back(std::move(*e));
    loop_timing.Add("latency", since_frame_in.ElapsedSeconds());
  };
  // An artificially slow backend (tests, benchmarks).
  const auto backend = [&](FramePacket packet) {
    if (options.injected_backend_delay_ms > 0 && packet.features.keyframe)
      std::this_thread::sleep_for(
          std::chrono::duration<double, std::milli>(options.injected_backend_delay_ms));
    return estimator.RunBackend(std::move(packet));
  };

  if (!options.threaded) {
    load([&](Packet packet) {
      for (const TimedImuSample& s : packet.imu) estimator.AddImu(s);
      for (const GnssSample& s : packet.gnss) estimator.AddGnss(s);
      if (packet.left.empty()) return true;
      ++result.frames_processed;
      const Timer frame_in;
      std::optional<FramePacket> frame =
          estimator.RunFrontend(packet.t_ns, packet.left, packet.right);
      if (frame) record(backend(std::move(*frame)), packet.left, packet.right, frame_in);
      return true;
    });
  } else {
    // loader -> frontend -> backend, each in its own thread; the backend's feedback reaches the
    // frontend through the estimator's numbered mailbox (the frontend waits for the feedback it
    // needs, so the result is the sequential one); a failure wakes a waiting frontend.
    RunThreeStages<Packet, TrackedPacket>(
        8, load,
        [&](Packet p) {
          for (const TimedImuSample& s : p.imu) estimator.AddImu(s);
          TrackedPacket out;
          out.gnss = std::move(p.gnss);
          if (!p.left.empty()) {
            ++result.frames_processed;
            out.frame = estimator.RunFrontend(p.t_ns, p.left, p.right);
            if (closer) out.left = p.left, out.right = p.right;
          }
          return out;
        },
        [&](TrackedPacket p) {
          for (const GnssSample& s : p.gnss) estimator.AddGnss(s);
          if (p.frame) record(backend(std::move(*p.frame)), p.left, p.right, p.since_frame_in);
        },
        [&] { estimator.CancelFeedbackWait(); });
  }
  estimator.Finish();
  if (closer) {  // the loops verified since the last solve
    ScopedTimer timer(loop_timing, "loop_closure.finish");
    closer->Finish();
  }
  result.lost = estimator.lost_intervals();
  result.initializations = estimator.initializations();
  result.frozen_frames = estimator.frozen_frames();
  result.imu_inflated_frames = estimator.imu_inflations();
  if (const GnssFusion* gnss = estimator.gnss()) {
    result.gnss_rejected = gnss->rejected();
    result.gnss_stats = gnss->stats();
    result.gnss_smoothing = SmoothGnssAlignment(result.estimates, result.track_starts, gnss->used(),
                                                gnss->inflations(), gnss->options());
    if (result.gnss_smoothing.tracks_smoothed)
      spdlog::info("gnss: output smoothed over {} sample(s) in {:.2f} s",
                   result.gnss_smoothing.samples, result.gnss_smoothing.solve_s);
  }
  for (const std::string& stage : estimator.timing().Stages())
    result.timing[stage] = estimator.timing().Summary(stage);
  for (const std::string& stage : loop_timing.Stages())
    result.timing[stage] = loop_timing.Summary(stage);
  if (closer) {
    result.loop_closure_ran = true;
    result.loops = closer->loops();
    result.loop_keyframes = closer->keyframes();
    result.loop_faded_keyframes = closer->faded_keyframes();
    result.loops_unsupported = closer->unsupported_loops();
    result.loops_aliased = closer->aliased_loops();
    if (!result.loops.empty()) {
      result.odometry = result.estimates;
      for (FrameEstimate& e : result.estimates) {
        const Rigid3d c = closer->CorrectionAt(e.state.t_ns);
        e.state.world_from_body = c * e.state.world_from_body;
        e.state.velocity = c.rotation * e.state.velocity;
      }
    }
  }
  return result;
}

}  // namespace

BodyImu ReadBodyImu(const io::EurocDataset& ds) {
  if (ds.imu_csv.empty() || !ds.imu_calibration)
    throw Error("no IMU: mav0/imu0 with data.csv and sensor.yaml is needed", {.file = ds.mav0_dir});
  const io::ImuCalibration& c = *ds.imu_calibration;
  BodyImu imu;
  imu.noise.gyro_noise_density = c.gyroscope_noise_density;
  imu.noise.accel_noise_density = c.accelerometer_noise_density;
  imu.noise.gyro_random_walk = c.gyroscope_random_walk;
  imu.noise.accel_random_walk = c.accelerometer_random_walk;
  if (c.body_from_imu.translation.norm() > 0.01)
    spdlog::warn("vio: imu0 T_BS has a {:.3f} m lever arm; it is ignored (IMU taken as body)",
                 c.body_from_imu.translation.norm());
  const Eigen::Quaterniond r = c.body_from_imu.rotation;
  for (const io::ImuSample& s : io::ReadImuCsv(ds.imu_csv))
    imu.samples.push_back({s.t_ns, r * s.gyro_rad_s, r * s.accel_m_s2});
  return imu;
}

VioRunResult RunVioOnEuroc(const std::string& dataset_dir, const VioRunOptions& options) {
  if (const std::string e = options.vio.Check(); !e.empty()) throw Error(e, {.field = "config"});
  io::EurocOpenOptions open;
  open.drop_missing_images = options.skip_missing_images;
  const io::EurocDataset ds = io::OpenEurocDataset(dataset_dir, open);
  if (!ds.cam0 || !ds.cam1)
    throw Error("VIO needs a stereo pair: mav0/cam0 and mav0/cam1", {.file = ds.mav0_dir});
  const bool use_imu = options.vio.mode == VioMode::kStereoImu;
  if (options.gnss && !use_imu)
    throw Error("GNSS fusion needs stereo-imu mode", {.file = ds.mav0_dir, .field = "--gnss"});
  if (use_imu && (ds.imu_csv.empty() || !ds.imu_calibration))
    throw Error("stereo-imu mode needs mav0/imu0 (use --mode stereo without IMU)",
                {.file = ds.mav0_dir});
  const camera::StereoRig rig = io::ToStereoRig(ds.cam0->calibration, ds.cam1->calibration);

  VioRunResult result;
  BodyImu imu;
  if (use_imu) imu = ReadBodyImu(ds);

  // Pair left and right images by stamp.
  std::vector<StereoPair> pairs;
  const auto& rights = ds.cam1->images;
  for (const io::ImageEntry& l : ds.cam0->images) {
    const auto it = std::lower_bound(rights.begin(), rights.end(), l.t_ns - 1'000'000,
                                     [](const io::ImageEntry& e, int64_t t) { return e.t_ns < t; });
    if (it == rights.end() || std::llabs(it->t_ns - l.t_ns) > 1'000'000) {
      ++result.frames_unpaired;
      continue;
    }
    pairs.push_back({l.t_ns, l.path, it->path});
  }
  if (result.frames_unpaired > 0)
    spdlog::warn("vio: {} left frames without a right frame within 1 ms are skipped",
                 result.frames_unpaired);
  return RunOnPairs(rig, ds.cam0->calibration.body_from_cam, imu.noise, imu.samples,
                    std::move(pairs), options, std::move(result));
}

VioRunResult RunVioOnAirsim(const std::string& dataset_dir, const VioRunOptions& options) {
  if (const std::string e = options.vio.Check(); !e.empty()) throw Error(e, {.field = "config"});
  if (options.vio.mode != VioMode::kStereo)
    throw Error("AirSim recordings carry no IMU: use --mode stereo", {.file = dataset_dir});
  if (options.gnss)
    throw Error("GNSS fusion needs a EuRoC dataset with IMU",
                {.file = dataset_dir, .field = "--gnss"});
  io::AirsimReadOptions read;
  read.check_images_exist = !options.skip_missing_images;
  const io::AirsimRecording rec = io::ReadAirsimRecording(dataset_dir, read);
  std::vector<StereoPair> pairs;
  VioRunResult result;
  for (const io::AirsimRecord& r : rec.records) {
    // Left and right by name (AirSim: img_<camera>_0_<t>.png), else in listed order.
    std::string left, right;
    for (const std::string& path : r.image_paths) {
      const std::string name = std::filesystem::path(path).filename().string();
      if (name.find("left") != std::string::npos && left.empty())
        left = path;
      else if (name.find("right") != std::string::npos && right.empty())
        right = path;
    }
    if ((left.empty() || right.empty()) && r.image_paths.size() >= 2)
      left = r.image_paths[0], right = r.image_paths[1];
    if (left.empty() || right.empty()) {
      ++result.frames_unpaired;
      continue;
    }
    pairs.push_back({r.t_ns, left, right});
  }
  if (pairs.empty()) throw Error("no stereo image pairs in the recording", {.file = dataset_dir});
  // The recording has no calibration: the rig of the AirSim weather dataset (SEEDS.md part 1:
  // rectified pinhole, given field of view and baseline), image size from the first left image.
  const cv::Mat first = cv::imread(pairs.front().left, cv::IMREAD_GRAYSCALE);
  if (first.empty()) throw Error("cannot read image", {.file = pairs.front().left});
  camera::StereoRig rig;
  rig.left = rig.right = camera::PinholeCamera::FromHorizontalFov(
      first.cols, first.rows, options.airsim_hfov_deg * M_PI / 180.0);
  rig.right_from_left =
      Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-options.airsim_baseline_m, 0, 0));
  // Camera mounting: from camera_info.csv when present, else looking along the body x axis.
  Eigen::Matrix3d body_from_optical;
  body_from_optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Rigid3d body_from_cam0(Eigen::Quaterniond(body_from_optical), Eigen::Vector3d::Zero());
  if (!rec.left_camera.empty() && rec.records.front().world_from_body)
    body_from_cam0 =
        rec.records.front().world_from_body->Inverse() * rec.left_camera.front().world_from_cam;
  return RunOnPairs(rig, body_from_cam0, ImuNoise{}, {}, std::move(pairs), options,
                    std::move(result));
}

}  // namespace optinav::vio
