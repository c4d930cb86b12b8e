// GeoTIFFs through the GDAL wrapper (geo/raster.h): open (georeference, CRS, nodata), then read
// bounded windows (inside, across the border, downsampled) as 8-bit grey with the valid mask.
#include "fuzz/fuzz_target.h"
#include "optinav/geo/raster.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(geotiff) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("raster.tif", data, size);
  try {
    const geo::GeoRaster r = geo::GeoRaster::Open(path);
    (void)r.data_type();
    (void)r.overview_count();
    cv::Mat valid;
    const int w = std::min(r.width(), 96), h = std::min(r.height(), 96);
    (void)r.ReadGray(0, 0, w, h, 0, 0, &valid);
    (void)r.ReadGray(r.width() - w / 2, r.height() - h / 2, w, h, 24, 24, &valid);
    (void)r.ReadGray(-8, -8, 2 * w, 2 * h, 16, 16);
  } catch (const Error&) {
  }
  return 0;
}
