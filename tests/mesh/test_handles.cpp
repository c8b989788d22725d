// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// remove_small_handles: a thin handle is cut, a thick one and a thin separating neck are
// kept, on implicit shapes meshed by extract_isosurface; bad input, cancellation,
// containers, determinism.
#include <doctest/doctest.h>

#include "closed_mesh.hpp"
#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/field/isosurface.hpp>
#include <kintsugi/mesh/handles.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stop_token>

namespace ks = kintsugi;
using SurfaceMesh = CGAL::Surface_mesh<CGAL::Exact_predicates_inexact_constructions_kernel::Point_3>;

namespace {

constexpr double thin = 0.06, medium = 0.09, thick = 0.25, neck = 0.06;

/// Signed distance (< 0 inside) to a torus of radii (R, r) around `axis` through `c`.
double torus(const ks::Vec3& p, const ks::Vec3& c, const ks::Vec3& axis, double R, double r) {
    const ks::Vec3 d = p - c;
    const double h = d.dot(axis);
    const double rho = (d - h * axis).norm();
    return std::hypot(rho - R, h) - r;
}

// The handles' centre lines (circles of radius 0.45 or 0.5 half inside the ball).
double circle_a(const ks::Vec3& p) { return torus(p, ks::Vec3(1, 0, 0), ks::Vec3(0, 1, 0), 0.45, 0); }
double circle_b(const ks::Vec3& p) { return torus(p, ks::Vec3(-1, 0, 0), ks::Vec3(0, 1, 0), 0.45, 0); }
double circle_c(const ks::Vec3& p) { return torus(p, ks::Vec3(0, 0, 1), ks::Vec3(1, 0, 0), 0.5, 0); }

/// A unit ball with three handles (thin on +x, medium on -x, thick on top) and a second
/// ball below joined by a thin neck: genus 3, one component.
double shape(const ks::Vec3& p) {
    const double ball = p.norm() - 1;
    const double lower = (p - ks::Vec3(0, 0, -2.3)).norm() - 0.8;
    const double rod = std::max(std::hypot(p.x(), p.y()) - neck, std::abs(p.z() + 1.25) - 0.35);
    return std::min({ball, circle_a(p) - thin, circle_b(p) - medium, circle_c(p) - thick, lower, rod});
}

ks::IndexedMesh shape_mesh() {
    ks::BoundingBox box;
    box.extend(ks::Vec3(-1.6, -1.1, -3.2));
    box.extend(ks::Vec3(1.6, 1.1, 1.8));
    ks::IndexedMesh m;
    const auto r = ks::extract_isosurface(shape, ks::IsoRegion::full(ks::IsoGrid::fit(box, 90)), m);
    REQUIRE(r.status == ks::Status::ok);
    return m;
}

const ks::IndexedMesh& cached_mesh() {
    static const ks::IndexedMesh m = shape_mesh();
    return m;
}

}  // namespace

