// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// fill_surfel_gaps (Kanamori et al. 2007) and surfel_coverage.
#include <doctest/doctest.h>

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/surfel_coverage.hpp>
#include <kintsugi/upsample/surfel_fill.hpp>

#include <stop_token>
#include <string>

#include "test_data.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

namespace ks = kintsugi;

namespace {

/// n points of a Fibonacci spiral on the sphere (centre 0, radius R), outward normals.
ks::PointCloud fibonacci_sphere(std::size_t n, double R = 1) {
    ks::PointCloud c;
    const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
    for (std::size_t i = 0; i < n; ++i) {
        const double z = 1 - (2 * static_cast<double>(i) + 1) / static_cast<double>(n);
        const double rho = std::sqrt(1 - z * z), phi = golden * static_cast<double>(i);
        const ks::Vec3 u(rho * std::cos(phi), rho * std::sin(phi), z);
        c.points.push_back(R * u);
        c.normals.push_back(u);
    }
    return c;
}

}  // namespace

TEST_CASE("unit sphere from 154 surfels at radius 0.018 of the diagonal: at most 2,100 surfels, fully covered") {
    const ks::PointCloud in = fibonacci_sphere(154);
    const auto t0 = std::chrono::steady_clock::now();
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, {.radius_rel = 0.018});
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    REQUIRE(r.status == ks::Status::ok);
    MESSAGE("sphere 0.018: " << r.surfels.points.size() << " surfels, rounds " << r.rounds << ", gaps " << r.gaps_filled
                             << ", " << secs << " s");
    CHECK(r.coverage_verified);
    CHECK(r.surfels.points.size() <= 2100);
    const ks::SurfelCoverage cov = ks::surfel_coverage(r.surfels, fibonacci_sphere(200000));
    MESSAGE("coverage " << cov.fraction << " uncovered " << cov.uncovered.size());
    CHECK(cov.uncovered.empty());
    double worst = 0;
    for (const ks::Vec3& p : r.surfels.points) worst = std::max(worst, std::abs(p.norm() - 1));
    MESSAGE("max |r - 1| " << worst);
    CHECK(worst < 1e-3);
}

TEST_CASE("unit sphere from 154 surfels at radius 0.010 of the diagonal: at most 6,127 surfels") {
    const ks::PointCloud in = fibonacci_sphere(154);
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, {.radius_rel = 0.010});
    REQUIRE(r.status == ks::Status::ok);
    MESSAGE("sphere 0.010: " << r.surfels.points.size() << " surfels, rounds " << r.rounds);
    CHECK(r.coverage_verified);
    CHECK(r.surfels.points.size() <= 6127);
    const ks::SurfelCoverage cov = ks::surfel_coverage(r.surfels, fibonacci_sphere(400000));
    CHECK(cov.uncovered.empty());
}

namespace {

/// The bunny points with every point within `hole_radius` of the three centres removed;
/// `removed` receives the removed points (samples of the true surface in the holes).
struct Holey {
    ks::PointCloud kept;
    std::vector<ks::Vec3> removed;
    std::vector<ks::Vec3> centres;
    double diag = 0;
};

Holey cut_holes(const ks::PointCloud& in, const std::vector<std::size_t>& centre_ids, double hole_radius_rel) {
    Holey h;
    ks::BoundingBox box;
    for (const ks::Vec3& p : in.points) box.extend(p);
    h.diag = box.diagonal();
    for (std::size_t id : centre_ids) h.centres.push_back(in.points[id]);
    const double hr = hole_radius_rel * h.diag;
    for (std::size_t i = 0; i < in.points.size(); ++i) {
        bool inside = false;
        for (const ks::Vec3& c : h.centres) inside = inside || (in.points[i] - c).norm() < hr;
        if (inside) {
            h.removed.push_back(in.points[i]);
        } else {
            h.kept.points.push_back(in.points[i]);
            h.kept.normals.push_back(in.normals[i]);
        }
    }
    return h;
}

}  // namespace

