// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Octree RBF (Miura, Sone, Masuda; Carr et al. 2001), the field: interpolation of the
// points and offsets, seams with and without the blend, the cell solve, duplicates,
// smoothing, bad input, determinism (the meshes: test_rbf_surface.cpp).
#include "test_data.hpp"
#include <doctest/doctest.h>

#include "rbf/rbf_test_support.hpp"

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/rbf/rbf_octree.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stop_token>
#include <string>
#include <vector>

namespace ks = kintsugi;
using ks::rbf_test::V;
using ks::rbf_test::diagonal;
using ks::rbf_test::sphere_points;

namespace {

/// Largest jumps of f and ∇f across the faces shared by two live leaves: 9 points on
/// the far face of each of the first max_cells live leaves, evaluated ±1e-9 x the
/// leaf side off it.
std::pair<double, double> seam_jumps(const ks::RBFOctreeField& f, std::size_t max_cells) {
    const auto cells = f.cells();
    auto live_at = [&](const ks::Vec3& y) {
        for (const auto& c : cells)
            if ((y.array() >= c.min.array()).all() && (y.array() < (c.min + ks::Vec3::Constant(c.side)).array()).all())
                return c.live;
        return false;
    };
    double jf = 0, jg = 0;
    std::size_t used = 0;
    for (const auto& c : cells) {
        if (!c.live || used >= max_cells) continue;
        ++used;
        for (int axis = 0; axis < 3; ++axis)
            for (int s = 0; s < 3; ++s)
                for (int t = 0; t < 3; ++t) {
                    ks::Vec3 x = c.min;
                    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
                    x[a1] += c.side * (0.2 + 0.3 * s);
                    x[a2] += c.side * (0.2 + 0.3 * t);
                    x[axis] += c.side;  // the far face
                    ks::Vec3 e = ks::Vec3::Zero();
                    e[axis] = 1e-9 * c.side;
                    const ks::Vec3 y0 = x - e, y1 = x + e;
                    if (!live_at(y1)) continue;
                    jf = std::max(jf, std::abs(f(y1) - f(y0)));
                    jg = std::max(jg, (f.gradient(y1) - f.gradient(y0)).norm());
                }
    }
    return {jf, jg};
}

}  // namespace

TEST_CASE("RBFOctreeField: interpolates the points (|f| <= 1e-6 diag) and the offsets (±d)") {
    V pts, nrm;
    sphere_points(4000, 1, pts, nrm);
    const double diag = diagonal(pts);
    for (const bool blend : {true, false}) {
        CAPTURE(blend);
        const auto res = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 60, .blend = blend});
        REQUIRE(res.status == ks::Status::ok);
        const auto& st = res.stats;
        CHECK(st.points == 4000);
        CHECK(st.merged_points == 0);
        CHECK(st.live_cells > 8);
        CHECK(st.live_cells + st.dead_cells == st.cells);
        CHECK(st.max_points_per_cell <= 60 + 20);
        CHECK(st.ill_conditioned_cells == 0);
        double worst = 0;
        for (const auto& p : pts) worst = std::max(worst, std::abs(res.field(p)));
        CHECK(worst <= 1e-6 * diag);
        // Offsets: centres other than the points carry ±d = ± their distance to the sphere.
        const auto C = res.field.centres();
        CHECK(C.size() == pts.size() + st.offset_points);
        double worst_off = 0;
        for (const auto& c : C) {
            const double sd = (c - ks::Vec3(0.2, -0.1, 0.3)).norm() - 1.0;
            worst_off = std::max(worst_off, std::abs(res.field(c) - sd));
        }
        CHECK(worst_off <= 1e-6 * diag);
        // Between the samples: close to the sphere's signed distance, the right sign.
        std::mt19937_64 rng(9);
        std::normal_distribution<double> g;
        double err = 0, sum = 0;
        for (int i = 0; i < 2000; ++i) {
            const ks::Vec3 v = ks::Vec3(g(rng), g(rng), g(rng)).normalized();
            const ks::Vec3 x = ks::Vec3(0.2, -0.1, 0.3) + v;
            err = std::max(err, std::abs(res.field(x)));
            sum += std::abs(res.field(x));
            CHECK(res.field(x + 0.05 * v) > 0);
            CHECK(res.field(x - 0.05 * v) < 0);
            // Gradient against central differences.
            if (i % 50 == 0) {
                const double h = 1e-6;
                ks::Vec3 fd;
                for (int k = 0; k < 3; ++k) {
                    ks::Vec3 e = ks::Vec3::Zero();
                    e[k] = h;
                    fd[k] = (res.field(x + e) - res.field(x - e)) / (2 * h);
                }
                CHECK((res.field.gradient(x) - fd).norm() <= 1e-4);
                CHECK(res.field.gradient(x).dot(v) > 0.9);
            }
        }
        // 4000 random samples (spacing ~0.056): the RBF between them.
        MESSAGE("sphere: max |f| " << err / diag << " diag, mean " << sum / 2000 / diag);
        CHECK(err <= 1e-3 * diag);
        CHECK(sum / 2000 <= 1e-4 * diag);
    }
}

