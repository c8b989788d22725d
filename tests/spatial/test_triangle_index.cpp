// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// TriangleIndex against brute force over every face: closest points of 10,000 queries
// (one by one and batched) and ray hits (first and all), on a real scan mesh through
// the three mesh adapters and on a closed genus-2 mesh; degenerate faces; bad input.
#include <doctest/doctest.h>

#include "metrics/mesh_fixtures.hpp"

#include <kintsugi/core/parallel.hpp>
#include <kintsugi/spatial/triangle_index.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

namespace ks = kintsugi;

namespace {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
ks::Vec3 closest_on_triangle(const ks::Vec3& p, const ks::Vec3& a, const ks::Vec3& b, const ks::Vec3& c) {
    const ks::Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const ks::Vec3 bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
    const ks::Vec3 cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
    const double denom = 1 / (va + vb + vc);
    return a + ab * (vb * denom) + ac * (vc * denom);
}

struct Brute {
    double best = std::numeric_limits<double>::infinity(), second = std::numeric_limits<double>::infinity();
    ks::Index face = 0;
};

Brute brute_closest(const ks::IndexedMesh& m, const ks::Vec3& q) {
    Brute r;
    for (ks::Index f = 0; f < m.faces.size(); ++f) {
        const auto& t = m.faces[f];
        const double d = (closest_on_triangle(q, m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]) - q).norm();
        if (d < r.best) {
            r.second = r.best;
            r.best = d;
            r.face = f;
        } else if (d < r.second) {
            r.second = d;
        }
    }
    return r;
}

// Möller–Trumbore: t >= 0 and the smallest barycentric coordinate, or nothing.
struct BruteRay {
    double t, margin;
    ks::Index face;
};
std::vector<BruteRay> brute_rays(const ks::IndexedMesh& m, const ks::Vec3& o, const ks::Vec3& d) {
    std::vector<BruteRay> out;
    for (ks::Index f = 0; f < m.faces.size(); ++f) {
        const auto& tri = m.faces[f];
        const ks::Vec3 &a = m.vertices[tri[0]], &b = m.vertices[tri[1]], &c = m.vertices[tri[2]];
        const ks::Vec3 e1 = b - a, e2 = c - a, p = d.cross(e2);
        const double det = e1.dot(p);
        if (std::abs(det) < 1e-14) continue;
        const ks::Vec3 s = o - a;
        const double u = s.dot(p) / det;
        const ks::Vec3 qv = s.cross(e1);
        const double v = d.dot(qv) / det, t = e2.dot(qv) / det;
        const double margin = std::min({u, v, 1 - u - v});
        if (margin >= 0 && t >= 0) out.push_back({t, margin, f});
    }
    std::sort(out.begin(), out.end(), [](const BruteRay& x, const BruteRay& y) { return x.t < y.t; });
    return out;
}

ks::IndexedMesh bunny() { return fixtures::load(fixtures::test_data("bun_zipper_res4.ply")); }

std::vector<ks::Vec3> queries(const ks::IndexedMesh& m, std::size_t n, unsigned seed) {
    ks::BoundingBox box;
    for (const auto& v : m.vertices) box.extend(v);
    const double diag = box.extent().norm();
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> g(0, 0.01 * diag);
    std::vector<ks::Vec3> q(n);
    for (std::size_t i = 0; i < n; ++i)
        if (i % 2 == 0)  // anywhere in the box grown by 20 %
            q[i] = box.min - 0.2 * box.extent() + 1.4 * box.extent().cwiseProduct(ks::Vec3(u(rng), u(rng), u(rng)));
        else  // near the surface
            q[i] = m.vertices[i % m.vertices.size()] + ks::Vec3(g(rng), g(rng), g(rng));
    return q;
}

}  // namespace

