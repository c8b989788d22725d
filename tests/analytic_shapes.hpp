// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Test helpers: seeded samplings and meshes of a sphere and a torus with their
// analytic normals and principal curvatures (curvature and MLS tests).
#pragma once

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/types.hpp>

#include <cmath>
#include <random>
#include <vector>

namespace kintsugi_test {

using kintsugi::Scalar;
using kintsugi::Vec3;

/// Analytic differential geometry at a surface point (outward normal; curvatures
/// positive on the convex side, k1 >= k2, d1 / d2 their directions; d1 zero where umbilic).
struct TrueCurvature {
    Vec3 normal, d1, d2;
    Scalar k1 = 0, k2 = 0;
};

/// Sphere of radius R at the origin.
struct Sphere {
    Scalar R = 1;
    [[nodiscard]] Vec3 closest(const Vec3& p) const { return p.normalized() * R; }
    [[nodiscard]] Scalar distance(const Vec3& p) const { return std::abs(p.norm() - R); }
    [[nodiscard]] TrueCurvature curvature(const Vec3& p) const {
        return {p.normalized(), Vec3::Zero(), Vec3::Zero(), 1 / R, 1 / R};
    }
    /// n points uniform on the sphere (seeded), with outward normals.
    [[nodiscard]] kintsugi::PointCloud sample(std::size_t n, unsigned seed) const {
        std::mt19937_64 rng(seed);
        std::normal_distribution<Scalar> g(0, 1);
        kintsugi::PointCloud c;
        while (c.points.size() < n) {
            const Vec3 d(g(rng), g(rng), g(rng));
            if (d.norm() < 1e-9) continue;
            c.points.push_back(d.normalized() * R);
            c.normals.push_back(d.normalized());
        }
        return c;
    }
    /// Icosahedron subdivided `levels` times, projected on the sphere (CCW outward).
    [[nodiscard]] kintsugi::IndexedMesh mesh(int levels) const {
        const Scalar t = (1 + std::sqrt(5.0)) / 2;
        kintsugi::IndexedMesh m;
        m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                      {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
        m.faces = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                   {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                   {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
        for (int l = 0; l < levels; ++l) {
            std::vector<kintsugi::Face> faces;
            std::vector<std::vector<std::pair<kintsugi::Index, kintsugi::Index>>> mid(m.vertices.size());
            auto midpoint = [&](kintsugi::Index a, kintsugi::Index b) {
                if (a > b) std::swap(a, b);
                for (auto& [o, v] : mid[a])
                    if (o == b) return v;
                m.vertices.push_back((m.vertices[a] + m.vertices[b]) / 2);
                mid[a].emplace_back(b, m.vertices.size() - 1);
                return m.vertices.size() - 1;
            };
            for (const auto& f : m.faces) {
                const auto a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
                faces.push_back({f[0], a, c});
                faces.push_back({f[1], b, a});
                faces.push_back({f[2], c, b});
                faces.push_back({a, b, c});
            }
            m.faces = std::move(faces);
        }
        for (auto& v : m.vertices) v = v.normalized() * R;
        return m;
    }
};

/// Torus around the z axis: ring radius R, tube radius r.
struct Torus {
    Scalar R = 1, r = 0.4;
    [[nodiscard]] Vec3 at(Scalar u, Scalar v) const {
        return {(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v)};
    }
    /// Closest point on the torus (exact: through the closest point of the core circle).
    [[nodiscard]] Vec3 closest(const Vec3& p) const {
        const Vec3 c = Vec3(p.x(), p.y(), 0).normalized() * R;
        return c + (p - c).normalized() * r;
    }
    [[nodiscard]] Scalar distance(const Vec3& p) const {
        const Scalar q = std::hypot(p.x(), p.y()) - R;
        return std::abs(std::hypot(q, p.z()) - r);
    }
    [[nodiscard]] TrueCurvature curvature(const Vec3& p) const {
        const Scalar u = std::atan2(p.y(), p.x());
        const Scalar v = std::atan2(p.z(), std::hypot(p.x(), p.y()) - R);
        TrueCurvature t;
        t.normal = Vec3(std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v));
        t.k1 = 1 / r;  // around the tube
        t.d1 = Vec3(-std::sin(v) * std::cos(u), -std::sin(v) * std::sin(u), std::cos(v));
        t.k2 = std::cos(v) / (R + r * std::cos(v));  // around the axis
        t.d2 = Vec3(-std::sin(u), std::cos(u), 0);
        return t;
    }
    /// n points uniform on the torus by area (rejection on the area element), outward normals.
    [[nodiscard]] kintsugi::PointCloud sample(std::size_t n, unsigned seed) const {
        std::mt19937_64 rng(seed);
        std::uniform_real_distribution<Scalar> U(0, 1);
        kintsugi::PointCloud c;
        const Scalar pi2 = 2 * std::acos(-1.0);
        while (c.points.size() < n) {
            const Scalar u = pi2 * U(rng), v = pi2 * U(rng);
            if (U(rng) * (R + r) > R + r * std::cos(v)) continue;
            c.points.push_back(at(u, v));
            c.normals.push_back(Vec3(std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v)));
        }
        return c;
    }
    /// nu x nv grid mesh (CCW outward).
    [[nodiscard]] kintsugi::IndexedMesh mesh(int nu, int nv) const {
        kintsugi::IndexedMesh m;
        const Scalar pi2 = 2 * std::acos(-1.0);
        for (int i = 0; i < nu; ++i)
            for (int j = 0; j < nv; ++j) m.vertices.push_back(at(pi2 * i / nu, pi2 * j / nv));
        auto id = [&](int i, int j) { return kintsugi::Index(((i % nu) * nv) + (j % nv)); };
        for (int i = 0; i < nu; ++i)
            for (int j = 0; j < nv; ++j) {
                m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
                m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
            }
        return m;
    }
};

/// Adds isotropic Gaussian noise of RMS `rms` (sigma rms/sqrt(3) per axis), as `kintsugi perturb --noise`.
inline void add_noise(std::vector<Vec3>& pts, Scalar rms, unsigned seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<Scalar> g(0, rms / std::sqrt(3.0));
    for (auto& p : pts) p += Vec3(g(rng), g(rng), g(rng));
}

}  // namespace kintsugi_test
