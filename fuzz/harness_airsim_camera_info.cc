// AirSim camera_info.csv beside a fixed, valid airsim_rec.txt.
#include <filesystem>

#include "fuzz/fuzz_target.h"
#include "optinav/io/airsim_recording.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(airsim_camera_info) {
  fuzz::QuietLibraries();
  static const std::string rec = fuzz::WriteScratch(
      "airsim_cam/airsim_rec.txt",
      "VehicleName\tTimeStamp\tPOS_X\tPOS_Y\tPOS_Z\tQ_W\tQ_X\tQ_Y\tQ_Z\tThrottle\tSteering\tBrake\t"
      "Gear\tHandbrake\tRPM\tSpeed\tImageFile\n"
      "PhysXCar\t1000\t0\t0\t-1\t1\t0\t0\t0\t0.5\t0\t0\t1\t0\t1000\t2\tim_0.png\n"
      "PhysXCar\t1050\t0.1\t0\t-1\t1\t0\t0\t0\t0.5\t0\t0\t1\t0\t1000\t2\tim_1.png\n");
  fuzz::WriteScratch("airsim_cam/camera_info.csv", data, size);
  try {
    io::ReadAirsimRecording(std::filesystem::path(rec).parent_path().string(),
                            {.check_images_exist = false});
  } catch (const Error&) {
  }
  return 0;
}
