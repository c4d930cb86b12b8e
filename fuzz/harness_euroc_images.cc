// EuRoC cam*/data.csv image lists ("timestamp [ns], filename"), without and with the existence
// check (dropping missing images).
#include "fuzz/fuzz_target.h"
#include "optinav/io/euroc_dataset.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(euroc_images) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("cam/data.csv", data, size);
  const std::string image_dir = fuzz::ScratchDir() + "/cam/data";
  try {
    io::ReadImageList(path, image_dir, /*check_exist=*/false);
  } catch (const Error&) {
  }
  try {
    io::ReadImageList(path, image_dir, /*check_exist=*/true, /*drop_missing=*/true);
  } catch (const Error&) {
  }
  return 0;
}
