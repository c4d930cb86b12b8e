#include "optinav/io/gnss_io.h"

#include <gtest/gtest.h>

#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav::io {
namespace {

class GnssIoTest : public ::testing::Test {
 protected:
  std::string Write(const std::string& name, const std::string& text) {
    return testing::WriteFile(dir_ / name, text);
  }
  // The message of the Error that reading `path` throws ("" when it does not throw).
  static std::string ErrorOf(const std::string& path,
                             std::optional<GnssFileKind> kind = std::nullopt) {
    try {
      ReadGnssFile(path, kind);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path dir_ = testing::MakeTempDir("gnss_io");
};

TEST_F(GnssIoTest, ReadsEnuFileWithoutSigma) {
  const std::string p = Write("enu.csv",
                              "#timestamp [ns],x [m],y [m],z [m]\n"
                              "1000000000,1.5,-2.25,10\n"
                              "\n"
                              "1100000000,1.75,-2.5,10.5\n");
  const GnssFile f = ReadGnssFile(p);
  EXPECT_EQ(f.kind, GnssFileKind::kEnu);
  ASSERT_EQ(f.records.size(), 2u);
  EXPECT_EQ(f.records[0].t_ns, 1000000000);
  EXPECT_DOUBLE_EQ(f.records[0].value.y(), -2.25);
  EXPECT_FALSE(f.records[0].sigma_m.has_value());
  EXPECT_EQ(f.records[1].line, 4);
  EXPECT_DOUBLE_EQ(f.records[1].value.z(), 10.5);
}

TEST_F(GnssIoTest, DetectsLatLonHeightAndSigmaFromHeader) {
  const std::string p =
      Write("llh.csv",
            "#timestamp [ns],latitude [deg],longitude [deg],height [m],sigma [m]\n"
            "5,47.5,8.25,400.0,2.5\n"
            "6,47.50001,8.25002,401.0,3\n");
  const GnssFile f = ReadGnssFile(p);
  EXPECT_EQ(f.kind, GnssFileKind::kLatLonHeight);
  ASSERT_EQ(f.records.size(), 2u);
  EXPECT_DOUBLE_EQ(f.records[0].value.x(), 47.5);
  ASSERT_TRUE(f.records[1].sigma_m.has_value());
  EXPECT_DOUBLE_EQ(*f.records[1].sigma_m, 3.0);
  // An explicit kind wins over the header.
  EXPECT_EQ(ReadGnssFile(p, GnssFileKind::kEnu).kind, GnssFileKind::kEnu);
}

TEST_F(GnssIoTest, DropsNonFiniteRowsAndCountsThem) {
  const std::string p = Write("nan.csv",
                              "#timestamp [ns],x,y,z\n"
                              "1,0,0,0\n"
                              "2,nan,0,0\n"
                              "3,0,inf,0\n"
                              "4,1,1,1\n");
  const GnssFile f = ReadGnssFile(p);
  ASSERT_EQ(f.records.size(), 2u);
  EXPECT_EQ(f.records[1].t_ns, 4);
  EXPECT_EQ(f.dropped_non_finite, 2u);
  EXPECT_EQ(f.first_dropped_line, 3);
}

TEST_F(GnssIoTest, UnsortedAndDuplicatedStampsAreErrorsNamingTheLine) {
  const std::string dup = Write("dup.csv", "#t,x,y,z\n1,0,0,0\n2,0,0,0\n2,1,1,1\n");
  std::string msg = ErrorOf(dup);
  EXPECT_NE(msg.find("dup.csv"), std::string::npos) << msg;
  EXPECT_NE(msg.find("dup.csv:4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("repeated"), std::string::npos) << msg;

  const std::string back = Write("back.csv", "#t,x,y,z\n1,0,0,0\n3,0,0,0\n2,1,1,1\n");
  msg = ErrorOf(back);
  EXPECT_NE(msg.find("back.csv:4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("goes back"), std::string::npos) << msg;

  // A NaN row with a stamp going back is still an error: the stamps are checked first.
  const std::string nan_back = Write("nan_back.csv", "#t,x,y,z\n5,0,0,0\n4,nan,0,0\n");
  EXPECT_NE(ErrorOf(nan_back).find("nan_back.csv:3:"), std::string::npos);
}

TEST_F(GnssIoTest, NonPositiveSigmaIsAnError) {
  for (const char* sigma : {"0", "-1.5"}) {
    const std::string p =
        Write("sigma.csv", std::string("#t,x,y,z,sigma_m\n1,0,0,0,1\n2,0,0,0,") + sigma + "\n");
    const std::string msg = ErrorOf(p);
    EXPECT_NE(msg.find("sigma must be > 0"), std::string::npos) << msg;
    EXPECT_NE(msg.find("sigma.csv:3:"), std::string::npos) << msg;
  }
}

TEST_F(GnssIoTest, OutOfRangeCoordinatesAndMalformedRowsAreErrors) {
  const std::string lat = Write("lat.csv", "#timestamp,latitude,longitude,height\n1,91,8,0\n");
  EXPECT_NE(ErrorOf(lat).find("latitude 91 outside"), std::string::npos) << ErrorOf(lat);
  const std::string lon = Write("lon.csv", "#timestamp,latitude,longitude,height\n1,45,-181,0\n");
  EXPECT_NE(ErrorOf(lon).find("longitude -181 outside"), std::string::npos) << ErrorOf(lon);

  const std::string few = Write("few.csv", "#t,x,y,z\n1,2,3\n");
  std::string msg = ErrorOf(few);
  EXPECT_NE(msg.find("found 3 field(s)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("few.csv:2:"), std::string::npos) << msg;

  const std::string word = Write("word.csv", "#t,x,y,z\n1,2,abc,4\n");
  msg = ErrorOf(word);
  EXPECT_NE(msg.find("word.csv"), std::string::npos) << msg;
  EXPECT_NE(msg.find("y"), std::string::npos) << msg;

  EXPECT_NE(ErrorOf((dir_ / "missing.csv").string()).find("missing.csv"), std::string::npos);
}

TEST_F(GnssIoTest, EmptyAndHeaderOnlyFilesGiveNoRecords) {
  EXPECT_TRUE(ReadGnssFile(Write("empty.csv", "")).records.empty());
  EXPECT_TRUE(ReadGnssFile(Write("header.csv", "#timestamp,x,y,z\n")).records.empty());
}

TEST_F(GnssIoTest, SensorYamlGivesLeverArmSigmaAndOrigin) {
  const std::string p = Write("sensor.yaml",
                              "sensor_type: gnss\n"
                              "T_BS:\n  cols: 4\n  rows: 4\n"
                              "  data: [1, 0, 0, 0.1, 0, 1, 0, -0.2, 0, 0, 1, 0.3, 0, 0, 0, 1]\n"
                              "sigma_m: 1.5\n"
                              "origin_latitude_deg: 47.0\n"
                              "origin_longitude_deg: 8.5\n"
                              "origin_height_m: 420\n");
  const GnssSensorInfo info = ReadGnssSensorYaml(p);
  ASSERT_TRUE(info.lever_arm_in_body && info.sigma_m && info.origin_lat_lon_height);
  EXPECT_TRUE(info.lever_arm_in_body->isApprox(Eigen::Vector3d(0.1, -0.2, 0.3)));
  EXPECT_DOUBLE_EQ(*info.sigma_m, 1.5);
  EXPECT_DOUBLE_EQ(info.origin_lat_lon_height->z(), 420);

  const GnssSensorInfo none = ReadGnssSensorYaml(Write("bare.yaml", "sensor_type: gnss\n"));
  EXPECT_FALSE(none.lever_arm_in_body || none.sigma_m || none.origin_lat_lon_height);

  const std::string bad = Write("bad.yaml", "sigma_m: -2\n");
  try {
    ReadGnssSensorYaml(bad);
    ADD_FAILURE() << "negative sigma accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("sigma_m"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace optinav::io
