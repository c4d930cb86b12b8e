#include "optinav/io/trajectory_io.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "optinav/util/testing.h"

namespace optinav::io {
namespace {

std::string Traj(const std::string& name) {
  return (testing::SharedDataDir() / "trajectories" / name).string();
}

// Independent count of data lines (not blank, not '#').
size_t CountDataLines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    const auto p = line.find_first_not_of(" \t\r");
    if (p != std::string::npos && line[p] != '#') ++n;
  }
  return n;
}

TEST(ReadTrajectory, DetectsAndReadsEvoTestData) {
  struct Case {
    const char* name;
    TrajectoryFormat format;
  };
  for (const Case& c :
       {Case{"KITTI_00_gt.txt", TrajectoryFormat::kKitti},
        Case{"KITTI_00_ORB.txt", TrajectoryFormat::kKitti},
        Case{"freiburg1_xyz-groundtruth.txt", TrajectoryFormat::kTum},
        Case{"freiburg1_xyz-rgbdslam.txt", TrajectoryFormat::kTum},
        Case{"fr2_desk_ORB.txt", TrajectoryFormat::kTum}, Case{"V102.txt", TrajectoryFormat::kTum},
        Case{"V102_groundtruth.csv", TrajectoryFormat::kEuroc}}) {
    const std::string path = Traj(c.name);
    EXPECT_EQ(DetectTrajectoryFormat(path), c.format) << c.name;
    const Trajectory t = ReadTrajectory(path);
    EXPECT_EQ(t.size(), CountDataLines(path)) << c.name;
    EXPECT_EQ(t.has_timestamps(), c.format != TrajectoryFormat::kKitti) << c.name;
  }
}

TEST(ReadTrajectory, ValuesMatchTheTextOfTheFirstLines) {
  // freiburg1_xyz-rgbdslam.txt line 2:
  // 1305031102.160407 1.344379 0.627206 1.661754 0.658249 0.611043 -0.294444 -0.326553
  const Trajectory tum = ReadTrajectory(Traj("freiburg1_xyz-rgbdslam.txt"));
  EXPECT_EQ(tum.t_ns[0], 1305031102160407000);
  EXPECT_TRUE(tum.positions[0].isApprox(Eigen::Vector3d(1.344379, 0.627206, 1.661754)));
  const Eigen::Vector4d q = Eigen::Vector4d(0.658249, 0.611043, -0.294444, -0.326553).normalized();
  EXPECT_NEAR(tum.quaternion(0).x(), q[0], 1e-12);
  EXPECT_NEAR(tum.quaternion(0).w(), q[3], 1e-12);

  // V102_groundtruth.csv line 2: 1403715524907143168,0.515356,1.996773,0.971104,
  // 0.161996,0.789985,-0.205376,0.554528,...  (q in w x y z)
  const Trajectory csv = ReadTrajectory(Traj("V102_groundtruth.csv"));
  EXPECT_EQ(csv.t_ns[0], 1403715524907143168);
  EXPECT_TRUE(csv.positions[0].isApprox(Eigen::Vector3d(0.515356, 1.996773, 0.971104)));
  EXPECT_NEAR(csv.quaternion(0).w(), 0.161996, 1e-5);
  EXPECT_NEAR(csv.quaternion(0).z(), 0.554528, 1e-5);

  // KITTI_00_ORB.txt line 2 translation column: -0.003019783 -0.005097120 0.666445315
  const Trajectory kitti = ReadTrajectory(Traj("KITTI_00_ORB.txt"));
  EXPECT_TRUE(
      kitti.positions[1].isApprox(Eigen::Vector3d(-0.003019783, -0.005097120, 0.666445315)));
  // Rotations are kept exactly as written (0.999999940 on the diagonal of line 1).
  EXPECT_EQ(kitti.rotations[0](1, 1), 0.999999940);
}

