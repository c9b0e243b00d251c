#pragma once
/// \file seeding.hpp (private)
/// Seeds of the synth's random draws: one generator per (seed, index) (a frame, a person),
/// so a draw never depends on which other frames or people were drawn.

#include <cstdint>

namespace omnipose::synth::detail {

/// SplitMix64 finaliser: decorrelates nearby seeds.
inline std::uint64_t splitMix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// The seed of item `index` (a frame, a person) of a sequence seeded by `seed`; `stream`
/// separates independent kinds of draws of the same item (0: degrade()'s own draws).
inline std::uint64_t itemSeed(std::uint64_t seed, std::uint64_t index, std::uint64_t stream = 0) {
  const std::uint64_t s = splitMix(seed ^ splitMix(index));
  return stream == 0 ? s : splitMix(s ^ splitMix(stream));
}

}  // namespace omnipose::synth::detail
