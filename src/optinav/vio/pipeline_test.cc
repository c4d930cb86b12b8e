#include "optinav/vio/pipeline.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <utility>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/eval/metrics.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/util/testing.h"

namespace optinav::vio {
namespace {

std::string Micro() {
  return (optinav::testing::SharedDataDir() / "euroc" / "V1_01_micro").string();
}

Trajectory GroundTruth() {
  return io::ReadTrajectory((optinav::testing::SharedDataDir() / "euroc" / "V1_01_micro" / "mav0" /
                             "state_groundtruth_estimate0" / "data.csv")
                                .string());
}

TEST(Pipeline, EurocMicroInitialisesStaticallyAndDriftsLessThan2cm) {
  VioRunOptions options;
  const VioRunResult r = RunVioOnEuroc(Micro(), options);
  ASSERT_GT(r.estimates.size(), 80u);
  EXPECT_EQ(r.first_init_kind, "static");
  EXPECT_TRUE(r.lost.empty());
  const Trajectory est = EstimatesToTrajectory(r.estimates);
  const Trajectory gt = GroundTruth();
  // End-to-end drift: the relative motion first -> last frame against the ground truth's.
  const Rigid3d est_rel = est.pose(0).Inverse() * est.pose(est.size() - 1);
  const auto gt0 = gt.InterpolateAt(est.t_ns.front());
  const auto gt1 = gt.InterpolateAt(est.t_ns.back());
  ASSERT_TRUE(gt0 && gt1);
  const Rigid3d gt_rel = gt0->Inverse() * *gt1;
  const double drift = (est_rel.translation - gt_rel.translation).norm();
  // APE after SE(3) alignment over the clip.
  eval::SyncedPair synced = eval::Synchronize(gt, est);
  eval::AlignTrajectory(synced.ref, &synced.est, {.mode = eval::AlignMode::kSe3});
  std::vector<double> errors;
  for (size_t i = 0; i < synced.est.size(); ++i)
    errors.push_back((synced.est.positions[i] - synced.ref.positions[i]).norm());
  const eval::Statistics ape = eval::ComputeStatistics(errors);
  std::printf(
      "V1_01_micro: %zu frames, %s initialisation, ground-truth motion %.3f m, drift "
      "first->last %.4f m (< 0.02), APE RMSE (SE3) %.4f m (< 0.02), lost intervals %zu; "
      "median frame %.1f ms\n",
      r.estimates.size(), r.first_init_kind.c_str(), gt_rel.translation.norm(), drift, ape.rmse,
      r.lost.size(), r.timing.at("total").median_s * 1e3);
  EXPECT_LT(drift, 0.02);
  EXPECT_LT(ape.rmse, 0.02);
}

// APE RMSE (SE(3) alignment) of the body trajectory against the clip's ground truth.
double ApeRmse(const std::vector<FrameEstimate>& estimates) {
  eval::SyncedPair synced = eval::Synchronize(GroundTruth(), EstimatesToTrajectory(estimates));
  eval::AlignTrajectory(synced.ref, &synced.est, {.mode = eval::AlignMode::kSe3});
  std::vector<double> errors;
  for (size_t i = 0; i < synced.est.size(); ++i)
    errors.push_back((synced.est.positions[i] - synced.ref.positions[i]).norm());
  return eval::ComputeStatistics(errors).rmse;
}

void ExpectTimingKeys(const VioRunResult& r) {
  for (const char* stage : {"frontend", "backend", "backend_keyframe", "total"}) {
    ASSERT_TRUE(r.timing.count(stage)) << stage;
    EXPECT_GT(r.timing.at(stage).count, 0u) << stage;
  }
  // One "total" sample per frame handed to the estimator.
  EXPECT_EQ(r.timing.at("total").count, r.frames_processed);
  EXPECT_EQ(r.timing.at("frontend").count, r.frames_processed);
}

// Every estimate bit for bit.
void ExpectSameEstimates(const VioRunResult& a, const VioRunResult& b, const std::string& what) {
  ASSERT_EQ(a.estimates.size(), b.estimates.size()) << what;
  size_t differing = 0;
  for (size_t i = 0; i < a.estimates.size(); ++i) {
    const StateEstimate &x = a.estimates[i].state, &y = b.estimates[i].state;
    differing += x.t_ns != y.t_ns ||
                 x.world_from_body.translation != y.world_from_body.translation ||
                 x.world_from_body.rotation.coeffs() != y.world_from_body.rotation.coeffs() ||
                 x.velocity != y.velocity || x.bias.gyro != y.bias.gyro ||
                 x.bias.accel != y.bias.accel || a.estimates[i].keyframe != b.estimates[i].keyframe;
  }
  EXPECT_EQ(differing, 0u) << what << ": estimates that differ";
  EXPECT_EQ(a.initializations, b.initializations) << what;
  EXPECT_EQ(a.lost.size(), b.lost.size()) << what;
  EXPECT_EQ(a.first_init_kind, b.first_init_kind) << what;
}

TEST(Pipeline, SequentialModeIsDeterministic) {
  VioRunOptions options;  // threaded = false
  const VioRunResult a = RunVioOnEuroc(Micro(), options);
  const VioRunResult b = RunVioOnEuroc(Micro(), options);
  ASSERT_GT(a.estimates.size(), 80u);
  ExpectSameEstimates(a, b, "two sequential runs");
  ExpectTimingKeys(a);
}

// The threaded pipeline's result must not depend on how busy the machine is: the frontend waits
// for the backend feedback it uses (numbered by frame), so threaded runs equal the sequential one
// bit for bit, with or without a backend slowed down by 40 ms per keyframe (which, unfixed, let
// the frontend run frames ahead with stale bias and rejected tracks), at both feedback lags.
TEST(Pipeline, ThreadedModeEqualsSequentialWhateverTheBackendSpeed) {
  for (const int lag : {1, 2}) {
    VioRunOptions options;
    options.vio.feedback_lag_frames = lag;
    const VioRunResult seq = RunVioOnEuroc(Micro(), options);
    ASSERT_GT(seq.estimates.size(), 80u);
    EXPECT_TRUE(seq.lost.empty());
    options.threaded = true;
    const VioRunResult thr = RunVioOnEuroc(Micro(), options);
    options.injected_backend_delay_ms = 40;
    const VioRunResult slow = RunVioOnEuroc(Micro(), options);
    EXPECT_EQ(thr.frames_processed, seq.frames_processed);
    ExpectSameEstimates(seq, thr, fmt::format("lag {}: threaded vs sequential", lag));
    ExpectSameEstimates(seq, slow, fmt::format("lag {}: slow backend vs sequential", lag));
    const auto ms = [](const VioRunResult& r, const char* stage) {
      return r.timing.count(stage) ? r.timing.at(stage).median_s * 1e3 : -1.0;
    };
    std::printf(
        "V1_01_micro, feedback lag %d: APE RMSE (SE3) %.5f m in all three runs; latency median "
        "sequential %.1f ms, threaded %.1f ms, slow backend %.1f ms (frontend wait %.1f ms)\n",
        lag, ApeRmse(seq.estimates), ms(seq, "latency"), ms(thr, "latency"), ms(slow, "latency"),
        ms(slow, "frontend_wait"));
    ExpectTimingKeys(thr);
    EXPECT_TRUE(thr.timing.count("latency"));
  }
}

// A copy of the clip (files symlinked, csv lines of images the clip does not ship removed) where
// one left image is replaced.
std::string MicroWithBadImage(const std::string& name, size_t frame,
                              const std::function<void(const std::string&)>& write) {
  namespace fs = std::filesystem;
  const fs::path dir = optinav::testing::MakeTempDir(name) / "V1_01_micro";
  const fs::path src = Micro();
  for (const auto& entry : fs::recursive_directory_iterator(src)) {
    const fs::path target = dir / fs::relative(entry.path(), src);
    if (entry.is_directory())
      fs::create_directories(target);
    else
      fs::create_symlink(entry.path(), target);
  }
  for (const char* cam : {"cam0", "cam1"}) {
    const fs::path csv = dir / "mav0" / cam / "data.csv";
    std::ifstream in(src / "mav0" / cam / "data.csv");
    std::string text, line;
    while (std::getline(in, line)) {
      const size_t comma = line.find(',');
      if (line.empty() || line[0] == '#' || comma == std::string::npos ||
          fs::exists(src / "mav0" / cam / "data" / line.substr(comma + 1)))
        text += line + "\n";
    }
    fs::remove(csv);
    optinav::testing::WriteFile(csv, text);
  }
  const io::EurocDataset ds = io::OpenEurocDataset(dir.string());
  const std::string image = ds.cam0->images.at(frame).path;
  fs::remove(image);
  write(image);
  return dir.string();
}

// Runs in both modes; returns the two error messages ("" when no error).
std::pair<std::string, std::string> ErrorsOfBothModes(const std::string& dataset,
                                                      VioRunOptions options) {
  std::pair<std::string, std::string> messages;
  for (const bool threaded : {false, true}) {
    options.threaded = threaded;
    std::string& message = threaded ? messages.second : messages.first;
    try {
      RunVioOnEuroc(dataset, options);
    } catch (const Error& e) {
      message = e.what();
    }
  }
  return messages;
}

// The gyro bias held on low-contrast frames (lowcontrast_gyro_walk_scale): the clip's frames have
// contrast, so the default run is the run without the hold, bit for bit; with every frame
// measured low in contrast (clahe_below_std above any image's std) the held run's biases differ
// from the modelled walk's, the accuracy holds, and threaded equals sequential.
TEST(Pipeline, LowContrastFramesHoldTheGyroBias) {
  VioRunOptions held, modelled;
  modelled.vio.lowcontrast_gyro_walk_scale = 1.0;
  ASSERT_LT(held.vio.lowcontrast_gyro_walk_scale, 1.0);
  ExpectSameEstimates(RunVioOnEuroc(Micro(), held), RunVioOnEuroc(Micro(), modelled),
                      "clear frames: default vs as modelled");
  held.vio.frontend.clahe_below_std = 1000;
  modelled.vio.frontend.clahe_below_std = 1000;
  const VioRunResult a = RunVioOnEuroc(Micro(), held), b = RunVioOnEuroc(Micro(), modelled);
  ASSERT_GT(a.estimates.size(), 80u);
  ASSERT_EQ(a.estimates.size(), b.estimates.size());
  double largest = 0;  // the largest gyro bias difference between the two runs
  for (size_t i = 0; i < a.estimates.size(); ++i)
    largest =
        std::max(largest, (a.estimates[i].state.bias.gyro - b.estimates[i].state.bias.gyro).norm());
  std::printf(
      "V1_01_micro, every frame low in contrast: gyro bias held vs as modelled differs by up to "
      "%.3g rad/s; APE RMSE (SE3) %.4f m held, %.4f m as modelled (< 0.05)\n",
      largest, ApeRmse(a.estimates), ApeRmse(b.estimates));
  EXPECT_GT(largest, 1e-6);
  EXPECT_LT(ApeRmse(a.estimates), 0.05);
  held.threaded = true;
  ExpectSameEstimates(a, RunVioOnEuroc(Micro(), held), "held: threaded vs sequential");
}

TEST(Pipeline, ThreadedModeReportsErrorsLikeSequential) {
  // Wrong size at frame 50: the loader thread throws; the frontend and backend threads stop.
  const std::string small = MicroWithBadImage("vio_small_image", 50, [](const std::string& path) {
    cv::imwrite(path, cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)));
  });
  const auto [seq, thr] = ErrorsOfBothModes(small, VioRunOptions{});
  std::printf("wrong-size image: '%s'\n", thr.c_str());
  EXPECT_NE(seq.find("image is 10x10"), std::string::npos) << seq;
  EXPECT_EQ(thr, seq);
  // An unreadable image: an error when missing images are not skipped ...
  const std::string garbage =
      MicroWithBadImage("vio_garbage_image", 20, [](const std::string& path) {
        std::FILE* f = std::fopen(path.c_str(), "wb");
        std::fputs("not a png", f);
        std::fclose(f);
      });
  VioRunOptions strict;
  strict.skip_missing_images = false;
  const auto [seq2, thr2] = ErrorsOfBothModes(garbage, strict);
  EXPECT_NE(seq2.find("cannot read image"), std::string::npos) << seq2;
  EXPECT_EQ(thr2, seq2);
  // ... else the frame is skipped in both modes.
  VioRunOptions lenient;
  lenient.max_frames = 40;
  const VioRunResult a = RunVioOnEuroc(garbage, lenient);
  lenient.threaded = true;
  const VioRunResult b = RunVioOnEuroc(garbage, lenient);
  EXPECT_EQ(a.frames_processed, 39u);
  EXPECT_EQ(b.frames_processed, 39u);
  EXPECT_EQ(b.estimates.size(), a.estimates.size());
}

