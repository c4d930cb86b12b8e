// One fuzz harness = one function over bytes, registered under a name. Built with libFuzzer
// (OPTINAV_FUZZ_LIBFUZZER, scripts/fuzz.sh) the harness file also defines the libFuzzer entry
// point; built into fuzz_replay (normal GCC build) every harness is registered in one executable
// that replays the regression and seed files (ctest fuzz/replay/<name>).
//
// Contract of a harness: malformed input must end in an optinav::Error (caught by the harness)
// or a normal return. Any other exception escaping, a crash, a sanitizer report or a hang is a
// finding: it reaches std::terminate / the sanitizer and fails the run.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "optinav/util/error.h"  // harnesses catch optinav::Error

namespace optinav::fuzz {

using HarnessFn = int (*)(const uint8_t* data, size_t size);

struct Harness {
  std::string name;
  HarnessFn fn;
};

bool RegisterHarness(const char* name, HarnessFn fn);
const std::vector<Harness>& Harnesses();

// A per-process scratch folder (under /dev/shm when it exists: no disk writes per execution),
// created on first use and removed at exit.
const std::string& ScratchDir();
// Writes `bytes` to ScratchDir()/name (truncating) and returns the path.
std::string WriteScratch(const std::string& name, std::string_view bytes);
std::string WriteScratch(const std::string& name, const uint8_t* data, size_t size);

// Splits the input at the first occurrence of `separator` (the rest after it is the second
// part; no separator: everything is the first part). For harnesses taking two files.
std::pair<std::string_view, std::string_view> SplitInput(const uint8_t* data, size_t size,
                                                         std::string_view separator);

// Logging off (parsers warn through spdlog; per-execution output would slow fuzzing down) and
// GDAL/OpenCV quiet. Called once by every harness before its first input.
void QuietLibraries();

}  // namespace optinav::fuzz

#ifdef OPTINAV_FUZZ_LIBFUZZER
#define OPTINAV_FUZZ_ENTRY(name)                                            \
  extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) { \
    return OptinavFuzz_##name(data, size);                                  \
  }
#else
#define OPTINAV_FUZZ_ENTRY(name)
#endif

#define OPTINAV_FUZZ_TARGET(name)                                     \
  static int OptinavFuzz_##name(const uint8_t* data, size_t size);    \
  [[maybe_unused]] static const bool optinav_fuzz_registered_##name = \
      ::optinav::fuzz::RegisterHarness(#name, &OptinavFuzz_##name);   \
  OPTINAV_FUZZ_ENTRY(name)                                            \
  static int OptinavFuzz_##name(const uint8_t* data, size_t size)