TEST(ReadTrajectory, KittiWithTimesFile) {
  TrajectoryReadOptions opt;
  opt.kitti_times_path = Traj("KITTI_00_gt_times.txt");
  const Trajectory t = ReadTrajectory(Traj("KITTI_00_gt.txt"), opt);
  ASSERT_TRUE(t.has_timestamps());
  EXPECT_EQ(t.t_ns[1], 103735900);
  // Count mismatch is an error naming the times file.
  const auto dir = testing::MakeTempDir("kittitimes");
  opt.kitti_times_path = testing::WriteFile(dir / "t.txt", "0.0\n0.1\n");
  EXPECT_ERROR(ReadTrajectory(Traj("KITTI_00_gt.txt"), opt), {.file = opt.kitti_times_path},
               "2 timestamps for 4541 poses in ");
}

TEST(WriteTrajectory, RoundTripsAllFormatsExactly) {
  Trajectory t;
  for (int i = 0; i < 10; ++i) {
    t.Add(1403715524907143168 + int64_t{i} * 5000037,
          Rigid3d(ExpSO3(Eigen::Vector3d(0.1 * i, -0.05, 0.3)),
                  Eigen::Vector3d(0.1 * i, 1.0 / 3.0, -2e-7 * i)));
  }
  const auto dir = testing::MakeTempDir("roundtrip");
  for (auto fmt : {TrajectoryFormat::kTum, TrajectoryFormat::kEuroc, TrajectoryFormat::kKitti}) {
    const std::string path = (dir / ("t." + TrajectoryFormatName(fmt))).string();
    WriteTrajectory(path, t, fmt);
    EXPECT_EQ(DetectTrajectoryFormat(path), fmt);
    const Trajectory back = ReadTrajectory(path);
    ASSERT_EQ(back.size(), t.size());
    for (size_t i = 0; i < t.size(); ++i) {
      EXPECT_LT((back.positions[i] - t.positions[i]).norm(), 1e-9);
      EXPECT_LT(back.quaternion(i).angularDistance(t.quaternion(i)), 1e-7);
      if (fmt != TrajectoryFormat::kKitti) {
        EXPECT_EQ(back.t_ns[i], t.t_ns[i]);
      }
    }
  }
  WriteKittiTimes((dir / "times.txt").string(), t);
  TrajectoryReadOptions opt{.format = TrajectoryFormat::kKitti,
                            .kitti_times_path = (dir / "times.txt").string()};
  EXPECT_EQ(ReadTrajectory((dir / "t.kitti").string(), opt).t_ns, t.t_ns);
}

struct BadCase {
  const char* what;
  const char* content;
  int line;  // expected line in the error, 0 = not checked
};

TEST(ReadTrajectory, BadInputIsAClearError) {
  const auto dir = testing::MakeTempDir("badtraj");
  const BadCase cases[] = {
      {"empty", "", 0},
      {"only comments", "# nothing\n\n", 0},
      {"short line", "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", 2},
      {"nan", "1.0 0 0 0 0 0 0 1\n2.0 nan 0 0 0 0 0 1\n", 2},
      {"inf", "1.0 0 0 inf 0 0 0 1\n", 1},
      {"text", "1.0 0 0 zero 0 0 0 1\n", 1},
      {"backwards", "1.0 0 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n", 3},
      {"zero quaternion", "1.0 0 0 0 0 0 0 0\n", 1},
      {"ns in tum layout", "1403715524907143168 0 0 0 0 0 0 1\n", 1},
      {"unknown columns", "1 2 3 4 5\n", 1},
      {"csv too short", "1,2,3\n", 1},
      {"csv seconds", "1.5,0,0,0,1,0,0,0\n", 1},
      {"csv backwards", "#timestamp,x\n20,0,0,0,1,0,0,0\n10,0,0,0,1,0,0,0\n", 3},
  };
  int i = 0;
  for (const BadCase& c : cases) {
    const std::string path = testing::WriteFile(dir / ("bad" + std::to_string(i++)), c.content);
    try {
      ReadTrajectory(path);
      ADD_FAILURE() << "no error for: " << c.what;
    } catch (const Error& e) {
      EXPECT_EQ(e.context().file, path) << c.what;
      if (c.line) {
        EXPECT_EQ(e.context().line, c.line) << c.what << ": " << e.what();
      }
    }
  }
  EXPECT_ERROR(ReadTrajectory((dir / "does_not_exist").string()),
               {.file = (dir / "does_not_exist").string()}, "cannot open file");
  // Repeated stamps (as in evo's V102.txt) are accepted.
  const auto dup = testing::WriteFile(dir / "dup.txt", "1.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n");
  EXPECT_EQ(ReadTrajectory(dup).size(), 2u);
  EXPECT_FALSE(ParseTrajectoryFormat("bag").has_value());
}

