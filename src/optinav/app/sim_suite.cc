#include "optinav/app/sim_suite.h"

#include <filesystem>
#include <memory>

#include <fmt/format.h>

#include "optinav/io/text_parse.h"
#include "optinav/util/progress.h"

namespace optinav::app {

sim::SimulationSummary SimulateWithProgress(const sim::SimulationOptions& options,
                                            const std::string& label) {
  std::unique_ptr<ProgressBar> bar;
  const sim::SimulationSummary s = sim::RunSimulation(options, [&](size_t, size_t total) {
    if (!bar) bar = std::make_unique<ProgressBar>(total, label);
    bar->Advance();
  });
  if (bar) bar->Finish();
  return s;
}

size_t RunWeatherSuite(const sim::SimulationOptions& options,
                       const std::function<void(size_t, const sim::SuiteEntry&,
                                                const sim::SimulationSummary&)>& done) {
  if (const std::string msg = options.Check(); !msg.empty()) throw Error(msg);
  io::PrepareOutputDir(options.out_dir, options.force, io::OnForce::kClear, "--out");
  const auto suite = sim::WeatherSuite();
  size_t frames = 0;
  for (size_t i = 0; i < suite.size(); ++i) {
    sim::SimulationOptions o = options;
    o.out_dir = (std::filesystem::path(options.out_dir) / suite[i].name).string();
    o.world.kind = suite[i].world;
    o.weather = suite[i].weather;
    o.force = true;  // the suite folder as a whole was checked above
    const sim::SimulationSummary s =
        SimulateWithProgress(o, fmt::format("[{}/{}] {}", i + 1, suite.size(), suite[i].name));
    frames += s.frames;
    done(i, suite[i], s);
  }
  return frames;
}

}  // namespace optinav::app
