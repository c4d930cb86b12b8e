// make_ortho SIZE GSD_M OUT.tif [SEED]: writes a procedural orthophoto
// (src/optinav/sim/synthetic_ortho.h).
#include <cstdio>
#include <cstdlib>

#include "optinav/sim/synthetic_ortho.h"

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: make_ortho SIZE GSD_M OUT.tif [SEED]\n");
    return 2;
  }
  optinav::sim::WriteSyntheticOrtho(argv[3], std::atoi(argv[1]), std::atof(argv[2]),
                                    argc > 4 ? std::atoi(argv[4]) : 1);
  return 0;
}
