#include "optinav/report/trajectory_plot.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "optinav/io/text_parse.h"
#include "optinav/report/svg.h"
#include "optinav/util/testing.h"

namespace optinav::report {
namespace {

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

struct Fixture {
  Trajectory ref, est;
  eval::ErrorSeries series;
  explicit Fixture(int n) {
    for (int i = 0; i < n; ++i) {
      const double a = i * 0.01;
      ref.Add(int64_t{i} * 50'000'000,
              Rigid3d(Eigen::Quaterniond::Identity(),
                      Eigen::Vector3d(10 * std::cos(a), 10 * std::sin(a), 0)));
      est.Add(int64_t{i} * 50'000'000,
              Rigid3d(Eigen::Quaterniond::Identity(),
                      Eigen::Vector3d(10 * std::cos(a) + 0.001 * i, 10 * std::sin(a), 0)));
    }
    series = eval::ComputeApe(ref, est, eval::PoseRelation::kTranslation);
  }
  ErrorPlotInput Input() const {
    return {.title = "APE <test> & more",
            .subtitle = "sub",
            .unit = "m",
            .ref = &ref,
            .est = &est,
            .series = &series};
  }
};

TEST(ErrorPlot, WellFormedSvgWithColouredSegments) {
  const Fixture f(200);
  const std::string svg = RenderErrorPlotSvg(f.Input());
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_NE(svg.find("<svg xmlns"), std::string::npos);
  EXPECT_EQ(svg.substr(svg.size() - 7), "</svg>\n");
  EXPECT_NE(svg.find("APE &lt;test&gt; &amp; more"), std::string::npos);  // escaped title
  EXPECT_EQ(Count(svg, "stroke-linecap=\"round\""), 199u);                // one per segment
  // Lowest error drawn in the map's first colour, highest in its last.
  EXPECT_NE(svg.find(ColorMap(1.0).Hex()), std::string::npos);
  EXPECT_NE(svg.find("rmse"), std::string::npos);
  EXPECT_NE(svg.find("time (s)"), std::string::npos);
}

TEST(ErrorPlot, DecimatesLongTrajectoriesAndRejectsBadPlane) {
  const Fixture f(50'000);
  const std::string svg = RenderErrorPlotSvg(f.Input());
  EXPECT_LE(Count(svg, "stroke-linecap=\"round\""), 4001u);
  EXPECT_LT(svg.size(), 2'000'000u);
  ErrorPlotInput bad = f.Input();
  bad.plane = "ab";
  EXPECT_ERROR(RenderErrorPlotSvg(bad), {.field = "--plot-plane"}, "unknown plot plane 'ab'");
  const auto dir = testing::MakeTempDir("plot");
  WriteErrorPlotSvg((dir / "p.svg").string(), f.Input());
  EXPECT_TRUE(std::filesystem::exists(dir / "p.svg"));
}

TEST(Svg, TicksAndColours) {
  const Ticks t = NiceTicks(0.0, 9.7, 5);
  EXPECT_DOUBLE_EQ(t.step, 2.0);
  EXPECT_EQ(t.count, 5);
  EXPECT_EQ(FormatTick(0.25, 0.05), "0.25");
  EXPECT_EQ(ColorMap(-1).Hex(), ColorMap(0).Hex());
  EXPECT_NE(ColorMap(0).Hex(), ColorMap(1).Hex());
}

}  // namespace
}  // namespace optinav::report
