// The `map locate --images-from` csv list, through MapLocateRun::LocateList on a small map (the
// parser lives in app/map_locate.cc). Rows naming no readable image end as per-row errors; the
// list itself must not crash or throw anything but an Error.
#include <memory>

#include "fuzz/fuzz_map.h"
#include "fuzz/fuzz_target.h"
#include "optinav/app/map_locate.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(locate_list) {
  fuzz::QuietLibraries();
  static const std::unique_ptr<app::MapLocateRun> run = [] {
    app::MapLocateOptions o;
    o.map_path = fuzz::BuildSmallMap(fuzz::ScratchDir() + "/locate_map");
    return std::make_unique<app::MapLocateRun>(o);
  }();
  const std::string path = fuzz::WriteScratch("list.csv", data, size);
  size_t rows = 0;
  try {
    run->LocateList(path, [&](const nlohmann::json& j) {
      ++rows;
      // As `map locate --images-from` prints it: image names that are not UTF-8 (found by this
      // harness: the strict handler threw and ended the whole list) print with U+FFFD.
      (void)j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    });
  } catch (const Error&) {
  }
  return 0;
}