TEST_CASE("RBFOctreeField: a long offset among dense points (the padding's tree of centres) still interpolates") {
    // Three points 9 units off a sphere of 6,000: their offsets are ~6 long, so the ball
    // that would hold a padded cell's 20 nearest centres covers the whole sphere (> 4,096
    // points) and the padding takes them from a kd-tree of the centres instead. Checked
    // once against brute force while writing this (all 1,484 padded cells: the same sets).
    V pts, nrm;
    sphere_points(6000, 3, pts, nrm, ks::Vec3::Zero());
    for (int i = 0; i < 3; ++i) {
        pts.emplace_back(10 + 0.01 * i, 0.003 * i, 0);
        nrm.emplace_back(1, 0, 0);
    }
    const double diag = diagonal(pts);
    const auto res = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 60});
    REQUIRE(res.status == ks::Status::ok);
    CHECK(res.stats.padded_cells > 100);
    CHECK(res.stats.ill_conditioned_cells == 0);
    double worst = 0;
    for (const auto& p : pts) worst = std::max(worst, std::abs(res.field(p)));
    CHECK(worst <= 1e-6 * diag);
    // Off the samples the sphere's side is still right.
    for (const auto& p : std::vector<ks::Vec3>{{0, 0, 0}, {0.5, 0.2, 0}, {1.2, 0, 0}, {0, -1.3, 0.2}})
        CHECK((res.field(p) < 0) == (p.norm() < 1));
}

TEST_CASE("RBFOctreeField: the blend removes the seams of the paper's per-cell evaluation") {
    V pts, nrm;
    sphere_points(6000, 2, pts, nrm);
    const auto res = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 50});
    REQUIRE(res.status == ks::Status::ok);
    REQUIRE(res.field.blended());
    const auto single = res.field.with_blend(false);
    const auto [bf, bg] = seam_jumps(res.field, 400);
    const auto [sf, sg] = seam_jumps(single, 400);
    MESSAGE("largest jump of f: single cell " << sf << ", blended " << bf << "; of the gradient: " << sg << ", "
                                               << bg);
    CHECK(sf > 0);
    CHECK(bf * 10 <= sf);
    CHECK(bg * 10 <= sg);
    // Same fit: equal at the centres.
    for (std::size_t i = 0; i < pts.size(); i += 97) CHECK(std::abs(single(pts[i]) - res.field(pts[i])) < 1e-9);
}

TEST_CASE("rbf_solve_cell: the null-space solve satisfies the whole saddle system, also in a reused workspace") {
    // Cells as the octree makes them (points on a curved sheet and their offsets ±d, in
    // normalised coordinates). Every row of [A P; Pᵀ 0][w; a] = [v; 0] is checked; the
    // small cell is solved again after a larger one grew the per-thread workspace.
    auto cell = [](int m, unsigned seed, V& u, std::vector<double>& v) {
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> U(-1, 1);
        while (static_cast<int>(u.size()) < m) {
            const double x = U(rng), y = U(rng);
            const double d = 0.05 * static_cast<double>(static_cast<int>(u.size() % 3) - 1);
            u.emplace_back(x, y, 0.3 * std::sin(2 * x) * std::cos(y) + d);
            v.push_back(d);
        }
    };
    auto residual = [](const V& u, const std::vector<double>& v, const std::vector<double>& w,
                       const Eigen::Vector4d& a) {
        double worst = 0;
        Eigen::Vector4d moments = Eigen::Vector4d::Zero();
        for (std::size_t i = 0; i < u.size(); ++i) {
            double f = a[0] + a[1] * u[i].x() + a[2] * u[i].y() + a[3] * u[i].z();
            for (std::size_t j = 0; j < u.size(); ++j) {
                const double r = (u[i] - u[j]).norm();
                f += w[j] * r * r * r;
            }
            worst = std::max(worst, std::abs(f - v[i]));
            moments += w[i] * Eigen::Vector4d(1, u[i].x(), u[i].y(), u[i].z());
        }
        return std::max(worst, moments.cwiseAbs().maxCoeff());
    };
    V us, ub;
    std::vector<double> vs, vb, w1, w2, wb;
    Eigen::Vector4d a1, a2, ab;
    cell(40, 1, us, vs);
    cell(250, 2, ub, vb);
    const auto i1 = ks::detail::rbf_solve_cell(us, vs, 0, w1, a1);
    const auto ib = ks::detail::rbf_solve_cell(ub, vb, 0, wb, ab);
    const auto i2 = ks::detail::rbf_solve_cell(us, vs, 0, w2, a2);
    CHECK_FALSE(i1.ill_conditioned);
    CHECK_FALSE(ib.ill_conditioned);
    CHECK_FALSE(i2.ill_conditioned);
    CHECK(residual(us, vs, w1, a1) <= 1e-10);
    CHECK(residual(ub, vb, wb, ab) <= 1e-10);
    CHECK(w1 == w2);  // bit for bit: the reused workspace leaves no trace
    CHECK(a1 == a2);
    // Coplanar centres (P rank-deficient): counted, and a finite fit.
    V flat;
    std::vector<double> vf, wf;
    Eigen::Vector4d af;
    for (int i = 0; i < 30; ++i) {
        flat.emplace_back(std::cos(i * 0.7) * 0.9, std::sin(i * 1.3) * 0.9, 0.0);
        vf.push_back(0.01 * i);
    }
    CHECK(ks::detail::rbf_solve_cell(flat, vf, 0, wf, af).ill_conditioned);
    CHECK(wf.size() == flat.size());
    CHECK(std::all_of(wf.begin(), wf.end(), [](double x) { return std::isfinite(x); }));
    CHECK(af.allFinite());
}