namespace {
template <class H>
void check_closest_points(const ks::IndexedMesh& m) {
    const H holder(m);
    const ks::TriangleIndex index(holder.mesh());
    CHECK(index.size() == m.faces.size());
    const auto q = queries(m, 10000, 1);
    const auto batch = index.closest_points(q);
    REQUIRE(batch.size() == q.size());
    double worst = 0;
    std::size_t ties = 0, same_face = 0;
    for (std::size_t i = 0; i < q.size(); ++i) {
        const Brute b = brute_closest(m, q[i]);
        const ks::ClosestPoint one = index.closest(q[i]);
        for (const ks::ClosestPoint& c : {one, batch[i]}) {
            worst = std::max(worst, std::abs(c.distance - b.best));
            REQUIRE(std::abs(c.distance - b.best) <= 1e-12);
            CHECK(std::abs((c.point - q[i]).norm() - c.distance) <= 1e-12);
            // The point lies on the face reported.
            const auto& t = m.faces[c.face];
            CHECK((closest_on_triangle(c.point, m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]) - c.point).norm() <=
                  1e-12);
        }
        CHECK(batch[i].distance == one.distance);
        if (b.second - b.best > 1e-12) {  // a unique nearest face
            CHECK(one.face == b.face);
            CHECK(batch[i].face == b.face);
            ++same_face;
        } else {
            ++ties;
        }
    }
    MESSAGE(std::string(H::name) << ", " << m.faces.size() << " faces: 10,000 queries, max |distance - brute force| "
                                 << worst << ", " << same_face << " with a unique nearest face (all equal), " << ties
                                 << " on shared edges or vertices");
    CHECK(same_face > 2500);
}
}  // namespace

TEST_CASE_TEMPLATE("TriangleIndex closest points equal brute force on 10,000 queries", H, fixtures::IndexedHolder,
                   fixtures::EigenHolder, fixtures::SurfaceMeshHolder) {
    // A closed genus-2 mesh through every adapter (the bunny scan is not manifold,
    // which CGAL::Surface_mesh refuses), and the bunny scan through the other two.
    check_closest_points<H>(fixtures::load(fixtures::test_data("eight.off")));
    if constexpr (!std::is_same_v<H, fixtures::SurfaceMeshHolder>) check_closest_points<H>(bunny());
}

TEST_CASE("TriangleIndex batch answers do not depend on the thread count") {
    const ks::IndexedMesh m = bunny();
    const ks::TriangleIndex index(m);
    const auto q = queries(m, 40000, 2);  // several blocks
    std::vector<double> seen;
    const auto two = index.closest_points(q, [&](double f) { seen.push_back(f); });
    CHECK(seen == std::vector<double>{0.0, 16384.0 / 40000, 32768.0 / 40000});
    ks::ThreadLimit one_thread(1);
    const auto one = index.closest_points(q);
    for (std::size_t i = 0; i < q.size(); ++i) {
        REQUIRE(one[i].face == two[i].face);
        REQUIRE(one[i].point == two[i].point);
    }
}

TEST_CASE("TriangleIndex ray hits equal brute force (first hit and all hits)") {
    for (const ks::IndexedMesh& m : {bunny(), fixtures::load(fixtures::test_data("eight.off"))}) {
        const ks::TriangleIndex index(m);
        ks::BoundingBox box;
        for (const auto& v : m.vertices) box.extend(v);
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> u(0, 1);
        std::normal_distribution<double> g(0, 1);
        std::size_t compared = 0, hit = 0, multi = 0;
        for (int r = 0; r < 2000; ++r) {
            const ks::Vec3 o = box.min + box.extent().cwiseProduct(ks::Vec3(u(rng), u(rng), u(rng)));
            const ks::Vec3 d(g(rng), g(rng), g(rng));
            const auto want = brute_rays(m, o, d);
            // Skip rays within round-off of an edge or vertex, or of a face's plane.
            bool clear = true;
            for (const auto& w : want) clear = clear && w.margin > 1e-9 && w.t > 1e-9;
            for (std::size_t k = 1; k < want.size(); ++k) clear = clear && want[k].t - want[k - 1].t > 1e-9;
            if (!clear) continue;
            ++compared;
            const std::optional<ks::RayHit> first = index.first_hit(o, d);
            const std::vector<ks::RayHit> all = index.all_hits(o, d);
            REQUIRE(first.has_value() == !want.empty());
            REQUIRE(all.size() == want.size());
            for (std::size_t k = 0; k < want.size(); ++k) {
                CHECK(all[k].face == want[k].face);
                CHECK(all[k].t == doctest::Approx(want[k].t).epsilon(1e-9));
                CHECK((all[k].point - (o + all[k].t * d)).norm() <= 1e-9 * box.extent().norm());
            }
            if (first) {
                ++hit;
                multi += want.size() > 1;
                CHECK(first->face == want[0].face);
                CHECK(first->t == doctest::Approx(want[0].t).epsilon(1e-9));
            }
        }
        MESSAGE(m.faces.size() << " faces: " << compared << " of 2000 rays compared, " << hit << " hit, " << multi
                                << " hit more than once; all equal to brute force");
        CHECK(compared > 1900);
        CHECK(hit > 500);
    }
}

