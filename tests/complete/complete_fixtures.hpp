// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
// Helpers shared by the completion tests (test_complete.cpp) and their comparisons with
// CGAL (test_complete_peer.cpp): cutting holes, distances to the truth, checks.
#include "test_data.hpp"
#include "mesh/edit_fixtures.hpp"
#include "peers/cgal_fair_fill.hpp"

#include <kintsugi/complete/example_completion.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/spatial/triangle_index.hpp>

#include <doctest/doctest.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi_test::completion {

namespace ks = kintsugi;

// Removes the faces whose centroid lies within `radius` of one of `centres`.
inline ks::IndexedMesh cut_holes(const ks::IndexedMesh& m, const std::vector<ks::Vec3>& centres, double radius) {
    return kintsugi_test::remove_faces(m, [&](const ks::Vec3& c) {
        for (const auto& x : centres)
            if ((c - x).norm() < radius) return true;
        return false;
    });
}

// Mean and largest distance of the vertices [first, end) to the ground truth.
inline std::pair<double, double> distance_to(const ks::TriangleIndex& truth, const std::vector<ks::Vec3>& pts) {
    double sum = 0, mx = 0;
    for (const auto& p : pts) {
        const double d = truth.closest(p).distance;
        sum += d;
        mx = std::max(mx, d);
    }
    return {pts.empty() ? 0.0 : sum / static_cast<double>(pts.size()), mx};
}

inline std::vector<ks::Vec3> new_vertices(const ks::IndexedMesh& m, std::size_t first) {
    return {m.vertices.begin() + static_cast<std::ptrdiff_t>(first), m.vertices.end()};
}

inline std::vector<std::vector<ks::Index>> selected_holes(const ks::IndexedMesh& m, double max_size) {
    std::vector<std::vector<ks::Index>> out;
    ks::BoundingBox box;
    for (const auto& p : m.vertices) box.extend(p);
    for (const auto& l : ks::find_boundary_loops(m).loops)
        if (!l.outer && l.extent <= max_size * box.diagonal()) out.push_back(l.vertices);
    return out;
}

// The energy per level and the stage timings, for the test's message.
inline std::string history(const ks::CompletionResult& r) {
    std::ostringstream out;
    for (const auto& l : r.energy) {
        out << " |";
        for (double e : l) out << ' ' << e;
    }
    for (const auto& t : r.timings) out << ' ' << t.stage << '=' << t.seconds;
    return out.str();
}

// Status ok, `holes` holes filled, manifold, oriented, `open` boundary loops left.
inline void check_completed(const ks::IndexedMesh& m, const ks::CompletionResult& r, std::size_t holes, std::size_t open) {
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.filled_holes == holes);
    const auto topo = ks::topology_report(m);
    CHECK(topo.manifold);
    CHECK(topo.consistently_oriented);
    CHECK(topo.boundary_loops == open);
}

inline void check_energy_monotone(const ks::CompletionResult& r) {
    for (std::size_t l = 0; l < r.energy.size(); ++l)
        for (std::size_t i = 1; i < r.energy[l].size(); ++i) {
            INFO("level " << l + 1 << " iteration " << i);
            CHECK(r.energy[l][i] <= r.energy[l][i - 1]);
        }
}

// CGAL's fair fill (triangulate_refine_and_fair_hole) of each loop (vertex indices, as
// find_boundary_loops gives them); returns the new vertices (tests/peers/cgal_fair_fill.cpp).
inline std::vector<ks::Vec3> cgal_fill(const ks::IndexedMesh& in, const std::vector<std::vector<ks::Index>>& loops) {
    return kintsugi_test::cgal_fair_fill(in, loops).new_vertices;
}

}  // namespace kintsugi_test::completion

// The completion on IndexedMesh is compiled once per test program, in test_complete.cpp
// (its explicit instantiation); the other files of the program only call it.
extern template kintsugi::CompletionResult kintsugi::complete_holes_example_based<kintsugi::IndexedMesh>(
    kintsugi::IndexedMesh&, const kintsugi::CompletionParams&);