TEST_CASE_TEMPLATE("remove_small_handles: thin handles are cut, a thick handle and a thin neck are kept", M,
                   ks::IndexedMesh, SurfaceMesh) {
    const ks::IndexedMesh& ref = cached_mesh();
    const auto before = ks::topology_report(ref);
    REQUIRE(before.closed);
    REQUIRE(before.manifold);
    REQUIRE(before.components == 1);
    REQUIRE(before.genus == 3);
    M mesh;
    ks::assign_mesh(mesh, ref);
    // Loops around the handles: 2 pi r = 0.38, 0.57 and 1.57; around the neck 0.38, but
    // it separates the lower ball (cutting it would split the mesh).
    const auto r = ks::remove_small_handles(mesh, {.max_loop_length = 0.7});
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.handles_removed == 2);
    CHECK(r.genus_before == 3);
    CHECK(r.genus_after == 1);
    REQUIRE(r.loop_lengths.size() == 2);
    MESSAGE("loops " << r.loop_lengths[0] << " " << r.loop_lengths[1]);
    const double two_pi = 2 * std::numbers::pi;
    CHECK(r.loop_lengths[0] > two_pi * thin * 0.9);
    CHECK(r.loop_lengths[0] < two_pi * thin * 1.3);
    CHECK(r.loop_lengths[1] > two_pi * medium * 0.9);
    CHECK(r.loop_lengths[1] < two_pi * medium * 1.3);
    const ks::IndexedMesh out = ks::to_indexed_mesh(mesh);
    const auto after = kintsugi_test::check_closed_manifold(out);
    CHECK(after.components == 1);
    CHECK(after.genus == 1);
    // Away from the two thin handles the surface is the same vertex for vertex (the thick
    // handle, the neck, the lower ball), and every new vertex (the caps) is on a cut tube.
    auto less = [](const ks::Vec3& a, const ks::Vec3& b) {
        return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    };
    std::vector<ks::Vec3> outs = out.vertices, refs = ref.vertices;
    std::sort(outs.begin(), outs.end(), less);
    std::sort(refs.begin(), refs.end(), less);
    std::size_t far = 0, kept = 0, caps = 0, caps_on_tubes = 0;
    for (const ks::Vec3& v : ref.vertices) {
        if (std::abs(circle_a(v)) < 0.3 || std::abs(circle_b(v)) < 0.3) continue;
        ++far;
        kept += std::binary_search(outs.begin(), outs.end(), v, less);
    }
    for (const ks::Vec3& v : out.vertices)
        if (!std::binary_search(refs.begin(), refs.end(), v, less)) {
            ++caps;
            caps_on_tubes += circle_a(v) < 2 * thin || circle_b(v) < 2 * medium;
        }
    CHECK(far > ref.vertices.size() / 2);
    CHECK(kept == far);
    CHECK(caps_on_tubes == caps);
}

TEST_CASE("remove_small_handles: a shorter limit, max_handles, determinism, a sphere") {
    const ks::IndexedMesh& ref = cached_mesh();
    // A shorter limit takes the thinnest only; max_handles takes the shortest loops first.
    ks::IndexedMesh a = ref;
    const auto ra = ks::remove_small_handles(a, {.max_loop_length = 0.45});
    CHECK(ra.handles_removed == 1);
    CHECK(ra.genus_after == 2);
    ks::IndexedMesh b = ref;
    const auto rb = ks::remove_small_handles(b, {.max_loop_length = 0.7, .max_handles = 1});
    CHECK(rb.handles_removed == 1);
    CHECK(a.vertices == b.vertices);
    CHECK(a.faces == b.faces);
    // Below the thinnest handle's loop nothing is touched.
    ks::IndexedMesh same = ref;
    const auto r3 = ks::remove_small_handles(same, {.max_loop_length = 0.2});
    CHECK(r3.handles_removed == 0);
    CHECK(same.faces == ref.faces);
    CHECK(same.vertices == ref.vertices);
    // A sphere has nothing to remove, whatever the limit.
    ks::IndexedMesh s;
    ks::BoundingBox box;
    box.extend(ks::Vec3(-1.1, -1.1, -1.1));
    box.extend(ks::Vec3(1.1, 1.1, 1.1));
    (void)ks::extract_isosurface([](const ks::Vec3& p) { return p.norm() - 1; },
                                 ks::IsoRegion::full(ks::IsoGrid::fit(box, 40)), s);
    const ks::IndexedMesh s0 = s;
    const auto rs = ks::remove_small_handles(s, {.max_loop_length = 100});
    CHECK(rs.handles_removed == 0);
    CHECK(rs.genus_before == 0);
    CHECK(s.faces == s0.faces);
}