TEST_CASE("bunny with 3 holes of 5 % of the diagonal: holes covered, new surfels within 0.1 % of the true surface "
          "where the rest of the scan predicts it") {
    const auto xyz = ks::test::shared_data("stanford_bunny/reconstruction/bun_zipper_points_normals.xyz");
    const auto ply = ks::test::shared_data("stanford_bunny/reconstruction/bun_zipper.ply");
    KINTSUGI_REQUIRE_DATA(xyz);
    KINTSUGI_REQUIRE_DATA(ply);
    const ks::PointCloud full = ks::read_point_cloud(xyz);
    const ks::IndexedMesh truth = ks::read_mesh(ply);
    // Three holes of diameter 5 % of the diagonal on the back, the flank and the side of
    // the body. How close any fill from the rim can come is set by the data: the removed
    // points lie 0.063 / 0.104 / 0.128 % of the diagonal from the MLS surface of what is
    // left (and 0.05-0.7 % at 9 held-out holes: docs/methods/surfel_upsampling.md).
    const Holey h = cut_holes(full, {3500, 9500, 24500}, 0.025);
    for (const ks::Vec3& c : h.centres) MESSAGE("hole centre " << c.transpose());
    MESSAGE("removed " << h.removed.size() << " of " << full.points.size());
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(h.kept, {.radius_rel = 0.005});
    REQUIRE(r.status == ks::Status::ok);
    MESSAGE("bunny: " << h.kept.points.size() << " -> " << r.surfels.points.size() << " surfels, rounds " << r.rounds
                      << ", not placed " << r.not_placed);
    const ks::SurfelCoverage cov = ks::surfel_coverage(r.surfels, h.removed);
    MESSAGE("hole coverage " << cov.fraction);
    CHECK(cov.uncovered.empty());
    // The data's limit per hole: the removed points projected onto the MLS surface of
    // the kept ones (the surface the new surfels are projected onto).
    const ks::PointSetSurface rest(h.kept, {.k = 20, .max_iterations = 10, .min_support_factor = 2});
    std::array<double, 3> limit{}, worst{};
    for (const ks::Vec3& q : h.removed)
        for (std::size_t k = 0; k < 3; ++k)
            if ((q - h.centres[k]).norm() < 0.025 * h.diag)
                limit[k] = std::max(limit[k], (rest.project(q).point - q).norm());
    // New surfels in the cut holes, against the scanned mesh.
    std::vector<ks::Vec3> in_holes;
    std::vector<std::size_t> hole_of;
    for (std::size_t i = r.input_surfels; i < r.surfels.points.size(); ++i)
        for (std::size_t k = 0; k < 3; ++k)
            if ((r.surfels.points[i] - h.centres[k]).norm() < 0.025 * h.diag) {
                in_holes.push_back(r.surfels.points[i]);
                hole_of.push_back(k);
                break;
            }
    REQUIRE(in_holes.size() > 120);
    const std::vector<double> d = ks::distances_to_mesh(in_holes, truth);
    double mean = 0;
    for (std::size_t j = 0; j < d.size(); ++j) {
        mean += d[j] / static_cast<double>(d.size());
        worst[hole_of[j]] = std::max(worst[hole_of[j]], d[j]);
    }
    MESSAGE(in_holes.size() << " new surfels in the holes, distance to the scanned mesh: mean " << mean / h.diag * 100
                            << " % of the diagonal");
    for (std::size_t k = 0; k < 3; ++k) {
        MESSAGE("hole " << k << ": max " << worst[k] / h.diag * 100 << " %, removed points from the MLS of the rest "
                        << limit[k] / h.diag * 100 << " %");
        // The fill is as close as the data allows (measured below the limit in all three).
        CHECK(worst[k] <= limit[k] + 0.0001 * h.diag);
    }
    // Where the new disks land decides which part of the MLS surface's deviation they
    // sample: the sequential fill measured 0.062 / 0.095 / 0.120 %, the tiled parallel
    // order 0.070 / 0.103 / 0.127 %. 0.1 % holds only where the data's limit is below it.
    CHECK(mean < 0.001 * h.diag);       // measured 0.030 %
    CHECK(worst[0] < 0.001 * h.diag);   // measured 0.070 %, data limit 0.063 %
    CHECK(worst[1] < 0.0011 * h.diag);  // measured 0.103 %, data limit 0.104 %: 0.1 % is not guaranteed there
    CHECK(worst[2] < 0.0015 * h.diag);  // measured 0.126 %, data limit 0.128 %: 0.1 % is out of reach there
}

