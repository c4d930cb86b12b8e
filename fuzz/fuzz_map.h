// A small map database for the harnesses that need one (map_db_rows, locate_list) and for the
// seed corpus: a seeded synthetic texture as a GeoTIFF (UTM 33N, 1 m pixels) cut into tiles with
// few features, so loading it per execution stays cheap.
#pragma once

#include <string>

namespace optinav::fuzz {

// Writes `dir`/fuzz_ortho.tif and `dir`/fuzz_map.db (once per process per dir); returns the
// database path.
std::string BuildSmallMap(const std::string& dir);

}  // namespace optinav::fuzz
