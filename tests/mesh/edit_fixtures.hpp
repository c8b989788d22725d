// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Test meshes with known topology for the editing, hole and fairing tests.
#pragma once

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/types.hpp>

#include <cmath>
#include <functional>
#include <map>
#include <utility>
#include <vector>

namespace kintsugi_test {

/// (n+1) x (n+1) grid over [0, n*h]^2 in the plane z = height(x, y), two triangles per
/// cell split along the (i, j) -> (i+1, j+1) diagonal, counter-clockwise seen from +z.
inline kintsugi::IndexedMesh grid_mesh(int n, double h,
                                       const std::function<double(double, double)>& height = {}) {
    kintsugi::IndexedMesh m;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const double x = i * h, y = j * h;
            m.vertices.emplace_back(x, y, height ? height(x, y) : 0.0);
        }
    auto id = [n](int i, int j) { return static_cast<kintsugi::Index>(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return m;
}

/// Unit icosphere (radius r) after `levels` 1:4 subdivisions: closed, genus 0, outward.
inline kintsugi::IndexedMesh icosphere(int levels, double r = 1.0) {
    using kintsugi::Index;
    using kintsugi::Vec3;
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    kintsugi::IndexedMesh m;
    m.vertices = {Vec3(-1, t, 0), Vec3(1, t, 0), Vec3(-1, -t, 0), Vec3(1, -t, 0),
                  Vec3(0, -1, t), Vec3(0, 1, t), Vec3(0, -1, -t), Vec3(0, 1, -t),
                  Vec3(t, 0, -1), Vec3(t, 0, 1), Vec3(-t, 0, -1), Vec3(-t, 0, 1)};
    m.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
               {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
               {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (auto& v : m.vertices) v.normalize();
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<Index, Index>, Index> mid;
        auto midpoint = [&](Index a, Index b) {
            const auto key = std::minmax(a, b);
            const auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
            mid.emplace(key, m.vertices.size() - 1);
            return m.vertices.size() - 1;
        };
        std::vector<kintsugi::Face> faces;
        for (const auto& f : m.faces) {
            const Index a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
            faces.push_back({f[0], a, c});
            faces.push_back({f[1], b, a});
            faces.push_back({f[2], c, b});
            faces.push_back({a, b, c});
        }
        m.faces = std::move(faces);
    }
    for (auto& v : m.vertices) v *= r;
    return m;
}

/// Torus (major radius R, minor radius r) on an nu x nv grid: closed, genus 1, outward.
inline kintsugi::IndexedMesh torus(int nu, int nv, double R = 1.0, double r = 0.4) {
    kintsugi::IndexedMesh m;
    const double pi = 3.14159265358979323846;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const double u = 2 * pi * i / nu, v = 2 * pi * j / nv;
            m.vertices.emplace_back((R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                                    r * std::sin(v));
        }
    auto id = [nu, nv](int i, int j) { return static_cast<kintsugi::Index>(((j + nv) % nv) * nu + (i + nu) % nu); };
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return m;
}

/// Removes the faces for which `drop(face centroid)` holds, and the vertices left unused.
inline kintsugi::IndexedMesh remove_faces(const kintsugi::IndexedMesh& in,
                                          const std::function<bool(const kintsugi::Vec3&)>& drop) {
    kintsugi::IndexedMesh out;
    std::vector<kintsugi::Index> map(in.vertices.size(), static_cast<kintsugi::Index>(-1));
    for (const auto& f : in.faces) {
        const kintsugi::Vec3 c = (in.vertices[f[0]] + in.vertices[f[1]] + in.vertices[f[2]]) / 3.0;
        if (drop(c)) continue;
        kintsugi::Face g{};
        for (int k = 0; k < 3; ++k) {
            if (map[f[k]] == static_cast<kintsugi::Index>(-1)) {
                map[f[k]] = out.vertices.size();
                out.vertices.push_back(in.vertices[f[k]]);
            }
            g[k] = map[f[k]];
        }
        out.faces.push_back(g);
    }
    return out;
}

}  // namespace kintsugi_test
