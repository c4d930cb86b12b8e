// Shared GoogleTest main and the helpers of testing.h.
#include <atomic>
#include <cstdlib>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "optinav/util/logging.h"
#include "optinav/util/testing.h"

namespace optinav::testing {

std::filesystem::path SharedDataDir() {
  const char* env = std::getenv("OPTINAV_SHARED_DATA");
  const std::filesystem::path dir = env ? env : OPTINAV_SHARED_DATA_DEFAULT;
  if (!std::filesystem::is_directory(dir)) {
    ADD_FAILURE() << "shared test data not found at " << dir
                  << " (set OPTINAV_SHARED_DATA to the shared/data folder)";
  }
  return dir;
}

std::filesystem::path MakeTempDir(const std::string& prefix) {
  static std::atomic<int> counter{0};
  std::random_device rd;
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("optinav_" + prefix + "_" + std::to_string(rd()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  return path.string();
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace optinav::testing

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  optinav::InitLogging();
  spdlog::set_level(spdlog::level::warn);
  return RUN_ALL_TESTS();
}
