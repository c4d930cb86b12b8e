// optinav report DIR [--out FILE.html]: the self-contained HTML report of a command's output
// (app::WriteHtmlReport); mission, bench gnss, bench weather and vio take --html to write it at
// the end of their run.
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "optinav/app/html_report.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"

namespace optinav {

void PrintHtmlReportLine(const app::HtmlReportResult& r) {
  std::printf("report: %s (%.1f MB, %zu paths, %zu fixes, %zu markers, %.2f s)\n", r.out.c_str(),
              r.bytes / 1e6, r.paths, r.fixes, r.markers, r.seconds);
}

int RunReport(int argc, char** argv) {
  CLI::App app{
      "Write one self-contained HTML report (offline: Leaflet map with the orthophoto, true and "
      "estimated paths, fixes coloured by error, start/target, error over time, summary, "
      "settings) of the output folder of optinav mission, bench gnss, bench weather or "
      "vio --gnss."};
  app.name("optinav report");
  std::string dir, out;
  app.add_option("DIR", dir,
                 "output folder (its report.json), or a report document (TRAJ.report.json)")
      ->required();
  app.add_option("--out", out, "HTML file (default: DIR/report.html)");
  return cli::RunCli(app, argc, argv, [&] {
    PrintHtmlReportLine(app::WriteHtmlReport(dir, out));
    return 0;
  });
}

}  // namespace optinav
