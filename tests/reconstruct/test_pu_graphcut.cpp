// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// PU + graph-cut reconstruction (Nagai, Ohtake, Suzuki 2011): accuracy with outliers,
// the output guarantee, the graph cut against the plain sign, containers,
// determinism, bad input, cancellation.
#include <doctest/doctest.h>

#include "reconstruct/pu_test_data.hpp"
#include "test_data.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/reconstruct/pu_graphcut.hpp>

#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <stop_token>
#include <string>
#include <vector>

namespace ks = kintsugi;
using kintsugi_test::Shape;
using kintsugi_test::check_guarantee;
using kintsugi_test::holey_noisy_sample;

namespace {

struct Outcome {
    std::size_t components = 0;
    long genus = -2;
    double mean = 0, max = 0;  // relative to the diagonal
};

Outcome run_shape(const Shape& s, ks::Labeling labeling, ks::PUGraphcutResult* keep = nullptr,
                  double far_site_band = ks::PUGraphcutParams{}.far_site_band, std::size_t samples = 20000) {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(s, samples, 0.001, 0.10, 42, pts, nrm);
    const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm),
                                               {.labeling = labeling, .far_site_band = far_site_band});
    REQUIRE(r.status == ks::Status::ok);
    Outcome o;
    const auto rep = check_guarantee(r.mesh);
    o.components = rep.components;
    o.genus = rep.genus;
    kintsugi_test::distance_to_shape(r.mesh, s, o.mean, o.max);
    o.mean /= s.diagonal();
    o.max /= s.diagonal();
    if (keep) *keep = r;
    return o;
}

/// Step 8 off and on (the defaults) on the same 20K samples of a shape, without outliers.
struct CoarseFine {
    ks::PUGraphcutResult coarse, fine;
    double coarse_mean = 0, coarse_max = 0, fine_mean = 0, fine_max = 0;  // in the shape's units
};

CoarseFine coarse_and_fine(const Shape& shape, double noise, std::uint64_t seed) {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(shape, 20000, noise, 0.0, seed, pts, nrm);
    CoarseFine r;
    r.coarse = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), {.refine_spacing = 0});
    r.fine = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm));
    REQUIRE(r.coarse.status == ks::Status::ok);
    REQUIRE(r.fine.status == ks::Status::ok);
    kintsugi_test::distance_to_shape(r.coarse.mesh, shape, r.coarse_mean, r.coarse_max);
    kintsugi_test::distance_to_shape(r.fine.mesh, shape, r.fine_mean, r.fine_max);
    return r;
}

}  // namespace

TEST_CASE("reconstruct_pu_graphcut: sphere with 10 % outliers -> one closed genus-0 surface") {
    ks::PUGraphcutResult r;
    const Shape sphere{0};
    const Outcome gc = run_shape(sphere, ks::Labeling::graphcut, &r);
    MESSAGE("sphere graphcut: components " << gc.components << " mean " << gc.mean << " max " << gc.max);
    CHECK(gc.components == 1);
    CHECK(gc.genus == 0);
    // Measured: mean 0.054 %, max 0.82 % of the diagonal.
    CHECK(gc.mean <= 0.001);
    CHECK(gc.max <= 0.012);
    // counts are filled and consistent
    CHECK(r.points == 22000);
    CHECK(r.supports > 0);
    CHECK(r.supports <= r.octree_cells);
    CHECK(r.graph_nodes == r.supports - r.hidden_supports - r.thinned_supports + r.outer_vertices);
    CHECK(r.thinned_supports > 0);
    CHECK(r.graph_edges > r.graph_nodes);
    CHECK(r.cut_value > 0);
    CHECK(r.parts == 1);
    CHECK(r.far_points == 0);
    CHECK(r.smoothed_vertices > 0);
    CHECK(r.smoothed_vertices <= r.mesh.vertices.size());
    std::vector<std::string> stages;
    for (const auto& t : r.timings) stages.push_back(t.stage);
    CHECK(stages == std::vector<std::string>{"pu_octree", "pu_cover", "pu_index", "triangulation", "graph_cut",
                                             "marching_tetrahedra", "smoothing", "handles", "refine"});
    // The plain sign of the PU field (the paper's "PU only") is measurably worse.
    ks::PUGraphcutResult rs;
    const Outcome sign = run_shape(sphere, ks::Labeling::sign, &rs);
    MESSAGE("sphere sign: components " << sign.components << " mean " << sign.mean << " handles removed "
                                       << rs.handles_removed);
    CHECK(sign.components > gc.components);
    CHECK(sign.mean > 5 * gc.mean);
    CHECK(rs.thinned_supports == 0);  // the sign of every support decides: none is thinned
    // Its surface is perforated by hundreds of small handles (genus 440 over 18
    // components, measured): step 7 removes nearly all (430) without splitting any.
    CHECK(rs.handles_removed >= 400);
}

TEST_CASE("reconstruct_pu_graphcut: far sites thinned — fewer graph nodes, the same surface") {
    // The torus with 10 % outliers with every support a vertex (far_site_band 0, the
    // paper) and with the far untrusted ones thinned (the default).
    const Shape torus{1};
    ks::PUGraphcutResult all, thin;
    const Outcome a = run_shape(torus, ks::Labeling::graphcut, &all, 0, 60000);
    const Outcome t = run_shape(torus, ks::Labeling::graphcut, &thin, ks::PUGraphcutParams{}.far_site_band, 60000);
    MESSAGE("torus, every support: nodes " << all.graph_nodes << " mean " << a.mean << " max " << a.max
                                           << "; thinned " << thin.thinned_supports << ": nodes " << thin.graph_nodes
                                           << " mean " << t.mean << " max " << t.max);
    CHECK(all.thinned_supports == 0);
    CHECK(all.graph_nodes == all.supports - all.hidden_supports + all.outer_vertices);
    CHECK(thin.supports == all.supports);  // the field is the same
    CHECK(thin.graph_nodes == thin.supports - thin.hidden_supports - thin.thinned_supports + thin.outer_vertices);
    // Measured: 816 of 29.5K supports thinned here (the band, 8 trusted radii, spans most of
    // this small box); 343K of 609K in the 2M bench input at level 9.
    CHECK(thin.thinned_supports > 0);
    CHECK(t.components == 1);
    CHECK(t.genus == 1);
    CHECK(t.mean <= 1.1 * a.mean);
    CHECK(t.max <= 1.1 * a.max);
}

