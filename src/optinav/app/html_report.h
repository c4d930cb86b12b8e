// The driver behind `optinav report` and the commands' --html: finds the report document a
// command wrote (report.json in its output folder, or TRAJ.report.json beside a `vio --gnss`
// trajectory), renders the self-contained HTML page (report/html_report.h) and writes it
// atomically.
//
// Commands that write a report document: mission, bench gnss, bench weather, vio --gnss. `nav`
// does not exist yet; when it does, it writes report.json with kind "nav" through the same
// report::ReportDocument and needs nothing here.
#pragma once

#include <string>

namespace optinav::app {

struct HtmlReportResult {
  std::string document;  // the report document read
  std::string out;       // the HTML written
  std::string kind;      // mission | bench gnss | bench weather | vio gnss | nav
  size_t bytes = 0;
  size_t paths = 0, fixes = 0, markers = 0;  // drawn on the maps
  double seconds = 0;                        // reading, rendering and writing
};

// `path`: an output folder (holding report.json, or a single *.report.json) or a report document.
// `out`: the HTML file; empty: report.html beside report.json, TRAJ.report.html beside
// TRAJ.report.json. Throws Error naming the file when there is no document, it is malformed, an
// image it names is missing, or the vendored Leaflet is missing.
HtmlReportResult WriteHtmlReport(const std::string& path, const std::string& out = "");

// Where a command's report document goes: DIR/report.json.
std::string ReportDocumentPath(const std::string& out_dir);

}  // namespace optinav::app
