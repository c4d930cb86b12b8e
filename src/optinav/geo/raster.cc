#include "optinav/geo/raster.h"

#include <filesystem>
#include <mutex>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>
#include <opencv2/imgproc.hpp>

namespace optinav::geo {
namespace {

void InitGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(CPLQuietErrorHandler);  // errors are reported through exceptions
  });
}

std::string LastGdalError() {
  const char* msg = CPLGetLastErrorMsg();
  return msg && *msg ? msg : "unknown GDAL error";
}

}  // namespace

struct GeoRaster::Impl {
  GDALDataset* ds = nullptr;
  std::vector<double> band_min, band_max;  // for non-8-bit stretching
  bool eight_bit = true;
  ~Impl() {
    if (ds) GDALClose(ds);
  }
};

GeoRaster GeoRaster::Open(const std::string& path) {
  InitGdal();
  // /vsi paths (/vsicurl/, /vsis3/, /vsizip/, ...) are GDAL's virtual file systems: GDAL opens
  // them.
  if (path.rfind("/vsi", 0) != 0 && !std::filesystem::is_regular_file(path))
    throw Error("raster file not found", {.file = path});
  GeoRaster r;
  r.impl_ = std::make_unique<Impl>();
  r.path_ = path;
  CPLErrorReset();
  r.impl_->ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  if (!r.impl_->ds) {
    throw Error("cannot open as a raster (corrupt or unsupported?): " + LastGdalError(),
                {.file = path});
  }
  GDALDataset* ds = r.impl_->ds;
  r.width_ = ds->GetRasterXSize();
  r.height_ = ds->GetRasterYSize();
  r.bands_ = ds->GetRasterCount();
  if (r.width_ <= 0 || r.height_ <= 0 || r.bands_ <= 0) {
    throw Error("raster has no pixels or no bands", {.file = path});
  }
  if (ds->GetGeoTransform(r.transform_.c.data()) != CE_None) {
    throw Error("raster has no georeference (no geotransform)", {.file = path});
  }
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (!srs || srs->IsEmpty())
    throw Error("raster has no coordinate reference system", {.file = path});
  char* wkt = nullptr;
  const char* const wkt_options[] = {"FORMAT=WKT2_2019", nullptr};
  srs->exportToWkt(&wkt, wkt_options);
  r.crs_wkt_ = wkt ? wkt : "";
  CPLFree(wkt);
  try {
    CrsTransform check(r.crs_wkt_);
  } catch (const Error& e) {
    throw Error("unusable CRS: " + e.message(), {.file = path});
  }
  int has_nodata = 0;
  GDALRasterBand* b1 = ds->GetRasterBand(1);
  const double nd = b1->GetNoDataValue(&has_nodata);
  if (has_nodata) r.nodata_ = nd;
  r.impl_->eight_bit = b1->GetRasterDataType() == GDT_Byte;
  if (!r.impl_->eight_bit) {
    for (int b = 1; b <= std::min(r.bands_, 3); ++b) {
      double mm[2] = {0, 255};
      if (ds->GetRasterBand(b)->ComputeRasterMinMax(TRUE, mm) != CE_None) {
        throw Error("cannot compute band statistics: " + LastGdalError(), {.file = path});
      }
      r.impl_->band_min.push_back(mm[0]);
      r.impl_->band_max.push_back(mm[1] > mm[0] ? mm[1] : mm[0] + 1);
    }
  }
  return r;
}

GeoRaster::~GeoRaster() = default;
GeoRaster::GeoRaster(GeoRaster&&) noexcept = default;
GeoRaster& GeoRaster::operator=(GeoRaster&&) noexcept = default;

std::string GeoRaster::data_type() const {
  return GDALGetDataTypeName(impl_->ds->GetRasterBand(1)->GetRasterDataType());
}

int GeoRaster::overview_count() const { return impl_->ds->GetRasterBand(1)->GetOverviewCount(); }