TEST_CASE("kitten (shipped) with 3 holes: holes covered, new surfels on the MLS surface of the whole scan") {
    const auto xyz = ks::test::test_data("kitten.xyz");
    const ks::PointCloud full = ks::read_point_cloud(xyz);
    const Holey h = cut_holes(full, {500, 2500, 4500}, 0.025);
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(h.kept, {.radius_rel = 0.01});
    REQUIRE(r.status == ks::Status::ok);
    const ks::SurfelCoverage cov = ks::surfel_coverage(r.surfels, h.removed);
    CHECK(cov.uncovered.empty());
    const ks::PointSetSurface truth(full);
    double worst = 0, mean = 0;
    std::size_t count = 0;
    for (std::size_t i = r.input_surfels; i < r.surfels.points.size(); ++i)
        for (const ks::Vec3& c : h.centres)
            if ((r.surfels.points[i] - c).norm() < 0.025 * h.diag) {
                const double d = std::abs(truth(r.surfels.points[i]));
                worst = std::max(worst, d);
                mean += d;
                ++count;
                break;
            }
    REQUIRE(count > 30);
    mean /= static_cast<double>(count);
    MESSAGE("kitten: " << h.kept.points.size() << " -> " << r.surfels.points.size() << ", " << count
                       << " in the holes, distance to the whole scan's MLS surface mean " << mean / h.diag * 100
                       << " %, max " << worst / h.diag * 100 << " %");
    CHECK(mean < 0.001 * h.diag);
    CHECK(worst < 0.003 * h.diag);
}

namespace user {
struct Disk {
    std::array<float, 3> p;
    Eigen::Vector3f n;
    float r;
};
}  // namespace user

TEST_CASE("the same surfels through a PointCloud, a user struct view and plain oriented points give the same fill") {
    const ks::PointCloud sphere = fibonacci_sphere(154);
    const double rad = 0.018 * std::sqrt(12.0);
    ks::PointCloud with_radii = sphere;
    with_radii.radii.assign(sphere.points.size(), rad);
    std::vector<user::Disk> disks;
    for (std::size_t i = 0; i < sphere.points.size(); ++i)
        disks.push_back({{float(sphere.points[i].x()), float(sphere.points[i].y()), float(sphere.points[i].z())},
                         sphere.normals[i].cast<float>(), float(rad)});
    // Float storage: the reference is the cloud of the same float values.
    ks::PointCloud as_float;
    for (const auto& d : disks) {
        as_float.points.emplace_back(d.p[0], d.p[1], d.p[2]);
        as_float.normals.push_back(d.n.cast<double>());
        as_float.radii.push_back(d.r);
    }
    const auto view = ks::project_surfels(disks, &user::Disk::p, &user::Disk::n, &user::Disk::r);
    const ks::SurfelFillResult a = ks::fill_surfel_gaps(view, {.radius = double(float(rad))});
    const ks::SurfelFillResult b = ks::fill_surfel_gaps(as_float, {.radius = double(float(rad))});
    REQUIRE(a.status == ks::Status::ok);
    CHECK(a.surfels.points == b.surfels.points);
    CHECK(a.surfels.radii == b.surfels.radii);
    // Plain oriented points (no radii) take params.radius: the same as radii all equal to it.
    std::vector<ks::Vec3> pts = sphere.points, nrm = sphere.normals;
    const ks::SurfelFillResult c = ks::fill_surfel_gaps(ks::with_normals(pts, nrm), {.radius = rad});
    const ks::SurfelFillResult d = ks::fill_surfel_gaps(with_radii, {.radius = rad});
    CHECK(c.surfels.points.size() > 1000);
    CHECK(c.surfels.points == d.surfels.points);
    CHECK(c.surfels.normals == d.surfels.normals);
    CHECK(c.coverage_verified);
}

