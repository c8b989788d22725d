// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
// The peer that the hole-filling and completion tests compare with: CGAL's
// triangulate_refine_and_fair_hole. Compiled once (cgal_fair_fill.cpp, object library
// kintsugi_test_peers) and linked into the programs that use it: its instantiation was the
// costliest part of two test files (tests/CMakeLists.txt says how it is compiled).
#include <kintsugi/adapters/indexed_mesh.hpp>

#include <vector>

namespace kintsugi_test {

struct CgalFairFill {
    std::vector<kintsugi::Vec3> new_vertices;  ///< every new vertex, loop after loop
    bool ok = true;                            ///< CGAL reported success for every loop
};

/// CGAL's fair fill (triangulate_refine_and_fair_hole, default parameters) of each loop of
/// `in`, given as vertex indices in the order find_boundary_loops gives them, on a CGAL
/// Surface_mesh copy of `in`.
CgalFairFill cgal_fair_fill(const kintsugi::IndexedMesh& in, const std::vector<std::vector<kintsugi::Index>>& loops);

}  // namespace kintsugi_test
