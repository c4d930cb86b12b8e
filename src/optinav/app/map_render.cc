#include "optinav/app/map_render.h"

#include <opencv2/imgcodecs.hpp>

#include "optinav/geo/raster.h"
#include "optinav/maploc/frame_synth.h"

namespace optinav::app {

RenderedFrame RenderFrame(const FrameRenderOptions& o) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(o.ortho_path);
  const geo::CrsTransform crs(raster.crs_wkt());
  maploc::FrameSpec s;
  s.width = o.width;
  s.height = o.height;
  s.centre_px = raster.transform().CrsToPixel(crs.FromLatLon(o.at));
  if (s.centre_px.x() < 0 || s.centre_px.y() < 0 || s.centre_px.x() > raster.width() ||
      s.centre_px.y() > raster.height()) {
    throw Error("position lies outside the orthophoto", {.field = "--at"});
  }
  const double map_gsd = raster.transform().UnitsPerPixel() *
                         crs.MetresPerUnit(raster.transform().PixelToCrs(s.centre_px));
  s.gsd_m = o.gsd_m > 0 ? o.gsd_m : map_gsd;
  s.heading_deg = o.heading_deg;
  s.tilt_deg = o.tilt_deg;
  s.tilt_azimuth_deg = o.tilt_azimuth_deg;
  const cv::Mat frame = maploc::SynthesizeFrame(raster, map_gsd, s);
  if (!cv::imwrite(o.out_path, frame)) throw Error("cannot write image", {.file = o.out_path});
  return {.gsd_m = s.gsd_m};
}

}  // namespace optinav::app