TEST_CASE("RBFOctreeField: duplicates and near-duplicates are merged, never a NaN") {
    V pts, nrm;
    sphere_points(2000, 3, pts, nrm);
    const std::size_t n0 = pts.size();
    for (std::size_t i = 0; i < n0; i += 4) {
        pts.push_back(pts[i]);  // exact duplicate, opposite normal
        nrm.push_back(-nrm[i]);
        pts.push_back(pts[i] + ks::Vec3(1e-9, -1e-9, 0));  // near-duplicate
        nrm.push_back(nrm[i]);
    }
    const auto res = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 40});
    REQUIRE(res.status == ks::Status::ok);
    CHECK(res.stats.merged_points == 1000);
    CHECK(res.stats.ill_conditioned_cells == 0);
    for (const auto& p : pts) {
        CHECK(std::isfinite(res.field(p)));
        CHECK(std::abs(res.field(p)) <= 1e-6);
    }
    // A degenerate cell (all its centres coplanar) still gives a finite field.
    V flat, fn;
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) {
            flat.emplace_back(i, j, 0);
            fn.emplace_back(0, 0, 1);
        }
    const auto r2 = ks::RBFOctreeField::build(ks::with_normals(flat, fn), {.n_max = 10});
    REQUIRE(r2.status == ks::Status::ok);
    for (double z : {-1.0, -0.1, 0.1, 1.0}) {
        const double f = r2.field(ks::Vec3(2.5, 2.5, z));
        CHECK(std::isfinite(f));
        CHECK((f > 0) == (z > 0));
    }
}

