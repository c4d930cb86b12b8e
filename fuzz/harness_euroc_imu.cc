// EuRoC imu0/data.csv ("timestamp [ns], wx, wy, wz, ax, ay, az") and, on the same bytes, the
// barometer's baro0/data.csv ("timestamp [ns], altitude [m]").
#include "fuzz/fuzz_target.h"
#include "optinav/io/euroc_dataset.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(euroc_imu) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("imu.csv", data, size);
  try {
    io::ReadImuCsv(path);
  } catch (const Error&) {
  }
  try {
    io::ReadBaroCsv(path);
  } catch (const Error&) {
  }
  return 0;
}
