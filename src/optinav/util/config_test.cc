#include "optinav/util/config.h"

#include <gtest/gtest.h>

#include "optinav/util/testing.h"

namespace optinav {
namespace {

TEST(Config, ReadsOpenCvStyleYamlWithMatrix) {
  const auto f = ParseYamlString(
      "%YAML:1.0\nrate_hz: 20\nname: cam\nT_BS:\n  cols: 2\n  rows: 1\n  data: [1.5, -2]\n",
      "mem.yaml");
  EXPECT_EQ(YamlGet<int>(f, f.root, "rate_hz"), 20);
  EXPECT_EQ(YamlGet<std::string>(f, f.root, "name"), "cam");
  EXPECT_EQ(YamlGetOr<double>(f, f.root, "missing", 4.0), 4.0);
  EXPECT_EQ(YamlGetNumbers(f, f.root, "T_BS", 2), (std::vector<double>{1.5, -2}));
}

TEST(Config, MissingKeyNamesFileAndKey) {
  const auto f = ParseYamlString("a: 1\n", "x.yaml");
  try {
    YamlGet<int>(f, f.root, "b");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.context().file, "x.yaml");
    EXPECT_EQ(e.context().field, "b");
  }
}

TEST(Config, WrongTypeAndWrongLengthAndNan) {
  const auto f = ParseYamlString("a: hello\nv: [1, 2]\nn: [1, .nan]\n", "x.yaml");
  EXPECT_THROW(YamlGet<int>(f, f.root, "a"), Error);
  EXPECT_THROW(YamlGetNumbers(f, f.root, "v", 3), Error);
  EXPECT_THROW(YamlGetNumbers(f, f.root, "n"), Error);
  try {
    YamlGetNumbers(f, f.root, "v", 3);
  } catch (const Error& e) {
    EXPECT_EQ(e.context().line, 2);
  }
}

TEST(Config, SyntaxErrorAndMissingFile) {
  EXPECT_THROW(ParseYamlString("a: [1, 2\n", "bad.yaml"), Error);
  EXPECT_THROW(ParseYamlString("", "empty.yaml"), Error);
  EXPECT_THROW(LoadYamlFile("/nonexistent/optinav.yaml"), Error);
  const auto dir = testing::MakeTempDir("config");
  const auto path = testing::WriteFile(dir / "ok.yaml", "k: 3\n");
  EXPECT_EQ(YamlGet<int>(LoadYamlFile(path), LoadYamlFile(path).root, "k"), 3);
}

}  // namespace
}  // namespace optinav
