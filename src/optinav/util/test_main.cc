// Shared GoogleTest main and the helpers of testing.h.
#include <atomic>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <mutex>
#include <random>
#include <typeinfo>
#include <vector>

#include <gtest/gtest.h>

#include "optinav/util/error.h"
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

namespace {
// Every directory MakeTempDir made in this process; main removes them after a passing run.
std::mutex scratch_mutex;
std::vector<std::filesystem::path>& ScratchDirs() {
  static std::vector<std::filesystem::path> dirs;
  return dirs;
}
}  // namespace

std::filesystem::path MakeTempDir(const std::string& prefix) {
  static std::atomic<int> counter{0};
  std::random_device rd;
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("optinav_" + prefix + "_" + std::to_string(rd()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::lock_guard lock(scratch_mutex);
  ScratchDirs().push_back(dir);
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

namespace internal {

void ExpectError(const char* test_file, int test_line, const char* statement_text,
                 const std::function<void()>& statement, const ExpectedError& expected,
                 const std::string& substring) {
  try {
    statement();
  } catch (const Error& e) {
    const ErrorContext& c = e.context();
    std::string mismatch;
    if (expected.file) {
      // A suffix on a path-component boundary: "imu0/data.csv" matches "/tmp/x/imu0/data.csv".
      const std::string& want = *expected.file;
      const bool ok =
          want.empty() ? c.file.empty()
                       : c.file == want || (c.file.ends_with(want) && c.file.size() > want.size() &&
                                            c.file[c.file.size() - want.size() - 1] == '/');
      if (!ok) mismatch += "\n  file: expected suffix '" + want + "', got '" + c.file + "'";
    }
    if (expected.line && c.line != *expected.line) {
      mismatch += "\n  line: expected " + std::to_string(*expected.line) + ", got " +
                  std::to_string(c.line);
    }
    if (expected.field && c.field != *expected.field) {
      mismatch += "\n  field: expected '" + *expected.field + "', got '" + c.field + "'";
    }
    if (e.message().find(substring) == std::string::npos) {
      mismatch += "\n  message: expected to contain '" + substring + "'";
    }
    if (!mismatch.empty()) {
      ADD_FAILURE_AT(test_file, test_line)
          << statement_text << " threw optinav::Error \"" << e.what() << "\"" << mismatch;
    }
    return;
  } catch (const std::exception& e) {
    ADD_FAILURE_AT(test_file, test_line) << statement_text << " threw a " << typeid(e).name()
                                         << " (\"" << e.what() << "\"), expected optinav::Error";
    return;
  } catch (...) {
    ADD_FAILURE_AT(test_file, test_line)
        << statement_text << " threw a non-std exception, expected optinav::Error";
    return;
  }
  ADD_FAILURE_AT(test_file, test_line)
      << statement_text << " threw nothing, expected optinav::Error";
}

}  // namespace internal

}  // namespace optinav::testing

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  optinav::InitLogging();
  spdlog::set_level(spdlog::level::warn);
  const int result = RUN_ALL_TESTS();
  // The scratch directories (simulated sequences among them, up to 200 MB each) are removed
  // when every test passed; a failing run keeps them to be looked at, as does
  // OPTINAV_KEEP_TEST_DIRS=1.
  const char* keep = std::getenv("OPTINAV_KEEP_TEST_DIRS");
  const bool keep_dirs = result != 0 || (keep != nullptr && std::string(keep) != "0");
  const std::lock_guard lock(optinav::testing::scratch_mutex);
  for (const auto& dir : optinav::testing::ScratchDirs()) {
    if (keep_dirs) {
      std::cerr << "scratch directory kept: " << dir.string() << "\n";
      continue;
    }
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    if (ec)
      std::cerr << "cannot remove scratch directory " << dir.string() << ": " << ec.message()
                << "\n";
  }
  return result;
}
