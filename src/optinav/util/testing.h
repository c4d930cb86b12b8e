// Helpers for tests: locating ../shared/data and making scratch directories.
#pragma once

#include <filesystem>
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

}  // namespace optinav::testing