TEST_CASE("TriangleIndex on a fan of slivers around one vertex equals brute force") {
    // 3,000 faces of aspect ratio ~500 sharing vertex 0 (their axis-aligned boxes all
    // overlap near it), flat and with every vertex moved by noise (slivers that cross).
    ks::IndexedMesh noisy = fixtures::fan(3000);
    std::mt19937 rng(7);
    std::normal_distribution<double> g(0, 0.002);
    for (auto& v : noisy.vertices) v += ks::Vec3(g(rng), g(rng), g(rng));
    for (const ks::IndexedMesh& m : {fixtures::fan(3000), noisy}) {
        const ks::TriangleIndex index(m);
        REQUIRE(index.size() == 3000);
        std::vector<ks::Vec3> q(3000);  // around the disk, on both sides and past its rim
        std::uniform_real_distribution<double> u(0, 1);
        for (auto& p : q) {
            const double rho = 1.2 * std::sqrt(u(rng)), a = 2 * std::numbers::pi * u(rng);
            p = ks::Vec3(rho * std::cos(a), rho * std::sin(a), 0.02 * (u(rng) - 0.5));
        }
        const auto batch = index.closest_points(q);
        std::size_t unique = 0;
        double worst = 0;
        for (std::size_t i = 0; i < q.size(); ++i) {
            const Brute b = brute_closest(m, q[i]);
            // The same closest point on a triangle as the index computes (CGAL's), over every face.
            double exact = std::numeric_limits<double>::infinity();
            using K = CGAL::Simple_cartesian<double>;
            const K::Point_3 p(q[i].x(), q[i].y(), q[i].z());
            for (const auto& t : m.faces) {
                auto P = [&](ks::Index v) { return K::Point_3(m.vertices[v].x(), m.vertices[v].y(), m.vertices[v].z()); };
                const K::Point_3 c = K::Construct_projected_point_3()(K::Triangle_3(P(t[0]), P(t[1]), P(t[2])), p);
                exact = std::min(exact, (ks::Vec3(c.x(), c.y(), c.z()) - q[i]).norm());
            }
            REQUIRE(batch[i].distance == exact);
            worst = std::max(worst, std::abs(batch[i].distance - b.best));
            REQUIRE(std::abs(batch[i].distance - b.best) <= 1e-10);
            REQUIRE(index.closest(q[i]).distance == batch[i].distance);
            if (b.second - b.best > 1e-12) {
                CHECK(batch[i].face == b.face);
                ++unique;
            }
        }
        CHECK(unique > 500);  // the others lie on a shared edge (the noisy fan is pleated)
        MESSAGE("fan of 3,000 faces: max |distance - brute force| " << worst);
    }
}

TEST_CASE("TriangleIndex ray queries from many threads at once (the ray tree is built on first use)") {
    const ks::IndexedMesh m = fixtures::load(fixtures::test_data("eight.off"));
    const ks::TriangleIndex index(m);
    ks::BoundingBox box;
    for (const auto& v : m.vertices) box.extend(v);
    const ks::Vec3 c = box.min + 0.5 * box.extent();
    std::vector<std::size_t> hits(64);
    ks::parallel_for(0, hits.size(), [&](std::size_t i) {
        const double a = 0.1 * static_cast<double>(i);
        hits[i] = index.all_hits(c - ks::Vec3(std::cos(a), std::sin(a), 0.3) * box.extent().norm(),
                                 ks::Vec3(std::cos(a), std::sin(a), 0.3)).size();
    }, 1);
    for (std::size_t i = 0; i < hits.size(); ++i) {
        const double a = 0.1 * static_cast<double>(i);
        const ks::Vec3 d(std::cos(a), std::sin(a), 0.3);
        CHECK(hits[i] == brute_rays(m, c - d * box.extent().norm(), d).size());
    }
}

