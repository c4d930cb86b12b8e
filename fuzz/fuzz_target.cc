#include "fuzz/fuzz_target.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <spdlog/spdlog.h>
#include <unistd.h>

namespace optinav::fuzz {
namespace {

std::vector<Harness>& Registry() {
  static std::vector<Harness> harnesses;
  return harnesses;
}

void RemoveScratch() {
  std::error_code ec;
  std::filesystem::remove_all(ScratchDir(), ec);
}

}  // namespace

bool RegisterHarness(const char* name, HarnessFn fn) {
  Registry().push_back({name, fn});
  return true;
}

const std::vector<Harness>& Harnesses() { return Registry(); }

const std::string& ScratchDir() {
  static const std::string dir = [] {
    const std::string base =
        std::filesystem::is_directory("/dev/shm") && access("/dev/shm", W_OK) == 0
            ? "/dev/shm"
            : std::filesystem::temp_directory_path().string();
    const std::string d = base + "/optinav-fuzz-" + std::to_string(getpid());
    std::filesystem::create_directories(d);
    return d;
  }();
  static const bool registered = (std::atexit(RemoveScratch), true);
  (void)registered;
  return dir;
}

std::string WriteScratch(const std::string& name, std::string_view bytes) {
  const std::string path = ScratchDir() + "/" + name;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}

std::string WriteScratch(const std::string& name, const uint8_t* data, size_t size) {
  return WriteScratch(name, std::string_view(reinterpret_cast<const char*>(data), size));
}

std::pair<std::string_view, std::string_view> SplitInput(const uint8_t* data, size_t size,
                                                         std::string_view separator) {
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  const size_t k = all.find(separator);
  if (k == std::string_view::npos) return {all, {}};
  return {all.substr(0, k), all.substr(k + separator.size())};
}

void QuietLibraries() {
  static const bool done = [] {
    spdlog::set_level(spdlog::level::off);
    setenv("CPL_LOG", "/dev/null", 0);  // GDAL warnings
    setenv("OPENCV_LOG_LEVEL", "SILENT", 0);
    return true;
  }();
  (void)done;
}

}  // namespace optinav::fuzz
