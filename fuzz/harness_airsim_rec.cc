// AirSim airsim_rec.txt (tab-separated, header row), read as a sequence folder without
// camera_info.csv; images are not checked (no files behind the names).
#include <filesystem>

#include "fuzz/fuzz_target.h"
#include "optinav/io/airsim_recording.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(airsim_rec) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("airsim_rec/airsim_rec.txt", data, size);
  try {
    io::ReadAirsimRecording(std::filesystem::path(path).parent_path().string(),
                            {.check_images_exist = false});
  } catch (const Error&) {
  }
  return 0;
}
