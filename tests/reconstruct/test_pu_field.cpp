// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// PUField: accuracy against known signed distances (sphere, torus), gradient against
// finite differences, the cover, determinism, containers, real data, bad input,
// cancellation.
#include "test_data.hpp"
#include <doctest/doctest.h>

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/field/isosurface.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/reconstruct/pu_field.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <vector>

namespace ks = kintsugi;

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using PointSet3 = CGAL::Point_set_3<K::Point_3, K::Vector_3>;
using V = std::vector<Eigen::Vector3d>;

struct UserSample {
    double pos[3];
    std::array<float, 3> dir;
    int id;
};

// Closed test shapes with an exact signed distance, negative INSIDE (the field's sign).
struct Sphere {
    Eigen::Vector3d c{0.2, -0.1, 0.3};
    double R = 1.0;
    double sd(const Eigen::Vector3d& x) const { return (x - c).norm() - R; }
    void sample(std::size_t n, std::mt19937_64& rng, V& p, V& nrm) const {
        std::normal_distribution<double> g;
        for (std::size_t i = 0; i < n; ++i) {
            const Eigen::Vector3d v = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
            p.push_back(c + R * v);
            nrm.push_back(v);  // outward
        }
    }
};
struct Torus {
    double R = 1.0, r = 0.4;
    double sd(const Eigen::Vector3d& x) const {
        const double q = std::hypot(x.x(), x.y()) - R;
        return std::hypot(q, x.z()) - r;
    }
    void sample(std::size_t n, std::mt19937_64& rng, V& p, V& nrm) const {
        std::uniform_real_distribution<double> u(0, 2 * M_PI), acc(0, 1);
        while (p.size() < n) {
            const double a = u(rng), b = u(rng);
            // area element ∝ R + r cos b: rejection for uniform density
            if (acc(rng) > (R + r * std::cos(b)) / (R + r)) continue;
            const Eigen::Vector3d n0(std::cos(a) * std::cos(b), std::sin(a) * std::cos(b), std::sin(b));
            p.push_back(Eigen::Vector3d(R * std::cos(a), R * std::sin(a), 0) + r * n0);
            nrm.push_back(n0);
        }
    }
};

bool bitwise_equal(const std::vector<ks::PUSupport>& a, const std::vector<ks::PUSupport>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (std::memcmp(a[i].center.data(), b[i].center.data(), sizeof(double) * 3) != 0 ||
            std::memcmp(&a[i].radius, &b[i].radius, sizeof(double)) != 0 ||
            std::memcmp(a[i].normal.data(), b[i].normal.data(), sizeof(double) * 3) != 0 ||
            std::memcmp(a[i].origin.data(), b[i].origin.data(), sizeof(double) * 3) != 0 ||
            a[i].point_count != b[i].point_count || a[i].level != b[i].level)
            return false;
    }
    return true;
}

template <class Shape>
void check_field_accuracy(const Shape& shape, const V& pts, const V& nrm, const ks::PUField& f, double band) {
    const double eps = f.epsilon();
    // At the input points |f| <= ε up to the supports held at their minimum radius.
    std::size_t within = 0;
    for (const auto& p : pts)
        if (std::abs(f(p)) <= eps) ++within;
    CHECK(double(within) >= 0.99 * double(pts.size()));

    // Near the surface, f is the signed distance to within about ε.
    std::mt19937_64 rng(99);
    std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
    std::uniform_real_distribution<double> off(-band, band);
    double max_err = 0, sum_err = 0;
    int n = 0;
    for (int q = 0; q < 3000; ++q) {
        const std::size_t i = pick(rng);
        const Eigen::Vector3d x = pts[i] + off(rng) * nrm[i];
        if (!f.in_domain(x)) continue;
        const double e = std::abs(f(x) - shape.sd(x));
        max_err = std::max(max_err, e);
        sum_err += e;
        ++n;
    }
    REQUIRE(n > 2000);
    MESSAGE("epsilon " << eps << ", near-surface |f - sd|: max " << max_err << ", mean " << sum_err / n);
    CHECK(max_err <= 2.0 * eps);
    CHECK(sum_err / n <= 0.5 * eps);

    // The sign is right everywhere in the domain away from the surface.
    const ks::Vec3 lo = f.domain_min();
    const double side = f.domain_side();
    std::uniform_real_distribution<double> u(0, 1);
    int wrong = 0, tested = 0;
    for (int q = 0; q < 5000; ++q) {
        const Eigen::Vector3d x = lo + side * Eigen::Vector3d(u(rng), u(rng), u(rng));
        const double sd = shape.sd(x);
        const double v = f(x);
        REQUIRE_FALSE(std::isnan(v));  // defined everywhere in the cube
        if (std::abs(sd) < 0.05 * side) continue;
        ++tested;
        if ((v > 0) != (sd > 0)) ++wrong;
    }
    CHECK(tested > 3000);
    CHECK(wrong == 0);
}

}  // namespace

