#include "optinav/sim/internal/png_writer.h"

#include <csetjmp>
#include <string>

#include <png.h>
#include <zlib.h>

#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

void Append(png_structp png, png_bytep data, png_size_t n) {
  auto* out = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + n);
}

void Flush(png_structp) {}

}  // namespace

std::vector<uint8_t> EncodePng(const cv::Mat& image, int compression_level) {
  if (image.empty() || (image.type() != CV_8UC3 && image.type() != CV_8UC1)) {
    throw Error("EncodePng needs a non-empty 8-bit 1- or 3-channel image");
  }
  std::vector<uint8_t> out;
  out.reserve(image.total() * image.elemSize() / 2);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    throw Error("libpng: out of memory");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw Error("libpng failed to encode an image");
  }
  png_set_write_fn(png, &out, Append, Flush);
  const bool colour = image.channels() == 3;
  png_set_IHDR(png, info, image.cols, image.rows, 8,
               colour ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, 0, compression_level == 0 ? PNG_FILTER_NONE : PNG_FILTER_SUB);
  png_set_compression_level(png, compression_level);
  png_set_compression_strategy(png, compression_level == 0 ? Z_DEFAULT_STRATEGY : Z_RLE);
  png_write_info(png, info);
  if (colour) png_set_bgr(png);
  for (int y = 0; y < image.rows; ++y) {
    png_write_row(png, const_cast<png_bytep>(image.ptr<uint8_t>(y)));
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

}  // namespace optinav::sim
