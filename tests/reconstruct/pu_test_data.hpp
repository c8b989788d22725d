// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Test inputs for the PU + graph-cut reconstruction: analytic shapes sampled with
// noise and uniform outliers, and mesh sampling with holes.
#pragma once

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>
#include <vector>

namespace kintsugi_test {

using kintsugi::Vec3;

struct Shape {
    int kind = 0;  // 0 sphere (R = 1), 1 torus (a = 1, b = 0.4), both centred at the origin, torus axis z
    [[nodiscard]] double distance(const Vec3& p) const {
        if (kind == 0) return std::abs(p.norm() - 1.0);
        return std::abs(std::hypot(std::hypot(p.x(), p.y()) - 1.0, p.z()) - 0.4);
    }
    [[nodiscard]] double diagonal() const { return kind == 0 ? std::sqrt(12.0) : std::sqrt(2 * 2.8 * 2.8 + 0.8 * 0.8); }
    void sample(std::mt19937_64& rng, Vec3& p, Vec3& n) const {
        std::normal_distribution<double> g(0, 1);
        std::uniform_real_distribution<double> u(0, 1);
        if (kind == 0) {
            n = Vec3(g(rng), g(rng), g(rng)).normalized();
            p = n;
            return;
        }
        for (;;) {  // area-uniform by rejection
            const double th = 2 * std::numbers::pi * u(rng), ph = 2 * std::numbers::pi * u(rng);
            if (u(rng) * 1.4 > 1.0 + 0.4 * std::cos(ph)) continue;
            const Vec3 c(std::cos(th), std::sin(th), 0);
            n = std::cos(ph) * c + std::sin(ph) * Vec3(0, 0, 1);
            p = c + 0.4 * n;
            return;
        }
    }
};

/// n samples with Gaussian noise (sigma = noise x diagonal per point, isotropic) and
/// round(outliers x n) extra points uniform in the bounding box enlarged by 10 %, with
/// random unit normals.
inline void sample_shape(const Shape& s, std::size_t n, double noise, double outliers, std::uint64_t seed,
                         std::vector<Vec3>& pts, std::vector<Vec3>& nrm) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(0, 1);
    pts.clear();
    nrm.clear();
    const double sigma = noise * s.diagonal() / std::sqrt(3.0);
    for (std::size_t i = 0; i < n; ++i) {
        Vec3 p, q;
        s.sample(rng, p, q);
        pts.push_back(p + sigma * Vec3(g(rng), g(rng), g(rng)));
        nrm.push_back(q);
    }
    kintsugi::BoundingBox box;
    for (const auto& p : pts) box.extend(p);
    const Vec3 c = box.center(), e = 1.1 * box.extent();
    const auto m = static_cast<std::size_t>(std::llround(outliers * static_cast<double>(n)));
    for (std::size_t i = 0; i < m; ++i) {
        pts.push_back(c + Vec3((u(rng) - 0.5) * e.x(), (u(rng) - 0.5) * e.y(), (u(rng) - 0.5) * e.z()));
        nrm.push_back(Vec3(g(rng), g(rng), g(rng)).normalized());
    }
}

/// Area-weighted samples of a mesh (deterministic).
inline std::vector<Vec3> sample_mesh(const kintsugi::IndexedMesh& m, std::size_t n, std::uint64_t seed,
                                     std::vector<Vec3>* normals = nullptr) {
    const auto areas = kintsugi::face_areas(m);
    std::vector<double> cum(areas.size());
    std::partial_sum(areas.begin(), areas.end(), cum.begin());
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<Vec3> out;
    out.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        const auto f = static_cast<std::size_t>(std::lower_bound(cum.begin(), cum.end(), u(rng) * cum.back()) -
                                                cum.begin());
        const auto& F = m.faces[std::min(f, m.faces.size() - 1)];
        double a = u(rng), b = u(rng);
        if (a + b > 1) {
            a = 1 - a;
            b = 1 - b;
        }
        out.push_back(m.vertices[F[0]] + a * (m.vertices[F[1]] - m.vertices[F[0]]) +
                      b * (m.vertices[F[2]] - m.vertices[F[0]]));
        if (normals) normals->push_back(kintsugi::face_normal(m, std::min(f, m.faces.size() - 1)));
    }
    return out;
}

/// Mean and max distance of a mesh (area-weighted samples) to an analytic shape.
inline void distance_to_shape(const kintsugi::IndexedMesh& m, const Shape& s, double& mean, double& max) {
    const auto pts = sample_mesh(m, 100000, 3);
    mean = 0;
    max = 0;
    for (const auto& p : pts) {
        const double d = s.distance(p);
        mean += d;
        max = std::max(max, d);
    }
    mean /= static_cast<double>(pts.size());
}

}  // namespace kintsugi_test