TEST_CASE("PUField: sphere — value, sign, gradient, cover") {
    const Sphere s;
    std::mt19937_64 rng(1);
    V pts, nrm;
    s.sample(20000, rng, pts, nrm);
    const auto res = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 7});
    REQUIRE(res.status == ks::Status::ok);
    const ks::PUField& f = res.field;
    CHECK(res.points == pts.size());
    CHECK(res.supports == f.supports().size());
    CHECK(res.octree_cells == f.num_cells());
    CHECK(res.supports > 100);
    CHECK(res.supports < res.octree_cells / 4);  // a support covers many cells (§2.1.2)
    CHECK(res.fits_evaluated >= res.supports);
    REQUIRE(res.timings.size() == 3);
    CHECK(res.timings[0].stage == "pu_octree");
    CHECK(f.epsilon() == doctest::Approx(4e-3 * 2.0).epsilon(1e-3));  // longest side = 2
    CHECK(f.domain_side() == doctest::Approx(2.0).epsilon(1e-3));

    check_field_accuracy(s, pts, nrm, f, 0.05);

    // Gradient: matches central differences, unit length, points outwards.
    std::mt19937_64 r2(5);
    std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
    std::uniform_real_distribution<double> off(-0.03, 0.03);
    const double h = 1e-6;
    for (int q = 0; q < 300; ++q) {
        const std::size_t i = pick(r2);
        const Eigen::Vector3d x = pts[i] + off(r2) * nrm[i];
        if (!f.in_domain(x + ks::Vec3::Constant(2 * h)) || !f.in_domain(x - ks::Vec3::Constant(2 * h))) continue;
        const ks::Vec3 g = f.gradient(x);
        ks::Vec3 fd;
        for (int k = 0; k < 3; ++k) {
            ks::Vec3 e = ks::Vec3::Zero();
            e[k] = h;
            fd[k] = (f(x + e) - f(x - e)) / (2 * h);
        }
        CHECK((g - fd).norm() <= 1e-5 * (1 + g.norm()));
        CHECK(g.norm() == doctest::Approx(1.0).epsilon(0.15));
        CHECK(g.dot(nrm[i]) > 0.9);
        ks::Vec3 g2;
        CHECK(f.value_and_gradient(x, g2) == f(x));
        CHECK(g2 == g);
    }

    // The supports cover every input point; normals point inwards, unit length.
    for (const auto& p : pts) {
        bool in = false;
        for (const auto& sp : f.supports()) in = in || (p - sp.center).norm() < sp.radius;
        REQUIRE(in);
    }
    for (const auto& sp : f.supports()) {
        CHECK(sp.normal.norm() == doctest::Approx(1.0));
        CHECK(sp.radius > 0);
        CHECK(sp.level >= 1);
        CHECK(sp.level <= 7);
        if (sp.point_count > 50) CHECK(std::abs(s.sd(sp.origin)) < 2 * f.epsilon());
    }

    // Batch evaluation equals single evaluation; NaN outside the cube.
    std::vector<ks::Vec3> xs;
    for (int q = 0; q < 2000; ++q) xs.push_back(pts[std::size_t(q) * 7] * 1.01);
    const auto vals = f.values(xs);
    const auto grads = f.gradients(xs);
    for (std::size_t q = 0; q < xs.size(); ++q) {
        const double v = f(xs[q]);
        const ks::Vec3 g = f.gradient(xs[q]);
        CHECK(std::memcmp(&vals[q], &v, sizeof v) == 0);  // bitwise: NaN outside the cube too
        CHECK(std::memcmp(grads[q].data(), g.data(), sizeof(double) * 3) == 0);
    }
    const ks::Vec3 outside = f.domain_min() - ks::Vec3::Constant(0.01);
    CHECK(std::isnan(f(outside)));
    CHECK(std::isnan(f.gradient(outside)[0]));
    CHECK_FALSE(f.in_domain(outside));
    CHECK(f.bounding_box().extent().maxCoeff() == doctest::Approx(2.0).epsilon(0.01));
}