TEST_CASE("reconstruct_pu_graphcut: torus with 10 % outliers -> one closed genus-1 surface") {
    const Shape torus{1};
    const Outcome gc = run_shape(torus, ks::Labeling::graphcut);
    MESSAGE("torus graphcut: components " << gc.components << " mean " << gc.mean << " max " << gc.max);
    CHECK(gc.components == 1);
    CHECK(gc.genus == 1);
    // Measured: mean 0.046 %, max 0.35 % of the diagonal.
    CHECK(gc.mean <= 0.001);
    CHECK(gc.max <= 0.006);
    const Outcome sign = run_shape(torus, ks::Labeling::sign);
    MESSAGE("torus sign: components " << sign.components << " mean " << sign.mean);
    CHECK(sign.components > gc.components);
    CHECK(sign.mean > 5 * gc.mean);
}

TEST_CASE("reconstruct_pu_graphcut: step 8 puts clean data's surface at the samples' resolution, same topology") {
    // Clean oriented points (no noise, no outliers): the surface of steps 6-7 is cut
    // along the support triangulation's edges; step 8 refines it to the samples'
    // spacing and moves it onto their MLS surface.
    for (const int kind : {0, 1}) {
        CAPTURE(kind);
        const Shape shape{kind};
        const CoarseFine cf = coarse_and_fine(shape, 0.0, 5);
        const auto& coarse = cf.coarse;
        const auto& fine = cf.fine;
        const double mc = cf.coarse_mean, xc = cf.coarse_max, mf = cf.fine_mean, xf = cf.fine_max;
        const auto rc = check_guarantee(coarse.mesh), rf = check_guarantee(fine.mesh);
        CHECK(rc.components == 1);
        CHECK(rf.components == 1);
        CHECK(rf.genus == kind);
        CHECK(rc.genus == kind);
        MESSAGE("clean " << std::string(kind ? "torus" : "sphere") << ": vertices " << coarse.mesh.vertices.size() << " -> "
                         << fine.mesh.vertices.size() << ", mean " << mc / shape.diagonal() << " -> "
                         << mf / shape.diagonal() << ", max " << xc / shape.diagonal() << " -> "
                         << xf / shape.diagonal() << ", refined " << fine.refined_vertices);
        CHECK(coarse.refined_vertices == 0);
        CHECK(fine.refined_vertices > fine.mesh.vertices.size() * 9 / 10);
        // No noise: the fit keeps its 20 neighbours.
        CHECK(fine.refine_noise_ratio < 0.1);
        CHECK(fine.refine_neighbors_used == 20);
        CHECK(fine.mesh.vertices.size() > 2 * coarse.mesh.vertices.size());
        CHECK(mf < mc / 3);
        CHECK(xf <= xc);
    }
}

TEST_CASE("reconstruct_pu_graphcut: step 8 with every point given 10 times, and beside a dense cluster, stays bounded") {
    // Copies of a point brought the spacing (the radius of 8 neighbours) to 0, and the
    // splits doubled the mesh for 30 rounds (the kitten with each point 10 times: 23 GB).
    std::vector<ks::Vec3> pts, nrm;
    const Shape sphere{0};
    kintsugi_test::sample_shape(sphere, 3000, 0.0, 0.0, 3, pts, nrm);
    const auto once = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm));
    std::vector<ks::Vec3> p10, n10;
    for (int c = 0; c < 10; ++c) {
        p10.insert(p10.end(), pts.begin(), pts.end());
        n10.insert(n10.end(), nrm.begin(), nrm.end());
    }
    const auto ten = ks::reconstruct_pu_graphcut(ks::with_normals(p10, n10));
    REQUIRE(ten.status == ks::Status::ok);
    const auto r10 = check_guarantee(ten.mesh);
    CHECK(r10.components == 1);
    CHECK(r10.genus == 0);
    CHECK_FALSE(ten.refine_budget_reached);
    MESSAGE("3,000 points once: " << once.mesh.vertices.size() << " vertices; each 10 times: " << ten.mesh.vertices.size());
    CHECK(ten.mesh.vertices.size() < 2 * once.mesh.vertices.size());
    CHECK(ten.refined_vertices > ten.mesh.vertices.size() / 2);
    double mean = 0, max = 0;
    kintsugi_test::distance_to_shape(ten.mesh, sphere, mean, max);
    CHECK(mean < 0.002 * sphere.diagonal());

    // Near-duplicates (copies 1e-9 of the diagonal apart) and a cluster 1000 times denser than
    // the rest read a spacing far below the surface's: the splits stop at the vertex budget.
    std::vector<ks::Vec3> pc = pts, nc = nrm;
    for (int i = 0; i < 20000; ++i) {
        const ks::Vec3 d = nrm[static_cast<std::size_t>(i) % 50];
        pc.push_back(pts[static_cast<std::size_t>(i) % 50] + 1e-9 * sphere.diagonal() * static_cast<double>(i / 50) * d.unitOrthogonal());
        nc.push_back(d);
    }
    const auto dense = ks::reconstruct_pu_graphcut(ks::with_normals(pc, nc));
    REQUIRE(dense.status == ks::Status::ok);
    MESSAGE("with 20,000 near-duplicates of 50 points: " << dense.mesh.vertices.size() << " vertices, budget reached "
                                                        << dense.refine_budget_reached);
    CHECK(check_guarantee(dense.mesh).components == 1);
    CHECK(dense.refine_budget_reached);
    // The budget: the mesh's vertices plus 4 per sample of the fit (at most the 23,000 points).
    CHECK(dense.mesh.vertices.size() <= 4 * pc.size() + 2 * once.mesh.vertices.size());
}

TEST_CASE("reconstruct_pu_graphcut: step 8 on data denser than their noise widens its fit") {
    // The sphere, 20K points with noise of 0.4 % of the diagonal (about a quarter of the
    // samples' spacing): a 20-point fit would follow the noise; step 8 measures it and takes more
    // neighbours, and the refined surface is no farther from the sphere than the coarse one.
    const Shape sphere{0};
    const CoarseFine cf = coarse_and_fine(sphere, 0.004, 9);
    const auto& fine = cf.fine;
    const double mc = cf.coarse_mean, mf = cf.fine_mean;
    const auto rf = check_guarantee(fine.mesh);
    CHECK(rf.components == 1);
    CHECK(rf.genus == 0);
    MESSAGE("noisy sphere: noise / spacing " << fine.refine_noise_ratio << ", neighbours " << fine.refine_neighbors_used
                                             << ", mean " << mc / sphere.diagonal() << " -> " << mf / sphere.diagonal());
    CHECK(fine.refine_noise_ratio > 0.25);
    CHECK(fine.refine_neighbors_used > 20);
    CHECK(fine.refined_vertices > fine.mesh.vertices.size() / 2);
    CHECK(mf <= mc);
}