TEST_CASE("TriangleIndex leaves out zero-area faces") {
    ks::IndexedMesh m = fixtures::tetrahedron();
    m.vertices.push_back(ks::Vec3(5, 5, 5));
    m.faces.push_back({4, 4, 4});  // a point
    m.faces.push_back({0, 1, 1});  // an edge
    const ks::TriangleIndex index(m);
    CHECK(index.size() == 4);
    const auto c = index.closest(ks::Vec3(5, 5, 5));
    CHECK(c.face == 3);
    CHECK(c.distance == doctest::Approx((ks::Vec3(5, 5, 5) - ks::Vec3::Constant(1.0 / 3)).norm()));
    const auto hits = index.all_hits(ks::Vec3(-1, 0.2, 0.2), ks::Vec3(1, 0, 0));  // in at x = 0, out at x = 0.6
    REQUIRE(hits.size() == 2);
    CHECK(hits[0].face == 2);
    CHECK(hits[0].t == doctest::Approx(1.0));
    CHECK(hits[1].face == 3);
    CHECK(hits[1].t == doctest::Approx(1.6));
}

TEST_CASE("TriangleIndex rejects empty and broken meshes, NaN queries and zero ray directions") {
    ks::IndexedMesh empty;
    CHECK_THROWS_WITH_AS(ks::TriangleIndex{empty}, doctest::Contains("is empty"), ks::invalid_input);
    ks::IndexedMesh no_faces = fixtures::tetrahedron();
    no_faces.faces.clear();
    CHECK_THROWS_WITH_AS(ks::TriangleIndex{no_faces}, doctest::Contains("is empty"), ks::invalid_input);
    ks::IndexedMesh bad_index = fixtures::tetrahedron();
    bad_index.faces[2][1] = 9;
    CHECK_THROWS_WITH_AS(ks::TriangleIndex{bad_index}, doctest::Contains("face 2 uses vertex 9"), ks::invalid_input);
    ks::IndexedMesh nan = fixtures::tetrahedron();
    nan.vertices[1].z() = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(ks::TriangleIndex{nan}, doctest::Contains("vertex 1"), ks::invalid_input);
    ks::IndexedMesh flat = fixtures::tetrahedron();
    for (auto& v : flat.vertices) v.z() = 0, v.y() = 0;
    CHECK_THROWS_WITH_AS(ks::TriangleIndex{flat}, doctest::Contains("zero surface area"), ks::invalid_input);

    const ks::TriangleIndex index(fixtures::tetrahedron());
    const ks::Vec3 bad(std::numeric_limits<double>::quiet_NaN(), 0, 0);
    CHECK_THROWS_WITH_AS((void)index.closest(bad), doctest::Contains("NaN"), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)index.closest_points({ks::Vec3::Zero(), bad}), doctest::Contains("query 1"),
                         ks::invalid_input);
    CHECK_THROWS_AS((void)index.first_hit(bad, ks::Vec3(1, 0, 0)), ks::invalid_input);
    CHECK_THROWS_AS((void)index.all_hits(ks::Vec3::Zero(), bad), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)index.first_hit(ks::Vec3::Zero(), ks::Vec3::Zero()), doctest::Contains("zero"),
                         ks::invalid_input);
    ks::TriangleIndex moved(fixtures::tetrahedron());
    const ks::TriangleIndex taken(std::move(moved));
    CHECK(taken.size() == 4);
    CHECK_THROWS_WITH_AS((void)moved.closest(ks::Vec3::Zero()), doctest::Contains("moved from"), ks::invalid_input);
}
