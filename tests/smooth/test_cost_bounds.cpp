// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Inputs whose neighbourhoods used to blow up (docs/methods/smoothing_cost.md has the
// time and memory before and after): repeated faces are smoothed as one face, a fan of
// thousands of triangles around one vertex gives a correct result with bounded
// neighbourhoods, and a non-manifold edge shared by many faces is handled.
#include <doctest/doctest.h>

#include "smooth/smooth_support.hpp"

#include <kintsugi/smooth/feature_bilateral.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace ks = kintsugi;
namespace ss = smooth_support;

TEST_CASE("repeated faces are smoothed as one face, bit for bit") {
    const auto clean = ss::box_mesh(6);
    const auto noisy = ss::add_normal_noise(clean, 0.3 * ks::mean_edge_length(clean), 9);
    ks::IndexedMesh once = noisy, many = noisy;
    // 500 copies of face 7, and each other face again with its corners rotated.
    for (int k = 0; k < 500; ++k) many.faces.push_back(noisy.faces[7]);
    for (const auto& f : noisy.faces) many.faces.push_back({f[1], f[2], f[0]});
    const auto r1 = ks::smooth_feature_bilateral(once);
    const auto rm = ks::smooth_feature_bilateral(many);
    CHECK(rm.faces == noisy.faces.size() * 2 + 500);
    CHECK(rm.duplicate_faces == noisy.faces.size() + 500);
    CHECK(r1.duplicate_faces == 0);
    CHECK(rm.features.sharp_edges == r1.features.sharp_edges);
    CHECK(many.vertices == once.vertices);
    // The opposite orientation is another face, not a repeat.
    ks::IndexedMesh flipped = noisy;
    flipped.faces.push_back({noisy.faces[3][0], noisy.faces[3][2], noisy.faces[3][1]});
    CHECK(ks::smooth_feature_bilateral(flipped).duplicate_faces == 0);
    // A triangle given 20,000 times (a 160 KB file) is one triangle.
    ks::IndexedMesh tri;
    tri.vertices = {ks::Vec3(0, 0, 0), ks::Vec3(1, 0, 0), ks::Vec3(0, 1, 0)};
    tri.faces.assign(20000, ks::Face{0, 1, 2});
    const auto rt = ks::smooth_feature_bilateral(tri);
    CHECK(rt.duplicate_faces == 19999);
    CHECK(tri.vertices[1] == ks::Vec3(1, 0, 0));  // an open triangle's corners stay in its plane
    CHECK(tri.vertices[2].z() == 0);
}

TEST_CASE("a flat fan of 6,000 triangles around one vertex stays flat and keeps its rim") {
    const int n = 6000;  // every cube then holds thousands of faces: the capped gathers
    ks::IndexedMesh fan;
    fan.vertices.emplace_back(0, 0, 0);
    for (int i = 0; i < n; ++i) {
        const double t = 2 * std::numbers::pi * i / n;
        fan.vertices.emplace_back(std::cos(t), std::sin(t), 0);
    }
    for (int i = 0; i < n; ++i)
        fan.faces.push_back({0, ks::Index(1 + i), ks::Index(1 + (i + 1) % n)});
    const auto r = ks::smooth_feature_bilateral(fan);
    REQUIRE(r.status == ks::Status::ok);
    double rmin = 2, rmax = 0;
    for (std::size_t v = 0; v < fan.vertices.size(); ++v) {
        REQUIRE(fan.vertices[v].allFinite());
        CHECK(fan.vertices[v].z() == 0);  // filter 4 moves along face normals only: in the plane, nothing
        if (v > 0) {
            rmin = std::min(rmin, fan.vertices[v].head<2>().norm());
            rmax = std::max(rmax, fan.vertices[v].head<2>().norm());
        }
    }
    CHECK(rmin == doctest::Approx(1.0));
    CHECK(rmax == doctest::Approx(1.0));
    CHECK(r.features.sharp_edges.empty());
}

TEST_CASE("the stored neighbour lists of a 40,000-face fan stay within their per-item cap") {
    namespace fbs = ks::detail::fbs;
    const std::size_t n = 40000;  // every cube holds thousands of faces
    std::vector<ks::Vec3> V{ks::Vec3(0, 0, 0)};
    std::vector<ks::Face> F;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = 2 * std::numbers::pi * static_cast<double>(i) / n;
        V.emplace_back(std::cos(t), std::sin(t), 0);
        F.push_back({0, ks::Index(1 + i), ks::Index(1 + (i + 1) % n)});
    }
    CHECK(fbs::max_listed(8192) == fbs::max_candidates);  // meshes up to 8K items: unchanged
    const std::size_t cap = fbs::max_listed(n);
    CHECK(cap == (std::size_t{1} << 24) / n);
    CHECK(fbs::max_listed(std::size_t{1} << 30) == 256);
    fbs::FaceGeometry g;
    fbs::compute_face_geometry(V, F, g);
    const ks::Scalar h = 0.5;  // about the mean edge length (spokes 1, rim ~0)
    ks::UniformGrid grid;
    grid.build(g.centroid, h, fbs::has_area(g.area));
    ks::RunControl control;
    ks::detail::Progress progress(control);
    fbs::Neighbourhoods lists;
    const auto normals = fbs::filter_normals(g, grid, g.normal, h, 1, progress, 0, 1, nullptr, nullptr, &lists);
    std::size_t longest = 0, shortest = n;
    for (std::size_t t = 0; t < n; ++t) {
        longest = std::max(longest, lists.of(t).size);
        shortest = std::min(shortest, lists.of(t).size);
    }
    CHECK(longest <= cap);     // 2048 candidates a face before: about 16 KB a face
    CHECK(shortest >= cap / 4);  // still a dense sample of the cube
    double flat = 1;  // the filtered normals of a flat fan stay ±z
    for (const auto& m : normals) flat = std::min(flat, std::abs(m.z()));
    CHECK(flat == doctest::Approx(1.0));
}

TEST_CASE("an edge shared by 3,000 faces (a book of pages) gives a finite result") {
    ks::IndexedMesh book;
    book.vertices = {ks::Vec3(0, 0, 0), ks::Vec3(0, 0, 1)};
    const int pages = 3000;
    for (int i = 0; i < pages; ++i) {
        const double t = std::numbers::pi * i / pages;
        book.vertices.emplace_back(std::cos(t), std::sin(t), 0.5);
        book.faces.push_back({0, 1, ks::Index(2 + i)});
    }
    const auto r = ks::smooth_feature_bilateral(book);
    REQUIRE(r.status == ks::Status::ok);
    for (const auto& v : book.vertices) REQUIRE(v.allFinite());
    CHECK(r.faces == std::size_t(pages));
}