TEST_CASE("reconstruct_pu_graphcut: step 8's group means are unbiased along the normal and keep thin walls apart") {
    // A tilted plane sampled on a jittered grid of spacing s with Gaussian noise sigma =
    // s / 2 in every direction; groups of side h = 2 s. A cube cut through the noisy slab
    // is biased along the normal; a column is not, so the means' offsets from the plane
    // average to about 0 and their spread is about sigma / sqrt(group size).
    const ks::Vec3 n = ks::Vec3(1, 2, 3).normalized();
    const ks::Vec3 t1 = n.unitOrthogonal(), t2 = n.cross(t1);
    const double s = 0.01, sigma = 0.5 * s, h = 2 * s;
    std::mt19937_64 rng(5);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(-0.5, 0.5);
    std::vector<ks::Vec3> pts, nrm;
    for (int i = 0; i < 200; ++i)
        for (int j = 0; j < 200; ++j) {
            pts.push_back((i + u(rng)) * s * t1 + (j + u(rng)) * s * t2 + sigma / std::sqrt(3.0) * ks::Vec3(g(rng), g(rng), g(rng)));
            nrm.push_back(n);
        }
    const auto [means, mn] = ks::detail::column_means(pts, nrm, h);
    REQUIRE(means.size() == mn.size());
    const double per_group = static_cast<double>(pts.size()) / static_cast<double>(means.size());
    double sum = 0, sum2 = 0;
    for (std::size_t i = 0; i < means.size(); ++i) {
        const double d = n.dot(means[i]);
        sum += d;
        sum2 += d * d;
        CHECK(mn[i].isApprox(n));
    }
    const double mean = sum / static_cast<double>(means.size());
    const double rms = std::sqrt(sum2 / static_cast<double>(means.size()));
    const double sigma_n = sigma / std::sqrt(3.0);  // the noise along the normal
    MESSAGE("column means: " << means.size() << " groups of " << per_group << " samples; offset mean " << mean / sigma_n
                             << " sigma, rms " << rms / sigma_n << " sigma");
    CHECK(per_group > 3);
    CHECK(per_group < 12);
    CHECK(std::abs(mean) < 0.02 * sigma_n);
    CHECK(rms < 1.3 * sigma_n / std::sqrt(per_group));

    // Two sides of a thin wall, 0.3 h apart with opposite normals: no mean between them.
    std::vector<ks::Vec3> wall, wn;
    for (int i = 0; i < 100; ++i)
        for (int j = 0; j < 100; ++j)
            for (int side = 0; side < 2; ++side) {
                wall.push_back(ks::Vec3((i + u(rng)) * s, (j + u(rng)) * s, side * 0.3 * h));
                wn.push_back(ks::Vec3(0, 0, side ? 1 : -1));
            }
    const auto [wm, wmn] = ks::detail::column_means(wall, wn, h);
    for (std::size_t i = 0; i < wm.size(); ++i) {
        const bool top = wmn[i].z() > 0;
        CHECK(std::abs(wm[i].z() - (top ? 0.3 * h : 0.0)) < 1e-12);
    }

    // An isolated sample (an outlier that passed the inlier test) is a group of one: kept
    // with min_count 1, dropped with 2, while the plane's groups stay.
    std::vector<ks::Vec3> lone = pts, lone_n = nrm;
    lone.push_back(ks::Vec3(5, 5, 5));
    lone_n.push_back(n);
    const auto with1 = ks::detail::column_means(lone, lone_n, h, 1).first;
    const auto with2 = ks::detail::column_means(lone, lone_n, h, 2).first;
    const auto far = [](const std::vector<ks::Vec3>& v) {
        return std::count_if(v.begin(), v.end(), [](const ks::Vec3& p) { return p.norm() > 5; });
    };
    CHECK(far(with1) == 1);
    CHECK(far(with2) == 0);
    CHECK(with2.size() > with1.size() * 3 / 4);

    // A side too small for 64-bit cell coordinates: every sample is its own group.
    const auto tiny = ks::detail::column_means(pts, nrm, 1e-300);
    CHECK(tiny.first.size() == pts.size());
    CHECK(tiny.first[7] == pts[7]);
    CHECK(ks::detail::column_means(pts, nrm, 1e-300, 2).first.empty());
}