TEST_CASE("PUField: reweighted — factors scale the supports' weights") {
    const Sphere s;
    std::mt19937_64 rng(3);
    V pts, nrm;
    s.sample(5000, rng, pts, nrm);
    const auto res = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6});
    REQUIRE(res.status == ks::Status::ok);
    const ks::PUField& f = res.field;
    const std::size_t ns = f.supports().size();
    std::vector<ks::Vec3> xs;
    for (std::size_t q = 0; q < pts.size(); q += 9) xs.push_back(pts[q] * 0.97);
    // All factors 1: the same field, bit for bit.
    const ks::PUField same = f.reweighted(std::vector<double>(ns, 1.0));
    const auto v0 = f.values(xs), v1 = same.values(xs);
    CHECK(std::memcmp(v0.data(), v1.data(), v0.size() * sizeof(double)) == 0);
    // One support alone (the others 0): its own linear function g_i inside its ball,
    // NaN where no other support is left.
    const std::size_t k = ns / 2;
    std::vector<double> one(ns, 0.0);
    one[k] = 1;
    const ks::PUField alone = f.reweighted(one);
    const ks::PUSupport& sk = f.supports()[k];
    const ks::Vec3 x = sk.center + 0.3 * sk.radius * ks::Vec3(1, 0, 0);
    // (support normals point inwards, g_i > 0 inside; the field is -g_i)
    CHECK(alone(x) == doctest::Approx(-sk.normal.dot(x - sk.origin)).epsilon(1e-9));
    CHECK(std::isnan(alone(sk.center + 1.01 * sk.radius * ks::Vec3(0, 1, 0))));
    // A tiny factor counts only where nothing else covers x.
    std::vector<double> tiny(ns, 1.0);
    tiny[k] = 1e-9;
    const ks::PUField t = f.reweighted(tiny);
    const ks::Vec3 c = sk.center;
    double without = 0, wsum = 0;
    for (std::size_t i = 0; i < ns; ++i) {
        const auto& si = f.supports()[i];
        const double d = (c - si.center).norm();
        if (i == k || d >= si.radius) continue;
        const double tt = 1.5 * d / si.radius;
        const double w = tt < 0.5 ? 0.75 - tt * tt : 0.5 * (1.5 - tt) * (1.5 - tt);
        without += w * si.normal.dot(c - si.origin);
        wsum += w;
    }
    if (wsum > 0) CHECK(t(c) == doctest::Approx(-without / wsum).epsilon(1e-6));
    CHECK(f.supports().size() == t.supports().size());  // shares the supports
    CHECK_THROWS_WITH_AS((void)f.reweighted(std::vector<double>(ns + 1, 1.0)), doctest::Contains("factors"),
                         ks::invalid_input);
    std::vector<double> neg(ns, 1.0);
    neg[0] = -1;
    CHECK_THROWS_WITH_AS((void)f.reweighted(neg), doctest::Contains(">= 0"), ks::invalid_input);
    neg[0] = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_AS((void)f.reweighted(neg), ks::invalid_input);
}

TEST_CASE("PUField: torus — value and sign (genus 1)") {
    const Torus t;
    std::mt19937_64 rng(2);
    V pts, nrm;
    t.sample(30000, rng, pts, nrm);
    const auto res = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 7});
    REQUIRE(res.status == ks::Status::ok);
    check_field_accuracy(t, pts, nrm, res.field, 0.04);
    // The hole of the torus is outside, the tube inside.
    CHECK(res.field(ks::Vec3(0, 0, 0)) > 0);
    CHECK(res.field(ks::Vec3(1, 0, 0)) < 0);
    CHECK(res.field(ks::Vec3(0, -1, 0)) < 0);
}

TEST_CASE("PUField: kintsugi's sign — extract_isosurface gives the outward torus from its own samples") {
    const Torus t;
    std::mt19937_64 rng(4);
    V pts, nrm;
    t.sample(20000, rng, pts, nrm);
    const auto res = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6});
    REQUIRE(res.status == ks::Status::ok);
    const ks::PUField& f = res.field;
    const auto grid = ks::IsoGrid::fit(f.bounding_box(), 64);
    ks::IndexedMesh m;
    const auto r = ks::extract_isosurface(f, ks::IsoRegion::narrow_band(grid, pts, grid.cell_size), m);
    REQUIRE(r.status == ks::Status::ok);
    const auto rep = ks::topology_report(m);
    CHECK(rep.closed);
    CHECK(rep.manifold);
    CHECK(rep.components == 1);
    CHECK(rep.genus == 1);
    CHECK(ks::signed_volume(m) > 0);  // outward: the field is negative inside
    double worst = 0;
    for (const auto& v : m.vertices) worst = std::max(worst, std::abs(t.sd(v)));
    MESSAGE("PU zero set: " << m.vertices.size() << " vertices, max distance to the torus " << worst << " (epsilon "
                            << f.epsilon() << ")");
    CHECK(worst < 2 * f.epsilon());
}

