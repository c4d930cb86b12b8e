// The benchmark's report: the tables, results.csv, results.json and the error plot, from the runs
// (app/gnss_bench.cc makes the runs). Internal to app.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "optinav/app/gnss_bench.h"

namespace optinav::app::internal {

// The tables as printed and written to tables.md (one row per condition x norm, one column per
// sequence); *never_worse: every fused run's ATE is within 5 % of the VIO alone's.
std::string GnssBenchTables(const std::vector<GnssBenchSequenceInfo>& sequences,
                            const std::vector<GnssCondition>& conditions,
                            const std::vector<vio::GnssNorm>& norms,
                            const std::vector<GnssRunResult>& runs, bool* never_worse);

std::string GnssBenchCsv(const std::vector<GnssRunResult>& runs);
nlohmann::json GnssBenchJson(const std::vector<GnssBenchSequenceInfo>& sequences,
                             const std::vector<GnssRunResult>& runs, bool never_worse);

// Global error over time of one sequence: no GNSS, sigma 3 m (output and live), outliers, outage
// (first seed, Huber).
void WriteGnssErrorPlot(const std::string& path, const std::vector<GnssRunResult>& runs,
                        const GnssBenchSequenceInfo& sequence);

// The HTML report's document: per sequence a map in the local ENU frame (truth, the VIO alone,
// every fused run's output, one layer per condition x norm), the GNSS samples of one run as fixes
// coloured by their error (rejected ones marked), the global error over time; the run table.
void WriteGnssBenchReportDocument(const std::string& path,
                                  const std::vector<GnssBenchSequenceInfo>& sequences,
                                  const std::vector<GnssRunResult>& runs,
                                  const nlohmann::json& settings, const std::string& tables);

}  // namespace optinav::app::internal
