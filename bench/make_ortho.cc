// make_ortho SIZE GSD_M OUT.tif [SEED] [noise|farmland]: writes a procedural orthophoto
// (src/optinav/sim/synthetic_ortho.h; default: noise).
#include <cstdio>
#include <cstdlib>
#include <string>

#include "optinav/sim/synthetic_ortho.h"

int main(int argc, char** argv) {
  const std::string kind = argc > 5 ? argv[5] : "noise";
  if (argc < 4 || (kind != "noise" && kind != "farmland")) {
    std::fprintf(stderr, "usage: make_ortho SIZE GSD_M OUT.tif [SEED] [noise|farmland]\n");
    return 2;
  }
  const int size = std::atoi(argv[1]);
  const double gsd = std::atof(argv[2]);
  const unsigned seed = argc > 4 ? static_cast<unsigned>(std::atoi(argv[4])) : 1;
  if (kind == "farmland") {
    optinav::sim::WriteSyntheticFarmland(argv[3], size, gsd, seed);
  } else {
    optinav::sim::WriteSyntheticOrtho(argv[3], size, gsd, seed);
  }
  return 0;
}
