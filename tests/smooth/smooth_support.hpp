// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
// Test/bench support for the smooth module: CGAL's smooth_shape as a peer (kintsugi's
// own Taubin is kintsugi::smooth_taubin), the reference sharp edges of a clean mesh and
// their precision/recall, and the per-face/per-vertex errors. Comparison code only.

// smooth_shape needs CGAL's Eigen support (Eigen is a kintsugi dependency anyway).
#ifndef CGAL_EIGEN3_ENABLED
#define CGAL_EIGEN3_ENABLED 1
#endif

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/metrics/denoise.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/smooth_shape.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace smooth_support {

namespace ks = kintsugi;

/// Edges whose two faces' normals make an angle above `degrees` (vertex pairs a < b).
inline std::set<std::array<ks::Index, 2>> crease_edges(const ks::IndexedMesh& m, double degrees) {
    const ks::MeshTopology topo(m.vertices.size(), m.faces);
    std::set<std::array<ks::Index, 2>> out;
    const double c = std::cos(degrees * std::numbers::pi / 180.0);
    for (ks::Index e = 0; e < topo.num_edges(); ++e) {
        const auto ef = topo.edge_faces(e);
        if (ef.size() != 2) continue;
        if (ks::face_normal(m, ef[0]).dot(ks::face_normal(m, ef[1])) < c) out.insert(topo.edges()[e]);
    }
    return out;
}

struct PrecisionRecall {
    double precision, recall;
    std::size_t detected, reference, common;
};

inline PrecisionRecall compare_edges(const std::vector<std::array<ks::Index, 2>>& detected,
                                     const std::set<std::array<ks::Index, 2>>& reference) {
    std::size_t common = 0;
    for (const auto& e : detected) common += reference.count(e);
    return {detected.empty() ? 0.0 : double(common) / double(detected.size()),
            reference.empty() ? 0.0 : double(common) / double(reference.size()), detected.size(), reference.size(),
            common};
}

/// The surface of the box [0,1]³ triangulated on an n×n grid per side, outward
/// orientation, vertices shared along the box edges.
inline ks::IndexedMesh box_mesh(int n) {
    ks::IndexedMesh m;
    std::map<std::array<int, 3>, ks::Index> id;
    auto vid = [&](std::array<int, 3> g) {
        const auto [it, fresh] = id.try_emplace(g, m.vertices.size());
        if (fresh) m.vertices.emplace_back(double(g[0]) / n, double(g[1]) / n, double(g[2]) / n);
        return it->second;
    };
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            const int u = (axis + 1) % 3, w = (axis + 2) % 3;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    std::array<ks::Index, 4> q;
                    const int di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
                    for (int k = 0; k < 4; ++k) {
                        std::array<int, 3> g{};
                        g[axis] = side * n;
                        g[u] = i + di[k];
                        g[w] = j + dj[k];
                        q[k] = vid(g);
                    }
                    if (side == 1) {
                        m.faces.push_back({q[0], q[1], q[2]});
                        m.faces.push_back({q[0], q[2], q[3]});
                    } else {
                        m.faces.push_back({q[0], q[2], q[1]});
                        m.faces.push_back({q[0], q[3], q[2]});
                    }
                }
        }
    return m;
}