cv::Mat GeoRaster::ReadGray(int x, int y, int w, int h, int out_w, int out_h,
                            cv::Mat* valid) const {
  if (w <= 0 || h <= 0) throw Error("empty read window", {.file = path_});
  if (out_w <= 0) out_w = w;
  if (out_h <= 0) out_h = h;
  cv::Mat out = cv::Mat::zeros(out_h, out_w, CV_8UC1);
  if (valid) *valid = cv::Mat::zeros(out_h, out_w, CV_8UC1);
  // Clip the window to the raster and map the clipped part into the output.
  const int x0 = std::max(x, 0), y0 = std::max(y, 0);
  const int x1 = std::min(x + w, width_), y1 = std::min(y + h, height_);
  if (x1 <= x0 || y1 <= y0) return out;
  const double sx = static_cast<double>(out_w) / w, sy = static_cast<double>(out_h) / h;
  const int ox0 = static_cast<int>(std::lround((x0 - x) * sx));
  const int oy0 = static_cast<int>(std::lround((y0 - y) * sy));
  const int ox1 = std::min(out_w, static_cast<int>(std::lround((x1 - x) * sx)));
  const int oy1 = std::min(out_h, static_cast<int>(std::lround((y1 - y) * sy)));
  const int ow = ox1 - ox0, oh = oy1 - oy0;
  if (ow <= 0 || oh <= 0) return out;

  const int nb = bands_ >= 3 ? 3 : 1;
  std::vector<cv::Mat> planes(nb);
  GDALRasterIOExtraArg extra;
  INIT_RASTERIO_EXTRA_ARG(extra);
  extra.eResampleAlg = (ow < x1 - x0) ? GRIORA_Average : GRIORA_Bilinear;
  for (int b = 0; b < nb; ++b) {
    planes[b].create(oh, ow, CV_32FC1);
    CPLErrorReset();
    const CPLErr err = impl_->ds->GetRasterBand(b + 1)->RasterIO(
        GF_Read, x0, y0, x1 - x0, y1 - y0, planes[b].data, ow, oh, GDT_Float32, 0, 0, &extra);
    if (err != CE_None) {
      throw Error("read failed (truncated or corrupt file?): " + LastGdalError(), {.file = path_});
    }
  }
  cv::Mat mask(oh, ow, CV_8UC1, cv::Scalar(255));
  if (nodata_) {
    for (int b = 0; b < nb; ++b) {
      cv::Mat is_nd;
      cv::compare(planes[b], static_cast<float>(*nodata_), is_nd, cv::CMP_EQ);
      mask.setTo(0, is_nd);
    }
  }
  if (!impl_->eight_bit) {
    for (int b = 0; b < nb; ++b) {
      const double lo = impl_->band_min[b], hi = impl_->band_max[b];
      planes[b] = (planes[b] - lo) * (255.0 / (hi - lo));
    }
  }
  cv::Mat gray;
  if (nb == 3) {
    gray = 0.299f * planes[0] + 0.587f * planes[1] + 0.114f * planes[2];
  } else {
    gray = planes[0];
  }
  cv::Mat gray8;
  gray.convertTo(gray8, CV_8UC1);  // saturates
  gray8.setTo(0, mask == 0);
  gray8.copyTo(out(cv::Rect(ox0, oy0, ow, oh)));
  if (valid) mask.copyTo((*valid)(cv::Rect(ox0, oy0, ow, oh)));
  return out;
}