TEST_CASE("reconstruct_pu_graphcut: a second object 20x smaller, sampled with the part and 10 % outliers, is kept") {
    // The torus (20K points, 0.1 % noise) and a sphere of radius 0.07 (3,000 points, the
    // same noise in absolute terms), 0.8 beyond the torus, plus 10 % uniform outliers over
    // both: the outliers leave no empty slab, so both are one part and one triangulation.
    std::vector<ks::Vec3> pts, nrm, sp, sn;
    kintsugi_test::sample_shape(Shape{1}, 20000, 0.001, 0.0, 1, pts, nrm);
    kintsugi_test::sample_shape(Shape{0}, 3000, 0.0, 0.0, 101, sp, sn);
    std::mt19937_64 rng(1);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(0, 1);
    const double sigma = 0.001 * Shape{1}.diagonal() / std::sqrt(3.0);
    const ks::Vec3 centre(2.2, 0, 0);
    constexpr double radius = 0.07;
    for (std::size_t i = 0; i < sp.size(); ++i) {
        pts.push_back(centre + radius * sp[i] + sigma * ks::Vec3(g(rng), g(rng), g(rng)));
        nrm.push_back(sn[i]);
    }
    ks::BoundingBox box;
    for (const auto& p : pts) box.extend(p);
    const ks::Vec3 c = box.center(), e = 1.1 * box.extent();
    for (std::size_t i = 0, m = pts.size() / 10; i < m; ++i) {
        pts.push_back(c + ks::Vec3((u(rng) - .5) * e.x(), (u(rng) - .5) * e.y(), (u(rng) - .5) * e.z()));
        nrm.push_back(ks::Vec3(g(rng), g(rng), g(rng)).normalized());
    }
    const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm));
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.parts == 1);
    CHECK(r.removed_regions == 0);
    const auto rep = check_guarantee(r.mesh);
    MESSAGE("torus + small sphere: components " << rep.components << " genus " << rep.genus);
    CHECK(rep.components == 2);
    // Each component on its own: the faces with a vertex beyond x = 1.8 are the sphere's.
    ks::IndexedMesh part[2];
    for (int k = 0; k < 2; ++k) part[k].vertices = r.mesh.vertices;
    for (const auto& f : r.mesh.faces) part[r.mesh.vertices[f[0]].x() > 1.8 ? 1 : 0].faces.push_back(f);
    REQUIRE(!part[1].faces.empty());
    const auto torus_rep = ks::topology_report(part[0]), sphere_rep = ks::topology_report(part[1]);
    CHECK(torus_rep.components == 1);
    CHECK(torus_rep.closed);
    CHECK(torus_rep.genus == 1);
    CHECK(sphere_rep.components == 1);
    CHECK(sphere_rep.closed);
    CHECK(sphere_rep.genus == 0);
    double torus_max = 0, sphere_mean = 0;
    std::size_t sphere_n = 0;
    for (const auto& f : part[0].faces)
        for (const auto v : f) torus_max = std::max(torus_max, Shape{1}.distance(r.mesh.vertices[v]));
    for (const auto& f : part[1].faces)
        for (const auto v : f) {
            sphere_mean += std::abs((r.mesh.vertices[v] - centre).norm() - radius);
            ++sphere_n;
        }
    sphere_mean /= static_cast<double>(sphere_n);
    MESSAGE("torus max distance " << torus_max << ", sphere mean |r - 0.07| " << sphere_mean);
    CHECK(torus_max < 0.006 * Shape{1}.diagonal());
    CHECK(sphere_mean < 0.1 * radius);
    // The former rule (a region under 1 % of the largest is a speck, whatever the data)
    // deleted the sphere: its 18-27 inside vertices are all trusted supports.
    const auto old = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm),
                                                 {.min_region_supports = std::numeric_limits<std::size_t>::max()});
    REQUIRE(old.status == ks::Status::ok);
    CHECK(old.removed_regions == 1);
    CHECK(ks::topology_report(old.mesh).components == 1);
    // Specks are still removed: with a weak trust (3 points, any normals) the sphere with
    // 25 % outliers leaves many outlier specks (measured 21, holding at most 3 trusted
    // supports and never half of their vertices); the data-based rule removes every one
    // the size rule alone removes.
    std::vector<ks::Vec3> sp25, sn25;
    kintsugi_test::sample_shape(Shape{0}, 20000, 0.001, 0.25, 42, sp25, sn25);
    ks::PUGraphcutParams weak{.min_support_points = 3, .min_support_coherence = 0};
    const auto data_rule = ks::reconstruct_pu_graphcut(ks::with_normals(sp25, sn25), weak);
    weak.min_region_supports = std::numeric_limits<std::size_t>::max();
    const auto size_rule = ks::reconstruct_pu_graphcut(ks::with_normals(sp25, sn25), weak);
    MESSAGE("weak trust, 25 % outliers: specks removed " << data_rule.removed_regions << " (size rule alone "
                                                         << size_rule.removed_regions << ")");
    CHECK(size_rule.removed_regions >= 10);
    CHECK(data_rule.removed_regions == size_rule.removed_regions);
    CHECK(data_rule.mesh.faces == size_rule.mesh.faces);
}

TEST_CASE("reconstruct_pu_graphcut: inward normals give the same surface") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{0}, 4000, 0.001, 0.0, 5, pts, nrm);
    const auto out = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), {.max_level = 6});
    for (auto& n : nrm) n = -n;
    const auto in = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm),
                                                {.max_level = 6, .normals = ks::NormalConvention::inward});
    CHECK(in.mesh.faces == out.mesh.faces);
    CHECK(in.mesh.vertices == out.mesh.vertices);
    check_guarantee(in.mesh);
}

namespace {
struct UserSample {
    float xyz[3];
    std::array<double, 3> n;
    int tag;
};
using Kernel = CGAL::Simple_cartesian<double>;
}  // namespace

TEST_CASE("reconstruct_pu_graphcut: any container gives the identical mesh; output into CGAL::Surface_mesh") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{1}, 5000, 0.001, 0.05, 9, pts, nrm);
    // float coordinates for every container, so all see the same input
    auto round_to_float = [](double x) {
        volatile float f = static_cast<float>(x);  // volatile: GCC 12 -O2 folds the double->float->double round trip
        return static_cast<double>(f);
    };
    for (auto& p : pts) p = ks::Vec3(round_to_float(p.x()), round_to_float(p.y()), round_to_float(p.z()));
    const ks::PUGraphcutParams params{.max_level = 7};
    std::vector<Eigen::Vector3d> vp(pts.begin(), pts.end()), vn(nrm.begin(), nrm.end());
    const auto a = ks::reconstruct_pu_graphcut(ks::with_normals(vp, vn), params);
    REQUIRE(a.status == ks::Status::ok);
    check_guarantee(a.mesh);

    CGAL::Point_set_3<Kernel::Point_3, Kernel::Vector_3> ps;
    ps.add_normal_map();
    for (std::size_t i = 0; i < pts.size(); ++i)
        ps.insert(Kernel::Point_3(pts[i].x(), pts[i].y(), pts[i].z()),
                  Kernel::Vector_3(nrm[i].x(), nrm[i].y(), nrm[i].z()));
    const auto b = ks::reconstruct_pu_graphcut(ps, params);
    CHECK(b.mesh.vertices == a.mesh.vertices);
    CHECK(b.mesh.faces == a.mesh.faces);

    std::vector<UserSample> user;
    for (std::size_t i = 0; i < pts.size(); ++i)
        user.push_back({{static_cast<float>(pts[i].x()), static_cast<float>(pts[i].y()), static_cast<float>(pts[i].z())},
                        {nrm[i].x(), nrm[i].y(), nrm[i].z()},
                        static_cast<int>(i)});
    const auto view = ks::project_points(user, &UserSample::xyz, &UserSample::n);
    REQUIRE(ks::gather_points(view) == ks::gather_points(ks::with_normals(vp, vn)));
    REQUIRE(ks::gather_normals(view) == ks::gather_normals(ks::with_normals(vp, vn)));
    const auto c = ks::reconstruct_pu_graphcut(view, params);
    CHECK(c.mesh.vertices == a.mesh.vertices);
    CHECK(c.mesh.faces == a.mesh.faces);

    CGAL::Surface_mesh<Kernel::Point_3> sm;
    const auto d = ks::reconstruct_pu_graphcut(ks::with_normals(vp, vn), sm, params);
    CHECK(d.status == ks::Status::ok);
    CHECK(d.mesh.faces.empty());
    CHECK(sm.number_of_faces() == a.mesh.faces.size());
    CHECK(ks::topology_report(sm).closed);
    CHECK(CGAL::is_valid_polygon_mesh(sm));
}

