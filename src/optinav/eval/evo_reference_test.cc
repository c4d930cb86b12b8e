// Reproduces evo's results on evo's own test data with a second, deliberately naive
// implementation that follows evo's Python code path step by step and shares no code with
// optinav's eval layer:
//  - stream parsing with std::istringstream, timestamps as double seconds (as numpy holds them);
//  - KITTI poses kept as the raw 4x4 matrices of the file, inverted by transposing the rotation
//    block (evo's lie.se3_inverse);
//  - O(n*m) association by argmin over all |t_long + offset - t_short| (evo's sync.py);
//  - alignment by Horn's closed-form quaternion method (a different algorithm from Umeyama's
//    SVD; both give the least-squares optimum);
//  - RPE pairs with evo's path rule written as a plain loop.
// Library and naive results must agree to 1e-6 relative.
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "optinav/eval/metrics.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/util/testing.h"

namespace optinav::eval {
namespace {

struct NaiveTraj {
  std::vector<double> t;  // seconds
  std::vector<Eigen::Matrix4d> poses;
};

std::string Data(const std::string& name) {
  return (testing::SharedDataDir() / "trajectories" / name).string();
}

NaiveTraj NaiveReadTum(const std::string& path) {
  NaiveTraj out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    double t, x, y, z, qx, qy, qz, qw;
    ss >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    m.topRightCorner<3, 1>() = Eigen::Vector3d(x, y, z);
    out.t.push_back(t);
    out.poses.push_back(m);
  }
  return out;
}

NaiveTraj NaiveReadEurocCsv(const std::string& path) {
  NaiveTraj out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    for (char& c : line) {
      if (c == ',') c = ' ';
    }
    std::istringstream ss(line);
    double t, x, y, z, qw, qx, qy, qz;
    ss >> t >> x >> y >> z >> qw >> qx >> qy >> qz;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    m.topRightCorner<3, 1>() = Eigen::Vector3d(x, y, z);
    out.t.push_back(t * 1e-9);
    out.poses.push_back(m);
  }
  return out;
}

NaiveTraj NaiveReadKitti(const std::string& path) {
  NaiveTraj out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) ss >> m(r, c);
    }
    out.poses.push_back(m);
  }
  return out;
}

Eigen::Matrix4d EvoInverse(const Eigen::Matrix4d& p) {
  Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();
  inv.topLeftCorner<3, 3>() = p.topLeftCorner<3, 3>().transpose();
  inv.topRightCorner<3, 1>() = -inv.topLeftCorner<3, 3>() * p.topRightCorner<3, 1>();
  return inv;
}

// evo's associate_trajectories: returns (ref, est) reduced to matches.
void NaiveAssociate(NaiveTraj* ref, NaiveTraj* est, double max_diff) {
  const bool est_longer = est->t.size() > ref->t.size();
  NaiveTraj& lng = est_longer ? *est : *ref;
  NaiveTraj& shrt = est_longer ? *ref : *est;
  NaiveTraj new_long, new_short;
  for (size_t i = 0; i < shrt.t.size(); ++i) {
    size_t best = 0;
    double best_diff = std::abs(lng.t[0] - shrt.t[i]);
    for (size_t j = 1; j < lng.t.size(); ++j) {
      const double d = std::abs(lng.t[j] - shrt.t[i]);
      if (d < best_diff) {
        best_diff = d;
        best = j;
      }
    }
    if (best_diff <= max_diff) {
      new_short.t.push_back(shrt.t[i]);
      new_short.poses.push_back(shrt.poses[i]);
      new_long.t.push_back(lng.t[best]);
      new_long.poses.push_back(lng.poses[best]);
    }
  }
  lng = new_long;
  shrt = new_short;
}

