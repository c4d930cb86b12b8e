// The weather benchmark's report: table.md, table.csv, results.json and the plot
// (weather_error.svg and .png), from the runs and cells (app/weather_bench.cc makes them).
// Internal to app.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "optinav/app/weather_bench.h"

namespace optinav::app::internal {

// The table as printed and written to table.md: one row per world x condition x mode, ours
// beside the document's ORB-SLAM3 figures.
std::string WeatherBenchTable(const WeatherBenchOptions& options,
                              const std::vector<WeatherCell>& cells,
                              const std::vector<WeatherRunResult>& runs);
std::string WeatherBenchCsv(const std::vector<WeatherCell>& cells);
nlohmann::json WeatherBenchJson(const WeatherBenchOptions& options,
                                const WeatherBenchResult& result);

// Mean error per condition and level, ours (per mode) beside the document's, one panel per
// world, log scale; writes stem.svg and stem.png.
void WriteWeatherPlot(const std::string& stem, const WeatherBenchOptions& options,
                      const std::vector<WeatherCell>& cells);

// results.json, table.md, table.csv, weather_error.svg/.png in options.out_dir.
void WriteWeatherBenchFiles(const WeatherBenchOptions& options, const WeatherBenchResult& result);

}  // namespace optinav::app::internal