TEST_CASE("PUField: inward normals give the same field; seeds change the cover only") {
    const Sphere s;
    std::mt19937_64 rng(3);
    V pts, nrm;
    s.sample(4000, rng, pts, nrm);
    V inward = nrm;
    for (auto& n : inward) n = -n;
    const auto a = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6});
    const auto b = ks::PUField::build(ks::with_normals(pts, inward), {.max_level = 6, .inward_normals = true});
    CHECK(bitwise_equal(a.field.supports(), b.field.supports()));
    // Unnormalised normals are normalised first.
    V scaled = nrm;
    for (auto& n : scaled) n *= 3.5;
    const auto c = ks::PUField::build(ks::with_normals(pts, scaled), {.max_level = 6});
    REQUIRE(c.supports == a.supports);
    for (std::size_t i = 0; i < c.supports; ++i)
        CHECK((c.field.supports()[i].normal - a.field.supports()[i].normal).norm() < 1e-12);

    const auto d = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6, .seed = 42});
    CHECK_FALSE(bitwise_equal(a.field.supports(), d.field.supports()));
    for (std::size_t i = 0; i < pts.size(); i += 97) CHECK(std::abs(a.field(pts[i]) - d.field(pts[i])) < a.field.epsilon());
}

TEST_CASE("PUField: keep_octree = false releases the octree and changes nothing else") {
    const Sphere s;
    std::mt19937_64 rng(5);
    V pts, nrm;
    s.sample(6000, rng, pts, nrm);
    const auto a = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6});
    const auto b = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6, .keep_octree = false});
    REQUIRE(a.status == ks::Status::ok);
    REQUIRE(b.status == ks::Status::ok);
    CHECK(a.field.octree().size() == a.field.num_cells());
    CHECK(b.field.octree().size() == 0);
    CHECK(b.field.num_cells() == a.field.num_cells());
    CHECK(b.octree_cells == a.octree_cells);
    CHECK(bitwise_equal(a.field.supports(), b.field.supports()));
    // Values and the domain test agree, also on the cube's faces and just outside.
    const ks::Vec3 lo = a.field.domain_min();
    const double side = a.field.domain_side();
    std::uniform_real_distribution<double> u(-0.1, 1.1);
    for (int q = 0; q < 3000; ++q) {
        ks::Vec3 x = lo + side * ks::Vec3(u(rng), u(rng), u(rng));
        if (q % 10 == 0) x[q % 3] = q % 20 == 0 ? lo[q % 3] : lo[q % 3] + side;
        CHECK(a.field.in_domain(x) == b.field.in_domain(x));
        const double va = a.field(x), vb = b.field(x);
        CHECK(((std::isnan(va) && std::isnan(vb)) || va == vb));
    }
}

TEST_CASE("PUField: bit-identical with 1 and 2 threads") {
    const Torus t;
    std::mt19937_64 rng(4);
    V pts, nrm;
    t.sample(40000, rng, pts, nrm);
    // some outliers so that small supports and fallbacks occur too
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    for (int i = 0; i < 400; ++i) {
        pts.emplace_back(u(rng), u(rng), u(rng) * 0.3);
        nrm.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized());
    }
    auto build = [&](int threads) {
        ks::ThreadLimit lim(threads);
        return ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 7, .seed = 9});
    };
    const auto a = build(1);
    const auto b = build(2);
    REQUIRE(a.status == ks::Status::ok);
    CHECK(a.supports == b.supports);
    CHECK(bitwise_equal(a.field.supports(), b.field.supports()));
    std::vector<ks::Vec3> xs;
    std::uniform_real_distribution<double> w(-1.4, 1.4);
    for (int q = 0; q < 20000; ++q) xs.emplace_back(w(rng), w(rng), w(rng) * 0.3);
    std::vector<double> va, vb;
    {
        ks::ThreadLimit lim(1);
        va = a.field.values(xs);
    }
    {
        ks::ThreadLimit lim(2);
        vb = b.field.values(xs);
    }
    CHECK(std::memcmp(va.data(), vb.data(), va.size() * sizeof(double)) == 0);
}