// Horn (1987) closed-form absolute orientation with the asymmetric scale of Umeyama.
Eigen::Matrix4d NaiveHornAlign(const NaiveTraj& ref, const NaiveTraj& est, bool with_scale) {
  const size_t n = ref.poses.size();
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), my = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mx += est.poses[i].topRightCorner<3, 1>();
    my += ref.poses[i].topRightCorner<3, 1>();
  }
  mx /= n;
  my /= n;
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  double sxx = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = est.poses[i].topRightCorner<3, 1>() - mx;
    const Eigen::Vector3d b = ref.poses[i].topRightCorner<3, 1>() - my;
    s += a * b.transpose();
    sxx += a.squaredNorm();
  }
  Eigen::Matrix4d nm;
  nm << s(0, 0) + s(1, 1) + s(2, 2), s(1, 2) - s(2, 1), s(2, 0) - s(0, 2), s(0, 1) - s(1, 0),
      s(1, 2) - s(2, 1), s(0, 0) - s(1, 1) - s(2, 2), s(0, 1) + s(1, 0), s(2, 0) + s(0, 2),
      s(2, 0) - s(0, 2), s(0, 1) + s(1, 0), -s(0, 0) + s(1, 1) - s(2, 2), s(1, 2) + s(2, 1),
      s(0, 1) - s(1, 0), s(2, 0) + s(0, 2), s(1, 2) + s(2, 1), -s(0, 0) - s(1, 1) + s(2, 2);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(nm);
  const Eigen::Vector4d q = eig.eigenvectors().col(3);  // largest eigenvalue
  const Eigen::Matrix3d r = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
  double c = 1.0;
  if (with_scale) {
    double num = 0;
    for (size_t i = 0; i < n; ++i) {
      num += (ref.poses[i].topRightCorner<3, 1>() - my)
                 .dot(r * (est.poses[i].topRightCorner<3, 1>() - mx));
    }
    c = num / sxx;
  }
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = c * r;  // as evo: scale positions, then rotate
  t.topRightCorner<3, 1>() = my - c * r * mx;
  return t;
}

void NaiveApply(const Eigen::Matrix4d& sim, NaiveTraj* est) {
  const Eigen::Matrix3d sr = sim.topLeftCorner<3, 3>();
  const double c = std::cbrt(sr.determinant());
  for (auto& p : est->poses) {
    Eigen::Matrix4d out = Eigen::Matrix4d::Identity();
    out.topLeftCorner<3, 3>() = (sr / c) * p.topLeftCorner<3, 3>();
    out.topRightCorner<3, 1>() = sr * p.topRightCorner<3, 1>() + sim.topRightCorner<3, 1>();
    p = out;
  }
}

struct NaiveStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0;
  size_t n = 0;
};

NaiveStats NaiveStatistics(std::vector<double> e) {
  NaiveStats s;
  s.n = e.size();
  std::sort(e.begin(), e.end());
  s.min = e.front();
  s.max = e.back();
  s.median = e.size() % 2 ? e[e.size() / 2] : 0.5 * (e[e.size() / 2 - 1] + e[e.size() / 2]);
  for (double x : e) {
    s.sse += x * x;
    s.mean += x;
  }
  s.mean /= e.size();
  s.rmse = std::sqrt(s.sse / e.size());
  for (double x : e) s.std += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(s.std / e.size());
  return s;
}

std::vector<double> NaiveApeTrans(const NaiveTraj& ref, const NaiveTraj& est) {
  std::vector<double> e;
  for (size_t i = 0; i < ref.poses.size(); ++i) {
    e.push_back((est.poses[i].topRightCorner<3, 1>() - ref.poses[i].topRightCorner<3, 1>()).norm());
  }
  return e;
}

// evo's relations on an error matrix: trans |t|, rot |R - I|_F, full |E - I|_F.
double NaiveRelation(const Eigen::Matrix4d& e, PoseRelation relation) {
  if (relation == PoseRelation::kTranslation) return e.topRightCorner<3, 1>().norm();
  if (relation == PoseRelation::kRotation) {
    return (e.topLeftCorner<3, 3>() - Eigen::Matrix3d::Identity()).norm();
  }
  return (e - Eigen::Matrix4d::Identity()).norm();
}

