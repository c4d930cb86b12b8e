// The commands of the single `optinav` binary (dispatched by optinav.cc). Each parses its own
// flags through cli::RunCli and returns the process exit code: 0 success, 1 an Error from the
// run, 2 bad usage (mission also 3: some run failed).
#pragma once

namespace optinav {

namespace app {
struct HtmlReportResult;
}  // namespace app
// The line the commands print after writing an HTML report (report_command.cc).
void PrintHtmlReportLine(const app::HtmlReportResult& result);

int RunEval(int argc, char** argv);     // optinav eval ape|rpe REF EST ...
int RunMap(int argc, char** argv);      // optinav map build|info|locate|render ...
int RunSim(int argc, char** argv);      // optinav sim ... | optinav sim suite ...
int RunMission(int argc, char** argv);  // optinav mission --map DB --start --target --out DIR ...
int RunVio(int argc, char** argv);      // optinav vio --dataset DIR --out TRAJ.tum ...
int RunBench(int argc, char** argv);    // optinav bench gnss|weather --out DIR ...
int RunWeatherBench(int argc, char** argv);  // optinav bench weather (through RunBench)
int RunDemo(int argc, char** argv);          // optinav demo --out DIR ...
int RunReport(int argc, char** argv);        // optinav report DIR [--out FILE.html]

}  // namespace optinav