// The rows of a file, as numbers in memory, give the file reader's trajectory exactly.
TEST(TrajectoryFromRows, EqualsTheFileReaderOnTheSameValues) {
  // freiburg1_xyz-rgbdslam.txt lines 2-3 as doubles (what numpy.loadtxt gives).
  const double tum[16] = {
      1305031102.160407, 1.344379, 0.627206, 1.661754, 0.658249, 0.611043, -0.294444, -0.326553,
      1305031102.194330, 1.343641, 0.626458, 1.652408, 0.657327, 0.613265, -0.295150, -0.323593};
  const Trajectory rows = TrajectoryFromTumRows(tum, 2, "est array");
  const Trajectory file = ReadTrajectory(Traj("freiburg1_xyz-rgbdslam.txt"));
  ASSERT_EQ(rows.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(rows.t_ns[i], file.t_ns[i]);
    EXPECT_EQ(rows.positions[i], file.positions[i]);
    EXPECT_EQ(rows.rotations[i], file.rotations[i]);
  }
  EXPECT_EQ(rows.t_ns[1], 1305031102194330000);

  // KITTI_00_ORB.txt line 1 (rotations are kept as written).
  const Trajectory kitti_file = ReadTrajectory(Traj("KITTI_00_ORB.txt"));
  double kitti[12];
  for (int k = 0; k < 12; ++k) {
    kitti[k] = k % 4 == 3 ? kitti_file.positions[0][k / 4] : kitti_file.rotations[0](k / 4, k % 4);
  }
  const Trajectory kitti_rows = TrajectoryFromKittiRows(kitti, 1, "ref array");
  EXPECT_FALSE(kitti_rows.has_timestamps());
  EXPECT_EQ(kitti_rows.rotations[0], kitti_file.rotations[0]);
  EXPECT_EQ(kitti_rows.positions[0], kitti_file.positions[0]);

  const int64_t t_ns[1] = {1403715524907143168};
  const double euroc[7] = {0.515356, 1.996773, 0.971104, 0.161996, 0.789985, -0.205376, 0.554528};
  const Trajectory e = TrajectoryFromEurocRows(t_ns, euroc, 1, "gt");
  const Trajectory e_file = ReadTrajectory(Traj("V102_groundtruth.csv"));
  EXPECT_EQ(e.t_ns[0], e_file.t_ns[0]);
  EXPECT_EQ(e.rotations[0], e_file.rotations[0]);
}

TEST(TrajectoryFromRows, BadRowsNameTheRowAndField) {
  double tum[16] = {2, 0, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 1};
  EXPECT_ERROR(TrajectoryFromTumRows(tum, 2, "est array"),
               {.file = "est array", .line = 2, .field = "t"}, "goes backwards");
  tum[8] = 3;
  tum[15] = 0;
  EXPECT_ERROR(TrajectoryFromTumRows(tum, 2, "est array"),
               {.file = "est array", .line = 2, .field = "qx qy qz qw"}, "zero norm");
  tum[2] = std::nan("");
  EXPECT_ERROR(TrajectoryFromTumRows(tum, 2, "est array"),
               {.file = "est array", .line = 1, .field = "y"}, "not a finite number");
  EXPECT_ERROR(TrajectoryFromTumRows(tum, 0, "est array"), {.file = "est array"}, "no poses");
  const double kitti[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0};
  EXPECT_ERROR(TrajectoryFromKittiRows(kitti, 1, "ref array"),
               {.file = "ref array", .line = 1, .field = "rotation"}, "singular");
}

}  // namespace
}  // namespace optinav::io