TEST_CASE("reconstruct_pu_graphcut: same seed, byte-identical output with 1 and 2 threads") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{0}, 8000, 0.001, 0.10, 11, pts, nrm);
    const ks::PUGraphcutParams params{.max_level = 7, .seed = 3};
    ks::PUGraphcutResult one, two;
    {
        ks::ThreadLimit limit(1);
        one = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), params);
    }
    {
        ks::ThreadLimit limit(2);
        two = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), params);
    }
    REQUIRE(one.mesh.vertices.size() == two.mesh.vertices.size());
    CHECK(one.mesh.faces == two.mesh.faces);
    CHECK(std::memcmp(one.mesh.vertices.data(), two.mesh.vertices.data(),
                      one.mesh.vertices.size() * sizeof(ks::Vec3)) == 0);
    CHECK(one.cut_value == two.cut_value);
    // another seed: another support cover, still a valid surface
    const auto other = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), {.max_level = 7, .seed = 4});
    CHECK(other.mesh.vertices != one.mesh.vertices);
    check_guarantee(other.mesh);
}

TEST_CASE("reconstruct_pu_graphcut: bad input throws invalid_input naming the problem") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{0}, 200, 0.0, 0.0, 1, pts, nrm);
    auto expect = [&](const std::vector<ks::Vec3>& p, const std::vector<ks::Vec3>& n, const ks::PUGraphcutParams& prm,
                      const char* what) {
        CAPTURE(what);
        CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(p, n), prm),
                             doctest::Contains(what), ks::invalid_input);
    };
    expect({pts[0], pts[1], pts[2]}, {nrm[0], nrm[1], nrm[2]}, {}, "at least 4 points");
    auto n2 = nrm;
    n2[7] = ks::Vec3::Zero();
    expect(pts, n2, {}, "zero length");
    auto p2 = pts;
    p2[3].y() = std::numeric_limits<double>::quiet_NaN();
    expect(p2, nrm, {}, "NaN");
    n2 = nrm;
    n2[4].x() = std::numeric_limits<double>::infinity();
    expect(pts, n2, {}, "normal of point 4");
    std::vector<ks::Vec3> flat, fn;
    for (int i = 0; i < 50; ++i) {
        flat.emplace_back(i % 7, i / 7, 0.0);
        fn.emplace_back(0, 0, 1);
    }
    expect(flat, fn, {}, "coplanar");
    std::vector<ks::Vec3> line;
    for (int i = 0; i < 50; ++i) line.emplace_back(i, 2.0 * i, 0.0);
    expect(line, fn, {}, "collinear");
    expect(pts, nrm, {.k = 0}, "k = ");
    expect(pts, nrm, {.k = -2}, "k = ");
    expect(pts, nrm, {.min_support_coherence = 1.5}, "min_support_coherence");
    expect(pts, nrm, {.triangulation_weight_scale = -0.5}, "triangulation_weight_scale");
    expect(pts, nrm, {.untrusted_weight = -0.1}, "untrusted_weight");
    expect(pts, nrm, {.untrusted_weight = 2}, "untrusted_weight");
    expect(pts, nrm, {.fill_radius_fraction = -1}, "fill_radius_fraction");
    expect(pts, nrm, {.fill_radius_fraction = std::numeric_limits<double>::quiet_NaN()}, "fill_radius_fraction");
    expect(pts, nrm, {.refine_spacing = -1}, "refine_spacing");
    expect(pts, nrm, {.refine_spacing = std::numeric_limits<double>::quiet_NaN()}, "refine_spacing");
    expect(pts, nrm, {.refine_spacing = 0.1}, ">= 0.25");  // 0 or >= min_refine_spacing
    expect(pts, nrm, {.refine_spacing = 4.9e-324}, "refine_spacing");
    expect(pts, nrm, {.refine_neighbors = 3}, "refine_neighbors");
    expect(pts, nrm, {.far_site_band = -1}, "far_site_band");
    expect(pts, nrm, {.far_site_band = std::numeric_limits<double>::quiet_NaN()}, "far_site_band");
    expect(pts, nrm, {.max_handle_loop = -1}, "max_handle_loop");
    expect(pts, nrm, {.max_handle_loop = std::numeric_limits<double>::infinity()}, "max_handle_loop");
    expect(pts, nrm, {.max_level = 0}, "max_level");
    expect(pts, nrm, {.max_level = 13}, "max_level");
    expect(pts, nrm, {.epsilon = 0}, "epsilon");
    // every message names the function
    CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), {.k = 0}),
                         doctest::Contains("kintsugi::reconstruct_pu_graphcut"), ks::invalid_input);
    // missing normals: a Point_set_3 without a normal map, and a with_normals of the wrong length
    CGAL::Point_set_3<Kernel::Point_3, Kernel::Vector_3> ps;
    for (const auto& p : pts) ps.insert(Kernel::Point_3(p.x(), p.y(), p.z()));
    CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(ps), doctest::Contains("no normals"), ks::invalid_input);
    std::vector<ks::Vec3> short_n(nrm.begin(), nrm.end() - 1);
    CHECK_THROWS_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(pts, short_n)), ks::invalid_input);
    // the output mesh is untouched on error
    ks::IndexedMesh out;
    out.vertices = {ks::Vec3(1, 2, 3)};
    CHECK_THROWS_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), out, {.k = 0}), ks::invalid_input);
    CHECK(out.vertices.size() == 1);
}

TEST_CASE("reconstruct_pu_graphcut: cancellation at every stage") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{0}, 3000, 0.001, 0.05, 2, pts, nrm);
    for (const std::string stage : {"pu_octree", "pu_cover", "pu_index", "triangulation", "graph_cut",
                                    "marching_tetrahedra", "smoothing", "handles", "refine"}) {
        CAPTURE(stage);
        bool seen = false;
        ks::PUGraphcutParams p{.max_level = 6};
        double last = -1;
        bool monotone = true;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            monotone = monotone && e.fraction >= last;
            last = e.fraction;
            if (e.stage == stage) seen = true;
            return !seen;
        };
        ks::IndexedMesh out;
        out.vertices = {ks::Vec3(1, 2, 3)};
        const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), out, p);
        CHECK(seen);
        CHECK(monotone);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(r.mesh.faces.empty());
        CHECK(out.vertices.size() == 1);
    }
    std::stop_source stop;
    stop.request_stop();
    ks::PUGraphcutParams p{.max_level = 6};
    p.control.stop = stop.get_token();
    CHECK(ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), p).status == ks::Status::cancelled);
}

