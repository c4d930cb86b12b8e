// Simulation runs for `optinav sim`: one sequence with a progress bar, or the weather suite (the
// 36 sequences of sim::WeatherSuite(), each in a folder named after it).
#pragma once

#include <functional>
#include <string>

#include "optinav/sim/simulation.h"

namespace optinav::app {

// sim::RunSimulation with a progress bar labelled `label` (drawn only on a terminal).
sim::SimulationSummary SimulateWithProgress(const sim::SimulationOptions& options,
                                            const std::string& label);

// Writes every suite sequence to options.out_dir/<name>: `options` with that sequence's world
// kind and weather. The suite folder is checked first, as a whole: Error (file: the folder,
// field "out") when it is not empty and !options.force, leaving it untouched; with force its
// contents are replaced. Calls `done(index, entry, summary)` after each sequence and returns the
// stereo frames written in all.
size_t RunWeatherSuite(
    const sim::SimulationOptions& options,
    const std::function<void(size_t, const sim::SuiteEntry&, const sim::SimulationSummary&)>& done);

}  // namespace optinav::app