using UserSamples = std::vector<UserSample>;
TEST_CASE_TEMPLATE("PUField: over the shipped containers", Container, V, PointSet3, UserSamples) {
    const Sphere s;
    std::mt19937_64 rng(6);
    V pts, nrm;
    s.sample(3000, rng, pts, nrm);
    const auto ref = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 6});
    Container c;
    V normals_storage;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        if constexpr (std::is_same_v<Container, V>) {
            c.push_back(pts[i]);
            normals_storage.push_back(nrm[i]);
        } else if constexpr (std::is_same_v<Container, PointSet3>) {
            if (!c.has_normal_map()) c.add_normal_map();
            c.insert(K::Point_3(pts[i].x(), pts[i].y(), pts[i].z()), K::Vector_3(nrm[i].x(), nrm[i].y(), nrm[i].z()));
        } else {
            c.push_back(UserSample{{pts[i].x(), pts[i].y(), pts[i].z()},
                                   {float(nrm[i].x()), float(nrm[i].y()), float(nrm[i].z())}, int(i)});
        }
    }
    auto build = [&]() {
        if constexpr (std::is_same_v<Container, V>)
            return ks::PUField::build(ks::with_normals(c, normals_storage), {.max_level = 6});
        else if constexpr (std::is_same_v<Container, PointSet3>)
            return ks::PUField::build(c, {.max_level = 6});
        else
            return ks::PUField::build(ks::project_points(c, &UserSample::pos, &UserSample::dir), {.max_level = 6});
    };
    const auto res = build();
    REQUIRE(res.status == ks::Status::ok);
    if constexpr (std::is_same_v<Container, UserSamples>) {
        // float normals: same cover size up to rounding, field equally accurate
        CHECK(res.supports == doctest::Approx(double(ref.supports)).epsilon(0.05));
    } else {
        CHECK(bitwise_equal(res.field.supports(), ref.field.supports()));
    }
    for (std::size_t i = 0; i < pts.size(); i += 31) CHECK(std::abs(res.field(pts[i])) <= res.field.epsilon());
}