std::vector<double> NaiveApe(const NaiveTraj& ref, const NaiveTraj& est, PoseRelation relation) {
  std::vector<double> e;
  for (size_t i = 0; i < ref.poses.size(); ++i) {
    e.push_back(NaiveRelation(EvoInverse(est.poses[i]) * ref.poses[i], relation));
  }
  return e;
}

std::vector<double> NaiveRpeTransMeters(const NaiveTraj& ref, const NaiveTraj& est, double delta,
                                        PoseRelation relation = PoseRelation::kTranslation) {
  std::vector<size_t> ids;
  double path = 0;
  for (size_t i = 0; i < est.poses.size(); ++i) {
    const size_t prev = i == 0 ? 0 : i - 1;
    path += (est.poses[i].topRightCorner<3, 1>() - est.poses[prev].topRightCorner<3, 1>()).norm();
    if (path >= delta) {
      ids.push_back(i);
      path = 0;
    }
  }
  std::vector<double> e;
  for (size_t k = 0; k + 1 < ids.size(); ++k) {
    const size_t i = ids[k], j = ids[k + 1];
    const Eigen::Matrix4d q_rel = EvoInverse(ref.poses[i]) * ref.poses[j];
    const Eigen::Matrix4d p_rel = EvoInverse(est.poses[i]) * est.poses[j];
    e.push_back(NaiveRelation(EvoInverse(q_rel) * p_rel, relation));
  }
  return e;
}

void ExpectSameStats(const Statistics& lib, const NaiveStats& ref, const std::string& what) {
  auto rel = [](double a, double b) { return std::abs(a - b) / std::max(std::abs(b), 1e-12); };
  EXPECT_EQ(lib.n, ref.n) << what;
  EXPECT_LT(rel(lib.rmse, ref.rmse), 1e-6) << what << " rmse " << lib.rmse << " vs " << ref.rmse;
  EXPECT_LT(rel(lib.mean, ref.mean), 1e-6) << what << " mean";
  EXPECT_LT(rel(lib.median, ref.median), 1e-6) << what << " median";
  EXPECT_LT(rel(lib.std, ref.std), 1e-6) << what << " std";
  EXPECT_LT(rel(lib.min, ref.min), 1e-6) << what << " min";
  EXPECT_LT(rel(lib.max, ref.max), 1e-6) << what << " max";
  EXPECT_LT(rel(lib.sse, ref.sse), 1e-6) << what << " sse";
  std::printf("%-44s n=%zu rmse=%.6f mean=%.6f median=%.6f max=%.6f (naive rmse %.6f)\n",
              what.c_str(), lib.n, lib.rmse, lib.mean, lib.median, lib.max, ref.rmse);
}

struct Case {
  std::string ref, est;
  AlignMode mode;
};

// Library pipeline: read, synchronize, align, metric.
SyncedPair LibraryPrepare(const Case& c, AlignMode mode) {
  const Trajectory ref = io::ReadTrajectory(Data(c.ref));
  const Trajectory est = io::ReadTrajectory(Data(c.est));
  SyncedPair p = Synchronize(ref, est, {.max_diff_s = 0.01});
  AlignTrajectory(p.ref, &p.est, {.mode = mode});
  return p;
}

NaiveTraj NaiveRead(const std::string& name) {
  if (name.find("KITTI") != std::string::npos) return NaiveReadKitti(Data(name));
  if (name.size() > 4 && name.substr(name.size() - 4) == ".csv")
    return NaiveReadEurocCsv(Data(name));
  return NaiveReadTum(Data(name));
}

void NaivePrepare(const Case& c, AlignMode mode, NaiveTraj* ref, NaiveTraj* est) {
  *ref = NaiveRead(c.ref);
  *est = NaiveRead(c.est);
  if (!ref->t.empty()) NaiveAssociate(ref, est, 0.01);
  if (mode != AlignMode::kNone)
    NaiveApply(NaiveHornAlign(*ref, *est, mode == AlignMode::kSim3), est);
}

