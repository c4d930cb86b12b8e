// Georeferenced rasters through GDAL: any GeoTIFF GDAL reads (1, 3 or more bands, 8/16-bit or
// float, nodata, overviews, tiled or striped), read by window so large maps never sit in memory.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "optinav/geo/geo.h"

namespace optinav::geo {

class GeoRaster {
 public:
  // Opens read-only. Throws Error naming the file when it cannot be read, has no geotransform,
  // or has no (or an unknown) CRS.
  static GeoRaster Open(const std::string& path);
  ~GeoRaster();
  GeoRaster(GeoRaster&&) noexcept;
  GeoRaster& operator=(GeoRaster&&) noexcept;

  const std::string& path() const { return path_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int band_count() const { return bands_; }
  std::string data_type() const;  // "Byte", "UInt16", "Float64", ...
  std::optional<double> nodata() const { return nodata_; }
  const GeoTransform& transform() const { return transform_; }
  const std::string& crs_wkt() const { return crs_wkt_; }
  int overview_count() const;

  // Reads the window [x, x + w) x [y, y + h) (map pixels; may extend past the raster, where
  // the result is 0) resampled to out_w x out_h (0: same as w, h), as 8-bit grey (bands 1-3
  // averaged with Rec. 601 weights when there are 3 or more bands). Values of other types are
  // stretched with the band's min/max. Uses overviews when downsampling. `valid` (optional)
  // receives 255 where data exists (inside the raster and not nodata).
  cv::Mat ReadGray(int x, int y, int w, int h, int out_w = 0, int out_h = 0,
                   cv::Mat* valid = nullptr) const;

 private:
  GeoRaster() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_, crs_wkt_;
  int width_ = 0, height_ = 0, bands_ = 0;
  std::optional<double> nodata_;
  GeoTransform transform_;
};

struct GeoTiffWriteOptions {
  bool tiled = true;
  std::string compress = "DEFLATE";  // or "NONE", "LZW", "JPEG"
  std::optional<double> nodata;
  bool build_overviews = false;
};

// Writes an 8-bit (1 or 3 channel, BGR order for 3) image as a GeoTIFF atomically.
// `crs` is WKT or "EPSG:n". Throws Error on failure.
void WriteGeoTiff(const std::string& path, const cv::Mat& image, const GeoTransform& transform,
                  const std::string& crs, const GeoTiffWriteOptions& options = {});

// Writes a GDAL VRT mosaic of `inputs` (paths GDAL opens, /vsi* included; one CRS, else Error
// naming the raster in another) to `vrt_path`, atomically. Read through GeoRaster, a mosaic is
// read by window like one raster: only the files a window touches are opened. Where rasters
// overlap, the later one wins (gdalbuildvrt's order); the finest resolution is kept.
void WriteMosaicVrt(const std::vector<std::string>& inputs, const std::string& vrt_path);

}  // namespace optinav::geo
