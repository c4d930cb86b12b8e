// GNSS csv files (gnss0/data.csv ENU and llh.csv latitude/longitude/height), kind detected from
// the header and forced.
#include "fuzz/fuzz_target.h"
#include "optinav/io/gnss_io.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(gnss_csv) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("gnss.csv", data, size);
  for (const auto kind : {std::optional<io::GnssFileKind>(), std::optional(io::GnssFileKind::kEnu),
                          std::optional(io::GnssFileKind::kLatLonHeight)}) {
    try {
      io::ReadGnssFile(path, kind);
    } catch (const Error&) {
    }
  }
  return 0;
}