TEST_CASE("bad input throws invalid_input naming the function and leaves the input untouched") {
    ks::PointCloud in = fibonacci_sphere(50);
    const ks::PointCloud copy = in;
    auto throws_with = [&](const ks::PointCloud& c, const ks::SurfelFillParams& p, const std::string& what) {
        try {
            (void)ks::fill_surfel_gaps(c, p);
            FAIL("no exception for " << what);
        } catch (const ks::invalid_input& e) {
            const std::string msg = e.what();
            CHECK(msg.find("kintsugi::fill_surfel_gaps") == 0);
            CHECK_MESSAGE(msg.find(what) != std::string::npos, msg);
        }
    };
    throws_with(in, {.radius = 0}, "exactly one of");
    throws_with(in, {.radius = -0.1}, "params.radius");
    throws_with(in, {.radius = 0.1, .radius_rel = 0.01}, "exactly one of");
    throws_with(in, {.radius = std::nan("")}, "params.radius");
    throws_with(in, {.radius = 0.1, .levels = 0}, "params.levels");
    ks::PointCloud no_normals = in;
    no_normals.normals.clear();
    throws_with(no_normals, {.radius = 0.1}, "no normals");
    ks::PointCloud nan_point = in;
    nan_point.points[7].y() = std::nan("");
    throws_with(nan_point, {.radius = 0.1}, "surfel 7");
    ks::PointCloud zero_normal = in;
    zero_normal.normals[3].setZero();
    throws_with(zero_normal, {.radius = 0.1}, "normal of surfel 3");
    ks::PointCloud bad_radius = in;
    bad_radius.radii.assign(in.points.size(), 0.1);
    bad_radius.radii[9] = 0;
    throws_with(bad_radius, {.radius = 0.1}, "radius of surfel 9");
    throws_with(ks::PointCloud{}, {.radius = 0.1}, "no surfels");
    ks::SurfelFillParams wide{.radius = 0.1};
    wide.mls_support_factor = 9;
    throws_with(in, wide, "params.mls_support_factor = 9");
    wide.mls_support_factor = 0.5;
    throws_with(in, wide, "params.mls_support_factor = 0.5");
    // The sphere's diagonal is 2 sqrt(3) ~ 3.46: a larger radius is refused.
    throws_with(in, {.radius = 4}, "larger than the input's bounding-box diagonal");
    // 1e-6 of the diagonal on the unit sphere: ~4e11 disks; the message names the count.
    throws_with(in, {.radius_rel = 1e-6}, "asks for about");
    ks::SurfelFillParams none{.radius = 0.1};
    none.max_output_surfels = 0;
    throws_with(in, none, "params.max_output_surfels");
    CHECK(in.points == copy.points);
    CHECK(in.normals == copy.normals);
    CHECK_THROWS_AS((void)ks::surfel_coverage(no_normals, in.points), ks::invalid_input);
    // surfel_coverage shares the checks and their messages (core/surfel_input.hpp).
    auto coverage_throws_with = [&](const ks::PointCloud& c, const std::string& what) {
        try {
            (void)ks::surfel_coverage(c, in.points);
            FAIL("no exception for " << what);
        } catch (const ks::invalid_input& e) {
            const std::string msg = e.what();
            CHECK(msg.find("kintsugi::surfel_coverage") == 0);
            CHECK_MESSAGE(msg.find(what) != std::string::npos, msg);
        }
    };
    coverage_throws_with(bad_radius, "radius of surfel 9");
    ks::PointCloud zero_normal_r = bad_radius;
    zero_normal_r.radii[9] = 0.1;
    zero_normal_r.normals[3].setZero();
    coverage_throws_with(zero_normal_r, "normal of surfel 3");
    coverage_throws_with(in, "no radii");
}

