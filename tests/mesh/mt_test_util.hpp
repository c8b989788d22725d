// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Test helpers: a Kuhn (Freudenthal) tetrahedralisation of a box grid.
#pragma once

#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/marching_tetrahedra.hpp>

#include <array>
#include <vector>

namespace kintsugi_test {

/// (n+1)^3 grid vertices over [lo, hi]^3, 6 conforming tets per cube.
struct TetGrid {
    int n = 0;
    std::vector<kintsugi::Vec3> vertices;
    std::vector<kintsugi::Tet> tets;
    [[nodiscard]] kintsugi::Index id(int i, int j, int k) const {
        return static_cast<kintsugi::Index>((k * (n + 1) + j) * (n + 1) + i);
    }
};

inline TetGrid make_tet_grid(int n, double lo, double hi) {
    TetGrid g;
    g.n = n;
    const double h = (hi - lo) / n;
    for (int k = 0; k <= n; ++k)
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) g.vertices.emplace_back(lo + i * h, lo + j * h, lo + k * h);
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                for (const auto& p : perms) {
                    std::array<int, 3> c{i, j, k};
                    kintsugi::Tet t{};
                    t[0] = g.id(c[0], c[1], c[2]);
                    for (int s = 0; s < 3; ++s) {
                        ++c[p[s]];
                        t[s + 1] = g.id(c[0], c[1], c[2]);
                    }
                    g.tets.push_back(t);
                }
    return g;
}

}  // namespace kintsugi_test
