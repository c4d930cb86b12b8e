// fuzz_replay: runs fuzz harnesses over files without libFuzzer (normal GCC build, ctest
// fuzz/replay/<name>), so every crash a fuzzer found stays a regression test.
//   fuzz_replay NAME FUZZ_DIR   every file in FUZZ_DIR/regressions/NAME and FUZZ_DIR/corpus/NAME
//   fuzz_replay NAME FILE...    the given files (folders: every file in them)
// Exit 0 when every input ran (an input the parser refuses with an Error is a pass); a crash or
// an escaping exception aborts. Fails when no input was found (a misnamed folder must not pass).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz/fuzz_target.h"

namespace fs = std::filesystem;

namespace {

void Collect(const fs::path& p, std::vector<fs::path>* files) {
  if (fs::is_regular_file(p)) {
    files->push_back(p);
  } else if (fs::is_directory(p)) {
    for (const auto& e : fs::recursive_directory_iterator(p))
      if (e.is_regular_file() && e.path().filename() != "README.md") files->push_back(e.path());
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: fuzz_replay NAME FUZZ_DIR | NAME FILE...\n");
    return 2;
  }
  const std::string name = argv[1];
  const auto& hs = optinav::fuzz::Harnesses();
  const auto h = std::find_if(hs.begin(), hs.end(), [&](const auto& x) { return x.name == name; });
  if (h == hs.end()) {
    std::fprintf(stderr, "fuzz_replay: no harness '%s'\n", name.c_str());
    return 2;
  }
  std::vector<fs::path> files;
  if (argc == 3 && fs::is_directory(fs::path(argv[2]) / "regressions")) {
    Collect(fs::path(argv[2]) / "regressions" / name, &files);
    Collect(fs::path(argv[2]) / "corpus" / name, &files);
  } else {
    for (int i = 2; i < argc; ++i) Collect(argv[i], &files);
  }
  if (files.empty()) {
    std::fprintf(stderr, "fuzz_replay: no input files for '%s'\n", name.c_str());
    return 1;
  }
  std::sort(files.begin(), files.end());
  h->fn(nullptr, 0);  // the empty input, as libFuzzer always tries it
  for (const auto& f : files) {
    std::ifstream in(f, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::fprintf(stderr, "%s: %s (%zu bytes)\n", name.c_str(), f.c_str(), bytes.size());
    h->fn(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
  }
  std::printf("%s: %zu inputs replayed, none crashed\n", name.c_str(), files.size());
  return 0;
}