TEST_CASE("max_output_surfels caps the output: a fill passing it stops with invalid_input") {
    const ks::PointCloud in = fibonacci_sphere(154);
    ks::SurfelFillParams p{.radius_rel = 0.018};
    p.max_output_surfels = 1000;  // the fill needs 1,747
    try {
        (void)ks::fill_surfel_gaps(in, p);
        FAIL("no exception for a cap of 1,000 surfels");
    } catch (const ks::invalid_input& e) {
        CHECK_MESSAGE(std::string(e.what()).find("max_output_surfels = 1000") != std::string::npos, e.what());
    }
    p.max_output_surfels = 2000;
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, p);
    CHECK(r.surfels.points.size() <= 2000);
    CHECK(r.coverage_verified);
}

TEST_CASE("a huge input radius counts as 4x the fill radius in the gap tests and is kept in the output") {
    const ks::PointCloud sphere = fibonacci_sphere(154);
    const double rad = 0.05;
    ks::PointCloud huge = sphere, capped = sphere;
    huge.radii.assign(sphere.points.size(), rad);
    capped.radii = huge.radii;
    huge.radii[10] = 1e6;      // would make every neighbour search see every surfel
    capped.radii[10] = 4 * rad;
    const ks::SurfelFillResult a = ks::fill_surfel_gaps(huge, {.radius = rad});
    const ks::SurfelFillResult b = ks::fill_surfel_gaps(capped, {.radius = rad});
    REQUIRE(a.status == ks::Status::ok);
    CHECK(a.surfels.points == b.surfels.points);
    CHECK(a.surfels.radii[10] == 1e6);
    CHECK(b.surfels.radii[10] == doctest::Approx(4 * rad));
    CHECK(a.coverage_verified);
}

TEST_CASE("an open surface: coverage_verified is false and uncovered_surfels lists the border") {
    // The upper half of the unit sphere: beyond max_distance_rel of the border no disk
    // is placed, so the surfels there keep an uncovered arc.
    const ks::PointCloud sphere = fibonacci_sphere(600);
    ks::PointCloud cap;
    for (std::size_t i = 0; i < sphere.points.size(); ++i)
        if (sphere.points[i].z() > 0) {
            cap.points.push_back(sphere.points[i]);
            cap.normals.push_back(sphere.normals[i]);
        }
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(cap, {.radius = 0.08});
    REQUIRE(r.status == ks::Status::ok);
    CHECK_FALSE(r.coverage_verified);
    REQUIRE_FALSE(r.uncovered_surfels.empty());
    CHECK(std::is_sorted(r.uncovered_surfels.begin(), r.uncovered_surfels.end()));
    double highest = -1;
    for (std::size_t i : r.uncovered_surfels) highest = std::max(highest, r.surfels.points[i].z());
    MESSAGE("open cap: " << r.surfels.points.size() << " surfels, " << r.uncovered_surfels.size()
                         << " uncovered, highest z " << highest);
    // The diagonal of the cap is ~2.45, max_distance_rel 0.1: the fill ends within
    // ~0.25 of the border z = 0, and only there are surfels left uncovered.
    CHECK(highest < 0.1);
    // A closed surface: verified and nothing listed.
    const ks::SurfelFillResult closed = ks::fill_surfel_gaps(sphere, {.radius = 0.08});
    CHECK(closed.coverage_verified);
    CHECK(closed.uncovered_surfels.empty());
}

