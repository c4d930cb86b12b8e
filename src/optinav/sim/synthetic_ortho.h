// A procedural orthophoto for demos and benchmarks at sizes no test data has: multi-octave value
// noise (fields, patches and fine texture) with straight "roads", unique everywhere, 8-bit grey,
// written as a tiled GeoTIFF in NAD83 / UTM 14N (upper-left corner at 480000 E, 5210000 N).
#pragma once

#include <string>

namespace optinav::sim {

// size x size pixels at gsd_m metres per pixel; throws Error on I/O failure.
void WriteSyntheticOrtho(const std::string& path, int size, double gsd_m, unsigned seed);

// Rural farmland like the NAIP imagery, procedurally: a grid of parcels (each with its own tone
// and crop-row stripes at its own angle), farmsteads, ponds and lakes (dark, smooth-edged), and a
// road grid, with fine texture; 3-band colour GeoTIFF, same georeference as above.
void WriteSyntheticFarmland(const std::string& path, int size, double gsd_m, unsigned seed);

}  // namespace optinav::sim