TEST(Pipeline, StereoOnlyModeRuns) {
  VioRunOptions options;
  options.vio.mode = VioMode::kStereo;
  options.max_frames = 40;
  const VioRunResult r = RunVioOnEuroc(Micro(), options);
  ASSERT_GT(r.estimates.size(), 30u);
  const Trajectory est = EstimatesToTrajectory(r.estimates);
  const double moved = (est.pose(0).Inverse() * est.pose(est.size() - 1)).translation.norm();
  std::printf(
      "stereo-only on V1_01_micro (40 frames): end-to-end motion %.4f m (nearly still: "
      "< 0.05)\n",
      moved);
  EXPECT_LT(moved, 0.05);
}

}  // namespace
}  // namespace optinav::vio

namespace optinav::vio {
namespace {

// Drives the estimator directly with the real clip and injected failures.
class FailureTest : public ::testing::Test {
 protected:
  void SetUp() override {
    io::EurocOpenOptions open;
    open.drop_missing_images = true;
    ds_ = io::OpenEurocDataset(Micro(), open);
    rig_ = io::ToStereoRig(ds_.cam0->calibration, ds_.cam1->calibration);
    for (const io::ImuSample& s : io::ReadImuCsv(ds_.imu_csv))
      imu_.push_back({s.t_ns, s.gyro_rad_s, s.accel_m_s2});
    std::map<int64_t, std::string> rights;
    for (const auto& r : ds_.cam1->images) rights[r.t_ns] = r.path;
    for (const auto& l : ds_.cam0->images)
      if (rights.count(l.t_ns)) frames_.push_back({l.t_ns, l.path, rights[l.t_ns]});
  }
  struct Frame {
    int64_t t_ns;
    std::string left, right;
  };
  // Runs frames [0, n) with `black(i)` frames replaced by black images, IMU samples in
  // [imu_gap_from, imu_gap_to) removed, and `t_shift_ns` added to frames from `shift_from` on.
  std::vector<std::optional<FrameEstimate>> Run(VioEstimator* e, size_t n,
                                                const std::function<bool(size_t)>& black,
                                                int64_t imu_gap_from = 0, int64_t imu_gap_to = 0) {
    std::vector<std::optional<FrameEstimate>> out;
    size_t k = 0;
    const cv::Mat dark(rig_.left.height, rig_.left.width, CV_8UC1, cv::Scalar(0));
    for (size_t i = 0; i < n && i < frames_.size(); ++i) {
      const int64_t t = frames_[i].t_ns;
      for (; k < imu_.size() && imu_[k].t_ns <= t + 20'000'000; ++k)
        if (imu_[k].t_ns < imu_gap_from || imu_[k].t_ns >= imu_gap_to) e->AddImu(imu_[k]);
      const bool b = black(i);
      const cv::Mat l = b ? dark : cv::imread(frames_[i].left, cv::IMREAD_GRAYSCALE);
      const cv::Mat r = b ? dark : cv::imread(frames_[i].right, cv::IMREAD_GRAYSCALE);
      out.push_back(e->ProcessFrame(t, l, r));
    }
    e->Finish();
    return out;
  }
  io::EurocDataset ds_;
  camera::StereoRig rig_;
  std::vector<TimedImuSample> imu_;
  std::vector<Frame> frames_;
};

TEST_F(FailureTest, BlackFramesAreALostIntervalThenReinitialisation) {
  VioEstimator e(rig_, ds_.cam0->calibration.body_from_cam, ImuNoise{}, VioOptions{});
  // Frames 30..59 (1.5 s) black.
  const auto out = Run(&e, 80, [](size_t i) { return i >= 30 && i < 60; });
  ASSERT_EQ(e.lost_intervals().size(), 1u);
  const LostInterval& lost = e.lost_intervals()[0];
  std::printf(
      "black frames 30..59: lost %.2f s .. %.2f s (%s), %d initialisations, last pose "
      "%s\n",
      (lost.start_ns - frames_[0].t_ns) * 1e-9, (lost.end_ns - frames_[0].t_ns) * 1e-9,
      lost.reason.c_str(), e.initializations(), out.back() ? "estimated" : "missing");
  EXPECT_NE(lost.reason.find("tracked landmarks"), std::string::npos);
  EXPECT_EQ(lost.end_ns, frames_[60].t_ns);  // re-initialised on the first good frame
  EXPECT_EQ(e.initializations(), 2);
  ASSERT_TRUE(out.back().has_value());
  // The re-initialised track continues from the last good position (nearly still clip).
  EXPECT_LT(out.back()->state.world_from_body.translation.norm(), 0.05);
  // The interval starts at the last well-tracked frame, before the black ones.
  EXPECT_LT(lost.start_ns, frames_[30].t_ns);
}

TEST_F(FailureTest, ImuGapIsALostInterval) {
  VioEstimator e(rig_, ds_.cam0->calibration.body_from_cam, ImuNoise{}, VioOptions{});
  const int64_t gap_from = frames_[30].t_ns - 60'000'000, gap_to = frames_[30].t_ns + 40'000'000;
  const auto out = Run(
      &e, 60, [](size_t) { return false; }, gap_from, gap_to);
  ASSERT_EQ(e.lost_intervals().size(), 1u);
  std::printf("IMU gap of 0.1 s: lost interval %.3f .. %.3f s '%s'\n",
              (e.lost_intervals()[0].start_ns - frames_[0].t_ns) * 1e-9,
              (e.lost_intervals()[0].end_ns - frames_[0].t_ns) * 1e-9,
              e.lost_intervals()[0].reason.c_str());
  EXPECT_NE(e.lost_intervals()[0].reason.find("IMU gap"), std::string::npos);
  EXPECT_TRUE(out.back().has_value());
}

TEST_F(FailureTest, TimestampJumpAndRepeatedStamps) {
  VioEstimator e(rig_, ds_.cam0->calibration.body_from_cam, ImuNoise{}, VioOptions{});
  const cv::Mat l = cv::imread(frames_[20].left, cv::IMREAD_GRAYSCALE);
  const cv::Mat r = cv::imread(frames_[20].right, cv::IMREAD_GRAYSCALE);
  Run(&e, 25, [](size_t) { return false; });
  // The same stamp again: skipped, no crash.
  EXPECT_FALSE(e.ProcessFrame(frames_[24].t_ns, l, r).has_value());
  // A jump of 2 s (the IMU continues): a lost interval, then a fresh start.
  for (const TimedImuSample& s : imu_)
    if (s.t_ns > frames_[24].t_ns + 20'000'000 && s.t_ns <= frames_[24].t_ns + 2'100'000'000)
      e.AddImu(s);
  e.ProcessFrame(frames_[24].t_ns + 2'000'000'000, l, r);
  e.Finish();
  ASSERT_EQ(e.lost_intervals().size(), 1u);
  std::printf("2 s frame jump: lost interval '%s'\n", e.lost_intervals()[0].reason.c_str());
  EXPECT_NE(e.lost_intervals()[0].reason.find("frame time jump"), std::string::npos);
  EXPECT_EQ(e.initializations(), 2);
}

// Sensor faults (issue 22): each case feeds the real clip through one fault and checks that the
// estimator reports it, recovers and keeps going. The clip is nearly still (1.7 cm of motion),
// so a recovered track ends within a few centimetres of the start.
class SensorFaultTest : public FailureTest {
 protected:
  struct Delivery {
    int64_t t_ns;
    size_t image;  // index into frames_ whose images are delivered at t_ns
  };
  // Delivers `frames` in the given order; before each, the samples of `imu` (in list order, as
  // a driver would hand them over) up to 20 ms past the frame.
  std::vector<std::optional<FrameEstimate>> Feed(VioEstimator* e,
                                                 const std::vector<Delivery>& frames,
                                                 const std::vector<TimedImuSample>& imu) {
    std::vector<std::optional<FrameEstimate>> out;
    size_t k = 0;
    for (const Delivery& d : frames) {
      for (; k < imu.size() && imu[k].t_ns <= d.t_ns + 20'000'000; ++k) e->AddImu(imu[k]);
      out.push_back(e->ProcessFrame(d.t_ns, cv::imread(frames_[d.image].left, cv::IMREAD_GRAYSCALE),
                                    cv::imread(frames_[d.image].right, cv::IMREAD_GRAYSCALE)));
    }
    e->Finish();
    return out;
  }
  std::vector<Delivery> Frames(size_t n) const {
    std::vector<Delivery> d;
    for (size_t i = 0; i < n && i < frames_.size(); ++i) d.push_back({frames_[i].t_ns, i});
    return d;
  }
  static double LastOffset(const std::vector<std::optional<FrameEstimate>>& out) {
    for (auto it = out.rbegin(); it != out.rend(); ++it)
      if (*it) return (*it)->state.world_from_body.translation.norm();
    return 1e9;
  }
  std::unique_ptr<VioEstimator> Make(const VioOptions& options = VioOptions{}) const {
    return std::make_unique<VioEstimator>(rig_, ds_.cam0->calibration.body_from_cam, ImuNoise{},
                                          options);
  }
};

TEST_F(SensorFaultTest, FrozenFramesAreSkippedAndBridgedByTheImu) {
  // Frames 30..37 repeat frame 29's images (0.4 s): skipped, no lost interval.
  std::vector<Delivery> frames = Frames(80);
  for (size_t i = 30; i < 38; ++i) frames[i].image = 29;
  const std::unique_ptr<VioEstimator> owner = Make();
  VioEstimator& e = *owner;
  const auto out = Feed(&e, frames, imu_);
  std::printf("frozen 0.4 s: %d frozen frames, %zu lost intervals, last offset %.3f m\n",
              e.frozen_frames(), e.lost_intervals().size(), LastOffset(out));
  EXPECT_EQ(e.frozen_frames(), 8);
  EXPECT_TRUE(e.lost_intervals().empty());
  EXPECT_EQ(e.initializations(), 1);
  EXPECT_LT(LastOffset(out), 0.05);
  EXPECT_EQ(e.imu_inflations(), 0);  // the IMU fault check does not fire on a sound IMU
}

TEST_F(SensorFaultTest, LongFreezeIsALostIntervalThenRecovery) {
  // 1.5 s frozen (frames 30..59 repeat frame 29): longer than max_frame_gap_s.
  std::vector<Delivery> frames = Frames(90);
  for (size_t i = 30; i < 60; ++i) frames[i].image = 29;
  const std::unique_ptr<VioEstimator> owner = Make();
  VioEstimator& e = *owner;
  const auto out = Feed(&e, frames, imu_);
  ASSERT_EQ(e.lost_intervals().size(), 1u);
  std::printf("frozen 1.5 s: '%s', %d initialisations, last offset %.3f m\n",
              e.lost_intervals()[0].reason.c_str(), e.initializations(), LastOffset(out));
  EXPECT_NE(e.lost_intervals()[0].reason.find("frame time jump"), std::string::npos);
  EXPECT_EQ(e.frozen_frames(), 30);
  EXPECT_EQ(e.initializations(), 2);
  ASSERT_TRUE(out.back().has_value());
  EXPECT_LT(LastOffset(out), 0.05);
}

TEST_F(SensorFaultTest, CameraStopsFor5sWhileTheImuRuns) {
  // Frames 0..39, then 5 s without frames (the IMU keeps reporting the still vehicle: samples
  // of the still clip replayed), then frames 40..79 and their IMU 5 s later.
  const int64_t stop = 5'000'000'000;
  const int64_t t_last = frames_[39].t_ns, t_first = frames_[0].t_ns;
  std::vector<TimedImuSample> imu;
  for (const TimedImuSample& s : imu_)
    if (s.t_ns <= t_last) imu.push_back(s);
  for (size_t k = 0; imu.back().t_ns < t_last + stop; ++k) {
    TimedImuSample s = imu_[k % 400];  // the first 2 s of the still clip, over and over
    s.t_ns = imu.back().t_ns + 5'000'000;
    imu.push_back(s);
  }
  for (const TimedImuSample& s : imu_) {
    if (s.t_ns <= t_last || s.t_ns - t_first > 6'000'000'000) continue;
    TimedImuSample shifted = s;
    shifted.t_ns += stop;
    if (shifted.t_ns > imu.back().t_ns) imu.push_back(shifted);
  }
  std::vector<Delivery> frames = Frames(80);
  for (size_t i = 40; i < frames.size(); ++i) frames[i].t_ns += stop;
  const std::unique_ptr<VioEstimator> owner = Make();
  VioEstimator& e = *owner;
  const auto out = Feed(&e, frames, imu);
  ASSERT_EQ(e.lost_intervals().size(), 1u);
  const LostInterval& lost = e.lost_intervals()[0];
  std::printf("camera stopped 5 s: '%s' (%.2f s lost), %d initialisations, last offset %.3f m\n",
              lost.reason.c_str(), (lost.end_ns - lost.start_ns) * 1e-9, e.initializations(),
              LastOffset(out));
  EXPECT_NE(lost.reason.find("frame time jump"), std::string::npos);
  EXPECT_EQ(lost.end_ns, frames[40].t_ns);
  EXPECT_EQ(e.initializations(), 2);
  ASSERT_TRUE(out.back().has_value());
  EXPECT_LT(LastOffset(out), 0.05);
}

// 0.5 s of samples with 100x the sensor's white noise (gyro and accelerometer), eight noise
// draws. Trusted as modelled, the faulty IMU pulled the still clip's pose away and the vision's
// observations were then removed as outliers: a mean 0.20 m off at the end over 32 draws, 24
// of them over 0.1 m, two lost (2026-12-07; the single draw this test used then, seed 22,
// ended 0.03 m off). The backend's PnP check (imu_pnp_check_pixels) finds the intervals the
// vision contradicts and inflates their IMU noise: 6-9 mm in all 32.
TEST_F(SensorFaultTest, ImuSpikeOf100TimesTheNoiseFor0_5s) {
  const ImuNoise noise;
  const double dt = 1.0 / 200.0;
  const double gyro_sigma = 100 * noise.gyro_noise_density / std::sqrt(dt);
  const double accel_sigma = 100 * noise.accel_noise_density / std::sqrt(dt);
  const int64_t from = frames_[30].t_ns;
  double sum_unchecked = 0;
  for (const unsigned seed : {22u, 1u, 2u, 3u, 4u, 5u, 6u, 7u}) {
    SCOPED_TRACE("noise seed " + std::to_string(seed));
    std::mt19937 rng(seed);
    std::normal_distribution<double> n01;
    std::vector<TimedImuSample> imu = imu_;
    for (TimedImuSample& s : imu) {
      if (s.t_ns < from || s.t_ns >= from + 500'000'000) continue;
      s.gyro += gyro_sigma * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      s.accel += accel_sigma * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
    }
    const std::unique_ptr<VioEstimator> owner = Make();
    VioEstimator& e = *owner;
    const auto out = Feed(&e, Frames(90), imu);
    VioOptions unchecked_options;
    unchecked_options.backend.imu_pnp_check_pixels = 0;
    const std::unique_ptr<VioEstimator> unchecked = Make(unchecked_options);
    const auto unchecked_out = Feed(unchecked.get(), Frames(90), imu);
    ASSERT_TRUE(unchecked_out.back().has_value());
    const double unchecked_offset = LastOffset(unchecked_out);
    sum_unchecked += unchecked_offset;
    std::printf(
        "IMU spike (gyro %.2f rad/s, accel %.2f m/s^2 1-sigma for 0.5 s), seed %u: %zu lost "
        "intervals, %d intervals' IMU noise inflated, last offset %.3f m (< 0.03); without the "
        "PnP check %.3f m\n",
        gyro_sigma, accel_sigma, seed, e.lost_intervals().size(), e.imu_inflations(),
        LastOffset(out), unchecked_offset);
    // The track survives; the vision keeps the still clip still.
    EXPECT_TRUE(e.lost_intervals().empty());
    ASSERT_TRUE(out.back().has_value());
    EXPECT_LT(LastOffset(out), 0.03);
    EXPECT_GT(e.imu_inflations(), 0);
  }
  // The premise: without the check the fault moves the clip (mean 0.11 m over these draws).
  std::printf("without the PnP check: mean last offset %.3f m (> 0.05)\n", sum_unchecked / 8);
  EXPECT_GT(sum_unchecked / 8, 0.05);
}

TEST_F(SensorFaultTest, DuplicatedReorderedAndNanImuSamples) {
  // Every 10th sample twice, every 7th pair swapped, every 25th NaN: dropped with a warning,
  // the track unaffected.
  std::vector<TimedImuSample> imu;
  for (size_t k = 0; k < imu_.size(); ++k) {
    TimedImuSample s = imu_[k];
    if (k % 25 == 3) s.accel.x() = std::numeric_limits<double>::quiet_NaN();
    if (k % 25 == 13) s.gyro.z() = std::numeric_limits<double>::infinity();
    imu.push_back(s);
    if (k % 10 == 5) imu.push_back(s);
  }
  for (size_t k = 0; k + 1 < imu.size(); k += 7) std::swap(imu[k], imu[k + 1]);
  const std::unique_ptr<VioEstimator> owner = Make();
  VioEstimator& e = *owner;
  const auto out = Feed(&e, Frames(90), imu);
  std::printf("duplicated, swapped and NaN IMU samples: %zu lost intervals, last offset %.3f m\n",
              e.lost_intervals().size(), LastOffset(out));
  EXPECT_TRUE(e.lost_intervals().empty());
  EXPECT_EQ(e.initializations(), 1);
  EXPECT_LT(LastOffset(out), 0.05);
}

TEST_F(SensorFaultTest, OutOfOrderAndDuplicatedFrames) {
  // Frames 20/21 and 50/51 delivered swapped, frame 35 twice: the late ones are skipped.
  std::vector<Delivery> frames = Frames(80);
  std::swap(frames[20], frames[21]);
  std::swap(frames[50], frames[51]);
  frames.insert(frames.begin() + 36, frames[35]);
  const std::unique_ptr<VioEstimator> owner = Make();
  VioEstimator& e = *owner;
  const auto out = Feed(&e, frames, imu_);
  EXPECT_FALSE(out[21].has_value());  // frame 20 after frame 21
  EXPECT_FALSE(out[36].has_value());  // frame 35 again
  EXPECT_TRUE(e.lost_intervals().empty());
  EXPECT_LT(LastOffset(out), 0.05);
}

}  // namespace
}  // namespace optinav::vio

namespace optinav::vio {
namespace {

TEST(Pipeline, ReadBodyImuRotatesIntoTheBodyAndTakesTheNoise) {
  const auto dir = optinav::testing::MakeTempDir("body_imu");
  io::EurocDataset ds;
  ds.mav0_dir = (dir / "mav0").string();
  ds.imu_csv = optinav::testing::WriteFile(
      dir / "data.csv",
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
      "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n"
      "1000,0.1,0,0,1,0,9.81\n2000,0,0.2,0,0,2,9.81\n");
  EXPECT_ERROR(ReadBodyImu(ds), {.file = ds.mav0_dir}, "no IMU");  // no sensor.yaml
  io::ImuCalibration c;
  c.gyroscope_noise_density = 1e-4;
  c.gyroscope_random_walk = 2e-5;
  c.accelerometer_noise_density = 3e-3;
  c.accelerometer_random_walk = 4e-4;
  // IMU x along body y (90 deg about z), with a lever arm (ignored, warned).
  c.body_from_imu =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(0.05, 0, 0));
  ds.imu_calibration = c;
  const BodyImu imu = ReadBodyImu(ds);
  EXPECT_EQ(imu.noise.gyro_noise_density, 1e-4);
  EXPECT_EQ(imu.noise.gyro_random_walk, 2e-5);
  EXPECT_EQ(imu.noise.accel_noise_density, 3e-3);
  EXPECT_EQ(imu.noise.accel_random_walk, 4e-4);
  ASSERT_EQ(imu.samples.size(), 2u);
  EXPECT_EQ(imu.samples[1].t_ns, 2000);
  EXPECT_LT((imu.samples[0].gyro - Eigen::Vector3d(0, 0.1, 0)).norm(), 1e-12);
  EXPECT_LT((imu.samples[0].accel - Eigen::Vector3d(0, 1, 9.81)).norm(), 1e-12);
  EXPECT_LT((imu.samples[1].gyro - Eigen::Vector3d(-0.2, 0, 0)).norm(), 1e-12);
  EXPECT_LT((imu.samples[1].accel - Eigen::Vector3d(-2, 0, 9.81)).norm(), 1e-12);
}

TEST(VioConfig, DocumentedConfigEqualsTheBuiltInDefaults) {
  const std::filesystem::path config =
      std::filesystem::path(__FILE__).parent_path() / "../../../config/vio_euroc.yaml";
  const VioOptions file = LoadVioOptions(config.string());
  const VioOptions d;
  EXPECT_EQ(file.mode, d.mode);
  EXPECT_EQ(file.frontend.max_features, d.frontend.max_features);
  EXPECT_EQ(file.frontend.klt_window_px, d.frontend.klt_window_px);
  EXPECT_EQ(file.frontend.stereo_window_px, d.frontend.stereo_window_px);
  EXPECT_EQ(file.frontend.klt_max_iterations, d.frontend.klt_max_iterations);
  EXPECT_EQ(file.frontend.keyframe_min_parallax_px, d.frontend.keyframe_min_parallax_px);
  EXPECT_EQ(file.frontend.keyframe_min_tracked_ratio, d.frontend.keyframe_min_tracked_ratio);
  EXPECT_EQ(file.frontend.keyframe_fresh_probation, d.frontend.keyframe_fresh_probation);
  EXPECT_EQ(file.frontend.clahe_clip_limit, d.frontend.clahe_clip_limit);
  EXPECT_EQ(file.frontend.clahe_tiles, d.frontend.clahe_tiles);
  EXPECT_EQ(file.frontend.clahe_below_std, d.frontend.clahe_below_std);
  EXPECT_EQ(file.frontend.clahe_below_local_std, d.frontend.clahe_below_local_std);
  EXPECT_EQ(file.frontend.contrast_stretch_std, d.frontend.contrast_stretch_std);
  EXPECT_EQ(file.frontend.min_corner_response, d.frontend.min_corner_response);
  EXPECT_EQ(file.frontend.corner_noise_floor, d.frontend.corner_noise_floor);
  EXPECT_EQ(file.frontend.stereo_only_corner_noise_floor,
            d.frontend.stereo_only_corner_noise_floor);
  EXPECT_EQ(file.frontend.detect_min_eigen, d.frontend.detect_min_eigen);
  EXPECT_EQ(file.frontend.highpass_sigma_px, d.frontend.highpass_sigma_px);
  EXPECT_EQ(file.frontend.local_norm_sigma_px, d.frontend.local_norm_sigma_px);
  EXPECT_EQ(file.frontend.local_norm_floor, d.frontend.local_norm_floor);
  EXPECT_EQ(file.frontend.min_corner_isotropy, d.frontend.min_corner_isotropy);
  EXPECT_EQ(file.frontend.fog_treatment_low_contrast_only,
            d.frontend.fog_treatment_low_contrast_only);
  EXPECT_EQ(file.frontend.median_filter_px, d.frontend.median_filter_px);
  EXPECT_EQ(file.frontend.corner_block_px, d.frontend.corner_block_px);
  EXPECT_EQ(file.frontend.klt_gain_offset, d.frontend.klt_gain_offset);
  EXPECT_EQ(file.frontend.stereo_only_klt_gain_offset, d.frontend.stereo_only_klt_gain_offset);
  EXPECT_EQ(file.frontend.stereo_refine_window_px, d.frontend.stereo_refine_window_px);
  EXPECT_EQ(file.backend.window_keyframes, d.backend.window_keyframes);
  EXPECT_EQ(file.backend.max_iterations, d.backend.max_iterations);
  EXPECT_EQ(file.stereo_only_pnp_gate_pixels, d.stereo_only_pnp_gate_pixels);
  EXPECT_EQ(file.stereo_only_pnp_gate_median_factor, d.stereo_only_pnp_gate_median_factor);
  EXPECT_EQ(file.backend.huber_pixels, d.backend.huber_pixels);
  EXPECT_EQ(file.backend.outlier_pixels, d.backend.outlier_pixels);
  EXPECT_EQ(file.backend.predicted_gate_pixels, d.backend.predicted_gate_pixels);
  EXPECT_EQ(file.backend.predicted_gate_median_factor, d.backend.predicted_gate_median_factor);
  EXPECT_EQ(file.backend.ground_vehicle_lateral_sigma_m_s,
            d.backend.ground_vehicle_lateral_sigma_m_s);
  EXPECT_EQ(file.backend.ground_vehicle_vertical_sigma_m_s,
            d.backend.ground_vehicle_vertical_sigma_m_s);
  EXPECT_EQ(file.lowcontrast_gyro_walk_scale, d.lowcontrast_gyro_walk_scale);
  EXPECT_EQ(file.backend.marginalize_tracked_landmarks, d.backend.marginalize_tracked_landmarks);
  EXPECT_EQ(file.stereo_only_marginalize_tracked_landmarks,
            d.stereo_only_marginalize_tracked_landmarks);
  EXPECT_EQ(file.backend.anchored_observations_per_landmark,
            d.backend.anchored_observations_per_landmark);
  EXPECT_EQ(file.stereo_only_anchored_observations_per_landmark,
            d.stereo_only_anchored_observations_per_landmark);
  EXPECT_EQ(file.backend.anchored_max_age_s, d.backend.anchored_max_age_s);
  EXPECT_EQ(file.backend.anchored_max_depth_m, d.backend.anchored_max_depth_m);
  EXPECT_EQ(file.backend.anchored_stereo, d.backend.anchored_stereo);
  EXPECT_EQ(file.backend.prior_accel_bias_sigma, d.backend.prior_accel_bias_sigma);
  EXPECT_EQ(file.still_max_gyro_std, d.still_max_gyro_std);
  EXPECT_EQ(file.still_max_accel_std, d.still_max_accel_std);
  EXPECT_EQ(file.still_max_image_motion_px, d.still_max_image_motion_px);
  EXPECT_EQ(file.static_gyro_bias_standard_errors, d.static_gyro_bias_standard_errors);
  EXPECT_EQ(file.static_gyro_bias_min_sigma, d.static_gyro_bias_min_sigma);
  EXPECT_EQ(file.static_gyro_bias_max_noise_ratio, d.static_gyro_bias_max_noise_ratio);
  EXPECT_EQ(file.motion_init_tilt_sigma_rad, d.motion_init_tilt_sigma_rad);
  EXPECT_EQ(file.motion_init_accel_bias_sigma, d.motion_init_accel_bias_sigma);
  EXPECT_EQ(file.max_imu_gap_s, d.max_imu_gap_s);
  EXPECT_EQ(file.min_tracked_landmarks, d.min_tracked_landmarks);
  EXPECT_EQ(file.max_accel_bias, d.max_accel_bias);
  EXPECT_EQ(file.feedback_lag_frames, d.feedback_lag_frames);
  const LoopClosureOptions &fl = file.loop_closure, &dl = d.loop_closure;
  EXPECT_EQ(fl.stereo_only, dl.stereo_only);
  EXPECT_EQ(fl.stereo_imu, dl.stereo_imu);
  EXPECT_EQ(fl.orb_features, dl.orb_features);
  EXPECT_EQ(fl.orb_fast_threshold, dl.orb_fast_threshold);
  EXPECT_EQ(fl.orb_retry_below_features, dl.orb_retry_below_features);
  EXPECT_EQ(fl.orb_retry_stereo_imu, dl.orb_retry_stereo_imu);
  EXPECT_EQ(fl.orb_retry_clahe_clip, dl.orb_retry_clahe_clip);
  EXPECT_EQ(fl.orb_retry_clahe_tiles, dl.orb_retry_clahe_tiles);
  EXPECT_EQ(fl.orb_retry_fast_threshold, dl.orb_retry_fast_threshold);
  EXPECT_EQ(fl.stereo_epipolar_px, dl.stereo_epipolar_px);
  EXPECT_EQ(fl.max_depth_baselines, dl.max_depth_baselines);
  EXPECT_EQ(fl.min_separation_s, dl.min_separation_s);
  EXPECT_EQ(fl.min_separation_m, dl.min_separation_m);
  EXPECT_EQ(fl.search_radius_m, dl.search_radius_m);
  EXPECT_EQ(fl.search_radius_fraction, dl.search_radius_fraction);
  EXPECT_EQ(fl.max_loop_distance_m, dl.max_loop_distance_m);
  EXPECT_EQ(fl.max_loop_residual_m, dl.max_loop_residual_m);
  EXPECT_EQ(fl.point_sigma_px, dl.point_sigma_px);
  EXPECT_EQ(fl.max_view_angle_deg, dl.max_view_angle_deg);
  EXPECT_EQ(fl.max_candidates, dl.max_candidates);
  EXPECT_EQ(fl.match_ratio, dl.match_ratio);
  EXPECT_EQ(fl.pnp_px, dl.pnp_px);
  EXPECT_EQ(fl.min_inliers, dl.min_inliers);
  EXPECT_EQ(fl.guided_radius_px, dl.guided_radius_px);
  EXPECT_EQ(fl.guided_seed_inliers, dl.guided_seed_inliers);
  EXPECT_EQ(fl.guided_max_hamming, dl.guided_max_hamming);
  EXPECT_EQ(fl.guided_ratio, dl.guided_ratio);
  EXPECT_EQ(fl.min_interval_s, dl.min_interval_s);
  EXPECT_EQ(fl.support_min_path_m, dl.support_min_path_m);
  EXPECT_EQ(fl.support_tolerance_m, dl.support_tolerance_m);
  EXPECT_EQ(fl.support_tolerance_fraction, dl.support_tolerance_fraction);
  EXPECT_EQ(fl.support_max_wait_s, dl.support_max_wait_s);
  EXPECT_EQ(fl.alias_path_m, dl.alias_path_m);
  EXPECT_EQ(fl.alias_keyframes, dl.alias_keyframes);
  EXPECT_EQ(fl.alias_min_offset_m, dl.alias_min_offset_m);
  EXPECT_EQ(fl.alias_drift_fraction, dl.alias_drift_fraction);
  EXPECT_EQ(fl.alias_min_sigmas, dl.alias_min_sigmas);
  EXPECT_EQ(fl.odometry_sigma_m_per_m, dl.odometry_sigma_m_per_m);
  EXPECT_EQ(fl.odometry_min_sigma_m, dl.odometry_min_sigma_m);
  EXPECT_EQ(fl.odometry_sigma_rad_per_m, dl.odometry_sigma_rad_per_m);
  EXPECT_EQ(fl.odometry_min_sigma_rad, dl.odometry_min_sigma_rad);
  EXPECT_EQ(fl.loop_sigma_m, dl.loop_sigma_m);
  EXPECT_EQ(fl.loop_sigma_rad, dl.loop_sigma_rad);
  // Every loadable option at once (the documented file may leave some out: then the defaults).
  EXPECT_EQ(VioOptionsYaml(file), VioOptionsYaml(d));
}

// The stereo_only_* frontend options replace theirs in stereo-only mode only, and -1 leaves the
// shared value.
TEST(VioConfig, StereoOnlyFrontendOptionsApplyInStereoModeOnly) {
  FrontendOptions f;
  f.local_norm_sigma_px = 0;
  f.min_corner_isotropy = 0;
  f.stereo_only_local_norm_sigma_px = 4;
  f.stereo_only_min_corner_isotropy = 0.05;
  const FrontendOptions stereo = FrontendOptionsForMode(f, VioMode::kStereo);
  EXPECT_EQ(stereo.local_norm_sigma_px, 4);
  EXPECT_EQ(stereo.min_corner_isotropy, 0.05);
  EXPECT_EQ(stereo.keyframe_min_parallax_px, f.stereo_only_keyframe_min_parallax_px);
  const FrontendOptions imu = FrontendOptionsForMode(f, VioMode::kStereoImu);
  EXPECT_EQ(imu.local_norm_sigma_px, 0);
  EXPECT_EQ(imu.min_corner_isotropy, 0);
  EXPECT_EQ(imu.keyframe_min_parallax_px, f.keyframe_min_parallax_px);
  f.local_norm_sigma_px = 3;
  f.stereo_only_local_norm_sigma_px = -1;
  f.stereo_only_min_corner_isotropy = -1;
  EXPECT_EQ(FrontendOptionsForMode(f, VioMode::kStereo).local_norm_sigma_px, 3);
  EXPECT_EQ(FrontendOptionsForMode(f, VioMode::kStereo).min_corner_isotropy, 0);
  f.stereo_only_local_norm_sigma_px = -2;
  EXPECT_NE(f.Check().find("stereo_only_local_norm_sigma_px"), std::string::npos);
  // The temporal gain-and-offset refinement: its stereo-only value in stereo mode, always.
  FrontendOptions g;
  g.klt_gain_offset = false;
  g.stereo_only_klt_gain_offset = true;
  EXPECT_TRUE(FrontendOptionsForMode(g, VioMode::kStereo).klt_gain_offset);
  EXPECT_FALSE(FrontendOptionsForMode(g, VioMode::kStereoImu).klt_gain_offset);
  // The corner noise floor: stereo-only's when >= 0, else the shared one.
  FrontendOptions n;
  EXPECT_EQ(FrontendOptionsForMode(n, VioMode::kStereo).corner_noise_floor, 6);
  EXPECT_EQ(FrontendOptionsForMode(n, VioMode::kStereoImu).corner_noise_floor, 0);
  n.corner_noise_floor = 2;
  n.stereo_only_corner_noise_floor = -1;
  EXPECT_EQ(FrontendOptionsForMode(n, VioMode::kStereo).corner_noise_floor, 2);
  n.stereo_only_corner_noise_floor = -3;
  EXPECT_NE(n.Check().find("stereo_only_corner_noise_floor"), std::string::npos);
  g.klt_gain_offset = true;
  g.stereo_only_klt_gain_offset = false;
  EXPECT_FALSE(FrontendOptionsForMode(g, VioMode::kStereo).klt_gain_offset);
  EXPECT_TRUE(FrontendOptionsForMode(g, VioMode::kStereoImu).klt_gain_offset);
}

// The effective configuration of a run: every option, loading back to the same options.
TEST(VioConfig, OptionsYamlLoadsBackToTheSameOptions) {
  const auto dir = optinav::testing::MakeTempDir("vio_options_yaml");
  VioOptions o;
  o.mode = VioMode::kStereo;
  o.frontend.max_features = 97;
  o.frontend.keyframe_fresh_probation = true;
  o.backend.pixel_sigma = 0.1 + 0.2;  // not exact in 3 digits: the shortest exact form
  o.backend.predicted_gate_median_factor = 2;
  o.backend.ground_vehicle_vertical_sigma_m_s = 1e-12;
  o.loop_closure.stereo_only = false;
  o.feedback_lag_frames = 2;
  const std::string text = VioOptionsYaml(o);
  EXPECT_NE(text.find("mode: stereo\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  max_features: 97\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  keyframe_fresh_probation: true\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  predicted_gate_median_factor: 2\n"), std::string::npos) << text;
  const std::string path = optinav::testing::WriteFile(dir / "effective.yaml", text);
  const VioOptions back = LoadVioOptions(path);
  EXPECT_EQ(back.backend.pixel_sigma, 0.1 + 0.2);
  EXPECT_EQ(back.backend.ground_vehicle_vertical_sigma_m_s, 1e-12);
  EXPECT_EQ(back.mode, VioMode::kStereo);
  EXPECT_FALSE(back.loop_closure.stereo_only);
  EXPECT_EQ(back.feedback_lag_frames, 2);
  EXPECT_EQ(VioOptionsYaml(back), text);
  // Any option changed changes the text (what `bench weather --reuse` compares).
  VioOptions other = o;
  other.lowcontrast_gyro_walk_scale = 0.5;
  EXPECT_NE(VioOptionsYaml(other), text);
  EXPECT_NE(VioOptionsYaml(VioOptions{}), text);
}

TEST(VioConfig, BadConfigsNameTheKey) {
  const auto dir = optinav::testing::MakeTempDir("vio_config");
  // The message of the error loading `path` throws ("" when it does not throw).
  auto error_of = [](const std::string& path) -> std::string {
    try {
      LoadVioOptions(path);
    } catch (const Error& e) {
      return e.what();
    }
    ADD_FAILURE() << "no error for " << path;
    return "";
  };
  const std::string unknown =
      error_of(optinav::testing::WriteFile(dir / "a.yaml", "backend:\n  windw_keyframes: 4\n"));
  EXPECT_NE(unknown.find("backend.windw_keyframes"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("a.yaml:2"), std::string::npos) << unknown;
  const std::string invalid =
      optinav::testing::WriteFile(dir / "b.yaml", "failure:\n  max_imu_gap_s: -1\n");
  // Range checks run on the whole options: the file and the message name it, no line.
  EXPECT_ERROR(LoadVioOptions(invalid), {.file = invalid}, "max gaps must be > 0");
  // The solver's wall-clock limit: 0 is "none" (the default), below 0 an error.
  const std::string time_limit =
      optinav::testing::WriteFile(dir / "h.yaml", "backend:\n  max_solver_time_s: -0.1\n");
  EXPECT_ERROR(LoadVioOptions(time_limit), {.file = time_limit},
               "max_solver_time_s must be >= 0 (0: no limit)");
  EXPECT_EQ(LoadVioOptions(
                optinav::testing::WriteFile(dir / "i.yaml", "backend:\n  max_solver_time_s: 0.2\n"))
                .backend.max_solver_time_s,
            0.2);
  const std::string check =
      optinav::testing::WriteFile(dir / "m.yaml", "backend:\n  imu_pnp_check_pixels: -1\n");
  EXPECT_ERROR(LoadVioOptions(check), {.file = check},
               "imu_pnp_check_pixels must be >= 0 (0: off)");
  const std::string held =
      optinav::testing::WriteFile(dir / "j.yaml", "backend:\n  lowcontrast_gyro_walk_scale: 0\n");
  EXPECT_ERROR(LoadVioOptions(held), {.file = held},
               "backend.lowcontrast_gyro_walk_scale must be in (0, 1]");
  const std::string anchors = optinav::testing::WriteFile(
      dir / "k.yaml", "backend:\n  stereo_only_anchored_observations_per_landmark: -1\n");
  EXPECT_ERROR(LoadVioOptions(anchors), {.file = anchors},
               "backend.stereo_only_anchored_observations_per_landmark must be >= 0 (0: off)");
  const std::string refine =
      optinav::testing::WriteFile(dir / "l.yaml", "frontend:\n  stereo_refine_window_px: 1\n");
  EXPECT_ERROR(LoadVioOptions(refine), {.file = refine},
               "stereo_refine_window_px must be 0 (off) or >= 3");
  const std::string mode = optinav::testing::WriteFile(dir / "c.yaml", "mode: mono\n");
  EXPECT_ERROR(LoadVioOptions(mode), {.file = mode, .line = 1, .field = "mode"},
               "expected stereo-imu or stereo, got 'mono'");
  const std::string loop =
      error_of(optinav::testing::WriteFile(dir / "d.yaml", "loop_closure:\n  min_inliers: 2\n"));
  EXPECT_NE(loop.find("loop_closure.min_inliers"), std::string::npos) << loop;
  const std::string flag =
      optinav::testing::WriteFile(dir / "e.yaml", "loop_closure:\n  stereo_imu: maybe\n");
  EXPECT_ERROR(LoadVioOptions(flag), {.file = flag, .line = 2, .field = "stereo_imu"},
               "cannot convert value 'maybe'");
  // A map or a sequence as a key (YAML's "? ..." form), at the top and inside a section: an
  // Error naming the line, not YAML's exception (fuzz/regressions/vio_config/complex_key_*).
  const std::string top = optinav::testing::WriteFile(dir / "f.yaml", "? {a: 1}\n: 2\n");
  EXPECT_ERROR(LoadVioOptions(top), {.file = top, .line = 1, .field = "<key>"},
               "a key must be a plain name");
  const std::string inner =
      optinav::testing::WriteFile(dir / "g.yaml", "frontend:\n  ? [max_features]\n  : 100\n");
  EXPECT_ERROR(LoadVioOptions(inner), {.file = inner, .line = 2, .field = "frontend.<key>"},
               "a key must be a plain name");
}

}  // namespace
}  // namespace optinav::vio