TEST_CASE("back-projection guard: a disk whose projection jumps to the other side of a thin part is not placed") {
    // A thin oblate spheroid (semi-axes 1, 1, 0.05: its two faces 0.1 apart at the
    // centre) with a hole of radius 0.3 in the top face at (0.4, 0). In the middle of
    // the hole the bottom face is nearer than the hole's rim, so the MLS projection of
    // a disk placed there on the top face's tangent plane lands on the bottom face
    // (moved 5 r, normal reversed): jump_radii and the normal test drop it. Without
    // the guard those disks are kept, stacked on the bottom face under the hole
    // (measured: 515 new surfels there against 315 in the mirror region at (-0.4, 0),
    // where the top face is whole; with the guard 309 against 315).
    const double c = 0.05, hole = 0.3, hx = 0.4, radius = 0.02;
    const int n = 3000;
    const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
    ks::PointCloud in;
    for (int side = 0; side < 2; ++side)
        for (int i = 0; i < n; ++i) {
            const double rho = std::sqrt((i + 0.5) / n), phi = golden * i + side;
            const double x = rho * std::cos(phi), y = rho * std::sin(phi);
            const double z = (side == 0 ? c : -c) * std::sqrt(std::max(0.0, 1 - rho * rho));
            if (side == 0 && std::hypot(x - hx, y) < hole) continue;
            in.points.emplace_back(x, y, z);
            in.normals.push_back(ks::Vec3(x, y, z / (c * c)).normalized());
        }
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, {.radius = radius});
    REQUIRE(r.status == ks::Status::ok);
    std::size_t under_hole = 0, under_mirror = 0, rim_open = 0;
    for (std::size_t i = in.points.size(); i < r.surfels.points.size(); ++i) {
        const ks::Vec3& p = r.surfels.points[i];
        if (p.z() < 0 && std::hypot(p.x() - hx, p.y()) < hole) ++under_hole;
        if (p.z() < 0 && std::hypot(p.x() + hx, p.y()) < hole) ++under_mirror;
    }
    for (std::size_t i : r.uncovered_surfels) {
        const ks::Vec3& p = r.surfels.points[i];
        if (p.z() > 0 && std::hypot(p.x() - hx, p.y()) < hole + 2 * radius) ++rim_open;
    }
    MESSAGE("thin spheroid: " << r.surfels.points.size() << " surfels, not placed " << r.not_placed
                              << ", new on the bottom face under the hole " << under_hole << ", under the whole top "
                              << under_mirror << ", open surfels at the hole " << rim_open);
    // The bottom face under the hole gets no more disks than elsewhere: none jumped there.
    REQUIRE(under_mirror > 100);
    CHECK(static_cast<double>(under_hole) <= 1.15 * static_cast<double>(under_mirror));
    // The dropped placements are counted and the hole's middle is reported open, not
    // claimed covered.
    CHECK(r.not_placed > 0);
    CHECK_FALSE(r.coverage_verified);
    CHECK(rim_open > 0);
}

TEST_CASE("cancellation: status cancelled, no output, input untouched") {
    const ks::PointCloud in = fibonacci_sphere(154);
    int calls = 0;
    ks::SurfelFillParams p{.radius_rel = 0.005};
    p.control.progress = [&](const ks::ProgressEvent&) { return ++calls < 4; };
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, p);
    CHECK(r.status == ks::Status::cancelled);
    CHECK(r.surfels.points.empty());
    CHECK(r.level_counts.empty());
    std::stop_source stop;
    stop.request_stop();
    ks::SurfelFillParams q{.radius_rel = 0.005};
    q.control.stop = stop.get_token();
    CHECK(ks::fill_surfel_gaps(in, q).status == ks::Status::cancelled);
    CHECK(in.points == fibonacci_sphere(154).points);
}

