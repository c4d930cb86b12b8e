// Helpers for tests: locating ../shared/data and making scratch directories.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace optinav::testing {

// The shared real-data folder: $OPTINAV_SHARED_DATA, else ../shared/data beside the checkout.
// Fails the calling test (via GTEST_SKIP-free hard failure) if it does not exist.
std::filesystem::path SharedDataDir();

// A fresh, empty directory under the system temp dir, unique per call.
std::filesystem::path MakeTempDir(const std::string& prefix);

// Writes `text` to `path` (creating parent folders) and returns the path as a string.
std::string WriteFile(const std::filesystem::path& path, const std::string& text);

// The whole file as a string; fails the calling test (and returns "") when it cannot be read.
std::string ReadFile(const std::filesystem::path& path);

// The context an error test expects; parts left unset are not checked. `file` matches as a path
// suffix ("" demands no file), `line` and `field` exactly (0 / "" demand that none is reported).
struct ExpectedError {
  std::optional<std::string> file;
  std::optional<int64_t> line;
  std::optional<std::string> field;
};

namespace internal {
// Runs `statement` and adds a failure at test_file:test_line unless it throws optinav::Error whose
// context() matches `expected` and whose message() contains `substring`.
void ExpectError(const char* test_file, int test_line, const char* statement_text,
                 const std::function<void()>& statement, const ExpectedError& expected,
                 const std::string& substring);
}  // namespace internal

}  // namespace optinav::testing

// EXPECT_ERROR(statement, {.file = "imu.csv", .line = 3, .field = "t"}, "not a number"):
// a non-fatal failure unless `statement` throws optinav::Error with that context and a message
// containing the substring. Error tests assert where the error is, not only that there is one.
#define EXPECT_ERROR(statement, ...)         \
  ::optinav::testing::internal::ExpectError( \
      __FILE__, __LINE__, #statement, [&] { statement; }, __VA_ARGS__)