/// A closed prism over a regular `sides`-gon of radius 1 and height h (a tessellated
/// cylinder, as CAD exports it): `rings` rows of side quads, each cap two concentric rows
/// and a fan, outward orientation. Its sides meet at 360°/sides and the caps at 90°.
inline ks::IndexedMesh cylinder_mesh(int sides, int rings, double h) {
    ks::IndexedMesh m;
    for (int k = 0; k <= rings; ++k)
        for (int i = 0; i < sides; ++i) {
            const double a = 2 * std::numbers::pi * i / sides;
            m.vertices.emplace_back(std::cos(a), std::sin(a), h * k / rings);
        }
    auto id = [&](int k, int i) { return ks::Index(k * sides + (i + sides) % sides); };
    for (int k = 0; k < rings; ++k)
        for (int i = 0; i < sides; ++i) {
            m.faces.push_back({id(k, i), id(k, i + 1), id(k + 1, i + 1)});
            m.faces.push_back({id(k, i), id(k + 1, i + 1), id(k + 1, i)});
        }
    for (int top = 0; top < 2; ++top) {
        const double z = top ? h : 0;
        std::vector<ks::Index> outer;
        for (int i = 0; i < sides; ++i) outer.push_back(id(top ? rings : 0, i));
        for (int row = 2; row >= 1; --row) {
            std::vector<ks::Index> inner;
            for (int i = 0; i < sides; ++i) {
                const double a = 2 * std::numbers::pi * (i + 0.5 * (3 - row)) / sides;
                m.vertices.emplace_back(row / 3.0 * std::cos(a), row / 3.0 * std::sin(a), z);
                inner.push_back(ks::Index(m.vertices.size() - 1));
            }
            for (int i = 0; i < sides; ++i) {
                const ks::Index a = outer[i], b = outer[(i + 1) % sides], c = inner[i], d = inner[(i + 1) % sides];
                if (top) {  // outward: +z on top, −z below (the side faces' winding)
                    m.faces.push_back({a, b, c});
                    m.faces.push_back({b, d, c});
                } else {
                    m.faces.push_back({a, c, b});
                    m.faces.push_back({b, c, d});
                }
            }
            outer = inner;
        }
        m.vertices.emplace_back(0, 0, z);
        const ks::Index c = ks::Index(m.vertices.size() - 1);
        for (int i = 0; i < sides; ++i)
            m.faces.push_back(top ? ks::Face{outer[i], outer[(i + 1) % sides], c} : ks::Face{outer[i], c, outer[(i + 1) % sides]});
    }
    return m;
}

/// Moves every vertex along its area-weighted normal by a deterministic pseudo-random
/// amount, uniform in [-amplitude, amplitude].
inline ks::IndexedMesh add_normal_noise(const ks::IndexedMesh& m, double amplitude, std::uint32_t seed = 1) {
    ks::IndexedMesh out = m;
    const auto n = ks::vertex_normals(m);
    std::uint32_t x = seed;
    for (std::size_t v = 0; v < m.vertices.size(); ++v) {
        x = x * 1664525u + 1013904223u;
        const double r = double(x >> 8) / double(1u << 24) * 2 - 1;
        out.vertices[v] += amplitude * r * n[v];
    }
    return out;
}

/// Gaussian noise of standard deviation `sigma` (model units), deterministic for a
/// seed on every platform (std::mt19937 and a Box–Muller transform of our own, not
/// std::normal_distribution, whose output the standard leaves open). `along_normals`:
/// each vertex moves along its area-weighted normal; otherwise along a uniformly
/// random unit direction, by a Gaussian amount. `normal_rms` (if given) receives the
/// rms of the displacements' components along the clean normals: the noise normal to
/// the surface, which estimate_noise_level estimates.
inline ks::IndexedMesh add_gaussian_noise(const ks::IndexedMesh& m, double sigma, bool along_normals,
                                          std::uint32_t seed, double* normal_rms = nullptr) {
    ks::IndexedMesh out = m;
    out.normals.clear();
    const auto n = ks::vertex_normals(m);
    std::mt19937 g(seed);
    auto u01 = [&] { return (double(g() >> 5) + 0.5) / double(1u << 27); };
    auto gauss = [&] { return std::sqrt(-2 * std::log(u01())) * std::cos(2 * std::numbers::pi * u01()); };
    double acc = 0;
    for (std::size_t v = 0; v < m.vertices.size(); ++v) {
        ks::Vec3 d;
        if (along_normals) {
            d = sigma * gauss() * n[v];
        } else {
            ks::Vec3 u(gauss(), gauss(), gauss());
            u.normalize();
            d = sigma * gauss() * u;
        }
        out.vertices[v] += d;
        acc += d.dot(n[v]) * d.dot(n[v]);
    }
    if (normal_rms) *normal_rms = std::sqrt(acc / double(m.vertices.size()));
    return out;
}

