// SplitMix64's finaliser: a 64-bit hash for the simulator's stateless random draws (weather
// particles per lattice cell, camera noise per pixel), where seeding a generator per item is too
// slow and the result must not depend on the order or the thread that draws it.
#pragma once

#include <cstdint>

namespace optinav::sim::internal {

inline uint64_t SplitMix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace optinav::sim::internal
