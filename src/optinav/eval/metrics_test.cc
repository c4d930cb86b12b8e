// Hand-checked small cases for association, alignment, APE, RPE and statistics.
#include "optinav/eval/metrics.h"

#include <cmath>

#include <gtest/gtest.h>

#include "optinav/util/testing.h"

namespace optinav::eval {
namespace {

constexpr int64_t kSec = 1'000'000'000;

Trajectory FromStamps(const std::vector<double>& seconds) {
  Trajectory t;
  for (double s : seconds) {
    t.Add(static_cast<int64_t>(std::llround(s * 1e9)),
          Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(s, 0, 0)));
  }
  return t;
}

TEST(Statistics, HandComputed) {
  const Statistics s = ComputeStatistics({4, 1, 3, 2});
  EXPECT_EQ(s.n, 4u);
  EXPECT_DOUBLE_EQ(s.sse, 30.0);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_DOUBLE_EQ(ComputeStatistics({5, 1, 3}).median, 3.0);
  EXPECT_ERROR(ComputeStatistics({}), {}, "no values to summarise");
}

TEST(Synchronize, NearestWithinMaxDiffFromTheShorterSide) {
  const Trajectory ref = FromStamps({0.0, 1.0, 2.0, 3.0, 4.0});
  const Trajectory est = FromStamps({0.004, 1.02, 2.0, 2.009});
  const SyncedPair p = Synchronize(ref, est, {.max_diff_s = 0.01});
  EXPECT_EQ(p.est_indices, (std::vector<size_t>{0, 2, 3}));
  EXPECT_EQ(p.ref_indices, (std::vector<size_t>{0, 2, 2}));  // a reference pose may repeat
  EXPECT_EQ(p.max_pairs, 4u);
  EXPECT_EQ(p.ref.size(), 3u);
  // Larger max_diff accepts the 20 ms gap.
  EXPECT_EQ(Synchronize(ref, est, {.max_diff_s = 0.05}).ref.size(), 4u);
}

TEST(Synchronize, TiesTakeTheEarlierStampAndOffsetShiftsTheEstimate) {
  const Trajectory ref = FromStamps({0.0, 0.02});
  const Trajectory est = FromStamps({0.01});
  const SyncedPair p = Synchronize(ref, est, {.max_diff_s = 0.01});
  EXPECT_EQ(p.ref_indices, std::vector<size_t>{0});
  const Trajectory late = FromStamps({10.5, 11.5, 12.5});
  const Trajectory gt = FromStamps({0.0, 1.0, 2.0, 3.0});
  EXPECT_ERROR(Synchronize(gt, late), {},
               "no matching timestamps between reference and estimate with max. time diff 0.01 s");
  const SyncedPair q = Synchronize(gt, late, {.max_diff_s = 0.01, .t_offset_s = -10.5});
  EXPECT_EQ(q.ref_indices, (std::vector<size_t>{0, 1, 2}));
  // The estimate longer than the reference: the reference drives.
  const SyncedPair r = Synchronize(FromStamps({1.0, 2.0}), FromStamps({0.0, 0.99, 1.0, 2.005, 3}));
  EXPECT_EQ(r.est_indices, (std::vector<size_t>{2, 3}));
}

TEST(Synchronize, ByIndexWithoutTimestamps) {
  Trajectory a, b;
  for (int i = 0; i < 3; ++i) a.Add(Rigid3d());
  for (int i = 0; i < 4; ++i) b.Add(Rigid3d());
  EXPECT_ERROR(Synchronize(a, b), {}, "same number of poses (reference 3, estimate 4)");
  b = a;
  EXPECT_TRUE(Synchronize(a, b).by_index);
  EXPECT_ERROR(Synchronize(Trajectory{}, a), {}, "cannot associate an empty trajectory");
}

Trajectory Square(double offset_y, double yaw) {
  Trajectory t;
  const Eigen::Vector3d corners[] = {{0, 0, 0}, {1, 0, 0.5}, {1, 1, 0}, {0, 1, 0.2}, {0.5, 0.5, 1}};
  int64_t stamp = 0;
  for (const auto& c : corners) {
    t.Add(stamp += kSec,
          Rigid3d(ExpSO3(Eigen::Vector3d(0, 0, yaw)),
                  ExpSO3(Eigen::Vector3d(0, 0, yaw)) * c + Eigen::Vector3d(0, offset_y, 0)));
  }
  return t;
}

TEST(Ape, TranslationWithAndWithoutAlignment) {
  const Trajectory ref = Square(0, 0);
  Trajectory est = Square(1.0, 0);
  EXPECT_DOUBLE_EQ(ComputeApe(ref, est, PoseRelation::kTranslation).stats.rmse, 1.0);
  const AlignmentResult a = AlignTrajectory(ref, &est, {.mode = AlignMode::kSe3});
  EXPECT_LT(ComputeApe(ref, est, PoseRelation::kTranslation).stats.max, 1e-12);
  EXPECT_NEAR(a.Total()(1, 3), -1.0, 1e-12);
}

TEST(Ape, RotationRelationsOfA90DegreeYaw) {
  const Trajectory ref = Square(0, 0);
  Trajectory est = ref;
  for (auto& r : est.rotations) r = ExpSO3(Eigen::Vector3d(0, 0, M_PI / 2)).toRotationMatrix() * r;
  // |R - I|_F for 90 deg about z: entries (0-1), (0-1), (-1), (1) -> sqrt(4) = 2.
  EXPECT_NEAR(ComputeApe(ref, est, PoseRelation::kRotation).stats.max, 2.0, 1e-12);
  EXPECT_NEAR(ComputeApe(ref, est, PoseRelation::kAngleDeg).stats.mean, 90.0, 1e-9);
  EXPECT_NEAR(ComputeApe(ref, est, PoseRelation::kAngleRad).stats.mean, M_PI / 2, 1e-12);
  est.positions[0] += Eigen::Vector3d(0, 0, 3);
  EXPECT_NEAR(ComputeApe(ref, est, PoseRelation::kFull).errors[0], std::sqrt(4.0 + 9.0), 1e-12);
}

TEST(Alignment, Sim3ScaleOnlyPosYawAndOrigin) {
  const Trajectory ref = Square(0, 0);
  Trajectory est = ref;
  for (auto& p : est.positions) p *= 2.0;
  Trajectory scaled = est;
  const AlignmentResult s = AlignTrajectory(ref, &scaled, {.mode = AlignMode::kScale});
  EXPECT_NEAR(s.ref_from_est.scale, 0.5, 1e-12);
  EXPECT_LT(ComputeApe(ref, scaled, PoseRelation::kTranslation).stats.max, 1e-12);
  // SE3 cannot fix scale, Sim3 can.
  Trajectory se3 = est, sim3 = est;
  AlignTrajectory(ref, &se3, {.mode = AlignMode::kSe3});
  AlignTrajectory(ref, &sim3, {.mode = AlignMode::kSim3});
  EXPECT_GT(ComputeApe(ref, se3, PoseRelation::kTranslation).stats.max, 0.1);
  EXPECT_LT(ComputeApe(ref, sim3, PoseRelation::kTranslation).stats.max, 1e-12);
  // Yaw-rotated and shifted: posyaw recovers it.
  Trajectory yawed = Square(3.0, 0.7);
  AlignTrajectory(ref, &yawed, {.mode = AlignMode::kPosYaw});
  EXPECT_LT(ComputeApe(ref, yawed, PoseRelation::kTranslation).stats.max, 1e-12);
  // Origin alignment makes the first poses coincide.
  Trajectory shifted = Square(2.0, 0.3);
  AlignTrajectory(ref, &shifted, {.mode = AlignMode::kNone, .align_origin = true});
  EXPECT_LT((shifted.positions[0] - ref.positions[0]).norm(), 1e-12);
  EXPECT_LT(shifted.quaternion(0).angularDistance(ref.quaternion(0)), 1e-9);
  // Too few pairs.
  Trajectory two = FromStamps({0, 1}), two_est = two;
  EXPECT_ERROR(AlignTrajectory(two, &two_est, {.mode = AlignMode::kSe3}), {},
               "alignment needs at least 3 pose pairs, got 2");
}

TEST(MeanErrorAfterStartPose, StartPoseOnlyThenMeanDistance) {
  // The estimate: the reference in another frame (yawed 0.7 rad, shifted) and drifting 0.5 m
  // along the reference's y per pose after the first: the start pose removes the frame, the
  // drift stays; errors 0, 0.5, 1, 1.5, 2 -> mean 1.0 (an RMSE would be sqrt(1.5)).
  const Trajectory ref = Square(0, 0);
  Trajectory drifted = ref;
  for (size_t i = 0; i < drifted.size(); ++i) drifted.positions[i].y() += 0.5 * i;
  Trajectory est = drifted;
  est.Transform(Sim3d{1.0, ExpSO3(Eigen::Vector3d(0, 0, 0.7)), Eigen::Vector3d(3, -2, 1)});
  EXPECT_NEAR(MeanErrorAfterStartPose(ref, est), 1.0, 1e-12);
  // A fit over the whole run (SE(3)) would hide part of the drift: the start pose does not.
  Trajectory se3 = est;
  AlignTrajectory(ref, &se3, {.mode = AlignMode::kSe3});
  EXPECT_LT(ComputeApe(ref, se3, PoseRelation::kTranslation).stats.mean, 0.9);
  // Positions turned 0.1 rad about the start (the start pose itself right): the error grows with
  // the horizontal distance from the start, 2 sin(0.05) |p_xy|.
  Trajectory turned = ref;
  turned.Transform(Sim3d{1.0, ExpSO3(Eigen::Vector3d(0, 0, 0.1)), Eigen::Vector3d::Zero()});
  for (size_t i = 0; i < turned.size(); ++i) turned.rotations[i] = ref.rotations[i];
  double expected = 0;
  for (size_t i = 0; i < ref.size(); ++i)
    expected += 2 * std::sin(0.05) * ref.positions[i].head<2>().norm() / ref.size();
  EXPECT_NEAR(MeanErrorAfterStartPose(ref, turned), expected, 1e-12);
  EXPECT_ERROR(MeanErrorAfterStartPose(ref, FromStamps({1, 2})), {},
               "synchronized trajectories of equal size");
  EXPECT_ERROR(MeanErrorAfterStartPose(Trajectory{}, Trajectory{}), {}, "empty trajectories");
}

// A straight line along x with poses every `step` metres.
Trajectory LineTraj(int n, double step) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    t.Add(int64_t{i} * kSec / 10,
          Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i * step, 0, 0)));
  }
  return t;
}