TEST_CASE("RBFOctreeField: a cluster of copies is merged in linear time, also at merge_distance = 0") {
    V pts, nrm;
    sphere_points(3000, 13, pts, nrm);
    const double diag = diagonal(pts);
    const ks::Vec3 p0 = pts[7], n0 = nrm[7];
    // 20,000 copies of one point, then 3,000 near-copies spread over 1e-9 along a line
    // (the pairwise merge of the first would visit 4e8 pairs; without a merge at 0 the
    // copies would form one dense cell of identical centres). Kept at merge_distance 0,
    // the near-copies and their offsets (9,000 centres) cannot be split by the 20 levels
    // of the octree: before the cap on such cells their dense fallback solve, cubic in
    // the cell's size, took 21 s CPU at 1,000 near-copies (Release) and over 20 minutes
    // at 2,000 under ASan.
    for (int i = 0; i < 20000; ++i) {
        pts.push_back(p0);
        nrm.push_back(i % 2 ? n0 : ks::Vec3(-n0));
    }
    const ks::Vec3 p1 = pts[11];
    constexpr int near_copies = 3000;
    for (int i = 1; i <= near_copies; ++i) {
        pts.push_back(p1 + ks::Vec3(1e-9 * i / near_copies, 0, 0));
        nrm.push_back(nrm[11]);
    }
    for (const double md : {1e-6, 0.0}) {
        CAPTURE(md);
        const auto res = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 60, .merge_distance = md});
        REQUIRE(res.status == ks::Status::ok);
        // at 0 only the exact copies go
        CHECK(res.stats.merged_points == (md > 0 ? 20000u + near_copies : 20000u));
        // No system is larger than n_max: at 0 the cells holding the near-copies are
        // capped (each drops all but at most 60 of its ~9,000 centres), at 1e-6 none is.
        CHECK(res.stats.max_points_per_cell <= 60);
        if (md > 0) {
            CHECK(res.stats.ill_conditioned_cells == 0);
            CHECK(res.stats.capped_cells == 0);
            CHECK(res.stats.capped_centres == 0);
        } else {
            CHECK(res.stats.capped_cells >= 1);
            CHECK(res.stats.capped_centres >= 3 * near_copies - 60);
            CHECK(res.stats.depth == 20);
            // The near-copies lie within 1e-9 of points the field interpolates.
            for (std::size_t i = 23000; i < pts.size(); i += 97) {
                const double f = res.field(pts[i]);
                CHECK(std::isfinite(f));
                CHECK(std::abs(f) <= 1e-6 * diag);
                CHECK(res.field.gradient(pts[i]).allFinite());
            }
        }
        CHECK(std::abs(res.field(p0)) <= 1e-6 * diag);
        for (std::size_t i = 0; i < 3000; i += 7) CHECK(std::abs(res.field(pts[i])) <= 1e-6 * diag);
        CHECK(std::abs(res.field(p1)) <= 1e-6 * diag);
    }
    // Cancellation during the duplicate search.
    ks::RBFOctreeParams prm{.n_max = 60};
    prm.control.progress = [](const ks::ProgressEvent& e) { return e.stage != std::string_view("rbf_offsets"); };
    CHECK(ks::RBFOctreeField::build(ks::with_normals(pts, nrm), prm).status == ks::Status::cancelled);
    // Fewer than 4 distinct points after the merge.
    const V few{p0, p0, p0, p1, p1, ks::Vec3(p1 + ks::Vec3(1e-12, 0, 0)), ks::Vec3(0, 0, 0)};
    const V few_n(few.size(), ks::Vec3(0, 0, 1));
    CHECK_THROWS_WITH_AS(ks::RBFOctreeField::build(ks::with_normals(few, few_n)),
                         doctest::Contains("needs at least 4 distinct points, got 3"), ks::invalid_input);
}

TEST_CASE("RBFOctreeField: smoothing λ > 0 brings the surface closer to the truth on noisy samples") {
    // 8,000 points of the unit sphere moved along the normal by Gaussian noise of
    // 0.5 % of the radius (exact normals). λ = 0 interpolates the noise; λ = 0.1 (in
    // the cells' normalised units) follows it less.
    V pts, nrm;
    std::mt19937_64 rng(21);
    std::normal_distribution<double> g;
    for (int i = 0; i < 8000; ++i) {
        const ks::Vec3 v = ks::Vec3(g(rng), g(rng), g(rng)).normalized();
        pts.push_back(v * (1 + 0.005 * g(rng)));
        nrm.push_back(v);
    }
    std::array<double, 2> on_truth{}, at_samples{};
    for (const int k : {0, 1}) {
        const auto r = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 100, .smoothing = k ? 0.1 : 0.0});
        REQUIRE(r.status == ks::Status::ok);
        std::mt19937_64 r2(5);
        for (int i = 0; i < 4000; ++i) {  // |f| on the true sphere ≈ its distance to the zero set
            const ks::Vec3 v = ks::Vec3(g(r2), g(r2), g(r2)).normalized();
            on_truth[k] += std::abs(r.field(v)) / 4000;
        }
        for (const auto& p : pts) at_samples[k] += std::abs(r.field(p)) / 8000;
    }
    MESSAGE("noisy sphere: mean |f| on the true sphere " << on_truth[0] << " (λ = 0), " << on_truth[1]
                                                        << " (λ = 0.1)");
    CHECK(at_samples[0] <= 1e-9);  // λ = 0 interpolates
    CHECK(at_samples[1] >= 1e-4);  // λ > 0 does not
    CHECK(on_truth[1] <= 0.6 * on_truth[0]);
}

TEST_CASE("RBFOctreeField: identical with 1 and 2 threads at 40K points (chunked octree lists)") {
    V pts, nrm;
    sphere_points(40000, 14, pts, nrm);
    std::vector<std::vector<double>> values;
    for (const int threads : {1, 2}) {
        const ks::ThreadLimit limit(threads);
        const auto r = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 80});
        REQUIRE(r.status == ks::Status::ok);
        std::vector<double> v;
        for (std::size_t i = 0; i < pts.size(); i += 13) v.push_back(r.field(1.01 * pts[i] - 0.003 * nrm[i]));
        for (const auto& c : r.field.cells()) v.push_back(c.side + static_cast<double>(c.centres));
        values.push_back(std::move(v));
    }
    REQUIRE(values[0].size() == values[1].size());
    CHECK(std::memcmp(values[0].data(), values[1].data(), values[0].size() * sizeof(double)) == 0);
}

