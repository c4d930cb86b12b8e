#include "optinav/app/html_report.h"

#include <chrono>
#include <filesystem>
#include <vector>

#include "optinav/io/text_parse.h"
#include "optinav/report/html_report.h"
#include "optinav/util/error.h"

namespace optinav::app {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSuffix = ".report.json";

bool EndsWith(const std::string& s, const std::string& end) {
  return s.size() >= end.size() && s.compare(s.size() - end.size(), end.size(), end) == 0;
}

std::string FindDocument(const std::string& path) {
  if (fs::is_regular_file(path)) return path;
  if (!fs::is_directory(path)) throw Error("no such folder or report document", {.file = path});
  if (fs::is_regular_file(fs::path(path) / "report.json"))
    return (fs::path(path) / "report.json").string();
  std::vector<std::string> found;
  for (const fs::directory_entry& e : fs::directory_iterator(path))
    if (e.is_regular_file() && EndsWith(e.path().filename().string(), kSuffix))
      found.push_back(e.path().string());
  if (found.size() == 1) return found[0];
  if (found.size() > 1)
    throw Error(
        "holds several *.report.json (vio --gnss runs): give the one to render, e.g. " + found[0],
        {.file = path});
  throw Error(
      "no report.json: the report is made from the output folder of optinav mission, bench gnss, "
      "bench weather or vio --gnss (made by this version or later; run it again)",
      {.file = path});
}

std::string DefaultOut(const std::string& document) {
  if (EndsWith(document, kSuffix))
    return document.substr(0, document.size() - std::string(kSuffix).size()) + ".report.html";
  return (fs::path(document).parent_path() / "report.html").string();
}

}  // namespace

std::string ReportDocumentPath(const std::string& out_dir) {
  return (fs::path(out_dir) / "report.json").string();
}

HtmlReportResult WriteHtmlReport(const std::string& path, const std::string& out) {
  const auto t0 = std::chrono::steady_clock::now();
  HtmlReportResult r;
  r.document = FindDocument(path);
  r.out = out.empty() ? DefaultOut(r.document) : out;
  const report::ReportDocument doc = report::ReadReportDocument(r.document);
  const report::LeafletAssets leaflet = report::LoadLeafletAssets();
  const std::string html =
      report::RenderHtmlReport(doc, leaflet, fs::path(r.document).parent_path().string());
  io::WriteFileAtomically(r.out, html);
  r.kind = doc.kind;
  r.bytes = html.size();
  for (const report::ReportView& v : doc.views) {
    r.paths += v.paths.size();
    r.fixes += v.fixes.size();
    r.markers += v.markers.size();
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace optinav::app