TEST(EvoReference, ApeTranslationOnEvoTestData) {
  const Case cases[] = {
      {"KITTI_00_gt.txt", "KITTI_00_ORB.txt", AlignMode::kSe3},
      {"KITTI_00_gt.txt", "KITTI_00_SPTAM.txt", AlignMode::kSe3},
      {"KITTI_00_gt.txt", "KITTI_00_ORB.txt", AlignMode::kNone},
      {"freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt", AlignMode::kSe3},
      {"freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-ORB_kf_mono.txt", AlignMode::kSim3},
      {"fr2_desk_groundtruth.txt", "fr2_desk_ORB.txt", AlignMode::kSe3},
      {"V102_groundtruth.csv", "V102.txt", AlignMode::kSe3},
  };
  for (const Case& c : cases) {
    const std::string what = c.est + " APE " + AlignModeName(c.mode);
    const SyncedPair p = LibraryPrepare(c, c.mode);
    NaiveTraj ref, est;
    NaivePrepare(c, c.mode, &ref, &est);
    const ErrorSeries lib = ComputeApe(p.ref, p.est, PoseRelation::kTranslation);
    ExpectSameStats(lib.stats, NaiveStatistics(NaiveApeTrans(ref, est)), what);
  }
}

TEST(EvoReference, RpeTranslationDelta10MetresOnKitti) {
  for (const char* est_name : {"KITTI_00_ORB.txt", "KITTI_00_SPTAM.txt"}) {
    const Case c{"KITTI_00_gt.txt", est_name, AlignMode::kSe3};
    const SyncedPair p = LibraryPrepare(c, c.mode);
    NaiveTraj ref, est;
    NaivePrepare(c, c.mode, &ref, &est);
    const ErrorSeries lib = ComputeRpe(p.ref, p.est, {.delta = 10, .unit = DeltaUnit::kMeters});
    ExpectSameStats(lib.stats, NaiveStatistics(NaiveRpeTransMeters(ref, est, 10.0)),
                    std::string(est_name) + " RPE 10 m");
  }
}

TEST(EvoReference, RotationAndFullRelations) {
  for (PoseRelation relation : {PoseRelation::kRotation, PoseRelation::kFull}) {
    const Case kitti{"KITTI_00_gt.txt", "KITTI_00_ORB.txt", AlignMode::kSe3};
    SyncedPair p = LibraryPrepare(kitti, kitti.mode);
    NaiveTraj ref, est;
    NaivePrepare(kitti, kitti.mode, &ref, &est);
    ExpectSameStats(
        ComputeRpe(p.ref, p.est, {.delta = 10, .unit = DeltaUnit::kMeters, .relation = relation})
            .stats,
        NaiveStatistics(NaiveRpeTransMeters(ref, est, 10.0, relation)),
        "KITTI_00_ORB RPE 10 m " + PoseRelationName(relation));
    const Case tum{"freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt", AlignMode::kSe3};
    p = LibraryPrepare(tum, tum.mode);
    NaivePrepare(tum, tum.mode, &ref, &est);
    ExpectSameStats(ComputeApe(p.ref, p.est, relation).stats,
                    NaiveStatistics(NaiveApe(ref, est, relation)),
                    "fr1_xyz rgbdslam APE " + PoseRelationName(relation));
  }
}

TEST(EvoReference, AssociationCountsOnTumData) {
  // fr2_desk: the estimate (2893 poses, ~30 Hz) against a 100 Hz ground truth.
  const Case c{"fr2_desk_groundtruth.txt", "fr2_desk_ORB.txt", AlignMode::kNone};
  const SyncedPair p = LibraryPrepare(c, AlignMode::kNone);
  NaiveTraj ref, est;
  NaivePrepare(c, AlignMode::kNone, &ref, &est);
  EXPECT_EQ(p.ref.size(), ref.poses.size());
  for (size_t i = 0; i < ref.t.size(); ++i) {
    ASSERT_NEAR(p.ref.t_ns[i] * 1e-9, ref.t[i], 1e-6);
    ASSERT_NEAR(p.est.t_ns[i] * 1e-9, est.t[i], 1e-6);
  }
}

}  // namespace
}  // namespace optinav::eval
