// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file random.hpp
/// @brief The fixed-seed ±1 draws of the Monte-Carlo estimates (Hutchinson traces, SURE probes).

#include <cstdint>

namespace kintsugi::detail {

/// Advances `state` one step of Knuth's 64-bit linear congruential generator (MMIX constants)
/// and returns its top bit as +1 or −1: a Rademacher draw, the same on every platform and
/// thread count (the callers draw in a fixed vertex order).
inline int rademacher(std::uint64_t& state) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return (state >> 63) ? 1 : -1;
}

}  // namespace kintsugi::detail