/// Impulsive noise: one vertex in `every` (chosen by a fixed generator) moved along its
/// clean normal by a Gaussian amount of standard deviation `sigma` (add_gaussian_noise's
/// moves, seed `seed`); the others stay exactly in place. `normal_rms` (if given)
/// receives the rms over all vertices of the moves along the normals.
inline ks::IndexedMesh add_impulsive_noise(const ks::IndexedMesh& m, double sigma, std::uint32_t seed,
                                           double* normal_rms = nullptr, unsigned every = 10) {
    const auto moved = add_gaussian_noise(m, sigma, true, seed);
    ks::IndexedMesh out = m;
    out.normals.clear();
    const auto n = ks::vertex_normals(m);
    std::uint32_t x = seed * 2654435761u;
    double acc = 0;
    for (std::size_t v = 0; v < m.vertices.size(); ++v) {
        x = x * 1664525u + 1013904223u;
        if ((x >> 8) % every != 0) continue;
        out.vertices[v] = moved.vertices[v];
        const double d = (moved.vertices[v] - m.vertices[v]).dot(n[v]);
        acc += d * d;
    }
    if (normal_rms) *normal_rms = std::sqrt(acc / double(m.vertices.size()));
    return out;
}

/// The sharp edges (a < b) of box_mesh(n): the mesh edges on the 12 box edges.
inline std::set<std::array<ks::Index, 2>> box_edges(const ks::IndexedMesh& m) {
    const ks::MeshTopology topo(m.vertices.size(), m.faces);
    std::set<std::array<ks::Index, 2>> out;
    auto on_two_sides = [&](const ks::Vec3& p) {
        int c = 0;
        for (int k = 0; k < 3; ++k) c += (p[k] == 0.0 || p[k] == 1.0);
        return c >= 2;
    };
    for (const auto& e : topo.edges()) {
        const ks::Vec3 &a = m.vertices[e[0]], &b = m.vertices[e[1]];
        if (!on_two_sides(a) || !on_two_sides(b)) continue;
        int shared = 0;  // both ends on the same two box sides
        for (int k = 0; k < 3; ++k)
            shared += (a[k] == b[k]) && (a[k] == 0.0 || a[k] == 1.0);
        if (shared >= 2) out.insert(e);
    }
    return out;
}

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

/// CGAL::Polygon_mesh_processing::smooth_shape (implicit mean-curvature flow) with
/// time step `time` and `iterations`; vertex order is kept.
/// Vertices no face uses are left out of the CGAL mesh: with them (bun_zipper.ply has
/// 1,113) its solve fails and the mesh comes back unchanged.
inline void cgal_smooth_shape(ks::IndexedMesh& m, double time, unsigned iterations) {
    constexpr ks::Index unused = std::numeric_limits<ks::Index>::max();
    std::vector<ks::Index> slot(m.vertices.size(), unused);
    ks::IndexedMesh used;
    for (const auto& f : m.faces) {
        ks::Face g;
        for (int k = 0; k < 3; ++k) {
            if (slot[f[k]] == unused) {
                slot[f[k]] = used.vertices.size();
                used.vertices.push_back(m.vertices[f[k]]);
            }
            g[k] = slot[f[k]];
        }
        used.faces.push_back(g);
    }
    SurfaceMesh sm;
    ks::assign_mesh(sm, used);
    CGAL::Polygon_mesh_processing::smooth_shape(sm, time,
                                                CGAL::parameters::number_of_iterations(iterations));
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
        if (slot[v] != unused) m.vertices[v] = ks::vertex_position(sm, slot[v]);
}

/// CGAL's smooth_shape at its best (by normal error against `clean`) over a sweep of time
/// step and iteration count. Its time step is in squared length units (mass matrix of areas
/// against a cotangent Laplacian), so the sweep is in |e|² of the noisy mesh: t|e|² for t in
/// {0.03, 0.1, 0.3, 1, 3} × {1, 3, 10} iterations. `setting` (when given) receives "t×it".
inline ks::IndexedMesh best_smooth_shape(const ks::IndexedMesh& noisy, const ks::IndexedMesh& clean,
                                         std::string* setting = nullptr) {
    const double L = ks::mean_edge_length(noisy);
    ks::IndexedMesh best;
    double be = 1e9;
    for (double t : {0.03, 0.1, 0.3, 1.0, 3.0})
        for (unsigned it : {1u, 3u, 10u}) {
            auto m = noisy;
            cgal_smooth_shape(m, t * L * L, it);
            const double e = ks::denoise_metrics(m, clean).mean_normal_angle_deg;
            if (e < be) {
                be = e, best = std::move(m);
                if (setting) {
                    char buf[32];
                    std::snprintf(buf, sizeof buf, "%gx%u", t, it);
                    *setting = buf;
                }
            }
        }
    return best;
}

}  // namespace smooth_support
