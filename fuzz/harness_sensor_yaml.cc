// EuRoC sensor.yaml files: camera (with the camera model built from it), IMU, GNSS and barometer
// readers
// all read the same bytes.
#include "fuzz/fuzz_target.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/io/gnss_io.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(sensor_yaml) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("sensor.yaml", data, size);
  try {
    const io::CameraCalibration c = io::ReadCameraCalibration(path);
    const camera::PinholeCamera cam = io::ToPinholeCamera(c);
    // Use the model as the pipeline does: undistort a corner (iterative), project it back.
    const Eigen::Vector2d n = cam.PixelToNormalized({0.0, 0.0});
    (void)cam.Project(Eigen::Vector3d(n.x(), n.y(), 1.0));
    (void)io::ToStereoRig(c, c).Essential();
  } catch (const Error&) {
  }
  try {
    io::ReadImuCalibration(path);
  } catch (const Error&) {
  }
  try {
    io::ReadGnssSensorYaml(path);
  } catch (const Error&) {
  }
  try {
    io::ReadBaroCalibration(path);
  } catch (const Error&) {
  }
  return 0;
}