TEST_CASE("deterministic whatever the thread count") {
    const ks::PointCloud in = fibonacci_sphere(300);
    ks::SurfelFillResult one;
    {
        const ks::ThreadLimit limit(1);
        one = ks::fill_surfel_gaps(in, {.radius_rel = 0.01, .epsilon_r = 0.05});
    }
    const ks::SurfelFillResult all = ks::fill_surfel_gaps(in, {.radius_rel = 0.01, .epsilon_r = 0.05});
    REQUIRE(one.surfels.points.size() > 1000);
    CHECK(one.surfels.points == all.surfels.points);
    CHECK(one.surfels.radii == all.surfels.radii);
}

TEST_CASE("levels of detail: every prefix covers the sphere at its own radius") {
    const ks::PointCloud in = fibonacci_sphere(154);
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, {.radius_rel = 0.02, .levels = 3});
    REQUIRE(r.status == ks::Status::ok);
    REQUIRE(r.level_counts.size() == 3);
    CHECK(r.level_counts[0] < r.level_counts[1]);
    CHECK(r.level_counts[1] < r.level_counts[2]);
    CHECK(r.level_counts[2] == r.surfels.points.size());
    MESSAGE("levels: rounds " << r.rounds << ", not placed " << r.not_placed << ", verified " << r.coverage_verified
                               << ", uncovered surfels " << r.uncovered_surfels.size());
    // Placements dropped on existing centres leave no gap once the level's neighbours
    // are all in: every level is verified.
    CHECK(r.coverage_verified);
    CHECK(r.uncovered_surfels.empty());
    CHECK(ks::fill_surfel_gaps(in, {.radius_rel = 0.02, .levels = 2}).coverage_verified);
    const ks::PointCloud dense = fibonacci_sphere(100000);
    for (std::size_t l = 0; l < 3; ++l) {
        ks::PointCloud prefix;
        for (std::size_t i = 0; i < r.level_counts[l]; ++i) {
            prefix.points.push_back(r.surfels.points[i]);
            prefix.normals.push_back(r.surfels.normals[i]);
            prefix.radii.push_back(r.surfels.radii[i] * std::ldexp(1.0, static_cast<int>(2 - l)));
        }
        const ks::SurfelCoverage cov = ks::surfel_coverage(prefix, dense);
        MESSAGE("level " << l << ": " << r.level_counts[l] << " surfels, coverage " << cov.fraction);
        CHECK(cov.uncovered.empty());
    }
    // Each level needs roughly 4x the disks of the one above (half the radius).
    CHECK(double(r.level_counts[2]) / double(r.level_counts[1]) > 2.5);
}

