// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Test inputs for the PU + graph-cut reconstruction: analytic shapes sampled with
// noise and uniform outliers, and mesh sampling with holes.
#pragma once

#include <doctest/doctest.h>

#include "closed_mesh.hpp"

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

/// A CAD-like part of genus 3 with sharp edges: the box [-3, 3] x [-1, 1] x [-0.6, 0.6]
/// pierced along z by three square holes of side 0.8 centred at x = -1.8, 0, 1.8.
struct HoledBlock {
    static constexpr double hx = 3, hy = 1, hz = 0.6, hole = 0.4;
    static constexpr double centres[3] = {-1.8, 0.0, 1.8};
    /// Signed distance (< 0 inside; exact near the faces, a bound near the edges).
    [[nodiscard]] static double sdf(const Vec3& p) {
        const Vec3 q = p.cwiseAbs() - Vec3(hx, hy, hz);
        const double box = q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
        double holes = -1e300;
        for (const double c : centres) holes = std::max(holes, -std::max(std::abs(p.x() - c), std::abs(p.y())) + hole);
        return std::max(box, holes);
    }
    [[nodiscard]] static double diagonal() { return 2 * std::sqrt(hx * hx + hy * hy + hz * hz); }
    /// n area-uniform samples with exact outward normals, Gaussian noise of sigma =
    /// noise x diagonal / sqrt(3) per coordinate, then round(outliers x n) uniform points
    /// in the box enlarged 1.1 times with random unit normals.
    static void sample(std::size_t n, double noise, double outliers, std::uint64_t seed, std::vector<Vec3>& pts,
                       std::vector<Vec3>& nrm) {
        std::mt19937_64 rng(seed);
        std::normal_distribution<double> g(0, 1);
        std::uniform_real_distribution<double> u(0, 1);
        pts.clear();
        nrm.clear();
        const double cap = 4 * hx * hy - 3 * 4 * hole * hole;  // top or bottom, holes removed
        const double areas[4] = {2 * cap, 2 * (2 * hy) * (2 * hz), 2 * (2 * hx) * (2 * hz), 3 * 4 * (2 * hole) * (2 * hz)};
        const double total = areas[0] + areas[1] + areas[2] + areas[3];
        const double sigma = noise * diagonal() / std::sqrt(3.0);
        for (std::size_t i = 0; i < n; ++i) {
            double a = u(rng) * total;
            int k = 0;
            while (k < 3 && a >= areas[k]) a -= areas[k++];
            const double s = u(rng) * 2 - 1, t = u(rng) * 2 - 1, side = u(rng) < 0.5 ? -1 : 1;
            Vec3 p, q;
            if (k == 0) {  // top or bottom, outside the holes (rejection)
                p = Vec3(s * hx, t * hy, side * hz);
                bool in_hole = false;
                for (const double c : centres)
                    in_hole = in_hole || (std::abs(p.x() - c) < hole && std::abs(p.y()) < hole);
                if (in_hole) {
                    --i;
                    continue;
                }
                q = Vec3(0, 0, side);
            } else if (k == 1) {
                p = Vec3(side * hx, s * hy, t * hz);
                q = Vec3(side, 0, 0);
            } else if (k == 2) {
                p = Vec3(s * hx, side * hy, t * hz);
                q = Vec3(0, side, 0);
            } else {  // a hole's wall; the normal points into the hole
                const double c = centres[std::min<std::size_t>(2, static_cast<std::size_t>(u(rng) * 3))];
                if (u(rng) < 0.5) {
                    p = Vec3(c + side * hole, s * hole, t * hz);
                    q = Vec3(-side, 0, 0);
                } else {
                    p = Vec3(c + s * hole, side * hole, t * hz);
                    q = Vec3(0, -side, 0);
                }
            }
            pts.push_back(p + sigma * Vec3(g(rng), g(rng), g(rng)));
            nrm.push_back(q);
        }
        const Vec3 e = 1.1 * Vec3(2 * hx, 2 * hy, 2 * hz);
        const auto m = static_cast<std::size_t>(std::llround(outliers * static_cast<double>(n)));
        for (std::size_t i = 0; i < m; ++i) {
            pts.push_back(Vec3((u(rng) - 0.5) * e.x(), (u(rng) - 0.5) * e.y(), (u(rng) - 0.5) * e.z()));
            nrm.push_back(Vec3(g(rng), g(rng), g(rng)).normalized());
        }
    }
};

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

/// The reconstruction's output guarantee (closed, manifold, oriented outward, no
/// degenerate face, no unused vertex); returns the report it was checked on.
inline kintsugi::TopologyReport check_guarantee(const kintsugi::IndexedMesh& m) {
    const auto r = check_closed_manifold(m);
    CHECK(r.isolated_vertices == 0);
    CHECK(kintsugi::signed_volume(m) > 0);  // outward
    return r;
}

/// The acceptance input on a real mesh: `draw` seeded samples, `holes` holes of radius
/// hole_radius x the diagonal cut around random vertices, the first `surface` samples
/// outside them with 0.1 % Gaussian noise, then `outliers` uniform points (random
/// normals) in the bounding box enlarged 1.1 times.
inline void holey_noisy_sample(const kintsugi::IndexedMesh& ref, const kintsugi::BoundingBox& bb, std::size_t draw,
                               std::size_t surface, std::size_t outliers, int holes, double hole_radius,
                               std::uint64_t seed, std::vector<kintsugi::Vec3>& pts,
                               std::vector<kintsugi::Vec3>& nn) {
    const double diag = bb.diagonal();
    std::vector<kintsugi::Vec3> nrm;
    const std::vector<kintsugi::Vec3> all = kintsugi_test::sample_mesh(ref, draw, seed, &nrm);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<kintsugi::Vec3> centres;
    for (int h = 0; h < holes; ++h) centres.push_back(ref.vertices[rng() % ref.vertices.size()]);
    for (std::size_t i = 0; i < all.size() && pts.size() < surface; ++i) {
        bool in_hole = false;
        for (const auto& h : centres) in_hole = in_hole || (all[i] - h).norm() < hole_radius * diag;
        if (in_hole) continue;
        pts.push_back(all[i] + 0.001 * diag / std::sqrt(3.0) * kintsugi::Vec3(g(rng), g(rng), g(rng)));
        nn.push_back(nrm[i]);
    }
    REQUIRE(pts.size() == surface);
    const kintsugi::Vec3 c = bb.center(), e = 1.1 * bb.extent();
    while (pts.size() < surface + outliers) {
        pts.push_back(c + kintsugi::Vec3((u(rng) - .5) * e.x(), (u(rng) - .5) * e.y(), (u(rng) - .5) * e.z()));
        nn.push_back(kintsugi::Vec3(g(rng), g(rng), g(rng)).normalized());
    }
}

/// The same, in the bounding box of `ref`'s vertices.
inline void holey_noisy_sample(const kintsugi::IndexedMesh& ref, std::size_t draw, std::size_t surface,
                               std::size_t outliers, int holes, double hole_radius, std::uint64_t seed,
                               std::vector<kintsugi::Vec3>& pts, std::vector<kintsugi::Vec3>& nn) {
    kintsugi::BoundingBox bb;
    for (const auto& v : ref.vertices) bb.extend(v);
    holey_noisy_sample(ref, bb, draw, surface, outliers, holes, hole_radius, seed, pts, nn);
}

}  // namespace kintsugi_test