TEST(Rpe, FramesConsecutiveAndAllPairs) {
  const Trajectory ref = LineTraj(7, 1.0), est = LineTraj(7, 1.1);
  RpeOptions o{.delta = 2, .unit = DeltaUnit::kFrames};
  EXPECT_EQ(SelectRpePairs(est, o),
            (std::vector<std::pair<size_t, size_t>>{{0, 2}, {2, 4}, {4, 6}}));
  const ErrorSeries e = ComputeRpe(ref, est, o);
  EXPECT_NEAR(e.stats.mean, 0.2, 1e-12);
  EXPECT_EQ(e.indices, (std::vector<size_t>{2, 4, 6}));
  o.all_pairs = true;
  EXPECT_EQ(SelectRpePairs(est, o).size(), 5u);
}

TEST(Rpe, MetersFollowEvoPathRule) {
  const Trajectory est = LineTraj(9, 0.5);  // path 0, .5, 1.0, ...
  RpeOptions o{.delta = 1.0, .unit = DeltaUnit::kMeters};
  // Boundaries where the path since the previous boundary reaches 1 m: 2, 4, 6, 8.
  EXPECT_EQ(SelectRpePairs(est, o),
            (std::vector<std::pair<size_t, size_t>>{{2, 4}, {4, 6}, {6, 8}}));
  o.all_pairs = true;
  const auto all = SelectRpePairs(est, o);
  ASSERT_EQ(all.size(), 7u);
  EXPECT_EQ(all.front(), (std::pair<size_t, size_t>{0, 2}));
  EXPECT_EQ(all.back(), (std::pair<size_t, size_t>{6, 8}));
}