TEST_CASE("curvature-adaptive radii: smaller disks where a torus bends more, still covered") {
    // An ellipsoid 1 x 1 x 3: largest curvature 3 at the tips, 1 around the waist.
    ks::PointCloud in = fibonacci_sphere(400);
    for (ks::Vec3& p : in.points) p.z() *= 3;  // ellipsoid 1 x 1 x 3
    for (std::size_t i = 0; i < in.points.size(); ++i) {
        const ks::Vec3& p = in.points[i];
        in.normals[i] = ks::Vec3(p.x(), p.y(), p.z() / 9).normalized();
    }
    const ks::SurfelFillResult r = ks::fill_surfel_gaps(in, {.radius = 0.2, .epsilon_r = 0.15});
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.coverage_verified);
    // Radii at the tips (|z| > 2.8, curvature 3) against the waist (|z| < 0.5, curvature ~1).
    double tip = 0, waist = 0;
    std::size_t nt = 0, nw = 0;
    for (std::size_t i = r.input_surfels; i < r.surfels.points.size(); ++i) {
        const double z = std::abs(r.surfels.points[i].z());
        if (z > 2.8) tip += r.surfels.radii[i], ++nt;
        if (z < 0.5) waist += r.surfels.radii[i], ++nw;
    }
    REQUIRE(nt > 0);
    REQUIRE(nw > 0);
    MESSAGE("adaptive: " << r.surfels.points.size() << " surfels, mean radius tip " << tip / nt << " waist " << waist / nw
                         << ", redos " << r.radius_redos);
    CHECK(tip / nt < 0.8 * waist / nw);
    ks::PointCloud dense = fibonacci_sphere(100000);
    for (ks::Vec3& p : dense.points) p.z() *= 3;
    CHECK(ks::surfel_coverage(r.surfels, dense.points).uncovered.empty());

    // The r_new / r' redo. The ellipsoid's curvature changes too slowly for the default
    // threshold 1.5 within one disk (no redo above); at 1.05 the radius computed at
    // p_i exceeds that of a new centre nearer the tip often enough and those fills are
    // redone with r'. With the threshold out of reach no fill is redone: the disks
    // around a surfel all take r_new, so larger disks reach the tips.
    CHECK(r.radius_redos == 0);
    const ks::SurfelFillResult redo =
        ks::fill_surfel_gaps(in, {.radius = 0.2, .epsilon_r = 0.15, .radius_ratio_threshold = 1.05});
    REQUIRE(redo.status == ks::Status::ok);
    CHECK(redo.radius_redos > 0);
    CHECK(redo.coverage_verified);
    CHECK(ks::surfel_coverage(redo.surfels, dense.points).uncovered.empty());
    const ks::SurfelFillResult never = ks::fill_surfel_gaps(in, {.radius = 0.2, .epsilon_r = 0.15, .radius_ratio_threshold = 1e9});
    REQUIRE(never.status == ks::Status::ok);
    CHECK(never.radius_redos == 0);
    CHECK(never.surfels.points == r.surfels.points);  // no redo at 1.5 either: the same fill
    CHECK(redo.surfels.points != never.surfels.points);
    double tip_never = 0;
    std::size_t nt_never = 0;
    for (std::size_t i = never.input_surfels; i < never.surfels.points.size(); ++i)
        if (std::abs(never.surfels.points[i].z()) > 2.8) tip_never += never.surfels.radii[i], ++nt_never;
    REQUIRE(nt_never > 0);
    double tip_redo = 0;
    std::size_t nt_redo = 0;
    for (std::size_t i = redo.input_surfels; i < redo.surfels.points.size(); ++i)
        if (std::abs(redo.surfels.points[i].z()) > 2.8) tip_redo += redo.surfels.radii[i], ++nt_redo;
    REQUIRE(nt_redo > 0);
    MESSAGE("redo at 1.05: " << redo.surfels.points.size() << " surfels, " << redo.radius_redos << " redos, mean radius tip "
                             << tip_redo / nt_redo << "; never: " << never.surfels.points.size()
                             << " surfels, mean radius tip " << tip_never / nt_never);
    CHECK(tip_redo / nt_redo < tip_never / nt_never);
    CHECK(ks::surfel_coverage(never.surfels, dense.points).uncovered.empty());
}

TEST_CASE("surfel_coverage counts the samples inside some disk") {
    ks::PointCloud disks;
    disks.points = {{0, 0, 0}, {2, 0, 0}};
    disks.normals = {{0, 0, 1}, {0, 0, 2}};
    disks.radii = {1.0, 0.5};
    const std::vector<ks::Vec3> samples = {{0.5, 0.5, 0.1},   // in disk 0
                                           {0.9, 0.5, 0},     // outside both (|.| > 1)
                                           {2.4, 0, -0.2},    // in disk 1 (depth 0.2 <= 0.25)
                                           {2, 0, 0.3},       // above disk 1 by more than 0.5 r
                                           {1.3, 0, 0}};      // between them
    const ks::SurfelCoverage c = ks::surfel_coverage(disks, samples);
    CHECK(c.covered == 2);
    CHECK(c.fraction == doctest::Approx(0.4));
    CHECK(c.uncovered == std::vector<std::size_t>{1, 3, 4});
}