void WriteGeoTiff(const std::string& path, const cv::Mat& image, const GeoTransform& transform,
                  const std::string& crs, const GeoTiffWriteOptions& options) {
  InitGdal();
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
    throw Error("WriteGeoTiff needs a non-empty 8-bit 1- or 3-channel image", {.file = path});
  }
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) throw Error("GDAL has no GTiff driver");
  std::vector<std::string> opts = {"COMPRESS=" + options.compress};
  if (options.tiled) opts.push_back("TILED=YES");
  if (image.channels() == 3) opts.push_back("PHOTOMETRIC=RGB");
  opts.push_back("BIGTIFF=IF_SAFER");
  std::vector<char*> copt;
  for (auto& o : opts) copt.push_back(o.data());
  copt.push_back(nullptr);
  const std::string tmp = path + ".tmp.tif";
  GDALDataset* ds =
      driver->Create(tmp.c_str(), image.cols, image.rows, image.channels(), GDT_Byte, copt.data());
  if (!ds) throw Error("cannot create GeoTIFF: " + LastGdalError(), {.file = path});
  auto fail = [&](const std::string& what) {
    GDALClose(ds);
    std::filesystem::remove(tmp);
    throw Error(what + ": " + LastGdalError(), {.file = path});
  };
  std::array<double, 6> gt = transform.c;
  if (ds->SetGeoTransform(gt.data()) != CE_None) fail("cannot set geotransform");
  OGRSpatialReference srs;
  if (srs.SetFromUserInput(crs.c_str()) != OGRERR_NONE) fail("unknown CRS '" + crs + "'");
  if (ds->SetSpatialRef(&srs) != CE_None) fail("cannot set CRS");
  std::vector<cv::Mat> ch;
  cv::split(image, ch);
  if (ch.size() == 3) std::swap(ch[0], ch[2]);  // BGR -> RGB bands
  for (int b = 0; b < image.channels(); ++b) {
    cv::Mat c = ch[b].isContinuous() ? ch[b] : ch[b].clone();
    GDALRasterBand* band = ds->GetRasterBand(b + 1);
    if (options.nodata) band->SetNoDataValue(*options.nodata);
    if (band->RasterIO(GF_Write, 0, 0, c.cols, c.rows, c.data, c.cols, c.rows, GDT_Byte, 0, 0) !=
        CE_None) {
      fail("write failed");
    }
  }
  if (options.build_overviews) {
    int levels[] = {2, 4, 8, 16};
    if (ds->BuildOverviews("AVERAGE", 4, levels, 0, nullptr, nullptr, nullptr) != CE_None) {
      fail("cannot build overviews");
    }
  }
  GDALClose(ds);
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    throw Error("cannot move GeoTIFF into place: " + ec.message(), {.file = path});
  }
}

}  // namespace optinav::geo

namespace optinav::geo {

void WriteMosaicVrt(const std::vector<std::string>& inputs, const std::string& vrt_path) {
  InitGdal();
  if (inputs.empty()) throw Error("a mosaic needs at least one raster", {.file = vrt_path});
  // One CRS: a VRT mosaic places rasters by their geotransforms, it does not reproject.
  OGRSpatialReference first;
  for (size_t i = 0; i < inputs.size(); ++i) {
    const GeoRaster r = GeoRaster::Open(inputs[i]);
    OGRSpatialReference srs;
    srs.importFromWkt(r.crs_wkt().c_str());
    if (i == 0) {
      first = srs;
    } else if (!srs.IsSame(&first)) {
      throw Error("is in another CRS than " + inputs[0] +
                      " (a mosaic needs one CRS; reproject "
                      "with gdalwarp first)",
                  {.file = inputs[i]});
    }
  }
  std::vector<const char*> names;
  for (const std::string& s : inputs) names.push_back(s.c_str());
  const char* argv[] = {"-resolution", "highest", "-r", "nearest", nullptr};
  GDALBuildVRTOptions* options = GDALBuildVRTOptionsNew(const_cast<char**>(argv), nullptr);
  const std::string tmp = vrt_path + ".tmp.vrt";
  CPLErrorReset();
  int usage_error = 0;
  GDALDatasetH vrt = GDALBuildVRT(tmp.c_str(), static_cast<int>(names.size()), nullptr,
                                  names.data(), options, &usage_error);
  GDALBuildVRTOptionsFree(options);
  if (!vrt) throw Error("cannot build the mosaic: " + LastGdalError(), {.file = vrt_path});
  GDALClose(vrt);  // writes the file
  std::error_code ec;
  std::filesystem::rename(tmp, vrt_path, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    throw Error("cannot move the mosaic into place: " + ec.message(), {.file = vrt_path});
  }
}

}  // namespace optinav::geo
