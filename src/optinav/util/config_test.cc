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
  EXPECT_ERROR(YamlGet<int>(f, f.root, "a"), {.file = "x.yaml", .line = 1, .field = "a"},
               "cannot convert value 'hello'");
  EXPECT_ERROR(YamlGetNumbers(f, f.root, "v", 3), {.file = "x.yaml", .line = 2, .field = "v"},
               "expected 3 numbers, found 2");
  EXPECT_ERROR(YamlGetNumbers(f, f.root, "n"), {.file = "x.yaml", .line = 3, .field = "n"},
               "element 1 is not finite");
}

TEST(Config, SyntaxErrorAndMissingFile) {
  EXPECT_ERROR(ParseYamlString("a: [1, 2\n", "bad.yaml"), {.file = "bad.yaml", .line = 2},
               "YAML syntax error");
  EXPECT_ERROR(ParseYamlString("", "empty.yaml"), {.file = "empty.yaml"}, "empty YAML document");
  EXPECT_ERROR(LoadYamlFile("/nonexistent/optinav.yaml"), {.file = "/nonexistent/optinav.yaml"},
               "cannot open file");
  const auto dir = testing::MakeTempDir("config");
  const auto path = testing::WriteFile(dir / "ok.yaml", "k: 3\n");
  EXPECT_EQ(YamlGet<int>(LoadYamlFile(path), LoadYamlFile(path).root, "k"), 3);
}

}  // namespace
}  // namespace optinav