TEST_CASE("reconstruct_pu_graphcut: real scans — the 9 registered bunny range scans (shipped subset)") {
    const std::string path = std::string(KINTSUGI_TEST_DATA_DIR) + "/../../data/bunny_scans_100k.ply";
    const ks::PointCloud cloud = ks::read_point_cloud(path);
    REQUIRE(cloud.points.size() == 100000);
    const auto r = ks::reconstruct_pu_graphcut(cloud);
    REQUIRE(r.status == ks::Status::ok);
    const auto rep = check_guarantee(r.mesh);
    MESSAGE("bunny scans: components " << rep.components << " genus " << rep.genus << " faces " << rep.faces
                                       << " handles removed " << r.handles_removed);
    CHECK(rep.components == 1);
    // The shipped subset is 100K of the 327K points: the labelling leaves one handle
    // where the ear is sampled too thinly (genus 1 before max_handle_loop); cut, the
    // bunny has its genus, 0, as the whole set has without a cut (next test).
    CHECK(rep.genus == 0);
    CHECK(r.handles_removed == 1);
}

TEST_CASE("reconstruct_pu_graphcut: real mesh shipped — tests/data/bunny.off sampled with noise, 2 holes and 10 % outliers") {
    // The accuracy check a plain clone runs (no ../shared): the same construction as the
    // bunny00 acceptance test below, on the small watertight bunny shipped in tests/data.
    const ks::IndexedMesh ref = ks::read_mesh(std::string(KINTSUGI_TEST_DATA_DIR) + "/bunny.off");
    std::vector<ks::Vec3> pts, nn;
    holey_noisy_sample(ref, 45000, 36000, 4000, 2, 0.03, 11, pts, nn);
    const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nn));
    REQUIRE(r.status == ks::Status::ok);
    const auto rep = check_guarantee(r.mesh);
    const auto d = ks::compare(r.mesh, ref, {.samples = 100000});
    const auto ab = d.relative(d.a_to_b), ba = d.relative(d.b_to_a);
    MESSAGE("bunny.off: components " << rep.components << " genus " << rep.genus << " result->truth mean " << ab.mean
                                     << " hausdorff " << ab.hausdorff << " truth->result mean " << ba.mean
                                     << " hausdorff " << ba.hausdorff);
    // Measured: 1 component, genus 0; mean 0.049 % / 0.051 % of the diagonal
    // (result->truth / truth->result), Hausdorff 1.44 % / 0.70 % (the shipped bunny is a
    // coarse 1.8K-vertex mesh: its flat facets are sampled, the field rounds their creases).
    CHECK(rep.components == 1);
    CHECK(rep.genus == 0);
    CHECK(ab.mean <= 0.0007);
    CHECK(ba.mean <= 0.0007);
    CHECK(ab.hausdorff <= 0.02);
    CHECK(ba.hausdorff <= 0.01);
}

TEST_CASE("reconstruct_pu_graphcut: real scans — the 9 registered bunny range scans, all 327K points") {
    const std::filesystem::path dir = std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / "stanford_bunny" / "scans";
    KINTSUGI_REQUIRE_DATA(dir);
    ks::PointCloud all;
    for (const char* name : {"bun000", "bun045", "bun090", "bun180", "bun270", "chin", "ear_back", "top2", "top3"}) {
        const ks::PointCloud scan = ks::read_point_cloud(dir / (std::string(name) + ".ply"));
        REQUIRE(scan.normals.size() == scan.points.size());
        all.points.insert(all.points.end(), scan.points.begin(), scan.points.end());
        all.normals.insert(all.normals.end(), scan.normals.begin(), scan.normals.end());
    }
    REQUIRE(all.points.size() == 326936);
    const auto r = ks::reconstruct_pu_graphcut(all);
    REQUIRE(r.status == ks::Status::ok);
    const auto rep = check_guarantee(r.mesh);
    MESSAGE("bunny scans (all): components " << rep.components << " genus " << rep.genus << " faces " << rep.faces);
    CHECK(rep.components == 1);
    CHECK(rep.genus == 0);
    CHECK(r.handles_removed == 0);  // the labelling alone has the right genus
    // With the paper's regular-triangulation weights the thin ears lose the nodes
    // inside them and are perforated: handles (measured genus 5), which the handle cut
    // (max_handle_loop) then has to remove.
    ks::PUGraphcutParams paper;
    paper.triangulation_weight_scale = 1;
    const auto rp = ks::reconstruct_pu_graphcut(all, paper);
    REQUIRE(rp.status == ks::Status::ok);
    const auto rep_paper = ks::topology_report(rp.mesh);
    MESSAGE("bunny scans (all), paper weights: genus " << rep_paper.genus << " after " << rp.handles_removed
                                                       << " handles cut");
    CHECK(rp.hidden_supports > 0);
    CHECK(rp.handles_removed >= 3);
    CHECK(rep_paper.genus + static_cast<long>(rp.handles_removed) > rep.genus);
}