TEST_CASE("PUField: bad input throws invalid_input and leaves the input alone") {
    const Sphere s;
    std::mt19937_64 rng(7);
    V pts, nrm;
    s.sample(200, rng, pts, nrm);
    auto build = [](const V& p, const V& n, ks::PUFieldParams prm = {}) {
        return ks::PUField::build(ks::with_normals(p, n), prm);
    };
    const V three(pts.begin(), pts.begin() + 3), three_n(nrm.begin(), nrm.begin() + 3);
    CHECK_THROWS_WITH_AS(build(three, three_n), doctest::Contains("at least 4 points"), ks::invalid_input);
    const V no_normals;
    CHECK_THROWS_WITH_AS(build(pts, no_normals), doctest::Contains("no normals"), ks::invalid_input);
    PointSet3 ps;
    for (const auto& p : pts) ps.insert(K::Point_3(p.x(), p.y(), p.z()));
    CHECK_THROWS_WITH_AS(ks::PUField::build(ps), doctest::Contains("no normals"), ks::invalid_input);

    V bad = nrm;
    bad[17] = Eigen::Vector3d::Zero();
    CHECK_THROWS_WITH_AS(build(pts, bad), doctest::Contains("normal of point 17 has zero length"), ks::invalid_input);
    bad = nrm;
    bad[5].y() = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(build(pts, bad), doctest::Contains("normal of point 5"), ks::invalid_input);
    V badp = pts;
    badp[9].z() = std::numeric_limits<double>::infinity();
    CHECK_THROWS_WITH_AS(build(badp, nrm), doctest::Contains("point 9 has a NaN or infinite"), ks::invalid_input);
    badp[9].z() = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_AS(build(badp, nrm), ks::invalid_input);

    V plane, line;
    std::uniform_real_distribution<double> u(-1, 1);
    const Eigen::Vector3d e1 = Eigen::Vector3d(1, 2, 0.5).normalized(), e2 = Eigen::Vector3d(-2, 1, 3).normalized();
    for (int i = 0; i < 100; ++i) {
        plane.push_back(Eigen::Vector3d(0.3, 0.1, 7) + u(rng) * e1 + u(rng) * (e2 - e2.dot(e1) * e1));
        line.push_back(Eigen::Vector3d(1, 1, 1) + u(rng) * e1);
    }
    const V up(100, Eigen::Vector3d(0, 0, 1));
    CHECK_THROWS_WITH_AS(build(plane, up), doctest::Contains("coplanar"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(build(line, up), doctest::Contains("collinear"), ks::invalid_input);

    CHECK_THROWS_WITH_AS(build(pts, nrm, {.max_level = 0}), doctest::Contains("max_level = 0"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(build(pts, nrm, {.max_level = 13}), doctest::Contains("[1, 12]"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(build(pts, nrm, {.epsilon = 0}), doctest::Contains("epsilon"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(build(pts, nrm, {.epsilon = -1e-3}), doctest::Contains("epsilon"), ks::invalid_input);
    CHECK_THROWS_AS(build(pts, nrm, {.epsilon = std::numeric_limits<double>::quiet_NaN()}), ks::invalid_input);

    // A default field is empty: NaN everywhere.
    const ks::PUField empty;
    CHECK(empty.empty());
    CHECK(std::isnan(empty(ks::Vec3::Zero())));
    CHECK(empty.supports().empty());
}

TEST_CASE("PUField: cancellation at each stage") {
    const Sphere s;
    std::mt19937_64 rng(8);
    V pts, nrm;
    s.sample(5000, rng, pts, nrm);
    for (const char* stage : {"pu_octree", "pu_cover", "pu_index"}) {
        ks::PUFieldParams prm{.max_level = 6};
        bool seen = false;
        prm.control.progress = [&](const ks::ProgressEvent& e) {
            seen = seen || e.stage == stage;
            return !seen;
        };
        const auto res = ks::PUField::build(ks::with_normals(pts, nrm), prm);
        CHECK(seen);
        CHECK(res.status == ks::Status::cancelled);
        CHECK(res.field.empty());
        CHECK(std::isnan(res.field(pts[0])));
    }
    std::stop_source src;
    src.request_stop();
    ks::PUFieldParams prm{.max_level = 6};
    prm.control.stop = src.get_token();
    const auto res = ks::PUField::build(ks::with_normals(pts, nrm), prm);
    CHECK(res.status == ks::Status::cancelled);
    // A callback that never cancels sees increasing fractions and all stages.
    ks::PUFieldParams ok{.max_level = 6};
    double last = -1;
    int calls = 0;
    ok.control.progress = [&](const ks::ProgressEvent& e) {
        CHECK(e.fraction >= last);
        last = e.fraction;
        ++calls;
        return true;
    };
    CHECK(ks::PUField::build(ks::with_normals(pts, nrm), ok).status == ks::Status::ok);
    CHECK(last == 1.0);
    CHECK(calls <= 110);
}

TEST_CASE("PUField: real data — the Stanford bunny") {
    const std::filesystem::path file =
        std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / "stanford_bunny/reconstruction/bun_zipper_points_normals.xyz";
    KINTSUGI_REQUIRE_DATA(file);
    V pts, nrm;
    std::ifstream in(file);
    double a[6];
    while (in >> a[0] >> a[1] >> a[2] >> a[3] >> a[4] >> a[5]) {
        pts.emplace_back(a[0], a[1], a[2]);
        nrm.emplace_back(a[3], a[4], a[5]);
    }
    REQUIRE(pts.size() == 34834);
    const auto res = ks::PUField::build(ks::with_normals(pts, nrm), {.max_level = 8, .epsilon = 4e-3});
    REQUIRE(res.status == ks::Status::ok);
    MESSAGE("bunny: " << res.octree_cells << " cells, " << res.supports << " supports, " << res.fits_evaluated
                      << " fits");
    // One support covers many cells (the point of §2.1.2): far fewer supports than cells.
    CHECK(res.supports * 20 < res.octree_cells);
    CHECK(res.supports > 1000);
    const ks::PUField& f = res.field;
    std::size_t within = 0;
    for (const auto& p : pts)
        if (std::abs(f(p)) <= f.epsilon()) ++within;
    CHECK(double(within) >= 0.99 * double(pts.size()));
    // Outward normals: a little outside each point is outside (f > 0), a little inside is inside.
    std::size_t right = 0, tested = 0;
    const double step = 2 * f.epsilon();
    for (std::size_t i = 0; i < pts.size(); i += 10) {
        ++tested;
        if (f(pts[i] + step * nrm[i]) > 0 && f(pts[i] - step * nrm[i]) < 0) ++right;
    }
    CHECK(double(right) >= 0.97 * double(tested));
    // Far corners of the domain are outside.
    CHECK(f(f.domain_min() + ks::Vec3::Constant(1e-6)) > 0);
}