TEST_CASE("remove_small_handles: a plate with 144 holes becomes a genus-0 plate, over several rounds") {
    // A 2.4 x 2.4 x 0.1 plate perforated by a 12 x 12 grid of holes of radius 0.06
    // (loops around them 2 pi 0.06 = 0.38 at the exact surface): more holes than one
    // round cuts, and bands of neighbouring holes close enough to touch.
    constexpr int n = 12;
    constexpr double spacing = 0.2, radius = 0.06, half = 0.05, ext = n * spacing / 2;
    const auto plate = [&](const ks::Vec3& p) {
        const double slab = std::max({std::abs(p.z()) - half, std::abs(p.x()) - ext, std::abs(p.y()) - ext});
        const auto centre = [&](double x) {
            return (std::clamp(std::floor(x / spacing + n / 2.0), 0.0, n - 1.0) + 0.5) * spacing - ext;
        };
        return std::max(slab, radius - std::hypot(p.x() - centre(p.x()), p.y() - centre(p.y())));
    };
    ks::BoundingBox box;
    box.extend(ks::Vec3(-ext - 0.1, -ext - 0.1, -0.15));
    box.extend(ks::Vec3(ext + 0.1, ext + 0.1, 0.15));
    ks::IndexedMesh m;
    REQUIRE(ks::extract_isosurface(plate, ks::IsoRegion::full(ks::IsoGrid::fit(box, 45)), m).status ==
            ks::Status::ok);
    const auto before = kintsugi_test::check_closed_manifold(m);
    REQUIRE(before.components == 1);
    REQUIRE(before.genus == n * n);
    const auto r = ks::remove_small_handles(m, {.max_loop_length = 0.5});
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.handles_removed == n * n);
    CHECK(r.genus_after == 0);
    const auto after = kintsugi_test::check_closed_manifold(m);
    CHECK(after.components == 1);
    CHECK(after.genus == 0);
    // Every cut loop goes around one hole (measured 0.22-0.33 on this mesh).
    for (const double l : r.loop_lengths) CHECK(l < 0.4);
}

TEST_CASE("remove_small_handles: bad input throws invalid_input and leaves the mesh untouched") {
    const ks::IndexedMesh& ref = cached_mesh();
    ks::IndexedMesh m = ref;
    for (const double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity()}) {
        CAPTURE(bad);
        CHECK_THROWS_WITH_AS((void)ks::remove_small_handles(m, {.max_loop_length = bad}),
                             doctest::Contains("max_loop_length"), ks::invalid_input);
    }
    // An open mesh (one face removed).
    m.faces.pop_back();
    const ks::IndexedMesh open = m;
    CHECK_THROWS_WITH_AS((void)ks::remove_small_handles(m, {.max_loop_length = 0.7}),
                         doctest::Contains("3 boundary edges"), ks::invalid_input);
    CHECK(m.faces == open.faces);
    // A NaN coordinate; a face index out of range.
    m = ref;
    m.vertices[5].x() = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS((void)ks::remove_small_handles(m, {.max_loop_length = 0.7}),
                         doctest::Contains("vertex 5"), ks::invalid_input);
    m = ref;
    m.faces[0][1] = m.vertices.size();
    CHECK_THROWS_WITH_AS((void)ks::remove_small_handles(m, {.max_loop_length = 0.7}),
                         doctest::Contains("out of range"), ks::invalid_input);
}

TEST_CASE("remove_small_handles: a stop request cancels and leaves the mesh untouched") {
    const ks::IndexedMesh& ref = cached_mesh();
    ks::IndexedMesh m = ref;
    std::stop_source src;
    src.request_stop();
    ks::HandleParams p{.max_loop_length = 0.7};
    p.control.stop = src.get_token();
    const auto r = ks::remove_small_handles(m, p);
    CHECK(r.status == ks::Status::cancelled);
    CHECK(r.handles_removed == 0);
    CHECK(m.faces == ref.faces);
    CHECK(m.vertices == ref.vertices);
    // Stopped from the progress callback.
    ks::HandleParams q{.max_loop_length = 0.7};
    q.control.progress = [&](const ks::ProgressEvent&) { return false; };
    const auto r2 = ks::remove_small_handles(m, q);
    CHECK(r2.status == ks::Status::cancelled);
    CHECK(m.faces == ref.faces);
}