TEST_CASE("reconstruct_pu_graphcut: real mesh — bunny00 sampled with noise, 3 holes and 10 % outliers") {
    const std::string path = std::string(KINTSUGI_SHARED_DATA_DIR) + "/cgal/meshes/bunny00.off";
    KINTSUGI_REQUIRE_DATA(path);
    const ks::IndexedMesh ref = ks::read_mesh(path);
    std::vector<ks::Vec3> pts, nn;
    holey_noisy_sample(ref, 110000, 90000, 10000, 3, 0.04, 7, pts, nn);
    const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nn));
    REQUIRE(r.status == ks::Status::ok);
    const auto rep = check_guarantee(r.mesh);
    const auto d = ks::compare(r.mesh, ref, {.samples = 100000});
    const auto ab = d.relative(d.a_to_b), ba = d.relative(d.b_to_a);
    MESSAGE("bunny00: components " << rep.components << " genus " << rep.genus << " result->truth mean "
                                   << ab.mean << " hausdorff " << ab.hausdorff << " truth->result mean " << ba.mean
                                   << " hausdorff " << ba.hausdorff << " filled " << r.filled_vertices);
    // Acceptance: one closed manifold component, result->truth mean <= 0.05 % and
    // Hausdorff <= 1 % of the diagonal. Measured on this input: 1 component, genus 0,
    // mean 0.036 % / 0.036 % (result->truth / truth->result), Hausdorff 0.67 % / 0.65 %.
    // On seeds 1-6 of the same construction: mean 0.034-0.036 %, result->truth
    // Hausdorff 0.59-0.98 %. Before the untrusted_weight and fill_radius_fraction
    // defaults: mean 0.051 %, Hausdorff 3.7 % here (a bulge of outliers beyond an ear
    // tip that a hole removed) and 0.94-2.8 % on the other seeds (hole fills following
    // the linear extrapolation of the rim planes; spikes where outlier supports bent
    // the field). truth->result stays up to 1.6 % on seeds 4 and 6, where a hole takes
    // an ear's tip: no data say how far the tip reached, and the fill closes it short.
    CHECK(rep.components == 1);
    CHECK(ab.mean <= 0.0005);
    CHECK(ba.mean <= 0.0005);
    CHECK(ab.hausdorff <= 0.01);
    CHECK(ba.hausdorff <= 0.02);
    CHECK(r.filled_vertices > 0);
    // Each of the two is needed: without the fill, or with the paper's field, the hole
    // fills leave the 1 % bound (measured 2.5 % and 1.1 %).
    ks::PUGraphcutParams no_fill;
    no_fill.fill_radius_fraction = 0;
    const auto rn = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nn), no_fill);
    REQUIRE(rn.status == ks::Status::ok);
    CHECK(rn.filled_vertices == 0);
    const auto dn = ks::compare(rn.mesh, ref, {.samples = 100000});
    MESSAGE("bunny00 without the fill: hausdorff " << dn.relative(dn.a_to_b).hausdorff);
    CHECK(dn.relative(dn.a_to_b).hausdorff > 0.01);
    ks::PUGraphcutParams paper_field;
    paper_field.untrusted_weight = 1;
    const auto rp = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nn), paper_field);
    REQUIRE(rp.status == ks::Status::ok);
    const auto dp = ks::compare(rp.mesh, ref, {.samples = 100000});
    MESSAGE("bunny00 with the paper's field: hausdorff " << dp.relative(dp.a_to_b).hausdorff);
    CHECK(dp.relative(dp.a_to_b).hausdorff > 0.01);
}

namespace {
/// Mean of | |v / scale - centre| - 1 | over the vertices (distance to the unit sphere
/// at `centre`, in the sphere's units; overflow-free for any scale).
double sphere_deviation(const std::vector<ks::Vec3>& vs, double scale, const ks::Vec3& centre = ks::Vec3::Zero()) {
    double sum = 0;
    for (const auto& v : vs) sum += std::abs((v / scale - centre).norm() - 1);
    return vs.empty() ? 1e9 : sum / static_cast<double>(vs.size());
}
}  // namespace

TEST_CASE("reconstruct_pu_graphcut: far outliers are left out; far-apart objects each get their own box") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{0}, 2000, 0.001, 0.0, 1, pts, nrm);
    const auto alone = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm));
    REQUIRE(alone.status == ks::Status::ok);
    check_guarantee(alone.mesh);
    CHECK(alone.parts == 1);
    CHECK(alone.far_points == 0);
    MESSAGE("sphere, 2,000 points: " << alone.mesh.vertices.size() << " vertices, deviation "
                                     << sphere_deviation(alone.mesh.vertices, 1));
    CHECK(sphere_deviation(alone.mesh.vertices, 1) < 0.01);
    // One point 3, 1,000 or 1e9 units away: it used to decide the octree's cube (1,000:
    // a 38-vertex blob reported closed; 1e9: "all points are collinear"). It is now left
    // out and the sphere is the sphere reconstructed alone, bit for bit.
    for (const double d : {3.0, 1000.0, 1e9}) {
        CAPTURE(d);
        auto p = pts, n = nrm;
        p.emplace_back(d, 0.5, 0.0);
        n.emplace_back(1, 0, 0);
        const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(p, n));
        REQUIRE(r.status == ks::Status::ok);
        CHECK(r.far_points == 1);
        CHECK(r.parts == 1);
        CHECK(r.points == 2001);
        CHECK(r.mesh.faces == alone.mesh.faces);
        CHECK(r.mesh.vertices == alone.mesh.vertices);
    }
    // Two spheres 1,000 apart (a mesh with 0 vertices before): both reconstructed, each
    // as if alone; a handful of far points around them are left out.
    auto p = pts, n = nrm;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        p.push_back(pts[i] + ks::Vec3(1000, 0, 0));
        n.push_back(nrm[i]);
    }
    for (int k = 0; k < 5; ++k) {
        p.emplace_back(500.0 + 50 * k, -300.0, 40.0 * k);
        n.emplace_back(0, 0, 1);
    }
    const auto two = ks::reconstruct_pu_graphcut(ks::with_normals(p, n));
    REQUIRE(two.status == ks::Status::ok);
    const auto rep = check_guarantee(two.mesh);
    CHECK(rep.components == 2);
    CHECK(rep.genus == 0);
    CHECK(two.parts == 2);
    CHECK(two.far_points == 5);
    std::vector<ks::Vec3> left, right;
    for (const auto& v : two.mesh.vertices) (v.x() < 500 ? left : right).push_back(v);
    CHECK(left == alone.mesh.vertices);  // the first part is the sphere's points, unchanged
    CHECK(std::abs(static_cast<double>(right.size()) / static_cast<double>(left.size()) - 1) < 0.02);
    CHECK(sphere_deviation(left, 1) < 0.01);
    CHECK(sphere_deviation(right, 1, ks::Vec3(1000, 0, 0)) < 0.01);
    std::vector<std::string> stages;
    for (const auto& t : two.timings) stages.push_back(t.stage);
    CHECK(stages == std::vector<std::string>{"pu_octree", "pu_cover", "pu_index", "triangulation", "graph_cut",
                                             "marching_tetrahedra", "smoothing", "handles", "refine"});
    // One box for everything (the paper's rule, part_gap_fraction = 0): each sphere fits
    // in one cell of the cube, no support is labelled inside, and the empty surface is an
    // error naming the reason and the fix, not an exit with 0 vertices.
    CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(p, n), {.part_gap_fraction = 0}),
                         doctest::Contains("the surface is empty"), ks::invalid_input);
    // Only scattered clusters too small to be objects: an error, not an empty mesh.
    std::vector<ks::Vec3> specks, speck_n;
    for (int c = 0; c < 6; ++c)
        for (int k = 0; k < 5; ++k) {
            specks.emplace_back(std::pow(10.0, c + 1) + (k & 1), 0.3 * k, 0.2 * (k >> 1));
            speck_n.emplace_back(0, 0, 1);
        }
    CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(specks, speck_n)),
                         doctest::Contains("no part of the input can be reconstructed"), ks::invalid_input);
    // bad values of the two parameters
    CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), {.part_gap_fraction = -1}),
                         doctest::Contains("part_gap_fraction"), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::reconstruct_pu_graphcut(
                             ks::with_normals(pts, nrm), {.min_part_fraction = std::numeric_limits<double>::quiet_NaN()}),
                         doctest::Contains("min_part_fraction"), ks::invalid_input);
}