TEST_CASE("RBFOctreeField: bit-identical with 1 and 2 threads") {
    V pts, nrm;
    sphere_points(5000, 8, pts, nrm);
    std::vector<ks::RBFReconstructResult> runs;
    for (const int threads : {1, 2}) {
        const ks::ThreadLimit limit(threads);
        runs.push_back(ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.n_max = 50, .resolution = 40}));
        REQUIRE(runs.back().status == ks::Status::ok);
    }
    const auto& a = runs[0].mesh;
    const auto& b = runs[1].mesh;
    CHECK(a.faces == b.faces);
    REQUIRE(a.vertices.size() == b.vertices.size());
    CHECK(std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(ks::Vec3)) == 0);
}

TEST_CASE("RBFOctreeField: coordinates of any magnitude give the same field up to scale") {
    V pts, nrm;
    sphere_points(2000, 10, pts, nrm);
    const auto ref = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), {.n_max = 60});
    for (const double s : {0x1p-60, 0x1p70}) {
        V q = pts;
        for (auto& p : q) p *= s;
        const auto r = ks::RBFOctreeField::build(ks::with_normals(q, nrm), {.n_max = 60});
        REQUIRE(r.status == ks::Status::ok);
        CHECK(r.stats.cells == ref.stats.cells);
        const ks::Vec3 x(0.5, 0.4, -0.3);
        CHECK(r.field(x * s) / s == doctest::Approx(ref.field(x)).epsilon(1e-9));
    }
}

TEST_CASE("RBFOctreeField: bad input throws invalid_input naming the fix, input untouched") {
    V pts, nrm;
    sphere_points(200, 11, pts, nrm);
    const V pts0 = pts, nrm0 = nrm;
    auto expect = [&](const V& p, const V& n, const ks::RBFOctreeParams& prm, const std::string& what) {
        CAPTURE(what);
        try {
            (void)ks::RBFOctreeField::build(ks::with_normals(p, n), prm);
            FAIL("no exception");
        } catch (const ks::invalid_input& e) {
            const std::string msg = e.what();
            CHECK(msg.find("kintsugi::RBFOctreeField::build") != std::string::npos);
            CHECK(msg.find(what) != std::string::npos);
        }
    };
    expect(pts, nrm, {.n_max = 9}, "n_max = 9 is below 10");
    expect(pts, nrm, {.overlap = 0.9}, "overlap = 0.9 must lie in [1, 3]");
    expect(pts, nrm, {.activity = 0.5}, "activity = 0.5 must lie in [1, 3]");
    expect(pts, nrm, {.root_size = 0}, "root_size");
    // 1e-7 would ask for 1e21 root cubes.
    expect(pts, nrm, {.root_size = 1e-7}, "root_size = 1e-07 must lie in [1/64, 1]");
    // Boxes above 3 x the cell reach past the neighbours the binning and the blend visit.
    expect(pts, nrm, {.overlap = 3.5}, "overlap = 3.5 must lie in [1, 3]");
    expect(pts, nrm, {.activity = 4}, "activity = 4 must lie in [1, 3]");
    expect(pts, nrm, {.offset_scale = -1}, "offset_scale");
    expect(pts, nrm, {.smoothing = -1}, "smoothing");
    expect(pts, nrm, {.merge_distance = std::nan("")}, "merge_distance");
    expect(V(pts.begin(), pts.begin() + 3), V(nrm.begin(), nrm.begin() + 3), {}, "at least 4 points");
    expect(pts, V{}, {}, "estimate oriented normals");
    V bad = pts;
    bad[17].y() = std::nan("");
    expect(bad, nrm, {}, "point 17 has a NaN");
    V badn = nrm;
    badn[5] = ks::Vec3::Zero();
    expect(pts, badn, {}, "the normal of point 5 is zero");
    CHECK(pts == pts0);
    CHECK(nrm == nrm0);
    // The CLI-facing function names itself and checks the resolution.
    CHECK_THROWS_WITH_AS(ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.resolution = 4}),
                         doctest::Contains("kintsugi::reconstruct_rbf_octree: resolution = 4"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.n_max = 3}),
                         doctest::Contains("n_max = 3 is below 10"), ks::invalid_input);
}