TEST(Rpe, SecondsAndDegrees) {
  Trajectory est = LineTraj(11, 1.0);  // 0.1 s apart
  RpeOptions o{.delta = 0.3, .unit = DeltaUnit::kSeconds};
  EXPECT_EQ(SelectRpePairs(est, o),
            (std::vector<std::pair<size_t, size_t>>{{0, 3}, {3, 6}, {6, 9}}));
  o.all_pairs = true;
  EXPECT_EQ(SelectRpePairs(est, o).size(), 8u);
  for (size_t i = 0; i < est.size(); ++i) {
    est.rotations[i] = ExpSO3(Eigen::Vector3d(0, 0, 10.0 * i * M_PI / 180.0)).toRotationMatrix();
  }
  RpeOptions d{.delta = 25, .unit = DeltaUnit::kDegrees};  // 3 steps of 10 deg reach 25
  EXPECT_EQ(SelectRpePairs(est, d),
            (std::vector<std::pair<size_t, size_t>>{{0, 3}, {3, 6}, {6, 9}}));
  d.all_pairs = true;
  d.delta = 30;
  EXPECT_EQ(SelectRpePairs(est, d).size(), 8u);  // 30 deg +- 3 deg: exactly j = i + 3
}

TEST(Rpe, RotationErrorOfAConstantYawRateBias) {
  // Reference turns 10 deg per step, estimate 11 deg: RPE angle over 1 frame = 1 deg.
  Trajectory ref = LineTraj(5, 1.0), est = LineTraj(5, 1.0);
  for (size_t i = 0; i < 5; ++i) {
    ref.rotations[i] = ExpSO3(Eigen::Vector3d(0, 0, 10.0 * i * M_PI / 180.0)).toRotationMatrix();
    est.rotations[i] = ExpSO3(Eigen::Vector3d(0, 0, 11.0 * i * M_PI / 180.0)).toRotationMatrix();
  }
  const ErrorSeries e = ComputeRpe(ref, est, {.relation = PoseRelation::kAngleDeg});
  EXPECT_NEAR(e.stats.max, 1.0, 1e-9);
  EXPECT_NEAR(e.stats.min, 1.0, 1e-9);
}

TEST(Rpe, InvalidOptionsAndNoPairs) {
  const Trajectory t = LineTraj(3, 1.0);
  EXPECT_FALSE((RpeOptions{.delta = 0}.Check().empty()));
  EXPECT_FALSE((RpeOptions{.delta = 1.5, .unit = DeltaUnit::kFrames}.Check().empty()));
  EXPECT_FALSE((RpeOptions{.delta = 200, .unit = DeltaUnit::kDegrees}.Check().empty()));
  // The messages name the flag to change (--delta): eval is not told which file it reads.
  EXPECT_ERROR(ComputeRpe(t, t, {.delta = 10}), {},
               "delta = 10 (frames) produced no pose pairs among 3 poses: try a smaller delta");
  EXPECT_ERROR(ComputeRpe(t, t, {.delta = -1}), {}, "--delta must be a positive number, got -1");
}

}  // namespace
}  // namespace optinav::eval