TEST_CASE("pu_separated_parts: empty slabs wider than the fraction of the box split, recursively") {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<ks::Vec3> pts;
    for (int i = 0; i < 20000; ++i) pts.emplace_back(u(rng), u(rng), u(rng));
    // a connected blob: one part (the linear pre-check decides it)
    auto parts = ks::detail::pu_separated_parts(pts, 0.25);
    REQUIRE(parts.size() == 1);
    CHECK(parts[0].size() == pts.size());
    // a geometric sequence of far points along x, +y and -z: each peels off alone; the
    // work stays proportional to the part moved (O(n log^2 n)), not to n per split
    const std::size_t cube = pts.size();
    for (int k = 2; k < 600; ++k) pts.emplace_back(std::ldexp(1.0, k), 0.5, 0.5);
    for (int k = 2; k < 300; ++k) pts.emplace_back(0.5, std::ldexp(1.0, k), -std::ldexp(1.0, k));
    pts.emplace_back(-1.7e308, 1.7e308, 0.0);  // no overflow of the gaps or the box
    parts = ks::detail::pu_separated_parts(pts, 0.25);
    REQUIRE(parts.size() == pts.size() - cube + 1);
    CHECK(parts[0].size() == cube);
    CHECK(parts[0].back() == cube - 1);
    for (std::size_t k = 1; k < parts.size(); ++k) {
        REQUIRE(parts[k].size() == 1);
        CHECK(parts[k][0] == cube + k - 1);
    }
    // 0 disables; a gap of 1/5 of the box is kept at 0.25 and split at 0.15
    CHECK(ks::detail::pu_separated_parts(pts, 0).size() == 1);
    std::vector<ks::Vec3> two;
    for (int i = 0; i < 1000; ++i) two.emplace_back(2 * u(rng) + (i % 2 ? 3.0 : 0.0), u(rng), u(rng));
    CHECK(ks::detail::pu_separated_parts(two, 0.25).size() == 1);
    parts = ks::detail::pu_separated_parts(two, 0.15);
    REQUIRE(parts.size() == 2);
    CHECK(parts[0].size() == 500);
    CHECK(parts[0][0] == 0);
    CHECK(parts[1][0] == 1);
}

TEST_CASE("reconstruct_pu_graphcut: finite coordinates of any magnitude give the same surface up to scale") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{0}, 2000, 0.001, 0.1, 1, pts, nrm);
    const auto ref = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm));
    REQUIRE(ref.status == ks::Status::ok);
    const auto nv = static_cast<double>(ref.mesh.vertices.size());
    const double dev = sphere_deviation(ref.mesh.vertices, 1);
    MESSAGE("scale 1: " << nv << " vertices, deviation " << dev);
    // Before: above ~1.4e154 squared distances overflowed ("all points coincide", and a
    // crash in the normal estimation); 1e-200 gave "all points coincide" and tiny
    // normals "zero length".
    for (const double s : {1e-300, 1e-200, 1e-20, 1e20, 1e154, 1e200, 1e300}) {
        for (const bool scale_normals : {false, true}) {
            CAPTURE(s);
            CAPTURE(scale_normals);
            auto p = pts, n = nrm;
            for (auto& x : p) x *= s;
            if (scale_normals)
                for (auto& x : n) x *= s;
            const auto p0 = p;
            const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(p, n));
            REQUIRE(r.status == ks::Status::ok);
            auto unit = r.mesh;  // in the sphere's units: the volume s^3 of the check would overflow
            for (auto& v : unit.vertices) v /= s;
            CHECK(check_guarantee(unit).components == 1);
            CHECK(std::abs(static_cast<double>(r.mesh.vertices.size()) - nv) <= 0.01 * nv);
            CHECK(sphere_deviation(r.mesh.vertices, s) == doctest::Approx(dev).epsilon(0.05));
            for (const auto& v : r.mesh.vertices) REQUIRE(v.allFinite());
            CHECK(p == p0);
        }
    }
    // Far from the origin relative to the size: a unit sphere at 1e12 (recentred frame).
    auto p = pts;
    for (auto& x : p) x += ks::Vec3(1e12, -1e12, 3e12);
    const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(p, nrm));
    REQUIRE(r.status == ks::Status::ok);
    CHECK(sphere_deviation(r.mesh.vertices, 1, ks::Vec3(1e12, -1e12, 3e12)) < 2 * dev + 1e-3);
}

TEST_CASE("reconstruct_pu_graphcut: progress moves through the triangulation, and a stop there cancels") {
    std::vector<ks::Vec3> pts, nrm;
    kintsugi_test::sample_shape(Shape{1}, 20000, 0.001, 0.1, 4, pts, nrm);
    // Between 35 % and 70 % (the triangulation) the callback used to be called once, at
    // the start of the stage, for any input under 32,768 supports.
    std::vector<double> inside;
    ks::PUGraphcutParams p;
    p.control.progress = [&](const ks::ProgressEvent& e) {
        if (e.stage == "triangulation" && e.fraction > 0.35 && e.fraction < 0.7) inside.push_back(e.fraction);
        return true;
    };
    const auto full = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), p);
    REQUIRE(full.status == ks::Status::ok);
    MESSAGE("progress events inside the triangulation: " << inside.size());
    CHECK(inside.size() >= 10);
    CHECK(std::is_sorted(inside.begin(), inside.end()));
    REQUIRE(!inside.empty());
    CHECK(inside.back() > 0.6);
    // Cancelled halfway through the insertion, through the callback and through the
    // stop token (polled every 1,024 insertions).
    for (const bool by_token : {false, true}) {
        CAPTURE(by_token);
        std::stop_source stop;
        double at = -1;
        ks::PUGraphcutParams q;
        q.control.stop = stop.get_token();
        q.control.progress = [&](const ks::ProgressEvent& e) {
            if (e.stage == "triangulation" && e.fraction > 0.5 && at < 0) {
                at = e.fraction;
                if (by_token) stop.request_stop();
                return by_token;
            }
            CHECK(at < 0);  // no event after the stop
            return true;
        };
        ks::IndexedMesh out;
        out.vertices = {ks::Vec3(1, 2, 3)};
        const auto r = ks::reconstruct_pu_graphcut(ks::with_normals(pts, nrm), out, q);
        CHECK(at > 0.5);
        CHECK(at < 0.7);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(r.mesh.faces.empty());
        CHECK(out.vertices.size() == 1);
    }
}
