// Where benchmarks find the shared real data and keep their generated files.
#pragma once

#include <cstdlib>
#include <filesystem>

namespace optinav::bench {

// ../shared/data beside the checkout, or $OPTINAV_SHARED_DATA.
inline std::filesystem::path SharedData() {
  const char* env = std::getenv("OPTINAV_SHARED_DATA");
  return env ? std::filesystem::path(env) : std::filesystem::path(OPTINAV_SHARED_DATA_DEFAULT);
}

// A scratch folder kept between runs (maps and orthophotos are reused).
inline std::filesystem::path WorkDir() {
  const std::filesystem::path d = std::filesystem::temp_directory_path() / "optinav_bench";
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace optinav::bench
