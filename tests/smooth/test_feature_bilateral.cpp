// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Feature-aware bilateral smoothing: edge strength on known shapes, sharp edges, the
// smoothing over every mesh adapter, bad input, cancellation, determinism, boundaries,
// non-manifold and degenerate input, and accuracy on a real noisy/clean pair.
#include "test_data.hpp"
#include <doctest/doctest.h>

#include "metrics/mesh_fixtures.hpp"
#include "smooth_support.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/taubin.hpp>
#include <kintsugi/mesh/impulses.hpp>
#include <kintsugi/mesh/noise_level.hpp>
#include <kintsugi/metrics/denoise.hpp>
#include <kintsugi/smooth/feature_bilateral.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <iostream>
#include <cstring>
#include <limits>
#include <numbers>
#include <set>
#include <stop_token>
#include <string>
#include <vector>

namespace ks = kintsugi;
namespace ss = smooth_support;

namespace {

// The paper's exact detection (no pre-smoothing, raw normals, direction test), as the
// `paper` preset sets it.
const ks::SharpFeatureParams paper_detection = ks::FeatureBilateralParams::paper().detection;

// How straight the detected sharp edges of a smoothed mesh are: the mean distance of
// their vertices to the true crease segments (the clean mesh's edges sharper than 60°)
// and the mean angle of each edge to the true segment nearest its midpoint (degrees).
struct Straightness {
    double distance, angle;
};
Straightness straightness(const ks::IndexedMesh& out, const std::vector<std::array<ks::Index, 2>>& detected,
                          const ks::IndexedMesh& clean) {
    std::vector<std::array<ks::Vec3, 2>> segs;
    for (const auto& e : ss::crease_edges(clean, 60)) segs.push_back({clean.vertices[e[0]], clean.vertices[e[1]]});
    REQUIRE(!segs.empty());
    REQUIRE(!detected.empty());
    auto nearest = [&](const ks::Vec3& p, double& dist) {
        std::size_t best = 0;
        dist = std::numeric_limits<double>::infinity();
        for (std::size_t k = 0; k < segs.size(); ++k) {
            const ks::Vec3 d = segs[k][1] - segs[k][0];
            const double t = std::clamp((p - segs[k][0]).dot(d) / d.squaredNorm(), 0.0, 1.0);
            const double r = (p - segs[k][0] - t * d).norm();
            if (r < dist) {
                dist = r;
                best = k;
            }
        }
        return best;
    };
    std::set<ks::Index> vertices;
    for (const auto& e : detected) vertices.insert(e.begin(), e.end());
    double distance = 0, angle = 0;
    for (ks::Index v : vertices) {
        double d;
        nearest(out.vertices[v], d);
        distance += d;
    }
    for (const auto& e : detected) {
        double d;
        const std::size_t k = nearest((out.vertices[e[0]] + out.vertices[e[1]]) / 2, d);
        const ks::Vec3 u = (out.vertices[e[1]] - out.vertices[e[0]]).normalized();
        const ks::Vec3 w = (segs[k][1] - segs[k][0]).normalized();
        angle += std::acos(std::min(1.0, std::abs(u.dot(w)))) * 180 / std::numbers::pi;
    }
    return {distance / double(vertices.size()), angle / double(detected.size())};
}

bool on_box_edge(const ks::Vec3& p) {
    int c = 0;
    for (int k = 0; k < 3; ++k) c += (p[k] == 0.0 || p[k] == 1.0);
    return c >= 2;
}
bool is_corner(const ks::Vec3& p) {
    int c = 0;
    for (int k = 0; k < 3; ++k) c += (p[k] == 0.0 || p[k] == 1.0);
    return c == 3;
}
// Distance from p to the nearest of the 12 box edges (p on the box surface).
double distance_to_box_edge(const ks::Vec3& p) {
    double best = 1e9;
    for (int k = 0; k < 3; ++k) {
        const int u = (k + 1) % 3, w = (k + 2) % 3;  // edge parallel to axis k
        for (double a : {0.0, 1.0})
            for (double b : {0.0, 1.0}) best = std::min(best, std::hypot(p[u] - a, p[w] - b));
    }
    return best;
}

bool all_finite(const ks::IndexedMesh& m) {
    for (const auto& p : m.vertices)
        if (!p.allFinite()) return false;
    return true;
}

struct Mesh3 {  // one mesh held by every adapter type under test
    ks::IndexedMesh indexed;
    Eigen::MatrixXd V;
    Eigen::MatrixXi F;
    ss::SurfaceMesh surface;
    explicit Mesh3(const ks::IndexedMesh& m) : indexed(m) {
        V.resize(static_cast<Eigen::Index>(m.vertices.size()), 3);
        F.resize(static_cast<Eigen::Index>(m.faces.size()), 3);
        for (std::size_t v = 0; v < m.vertices.size(); ++v) V.row(static_cast<Eigen::Index>(v)) = m.vertices[v].transpose();
        for (std::size_t f = 0; f < m.faces.size(); ++f)
            for (int k = 0; k < 3; ++k) F(static_cast<Eigen::Index>(f), k) = static_cast<int>(m.faces[f][k]);
        ks::assign_mesh(surface, m);
    }
};

// The mesh under test as type T, and back to an IndexedMesh.
template <class T>
struct Holder;
template <>
struct Holder<ks::IndexedMesh> {
    ks::IndexedMesh m;
    explicit Holder(const ks::IndexedMesh& x) : m(x) {}
    ks::IndexedMesh& mesh() { return m; }
    ks::IndexedMesh get() const { return m; }
};
template <>
struct Holder<ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>> {
    Mesh3 data;
    ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi> view;
    explicit Holder(const ks::IndexedMesh& x) : data(x), view(ks::eigen_mesh(data.V, data.F)) {}
    auto& mesh() { return view; }
    ks::IndexedMesh get() const { return ks::to_indexed_mesh(view); }
};
template <>
struct Holder<ss::SurfaceMesh> {
    ss::SurfaceMesh m;
    explicit Holder(const ks::IndexedMesh& x) { ks::assign_mesh(m, x); }
    ss::SurfaceMesh& mesh() { return m; }
    ks::IndexedMesh get() const { return ks::to_indexed_mesh(m); }
};

// The run's own stages, without the risk selection's ("risk: ..." timings).
std::size_t stages_outside_risk(const ks::FeatureBilateralResult& r) {
    return static_cast<std::size_t>(std::count_if(r.timings.begin(), r.timings.end(),
                                                  [](const auto& t) { return !t.stage.starts_with("risk: "); }));
}

std::filesystem::path test_data(const char* name) { return std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "smooth" / name; }

}  // namespace

static_assert(ks::MutableTriangleMesh<ks::IndexedMesh>);
static_assert(ks::MutableTriangleMesh<ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>>);
static_assert(!ks::MutableTriangleMesh<ks::EigenMeshView<const Eigen::MatrixXd, Eigen::MatrixXi>>);
static_assert(ks::TriangleMesh<ks::EigenMeshView<const Eigen::MatrixXd, Eigen::MatrixXi>>);

TEST_CASE("edge strength is ~1 on sharp edges and corners and ~0 on flat faces") {
    const auto box = ss::box_mesh(12);
    const auto r = ks::detect_sharp_features(box, paper_detection);
    REQUIRE(r.status == ks::Status::ok);
    const auto& f = r.features;
    REQUIRE(f.edge_strength.size() == box.vertices.size());
    CHECK(f.mean_edge_length == doctest::Approx(ks::mean_edge_length(box)));
    std::size_t flat = 0, edge = 0, corner = 0;
    for (std::size_t v = 0; v < box.vertices.size(); ++v) {
        const ks::Vec3& p = box.vertices[v];
        const double s = f.edge_strength[v];
        CHECK(s >= 0.0);
        CHECK(s <= 1.0);
        CHECK(f.eigenvalues[v].sum() == doctest::Approx(1.0));
        if (is_corner(p)) {
            ++corner;
            CHECK(s > 0.9);
        } else if (on_box_edge(p)) {
            ++edge;
            CHECK(s > 0.9);
            // e3 is the crease direction: along the one axis where p is not on a side.
            int axis = 0;
            for (int k = 0; k < 3; ++k)
                if (p[k] != 0.0 && p[k] != 1.0) axis = k;
            CHECK(std::abs(f.eigenvectors[v][2][axis]) > 0.99);
        } else if (distance_to_box_edge(p) > 2.5 / 12) {  // outside every voting cube reaching an edge
            ++flat;
            CHECK(s < 1e-6);
        }
    }
    CHECK(corner == 8);
    CHECK(edge == 12 * 11);
    CHECK(flat > 0);
}

TEST_CASE("symmetric creases: s = tan^2(phi/2), as documented") {
    // A folded strip: two planes meeting along the x axis with normals phi apart.
    for (double phi_deg : {30.0, 60.0, 90.0}) {
        const double phi = phi_deg * std::numbers::pi / 180;
        ks::IndexedMesh m;
        const int n = 16;
        // Rows j = -n..n across the crease; the half-planes are rotated by ±phi/2.
        for (int j = -n; j <= n; ++j)
            for (int i = 0; i <= n; ++i) {
                const double t = j / double(n), a = phi / 2;
                const double y = std::abs(t) * std::cos(a) * (t < 0 ? -1 : 1);
                const double z = -std::abs(t) * std::sin(a);
                m.vertices.emplace_back(i / double(n), y, z);
            }
        auto id = [&](int i, int j) { return static_cast<ks::Index>((j + n) * (n + 1) + i); };
        for (int j = -n; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
                m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
            }
        const auto r = ks::detect_sharp_features(m, paper_detection);
        // A vertex in the middle of the crease sees both sides symmetrically.
        const double s = r.features.edge_strength[id(n / 2, 0)];
        CHECK(s == doctest::Approx(std::pow(std::tan(phi / 2), 2)).epsilon(0.05));
    }
}

TEST_CASE("sharp edges of a clean box: exactly its 12 edges by default, a band around them with the paper's test") {
    const auto box = ss::box_mesh(10);
    const auto truth = ss::box_edges(box);
    REQUIRE(truth.size() == 12 * 10);
    const auto r = ks::detect_sharp_features(box);
    const auto pr = ss::compare_edges(r.features.sharp_edges, truth);
    CHECK(pr.precision == 1.0);
    CHECK(pr.recall == 1.0);
    // The paper's direction test also keeps the edges parallel to a crease whose
    // vertices see both sides inside the voting cube (half side 1.5|e|): every box
    // edge is found, and every edge found lies within that band.
    const auto rp = ks::detect_sharp_features(box, paper_detection);
    CHECK(ss::compare_edges(rp.features.sharp_edges, truth).recall == 1.0);
    for (const auto& e : rp.features.sharp_edges) {
        CHECK(distance_to_box_edge(box.vertices[e[0]]) <= 1.5 / 10 + 1e-12);
        CHECK(distance_to_box_edge(box.vertices[e[1]]) <= 1.5 / 10 + 1e-12);
    }
}

TEST_CASE_TEMPLATE("smooth_feature_bilateral denoises a noisy box on every mesh type", T, ks::IndexedMesh,
                   ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>, ss::SurfaceMesh) {
    const auto clean = ss::box_mesh(16);
    const auto noisy = ss::add_normal_noise(clean, 0.3 * ks::mean_edge_length(clean));
    Holder<T> h(noisy);
    const auto r = ks::smooth_feature_bilateral(h.mesh());
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.vertices == clean.vertices.size());
    CHECK(r.faces == clean.faces.size());
    CHECK(r.feature_vertices > 0);
    // spikes, untangle, topology, coplanar creases, impulses, noise level, features, edge and face
    // smoothing, straightening; then the risk selection's perturbed run (its stages nested) and the
    // Taubin sweep.
    CHECK(stages_outside_risk(r) == 10u);
    CHECK(r.timings.front().stage == "spikes");
    CHECK(r.timings[1].stage == "untangle");
    CHECK(r.spike_vertices == 0);
    CHECK_FALSE(r.untangle.tangential_noise);  // noise along the normals
    CHECK(r.untangle.moved_vertices == 0);
    CHECK_FALSE(r.impulsive_noise);  // Gaussian noise: nothing put back
    CHECK(r.impulse_vertices == 0);
    CHECK(r.timings.back().stage == "risk: Taubin sweep");
    CHECK(r.risk.evaluated);
    CHECK_FALSE(r.risk.taubin);  // a box: the filters' result
    const auto out = h.get();
    REQUIRE(all_finite(out));
    const auto before = ks::denoise_metrics(noisy, clean);
    const auto after = ks::denoise_metrics(out, clean);
    MESSAGE("box: normal error " << before.mean_normal_angle_deg << " -> " << after.mean_normal_angle_deg
                                 << " deg, vertex rms " << before.vertex_rms << " -> " << after.vertex_rms);
    CHECK(after.mean_normal_angle_deg < before.mean_normal_angle_deg / 4);
    CHECK(after.vertex_rms < before.vertex_rms / 2);
    // The creases are found again: most box edges are sharp edges.
    const auto pr = ss::compare_edges(r.features.sharp_edges, ss::box_edges(clean));
    CHECK(pr.recall > 0.9);
    CHECK(pr.precision > 0.9);
    // Same result whatever the container.
    ks::IndexedMesh reference = noisy;
    (void)ks::smooth_feature_bilateral(reference);
    for (std::size_t v = 0; v < out.vertices.size(); ++v)
        REQUIRE((out.vertices[v] - reference.vertices[v]).norm() < 1e-12);
}

TEST_CASE("features = false runs the same filters without feature handling") {
    const auto clean = ss::box_mesh(12);
    const auto noisy = ss::add_normal_noise(clean, 0.3 * ks::mean_edge_length(clean), 7);
    auto with = noisy, without = noisy;
    const auto rw = ks::smooth_feature_bilateral(with);
    const auto ro = ks::smooth_feature_bilateral(without, {.features = false});
    CHECK(ro.features.sharp_edges.empty());
    CHECK(ro.feature_vertices == 0);
    CHECK(rw.feature_vertices > 0);
    // spikes, untangle, topology, impulses, noise level, low-pass (when a step runs), face smoothing; then the risk selection's
    CHECK(stages_outside_risk(ro) == (ro.lowpass_iterations > 0 ? 7u : 6u));
    CHECK(ks::denoise_metrics(without, clean).mean_normal_angle_deg <
          ks::denoise_metrics(noisy, clean).mean_normal_angle_deg);
    CHECK(with.vertices != without.vertices);
}

TEST_CASE("edges straighten: the sharp-edge vertices end on straight creases, and the normals do not suffer") {
    // A noisy box (0.5|e| along the normals) and Block0.4 (guided denoising, its clean
    // original); the sharp edges are those detected on the noisy input (the same in
    // every run that detects them).
    const auto box = ss::box_mesh(16);
    const auto block_noisy = ks::read_mesh(test_data("block_noisy.ply"));
    const auto block_clean = ks::read_mesh(test_data("block_clean.ply"));
    struct Shape {
        const char* name;
        ks::IndexedMesh noisy, clean;
    };
    for (const Shape& sh : {Shape{"box", ss::add_normal_noise(box, 0.5 * ks::mean_edge_length(box), 3), box},
                            Shape{"Block0.4", block_noisy, block_clean}}) {
        const double L = ks::mean_edge_length(sh.clean);
        auto run = [&](ks::FeatureBilateralParams p, std::vector<std::array<ks::Index, 2>>* edges = nullptr) {
            ks::IndexedMesh m = sh.noisy;
            // The edge stage alone, at the settings it was measured with: no low-pass (with
            // it, Block0.4's edge angle falls 5.32 -> 5.02 deg, 6 %; docs/methods/feature_bilateral.md).
            p.lowpass_noise = 0;
            const auto r = ks::smooth_feature_bilateral(m, p);
            REQUIRE(r.status == ks::Status::ok);
            if (edges) *edges = r.features.sharp_edges;
            return m;
        };
        std::vector<std::array<ks::Index, 2>> detected;
        const auto straight = run({}, &detected);
        const auto no_edge_stage = run({.edge_iterations = 0});
        const auto filter4_last = run({.edge_vertex_motion = ks::EdgeVertexMotion::free});
        const auto no_features = run({.features = false});
        const Straightness s_in = straightness(sh.noisy, detected, sh.clean), s = straightness(straight, detected, sh.clean),
                           s0 = straightness(no_edge_stage, detected, sh.clean),
                           s4 = straightness(filter4_last, detected, sh.clean),
                           sf = straightness(no_features, detected, sh.clean);
        const double n = ks::denoise_metrics(straight, sh.clean).mean_normal_angle_deg,
                     n4 = ks::denoise_metrics(filter4_last, sh.clean).mean_normal_angle_deg;
        MESSAGE(std::string(sh.name) << " (" << detected.size() << " sharp edges): distance to the creases (|e|) / angle (deg): noisy "
                        << s_in.distance / L << " / " << s_in.angle << ", straightened " << s.distance / L << " / "
                        << s.angle << ", no edge stage " << s0.distance / L << " / " << s0.angle
                        << ", filter 4 last " << s4.distance / L << " / " << s4.angle << ", features=false "
                        << sf.distance / L << " / " << sf.angle << "; normal error " << n << " (filter 4 last " << n4
                        << ")");
        // Filters 1–2 straighten: the edges' angle to the true creases drops by more than
        // 8 % against the same run without them and against filter 4 moving the edge
        // vertices last (measured: box 20 % / 14 %, Block0.4 15 % / 11 %), and the
        // vertices do not move away from the creases.
        CHECK(s.angle < 0.92 * s0.angle);
        CHECK(s.angle < 0.92 * s4.angle);
        CHECK(s.distance <= s0.distance);
        CHECK(s.distance <= s4.distance);
        // The whole feature stage against the face filters alone: both measures by more
        // than 10 % (measured: box 22 % / 33 %, Block0.4 15 % / 19 %).
        CHECK(s.distance < 0.9 * sf.distance);
        CHECK(s.angle < 0.9 * sf.angle);
        CHECK(s.angle < 0.5 * s_in.angle);
        // Straightening the creases does not cost face-normal accuracy.
        CHECK(n <= n4);
    }
}

TEST_CASE("the paper preset: the published parameters and detection, and the departures measured against it") {
    const auto paper = ks::FeatureBilateralParams::paper();
    const ks::FeatureBilateralParams defaults;
    CHECK(paper.a == 2);
    CHECK(paper.b == 0.1);
    CHECK(paper.c == 2);
    CHECK(paper.d == 0.1);
    CHECK(paper.face_iterations == std::size_t{2});
    CHECK(paper.edge_iterations == 2);
    CHECK(paper.normal_iterations == 1);
    CHECK(paper.vertex_iterations == 1);
    CHECK(paper.detection.voting_cube == 3);
    CHECK(paper.detection.edge_threshold == 0.251);
    CHECK(paper.detection.direction_threshold == 0.9);
    CHECK(paper.detection.prefilter_iterations == 0);
    CHECK(paper.detection.presmooth_iterations == 0);
    CHECK_FALSE(paper.detection.crease_test);
    CHECK_FALSE(paper.risk_selection);  // the paper has no such step
    CHECK(defaults.risk_selection);
    CHECK_FALSE(paper.separate_features);
    CHECK(paper.edge_vertex_motion == ks::EdgeVertexMotion::free);
    // The defaults depart from it (c, d from the noise, passes, detection, barriers).
    CHECK(defaults.c != paper.c);
    CHECK_FALSE(defaults.d.has_value());
    CHECK_FALSE(defaults.face_iterations.has_value());
    CHECK_FALSE(defaults.normal_iterations.has_value());  // from the noise
    CHECK(paper.normal_iterations == std::size_t{1});
    CHECK(defaults.detection.crease_test != paper.detection.crease_test);
    CHECK(defaults.separate_features != paper.separate_features);
    CHECK(defaults.edge_vertex_motion != paper.edge_vertex_motion);

    // On the noisy box at 0.3|e| both run; the preset uses its values as given (no
    // noise estimate) and the defaults, tuned for such noise, are clearly more accurate.
    const auto clean = ss::box_mesh(16);
    const auto noisy = ss::add_normal_noise(clean, 0.3 * ks::mean_edge_length(clean), 5);
    auto mp = noisy, md = noisy;
    const auto rp = ks::smooth_feature_bilateral(mp, paper);
    const auto rd = ks::smooth_feature_bilateral(md);
    REQUIRE(rp.status == ks::Status::ok);
    CHECK_FALSE(rp.noise_estimated);
    CHECK(rp.d == 0.1);
    CHECK(rp.face_iterations == 2);
    CHECK(rp.timings.size() == 4);  // topology, features, edge and face smoothing
    CHECK(rp.feature_vertices > 0);
    const double e_in = ks::denoise_metrics(noisy, clean).mean_normal_angle_deg,
                 e_paper = ks::denoise_metrics(mp, clean).mean_normal_angle_deg,
                 e_default = ks::denoise_metrics(md, clean).mean_normal_angle_deg;
    MESSAGE("box 0.3|e|: normal error noisy " << e_in << ", paper " << e_paper << ", defaults " << e_default << " deg");
    CHECK(e_paper < e_in);
    CHECK(e_default < 0.5 * e_paper);
}

TEST_CASE("bad input throws invalid_input naming the problem and leaves the mesh untouched") {
    const auto box = ss::box_mesh(4);
    auto expect_throw = [](auto&& call, const char* what) {
        try {
            call();
            FAIL("no exception");
        } catch (const ks::invalid_input& e) {
            CHECK(std::string(e.what()).find(what) != std::string::npos);
        }
    };
    ks::IndexedMesh empty;
    expect_throw([&] { (void)ks::smooth_feature_bilateral(empty); }, "no faces");
    expect_throw([&] { (void)ks::detect_sharp_features(empty); }, "no faces");

    auto nan = box;
    nan.vertices[3].x() = std::numeric_limits<double>::quiet_NaN();
    auto nan_copy = nan;
    expect_throw([&] { (void)ks::smooth_feature_bilateral(nan); }, "vertex 3");
    CHECK(std::isnan(nan.vertices[3].x()));
    nan.vertices[3].x() = nan_copy.vertices[3].x() = 0;
    CHECK(nan.vertices == nan_copy.vertices);

    auto bad_face = box;
    bad_face.faces[5][1] = 999;
    expect_throw([&] { (void)ks::smooth_feature_bilateral(bad_face); }, "face 5 uses vertex 999");

    ks::IndexedMesh collapsed{{ks::Vec3(1, 1, 1), ks::Vec3(1, 1, 1), ks::Vec3(1, 1, 1)}, {{0, 1, 2}}, {}};
    expect_throw([&] { (void)ks::smooth_feature_bilateral(collapsed); }, "zero length");

    auto m = box;
    expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.a = 0}); }, "a = 0");
    expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.d = std::numeric_limits<double>::quiet_NaN()}); },
                 "d = ");
    expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.c = -1}); }, "c = -1");
    expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.detection = {.edge_threshold = 2}}); }, "edge_threshold");
    expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.face_iterations = 20000}); }, "face_iterations");
    expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.lowpass_iterations = 10001}); }, "lowpass_iterations");
    for (double bad : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()})
        expect_throw([&] { (void)ks::smooth_feature_bilateral(m, {.lowpass_noise = bad}); }, "lowpass_noise");
    expect_throw([&] { (void)ks::detect_sharp_features(m, {.voting_cube = 0}); }, "voting_cube");
    expect_throw([&] { (void)ks::detect_sharp_features(m, {.direction_threshold = -0.5}); }, "direction_threshold");
    CHECK(m.vertices == box.vertices);
}

TEST_CASE("cancellation leaves the mesh untouched") {
    const auto noisy = ss::add_normal_noise(ss::box_mesh(10), 0.02);
    SUBCASE("through the progress callback") {
        auto m = noisy;
        int calls = 0;
        std::vector<std::string> stages;
        ks::FeatureBilateralParams p;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            stages.emplace_back(e.stage);
            return ++calls < 8;
        };
        const auto r = ks::smooth_feature_bilateral(m, p);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(m.vertices == noisy.vertices);
        CHECK(r.features.sharp_edges.empty());
        CHECK(calls == 8);
    }
    SUBCASE("through a stop token, late in the run") {
        // Without the risk selection: in the face smoothing; with it (the default): in the
        // perturbed run's face smoothing (reported at 0.4-0.8 of the whole) and in the Taubin
        // sweep, the last stage.
        struct At {
            std::string stage;
            double after;
            bool risk;
        };
        for (const At& at : {At{"face smoothing", 0.8, false}, At{"face smoothing", 0.6, true},
                             At{"risk: Taubin sweep", 0.0, true}}) {
            auto m = noisy;
            std::stop_source stop;
            ks::FeatureBilateralParams p;
            p.risk_selection = at.risk;
            p.control.stop = stop.get_token();
            bool seen = false;
            p.control.progress = [&](const ks::ProgressEvent& e) {
                if (std::string(e.stage) == at.stage && e.fraction > at.after) {
                    seen = true;
                    stop.request_stop();
                }
                return true;
            };
            const auto r = ks::smooth_feature_bilateral(m, p);
            CAPTURE(at.stage);
            CAPTURE(at.after);
            CHECK(seen);
            CHECK(r.status == ks::Status::cancelled);
            CHECK(m.vertices == noisy.vertices);
        }
    }
    SUBCASE("progress stays in order when the low-pass runs") {
        auto m = ss::add_normal_noise(ss::box_mesh(10), 0.08);  // about 0.46|e|: low-pass steps run
        std::vector<double> fractions;
        ks::FeatureBilateralParams p;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            fractions.push_back(e.fraction);
            return true;
        };
        CHECK(ks::smooth_feature_bilateral(m, p).lowpass_iterations > 0);
        CHECK(std::is_sorted(fractions.begin(), fractions.end()));
    }
    SUBCASE("through a stop token, in the low-pass") {
        const auto strong = ss::add_normal_noise(ss::box_mesh(10), 0.08);  // about 0.46|e|: low-pass steps run
        auto m = strong;
        std::stop_source stop;
        ks::FeatureBilateralParams p;
        p.control.stop = stop.get_token();
        bool seen = false;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            if (std::string(e.stage) == "low-pass") {
                seen = true;
                stop.request_stop();
            }
            return true;
        };
        const auto r = ks::smooth_feature_bilateral(m, p);
        CHECK(seen);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(m.vertices == strong.vertices);
    }
    SUBCASE("detection") {
        std::stop_source stop;
        stop.request_stop();
        ks::SharpFeatureParams p;
        p.control.stop = stop.get_token();
        const auto r = ks::detect_sharp_features(noisy, p);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(r.features.edge_strength.empty());
    }
    SUBCASE("progress is reported in order, at most ~100 times") {
        auto m = noisy;
        std::vector<double> fractions;
        ks::FeatureBilateralParams p;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            fractions.push_back(e.fraction);
            return true;
        };
        CHECK(ks::smooth_feature_bilateral(m, p).status == ks::Status::ok);
        CHECK(fractions.size() <= 120);
        CHECK(std::is_sorted(fractions.begin(), fractions.end()));
        CHECK(fractions.back() == 1.0);
    }
}

TEST_CASE("the result does not depend on the thread count") {
    const auto noisy = ss::add_normal_noise(ss::box_mesh(20), 0.01, 3);
    auto a = noisy, b = noisy;
    {
        ks::ThreadLimit one(1);
        (void)ks::smooth_feature_bilateral(a);
    }
    (void)ks::smooth_feature_bilateral(b);
    CHECK(a.vertices == b.vertices);

    // Real data with sharp edges found (so the edge filters and the sharp-edge walks of
    // the face filters run), and the detection alone: bit-identical with 1 and 2 threads.
    const auto block = ks::read_mesh(test_data("block_noisy.ply"));
    auto c = block, d = block;
    ks::FeatureBilateralResult rc, rd;
    ks::SharpFeatureResult fc, fd;
    {
        ks::ThreadLimit one(1);
        rc = ks::smooth_feature_bilateral(c);
        fc = ks::detect_sharp_features(block);
    }
    {
        ks::ThreadLimit two(2);
        rd = ks::smooth_feature_bilateral(d);
        fd = ks::detect_sharp_features(block);
    }
    CHECK(rc.feature_vertices > 500);
    CHECK(rc.features.sharp_edges == rd.features.sharp_edges);
    CHECK(fc.features.sharp_edges == fd.features.sharp_edges);
    CHECK(fc.features.edge_strength == fd.features.edge_strength);
    CHECK(c.vertices == d.vertices);
}

/// Whether the AVX bodies are missing here (a CPU without AVX, or a build with FMA enabled); then
/// reports the test as skipped.
namespace {
bool no_avx_body() {
    if (ks::detail::fbs::cpu_has_avx()) return false;
    std::cout << ks::test::skip_marker << ": no AVX body here (a CPU without AVX, or a build with FMA enabled)\n";
    return true;
}
}  // namespace

TEST_CASE("filter 3's AVX body gives the SSE2 body's bits, on lists of every length and both range kernels") {
    namespace fbs = ks::detail::fbs;
    if (no_avx_body()) return;
    // Normals as the passes hold them (padded float4): unit, noisy, a few zero (degenerate
    // faces) and a few opposite; lists of 0 to 41 neighbours (every remainder mod 8 and 4).
    std::mt19937 gen(5);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    const std::size_t nf = 500;
    std::vector<float, Eigen::aligned_allocator<float>> normal(4 * nf, 0.f);
    for (std::size_t t = 0; t < nf; ++t) {
        Eigen::Vector3f n(0.2f * u(gen), 0.2f * u(gen), 1.f);
        if (t % 7 == 0) n = Eigen::Vector3f(u(gen), u(gen), u(gen));
        if (t % 31 == 0) n.setZero();
        if (t % 13 == 0) n = -n;
        if (n.norm() > 0) n.normalize();
        for (int k = 0; k < 3; ++k) normal[4 * t + k] = n[k];
    }
    std::vector<std::uint32_t> index;
    std::vector<float> weight;
    for (std::size_t i = 0; i < 42 * 43 / 2; ++i) {
        index.push_back(static_cast<std::uint32_t>(gen() % nf));
        weight.push_back(0.5f + 0.5f * u(gen));
    }
    std::size_t compared = 0;
    for (const auto& [sigma, cut] : {std::pair{0.6, 1.0}, std::pair{0.3, 0.85}}) {
        const float a = static_cast<float>(1 / (2 * sigma * sigma)), cut2 = static_cast<float>(cut * cut);
        std::size_t first = 0;
        for (std::size_t len = 0; len <= 41; first += len, ++len) {
            // The list stored both ways: 32-bit indices, and 16-bit offsets from its smallest.
            const std::uint32_t base = len ? *std::min_element(index.begin() + first, index.begin() + first + len) : 0;
            std::vector<std::uint16_t> delta;
            for (std::size_t k = 0; k < len; ++k) delta.push_back(static_cast<std::uint16_t>(index[first + k] - base));
            const fbs::Neighbourhoods::Span wide{index.data() + first, nullptr, 0, weight.data() + first, len};
            const fbs::Neighbourhoods::Span narrow{nullptr, delta.data(), base, weight.data() + first, len};
            for (std::size_t t = 0; t < nf; t += 37) {
                const float* nt = normal.data() + 4 * t;
                const fbs::NormalSum s = fbs::sum_normals(normal.data(), nt, wide, a, cut2, false);
                for (const auto& span : {wide, narrow})
                    for (bool avx : {false, true}) {
                        const fbs::NormalSum w = fbs::sum_normals(normal.data(), nt, span, a, cut2, avx);
                        CHECK(std::memcmp(&s, &w, sizeof s) == 0);
                    }
                compared += len;
            }
        }
    }
    CHECK(compared > 10000);
}

TEST_CASE("neighbour lists: 16-bit offsets where a list spans at most 65535 indices, 32-bit elsewhere, the same lists") {
    namespace fbs = ks::detail::fbs;
    constexpr std::size_t chunk = fbs::Neighbourhoods::chunk;
    const std::size_t n = 3 * chunk + 100;  // four chunks, the last one short
    // Item i's list: i + 30000, i + 7 and one between; every 9th (every 4th on the second
    // build) also i + 7 + 65536, a span of 65536; every 10th i + 7 + 65535, a span of exactly
    // 65535; a few lists empty.
    auto list = [&](std::size_t i, bool second) {
        std::vector<std::uint32_t> q;
        if (i % 1000 == 17) return q;
        q = {std::uint32_t(i + 30000), std::uint32_t(i + 7), std::uint32_t(i + 30000 - (i % 5) * 1000)};
        if (i % (second ? 4 : 9) == 0) q.push_back(std::uint32_t(i + 7 + 65536));
        else if (i % 10 == 0) q.push_back(std::uint32_t(i + 7 + 65535));
        return q;
    };
    ks::RunControl control;
    ks::detail::Progress progress(control);
    fbs::Neighbourhoods lists;
    for (bool second : {false, true}) {  // the same lists object built again (kept capacities)
        fbs::build_neighbourhoods(n, lists, progress, 0, 1, [&](std::size_t i, auto&& append) {
            const std::vector<std::uint32_t> q = list(i, second);
            std::vector<float> w;
            for (std::uint32_t v : q) w.push_back(static_cast<float>(v) * 0.5f);
            append(q.data(), w.data(), q.size());
        });
        REQUIRE(lists.parts.size() == 4);
        std::size_t checked = 0, wide = 0, narrow = 0;
        for (std::size_t i = 0; i < n; ++i) {
            const std::vector<std::uint32_t> q = list(i, second);
            const fbs::Neighbourhoods::Span s = lists.of(i);
            REQUIRE(s.size == q.size());
            const bool far = !q.empty() && *std::max_element(q.begin(), q.end()) - *std::min_element(q.begin(), q.end()) > 65535;
            CHECK((s.index != nullptr) == far);
            (far ? wide : narrow) += 1;
            for (std::size_t j = 0; j < q.size(); ++j) {
                CHECK(s.at(j) == q[j]);
                CHECK(s.with_indices([&](auto index) { return index[j]; }) == q[j]);
                CHECK(s.weight[j] == static_cast<float>(q[j]) * 0.5f);
                ++checked;
            }
        }
        CHECK(checked > 3 * n);
        // The sums and weights read the stored lists as the plain ones, in either width and
        // whatever the CPU (the AVX bodies too where there are).
        const std::size_t items = n + 30000 + 65536 + 8;
        std::vector<float, Eigen::aligned_allocator<float>> normal(4 * items, 0.f);
        fbs::FaceGeometry g;
        for (std::size_t t = 0; t < items; ++t) {
            const double a = 0.001 * static_cast<double>(t % 997);
            const ks::Vec3 nt = ks::Vec3(std::sin(a), std::cos(a), 0.3).normalized();
            for (int k = 0; k < 3; ++k) normal[4 * t + k] = static_cast<float>(nt[k]);
            g.centroid.emplace_back(std::cos(a), std::sin(a), 0.01 * static_cast<double>(t % 13));
            g.area.push_back(0.5 + 0.001 * static_cast<double>(t % 7));
        }
        g.normal.assign(items, ks::Vec3::UnitZ());
        fbs::CentroidArea ca;
        fbs::pack_centroid_area(g, ca);
        const fbs::GaussTable f(0.7, 3.0);
        for (std::size_t i = 0; i < n; i += 7) {
            const std::vector<std::uint32_t> q = list(i, second);
            const fbs::Neighbourhoods::Span s = lists.of(i);
            const fbs::IndexedList<fbs::WideIndex> plain{fbs::WideIndex{q.data()}, s.weight, q.size()};
            for (bool avx : {false, fbs::cpu_has_avx()}) {
                const fbs::NormalSum x = fbs::sum_normals(normal.data(), normal.data() + 4 * i, plain, 2.f, 1.f, avx);
                const fbs::NormalSum y = fbs::sum_normals(normal.data(), normal.data() + 4 * i, s, 2.f, 1.f, avx);
                CHECK(std::memcmp(&x, &y, sizeof x) == 0);
                std::vector<float> u(q.size()), v(q.size());
                fbs::spatial_weights(ca.data(), f, i, fbs::WideIndex{q.data()}, q.size(), u.data(), avx);
                s.with_indices([&](auto index) { fbs::spatial_weights(ca.data(), f, i, index, s.size, v.data(), avx); });
                CHECK(u == v);
            }
        }
        CHECK(wide > n / (second ? 5 : 10));  // both kinds in every chunk
        CHECK(narrow > n / 2);
    }
}

TEST_CASE("filter 3's spatial weights: the AVX body gives the scalar body's bits, inside, at and beyond the table's end") {
    namespace fbs = ks::detail::fbs;
    if (no_avx_body()) return;
    // Centroids in a cube of side 2 around the origin (squared distances 0 to 12), areas of
    // 0 to 1 with some zero; face 1 exactly at distance 1 from face 0, the table's last knot
    // (max2 = 1), so one weight is the value at the end rather than an interpolation.
    std::mt19937 gen(9);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const std::size_t nf = 400;
    fbs::FaceGeometry g;
    for (std::size_t t = 0; t < nf; ++t) {
        g.centroid.emplace_back(u(gen), u(gen), u(gen));
        g.area.push_back(t % 11 == 0 ? 0.0 : 0.5 + 0.5 * u(gen));
    }
    g.centroid[0] = ks::Vec3(0.25, -0.5, 0.125);
    g.centroid[1] = g.centroid[0] + ks::Vec3(1, 0, 0);
    g.area[1] = 1;
    g.normal.assign(nf, ks::Vec3::UnitZ());
    fbs::CentroidArea ca;
    fbs::pack_centroid_area(g, ca);
    const fbs::GaussTable f(0.5, 1.0);
    std::vector<std::uint32_t> index{1};  // the pair at the last knot first
    for (std::size_t i = 0; i < 42 * 43 / 2; ++i) index.push_back(static_cast<std::uint32_t>(gen() % nf));
    std::size_t compared = 0, zero = 0, inside = 0;
    std::size_t first = 0;
    for (std::size_t len = 0; len <= 41; first += len, ++len) {
        for (std::size_t t : {std::size_t{0}, std::size_t{3}, std::size_t{57}, std::size_t{398}}) {
            std::vector<float> a(len + 1, -1.f), b(len + 1, -1.f), c(len + 1, -1.f);
            const fbs::WideIndex wide{index.data() + first};
            fbs::spatial_weights(ca.data(), f, t, wide, len, a.data(), false);
            fbs::spatial_weights(ca.data(), f, t, wide, len, b.data(), true);
            CHECK(std::memcmp(a.data(), b.data(), sizeof(float) * a.size()) == 0);
            CHECK(b[len] == -1.f);  // nothing written past the list
            std::vector<std::uint16_t> delta;  // 16-bit offsets from 3 below the list's indices
            for (std::size_t k = 0; k < len; ++k) delta.push_back(static_cast<std::uint16_t>(index[first + k] + 3));
            fbs::spatial_weights(ca.data(), f, t, fbs::NarrowIndex{delta.data(), std::uint32_t(-3)}, len, c.data(), true);
            CHECK(std::memcmp(a.data(), c.data(), sizeof(float) * a.size()) == 0);
            for (std::size_t k = 0; k < len; ++k) {
                (a[k] == 0 ? zero : inside) += 1;
                // The definition: a_q·f((dx² + dy²) + dz²) in double, stored as float.
                const ks::Vec3 d = g.centroid[index[first + k]] - g.centroid[t];
                CHECK(a[k] == static_cast<float>(g.area[index[first + k]] * f((d.x() * d.x() + d.y() * d.y()) + d.z() * d.z())));
            }
            compared += len;
        }
    }
    CHECK(compared > 3000);
    CHECK(zero > 100);  // beyond the table (and zero areas)
    CHECK(inside > 100);
    // The pair at the last knot, in the first lane of a group of four: the table's end value
    // (exp(-2)), not 0.
    const std::uint32_t four[4] = {1, 2, 3, 4};
    float w[4] = {};
    fbs::spatial_weights(ca.data(), f, 0, fbs::WideIndex{four}, 4, w, true);
    CHECK(w[0] == static_cast<float>(g.area[1] * f(1.0)));
    CHECK(w[0] == doctest::Approx(std::exp(-2.0)).epsilon(1e-6));
}

TEST_CASE("open meshes: boundary edges are not sharp, boundary vertices move only across the surface") {
    auto open = ss::box_mesh(10);
    // Remove the top side (z = 1): its faces have all three vertices at z = 1.
    std::erase_if(open.faces, [&](const ks::Face& f) {
        return open.vertices[f[0]].z() == 1.0 && open.vertices[f[1]].z() == 1.0 && open.vertices[f[2]].z() == 1.0;
    });
    const ks::MeshTopology topo(open);
    REQUIRE(topo.boundary_loops().size() == 1);
    const auto r = ks::detect_sharp_features(open);
    for (const auto& e : r.features.sharp_edges) {
        const auto id = topo.find_edge(e[0], e[1]);
        REQUIRE(id);
        CHECK_FALSE(topo.is_boundary_edge(*id));
    }
    CHECK(r.features.sharp_edges.size() == 8 * 10);  // the 8 box edges left, none on the rim

    // A flat open patch with noise across it: the boundary stays where it is in the plane.
    ks::IndexedMesh patch;
    const int n = 20;
    std::uint32_t x = 5;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            x = x * 1664525u + 1013904223u;
            patch.vertices.emplace_back(i, j, 0.2 * (double(x >> 8) / double(1u << 24) - 0.5));
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const ks::Index a = ks::Index(j * (n + 1) + i);
            patch.faces.push_back({a, a + 1, a + n + 2});
            patch.faces.push_back({a, a + n + 2, a + n + 1});
        }
    // The filters (the risk selection off: on this flat patch it returns Taubin's result, whose
    // umbrella steps pull an open border inward, the corners by 1.7|e|; moving border vertices
    // along their normals only, as the low-pass does, cost CGAL's elephant-with-holes 0.8-5.1 deg
    // at 0.3-0.7|e|:
    // docs/methods/feature_bilateral.md, "Faces coplanar by accident").
    for (const bool select : {false, true}) {
        auto smoothed = patch;
        const auto r = ks::smooth_feature_bilateral(smoothed, {.risk_selection = select});
        REQUIRE(r.status == ks::Status::ok);
        double before = 0, after = 0, tangential = 0;
        for (std::size_t v = 0; v < patch.vertices.size(); ++v) {
            before += patch.vertices[v].z() * patch.vertices[v].z();
            after += smoothed.vertices[v].z() * smoothed.vertices[v].z();
            tangential = std::max(tangential, (smoothed.vertices[v] - patch.vertices[v]).head<2>().norm());
        }
        MESSAGE("open patch, risk selection " << select << std::string(r.risk.taubin ? " (Taubin's result)" : "")
                                              << ": rms height " << std::sqrt(before / double(patch.vertices.size()))
                                              << " -> " << std::sqrt(after / double(patch.vertices.size()))
                                              << ", largest move across the plane " << tangential);
        CHECK(after < before / 4);  // the rms height at least halves
        if (!select) CHECK(tangential < 0.05);  // no shrinking of the boundary
    }
}

TEST_CASE("non-manifold and degenerate input work and give finite results") {
    auto m = ss::add_normal_noise(ss::box_mesh(6), 0.01, 11);
    // A fin: a third face on an existing edge (non-manifold edge) ...
    const ks::Face f0 = m.faces[0];
    m.vertices.emplace_back(0.5, 0.5, -0.3);
    m.faces.push_back({f0[0], f0[1], m.vertices.size() - 1});
    // ... a zero-area face (three collinear vertices), a face with a repeated index,
    // and an isolated vertex.
    m.vertices.emplace_back(2, 2, 2);
    m.vertices.emplace_back(3, 3, 3);
    m.vertices.emplace_back(4, 4, 4);
    const ks::Index n = m.vertices.size();
    m.faces.push_back({n - 3, n - 2, n - 1});
    m.faces.push_back({f0[0], f0[0], f0[2]});
    m.vertices.emplace_back(9, 9, 9);
    const auto r = ks::smooth_feature_bilateral(m);
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.degenerate_faces == 2);
    CHECK(all_finite(m));
    CHECK(m.vertices.back() == ks::Vec3(9, 9, 9));  // used by no face: never moved
    const auto f = ks::detect_sharp_features(m);
    for (double s : f.features.edge_strength) CHECK(std::isfinite(s));
}

TEST_CASE("real data: Block0.4 (guided denoising) beats Taubin, smooth_shape and features=false") {
    const auto noisy_path = test_data("block_noisy.ply"), clean_path = test_data("block_clean.ply");
    REQUIRE(std::filesystem::exists(noisy_path));
    const auto noisy = ks::read_mesh(noisy_path);
    const auto clean = ks::read_mesh(clean_path);
    REQUIRE(noisy.faces == clean.faces);
    const double L = ks::mean_edge_length(clean);

    // Sharp edges on the noisy mesh against the clean mesh's edges sharper than 60°.
    const auto reference = ss::crease_edges(clean, 60);
    const auto det = ks::detect_sharp_features(noisy);
    const auto pr = ss::compare_edges(det.features.sharp_edges, reference);
    MESSAGE("sharp edges: precision " << pr.precision << " recall " << pr.recall << " (" << pr.detected
                                      << " found, " << pr.reference << " in the clean mesh)");
    CHECK(pr.precision >= 0.9);
    CHECK(pr.recall >= 0.9);

    auto ours = noisy;
    REQUIRE(ks::smooth_feature_bilateral(ours).status == ks::Status::ok);
    const auto m_ours = ks::denoise_metrics(ours, clean);
    auto plain = noisy;
    (void)ks::smooth_feature_bilateral(plain, {.features = false});
    const auto m_plain = ks::denoise_metrics(plain, clean);
    // Peers, each at its best setting of a small sweep (by normal error).
    ks::DenoiseMetrics m_taubin{1e9, 1e9, 0};
    for (std::size_t it : {10, 30, 50}) {
        auto t = noisy;
        (void)ks::smooth_taubin(t, {}, {.iterations = it});
        const auto mt = ks::denoise_metrics(t, clean);
        if (mt.mean_normal_angle_deg < m_taubin.mean_normal_angle_deg) m_taubin = mt;
    }
    // smooth_shape's time step is in squared length units: the sweep is in |e|² (as in bench_smooth).
    const auto m_shape = ks::denoise_metrics(ss::best_smooth_shape(noisy, clean), clean);
    const auto m_noisy = ks::denoise_metrics(noisy, clean);
    MESSAGE("Block0.4 normal error (deg) / vertex rms (|e|): noisy " << m_noisy.mean_normal_angle_deg << " / "
            << m_noisy.vertex_rms / L << ", ours " << m_ours.mean_normal_angle_deg << " / " << m_ours.vertex_rms / L
            << ", features=false " << m_plain.mean_normal_angle_deg << " / " << m_plain.vertex_rms / L << ", Taubin "
            << m_taubin.mean_normal_angle_deg << " / " << m_taubin.vertex_rms / L << ", smooth_shape "
            << m_shape.mean_normal_angle_deg << " / " << m_shape.vertex_rms / L);
    CHECK(m_ours.mean_normal_angle_deg < 6.5);
    // The feature handling matters: sharp edges bounding the face filters' cubes take
    // more than a degree off the normal error of the same filters without features.
    CHECK(m_ours.mean_normal_angle_deg < m_plain.mean_normal_angle_deg - 1.0);
    CHECK(m_ours.mean_normal_angle_deg < m_taubin.mean_normal_angle_deg);
    CHECK(m_ours.mean_normal_angle_deg < m_shape.mean_normal_angle_deg);
    CHECK(m_ours.vertex_rms < m_plain.vertex_rms);
    CHECK(m_ours.vertex_rms < m_taubin.vertex_rms);
    CHECK(m_ours.vertex_rms < m_shape.vertex_rms);
    // Volume (closed genus-3 block) changes by at most 0.5 %.
    CHECK(std::abs(ks::signed_volume(ours) / ks::signed_volume(noisy) - 1) <= 0.005);
}

TEST_CASE("shared data: SharpSphere0.3 and Twelve0.5Impulsive against the peers") {
    const auto root = std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / "guided_denoising";
    KINTSUGI_REQUIRE_DATA(root);
    for (const char* name : {"SharpSphere0.3", "Twelve0.5Impulsive"}) {
        const bool twelve = std::string(name) == "Twelve0.5Impulsive";
        const auto noisy = ks::read_mesh(root / name / "Noisy.obj");
        const auto clean = ks::read_mesh(root / name / "Original.obj");
        auto ours = noisy, plain = noisy, taubin = noisy;
        const auto r = ks::smooth_feature_bilateral(ours);
        (void)ks::smooth_feature_bilateral(plain, {.features = false});
        (void)ks::smooth_taubin(taubin, {}, {.iterations = 30});
        const auto mo = ks::denoise_metrics(ours, clean), mp = ks::denoise_metrics(plain, clean),
                   mt = ks::denoise_metrics(taubin, clean);
        MESSAGE(std::string(name) << ": ours " << mo.mean_normal_angle_deg << " deg / " << mo.vertex_rms << ", features=false "
                     << mp.mean_normal_angle_deg << " / " << mp.vertex_rms << ", Taubin(30) "
                     << mt.mean_normal_angle_deg << " / " << mt.vertex_rms);
        // Twelve's 63° creases under its impulsive noise come from the faces the noise left
        // in their planes (the voting tensor alone: recall 0.019, 7.67 deg). On SharpSphere the
        // detected edges (P/R about 0.5/0.5) cost 0.5 deg against features = false
        // (docs/methods/feature_bilateral.md).
        const auto pr = ss::compare_edges(ks::detect_sharp_features(noisy).features.sharp_edges,
                                          ss::crease_edges(clean, 60));
        MESSAGE(std::string(name) << ": sharp edges P " << pr.precision << " R " << pr.recall << ", anchored faces "
                     << r.features.anchored_faces);
        if (twelve) {
            CHECK(pr.precision >= 0.8);  // 0.907 (0.856 with the earlier 0.5° / 0.01|e| anchoring)
            CHECK(pr.recall >= 0.8);     // 0.833 (0.819)
            CHECK(r.features.anchored_faces > 1000);
        }
        CHECK(mo.mean_normal_angle_deg < mt.mean_normal_angle_deg - 0.4);
        CHECK(mo.vertex_rms < mt.vertex_rms);
        CHECK(mo.mean_normal_angle_deg < (twelve ? 4.5 : 8.0));  // 3.99, 7.56 (before the stage: 7.67, 7.56)
        CHECK(mo.mean_normal_angle_deg <= mp.mean_normal_angle_deg + 0.6);
        if (twelve) CHECK(mo.mean_normal_angle_deg < mp.mean_normal_angle_deg - 2);
        CHECK(std::abs(ks::signed_volume(ours) / ks::signed_volume(noisy) - 1) <= 0.005);
    }
}

/// The sharp edges of `noisy` detected with `params` and with the defaults, and their precision
/// and recall against `reference`.
struct DetectionPair {
    ks::SharpFeatureResult given, defaults;
    ss::PrecisionRecall given_pr, defaults_pr;
};
DetectionPair detect_both(const ks::IndexedMesh& noisy, const ks::SharpFeatureParams& params,
                          const std::set<std::array<ks::Index, 2>>& reference) {
    DetectionPair out{ks::detect_sharp_features(noisy, params), ks::detect_sharp_features(noisy), {}, {}};
    REQUIRE(out.given.status == ks::Status::ok);
    REQUIRE(out.defaults.status == ks::Status::ok);
    out.given_pr = ss::compare_edges(out.given.features.sharp_edges, reference);
    out.defaults_pr = ss::compare_edges(out.defaults.features.sharp_edges, reference);
    return out;
}

TEST_CASE("impulsive noise: creases read from the faces left in their planes (twelve.obj, repository data)") {
    // The clean Twelve (63° creases) with 10 % of its vertices moved along the normals by
    // Gaussian amounts of sigma = |e| (bench_smooth's impulsive model, seed 11).
    auto clean = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "twelve.obj");
    clean.normals.clear();
    const double L = ks::mean_edge_length(clean);
    const auto noisy = ss::add_impulsive_noise(clean, L, 11);
    const auto reference = ss::crease_edges(clean, 60);
    REQUIRE(reference.size() == 480);
    ks::SharpFeatureParams tensor_only;
    tensor_only.coplanar_creases = false;
    tensor_only.straight_creases = false;
    const auto [tensor, both, pt, pb] = detect_both(noisy, tensor_only, reference);
    MESSAGE("voting tensor P " << pt.precision << " R " << pt.recall << "; with the coplanar faces P " << pb.precision
                               << " R " << pb.recall << " (" << both.features.anchored_faces << " anchored faces, "
                               << both.features.coplanar_sharp_edges << " edges from their planes)");
    CHECK(pt.recall < 0.1);  // 0.006: the averaged normals do not show the creases
    CHECK(tensor.features.anchored_faces == 0);
    CHECK(both.features.anchored_faces > 5000);  // 6,686 of 9,216
    CHECK(pb.precision >= 0.8);                  // 0.828 (the tensor's own edges are mostly wrong here)
    CHECK(pb.recall >= 0.95);                    // 0.971
    // The union: every edge the tensor found is kept.
    CHECK(std::includes(both.features.sharp_edges.begin(), both.features.sharp_edges.end(),
                        tensor.features.sharp_edges.begin(), tensor.features.sharp_edges.end()));
    // The smoothing: 7.57 deg without the stage, 2.76 with its creases, 1.10 with the
    // unmoved vertices (corners of two anchored faces or more) also held in place.
    // (Impulse removal off: this measures the coplanar stage alone; with it, below.)
    auto with = noisy, creases_only = noisy, without = noisy;
    const auto rw = ks::smooth_feature_bilateral(with, {.impulse_removal = false});
    ks::FeatureBilateralParams p;
    p.impulse_removal = false;
    p.hold_unmoved = false;
    const auto rc = ks::smooth_feature_bilateral(creases_only, p);
    p.detection.coplanar_creases = false;
    auto straight_only = noisy;  // the straight-crease detection finds some of the creases too
    const auto rs = ks::smooth_feature_bilateral(straight_only, p);
    p.detection.straight_creases = false;
    const auto ro = ks::smooth_feature_bilateral(without, p);
    const double ew = ks::denoise_metrics(with, clean).mean_normal_angle_deg,
                 ec = ks::denoise_metrics(creases_only, clean).mean_normal_angle_deg,
                 es = ks::denoise_metrics(straight_only, clean).mean_normal_angle_deg,
                 eo = ks::denoise_metrics(without, clean).mean_normal_angle_deg;
    MESSAGE("smoothing: " << ew << " deg (" << rw.held_vertices << " vertices held), " << ec
                          << " with the creases only, " << es << " without the stage, " << eo
                          << " without it and the straight-crease detection");
    CHECK(ew < 2.0);
    CHECK(ew < ec - 1);
    CHECK(ec < es - 0.5);  // 2.75, 3.66
    CHECK(ec < eo - 3);    // 7.57
    CHECK(rs.features.straight_sharp_edges > 0);
    CHECK(rc.held_vertices == 0);
    CHECK(ro.held_vertices == 0);
    // The held vertices are vertices the noise did not move (or by less than the stage's
    // 0.01|e| tolerance), and they stay there (up to the round-off of the
    // internal frame's shift and scale).
    std::size_t kept = 0;
    for (std::size_t v = 0; v < clean.vertices.size(); ++v)
        kept += (with.vertices[v] - noisy.vertices[v]).norm() < 1e-9 * L &&
                (noisy.vertices[v] - clean.vertices[v]).norm() <= 0.01 * L;
    CHECK(rw.held_vertices > clean.vertices.size() / 2);
    CHECK(kept >= rw.held_vertices);
    // The paper preset does not use them.
    CHECK(!ks::FeatureBilateralParams::paper().detection.coplanar_creases);
    // Gaussian noise leaves almost no face in its plane (a few by accident, no crease
    // explained): the same edges as the tensor's.
    const auto gauss = ss::add_gaussian_noise(clean, 0.3 * L, true, 5);
    ks::SharpFeatureParams no_coplanar;
    no_coplanar.coplanar_creases = false;
    const auto g1 = ks::detect_sharp_features(gauss), g0 = ks::detect_sharp_features(gauss, no_coplanar);
    MESSAGE("Gaussian noise 0.3|e|: " << g1.features.anchored_faces << " anchored faces, "
                                      << g1.features.coplanar_sharp_edges << " edges from their planes");
    CHECK(g1.features.anchored_faces < clean.faces.size() / 100);
    CHECK(g1.features.coplanar_sharp_edges == 0);
    CHECK(g1.features.sharp_edges == g0.features.sharp_edges);
    // In random directions the noise's component along the normal is often near 0, so more
    // faces fall into a neighbour's plane by accident: at 0.1|e| 286 of the 9,216 (3 %) with
    // the earlier 0.5° / 0.01|e| tolerances, and 191 vertices held as if unmoved (the risk
    // selection then skipped). With 0.1° / 0.002|e|: 15, under 1 %, nothing held.
    const auto random = ss::add_gaussian_noise(clean, 0.1 * L, false, 11);
    auto random_out = random;
    const auto rr = ks::smooth_feature_bilateral(random_out);
    MESSAGE("Gaussian noise 0.1|e| in random directions: " << rr.features.anchored_faces << " anchored faces, "
                                                           << rr.held_vertices << " vertices held");
    REQUIRE(rr.status == ks::Status::ok);
    CHECK(rr.features.anchored_faces < clean.faces.size() / 100);
    CHECK(rr.held_vertices == 0);
    // A curved shape with the same impulsive noise: no face lies in a neighbour's plane (25
    // by accident at 0.5° / 0.01|e|), no crease is explained. (Denser curved meshes anchor
    // more by accident: bunny00 103 of 75,408 faces, 2,418 at the earlier tolerances, where
    // the support test cut 1,715 false creases to 104; docs/methods/feature_bilateral.md.)
    auto bunny = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "bunny.off");
    bunny.normals.clear();
    const auto bi = ss::add_impulsive_noise(bunny, ks::mean_edge_length(bunny), 11);
    const auto b1 = ks::detect_sharp_features(bi), b0 = ks::detect_sharp_features(bi, no_coplanar);
    MESSAGE("bunny.off, impulsive: " << b1.features.anchored_faces << " anchored faces, "
                                     << b1.features.coplanar_sharp_edges << " edges from their planes");
    CHECK(b1.features.anchored_faces < bunny.faces.size() / 100);
    CHECK(b1.features.coplanar_sharp_edges == 0);
    CHECK(b1.features.sharp_edges == b0.features.sharp_edges);
}

TEST_CASE("straight creases: Twelve's 63 deg creases under Gaussian noise; a prism's 30 deg sides not added") {
    // Twelve (repository data) with 0.1|e| of Gaussian noise along the normals, seed 11: the
    // default kernel's pre-smoothing averages across its 63 deg creases and the voting tensor finds
    // none; the narrow-kernel detection finds them on straight two-sided runs.
    auto clean = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "twelve.obj");
    clean.normals.clear();
    const double L = ks::mean_edge_length(clean);
    const auto noisy = ss::add_gaussian_noise(clean, 0.1 * L, true, 11);
    const auto reference = ss::crease_edges(clean, 60);
    REQUIRE(reference.size() == 480);
    ks::SharpFeatureParams off;
    off.straight_creases = false;
    const auto [without, with, p0, p1] = detect_both(noisy, off, reference);
    MESSAGE("Twelve + 0.1|e|: P/R " << p0.precision << "/" << p0.recall << " without, " << p1.precision << "/"
                                    << p1.recall << " with (" << with.features.straight_sharp_edges << " added)");
    CHECK(p0.recall < 0.05);  // 0
    CHECK(without.features.straight_sharp_edges == 0);
    CHECK(p1.precision >= 0.95);  // 1.000
    CHECK(p1.recall >= 0.95);     // 1.000
    CHECK(with.features.straight_sharp_edges == with.features.sharp_edges.size() - without.features.sharp_edges.size());
    CHECK(std::includes(with.features.sharp_edges.begin(), with.features.sharp_edges.end(),
                        without.features.sharp_edges.begin(), without.features.sharp_edges.end()));
    // The smoothing: 3.49 deg without, 1.86 with (the paper preset, raw normals: 1.94).
    auto a = noisy, b = noisy;
    ks::FeatureBilateralParams no_straight;
    no_straight.detection.straight_creases = false;
    const auto ra = ks::smooth_feature_bilateral(a, no_straight);
    const auto rb = ks::smooth_feature_bilateral(b);
    const double ea = ks::denoise_metrics(a, clean).mean_normal_angle_deg, eb = ks::denoise_metrics(b, clean).mean_normal_angle_deg;
    MESSAGE("Twelve + 0.1|e|: " << ea << " deg without, " << eb << " deg with");
    CHECK(ra.features.straight_sharp_edges == 0);
    CHECK(rb.features.straight_sharp_edges >= 400);
    CHECK(eb < 2.2);
    CHECK(eb < ea - 1);
    CHECK(ks::FeatureBilateralParams::paper().detection.straight_creases == false);

    // A 12-sided prism (sides 30 deg apart, caps at 90 deg) with 0.1 and 0.3|e|: the narrow kernel
    // reads parts of the 30 deg side edges as creases; the side test keeps them out, so the result
    // is the one without the detection, bit for bit.
    const auto prism = ss::cylinder_mesh(12, 10, 2);
    const double Lp = ks::mean_edge_length(prism);
    for (double level : {0.1, 0.3}) {
        CAPTURE(level);
        const auto noisy_prism = ss::add_gaussian_noise(prism, level * Lp, true, 11);
        auto c = noisy_prism, d = noisy_prism;
        const auto rc = ks::smooth_feature_bilateral(c, no_straight);
        const auto rd = ks::smooth_feature_bilateral(d);
        CHECK(rd.features.straight_sharp_edges == 0);
        CHECK(rd.features.sharp_edges == rc.features.sharp_edges);
        CHECK(c.vertices == d.vertices);
    }
}

TEST_CASE_TEMPLATE("impulsive noise on a box: the same creases on every mesh type and thread count", T, ks::IndexedMesh,
                   ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>, ss::SurfaceMesh) {
    const auto clean = ss::box_mesh(16);
    const auto noisy = ss::add_impulsive_noise(clean, 0.5 * ks::mean_edge_length(clean), 3, nullptr, 4);
    Holder<T> h(noisy);
    const auto r = ks::detect_sharp_features(h.mesh());
    REQUIRE(r.status == ks::Status::ok);
    const auto pr = ss::compare_edges(r.features.sharp_edges, ss::box_edges(clean));
    MESSAGE("box, 25 % of the vertices moved by 0.5|e|: P " << pr.precision << " R " << pr.recall << ", "
                                                          << r.features.anchored_faces << " anchored faces");
    CHECK(r.features.anchored_faces > 0);
    CHECK(r.features.coplanar_sharp_edges > 0);
    CHECK(pr.precision >= 0.9);
    CHECK(pr.recall >= 0.9);
    ks::SharpFeatureResult one;
    {
        ks::ThreadLimit limit(1);
        one = ks::detect_sharp_features(noisy);
    }
    CHECK(one.features.sharp_edges == r.features.sharp_edges);
    CHECK(one.features.anchored_faces == r.features.anchored_faces);
}

// ---------------------------------------------------------------- noise level

namespace {
// The estimate against the noise normal to the surface (its rms over the vertices)
// for Gaussian noise of 0.1 to 0.8 mean edge lengths along the normals and along random
// directions (from `from`|e| on); returns the worst ratio's distance from 1.
double noise_level_worst(const ks::IndexedMesh& clean, const std::string& name, double from = 0.1) {
    const double L = ks::mean_edge_length(clean);
    double worst = 0;
    for (bool along : {true, false})
        for (double k : {0.1, 0.3, 0.5, 0.7, 0.8}) {
            if (k < from) continue;
            double truth = 0;
            const auto noisy = ss::add_gaussian_noise(clean, k * L, along, 17, &truth);
            const ks::NoiseLevel e = ks::estimate_noise_level(noisy);
            REQUIRE(e.status == ks::Status::ok);
            CHECK(e.vertices_used == clean.vertices.size());
            const double ratio = e.sigma / truth;
            MESSAGE(name << (along ? " normals " : " random  ") << k << "|e|: truth " << truth / L << "|e|, estimate "
                         << e.sigma / L << "|e| (ratio " << ratio << "), clean |e| estimate "
                         << e.clean_edge_length / L << "|e|");
            CHECK(ratio > 0.75);
            CHECK(ratio < 1.25);
            if (along) CHECK(e.clean_edge_length / L == doctest::Approx(1.0).epsilon(0.1));
            worst = std::max(worst, std::abs(ratio - 1));
        }
    return worst;
}
}  // namespace

TEST_CASE("estimate_noise_level: within 25 % of the normal noise from 0.1 to 0.8 |e| on a CAD and a curved shape") {
    // The ring count was chosen on the guided-denoising pairs (Block0.4, SharpSphere0.3,
    // Twelve0.5Impulsive); these shapes were not used for it.
    CHECK(noise_level_worst(ss::box_mesh(24), "box") < 0.25);
    auto twelve = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "twelve.obj");
    twelve.normals.clear();
    CHECK(noise_level_worst(twelve, "twelve.obj") < 0.25);
    // A coarse curved mesh (1,839 vertices): to the quadric fits its own facets read as
    // noise of about 0.1|e| (a quadric does not follow the ears over two rings; 0.1|e|
    // along the normals read 1.38 times the truth with them alone); the umbrella
    // differences, which take over below 0.3|e|, read less of it.
    auto bunny = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "bunny.off");
    CHECK(noise_level_worst(bunny, "bunny.off") < 0.25);
    const auto clean_bunny = ks::estimate_noise_level(bunny);
    MESSAGE("clean bunny.off: " << clean_bunny.sigma / clean_bunny.mean_edge_length << "|e| (quadric "
                                << clean_bunny.quadric_sigma / clean_bunny.mean_edge_length << ", differences "
                                << clean_bunny.difference_sigma / clean_bunny.mean_edge_length << ")");
    CHECK(clean_bunny.quadric_sigma > 0.05 * clean_bunny.mean_edge_length);
    CHECK(clean_bunny.sigma == clean_bunny.difference_sigma);
    CHECK(clean_bunny.sigma < 0.5 * clean_bunny.quadric_sigma);
    // A clean box reads as noise-free: its faces are planes, every fit away from the
    // box edges is exact.
    const auto clean = ks::estimate_noise_level(ss::box_mesh(24));
    CHECK(clean.sigma < 1e-9);
    CHECK(clean.relative < 1e-9);
}

TEST_CASE("estimate_noise_level: scale, bad input, cancellation, thread count") {
    const auto noisy = ss::add_gaussian_noise(ss::box_mesh(16), 0.02, true, 5);
    const auto e = ks::estimate_noise_level(noisy);
    // Scaling the mesh by 1e6 (or 1e-200) scales sigma exactly: the fit runs in a
    // power-of-two frame.
    for (double f : {1e6, 1e-200}) {
        auto big = noisy;
        for (auto& p : big.vertices) p *= f;
        const auto eb = ks::estimate_noise_level(big);
        CHECK(eb.sigma / f == doctest::Approx(e.sigma).epsilon(1e-9));
        CHECK(eb.relative == doctest::Approx(e.relative).epsilon(1e-9));
        CHECK(eb.quadric_sigma / f == doctest::Approx(e.quadric_sigma).epsilon(1e-9));
        CHECK(eb.difference_sigma / f == doctest::Approx(e.difference_sigma).epsilon(1e-9));
    }
    auto expect_throw = [](auto&& call, const char* what) {
        try {
            call();
            FAIL("no exception");
        } catch (const ks::invalid_input& ex) {
            CHECK(std::string(ex.what()).find(what) != std::string::npos);
        }
    };
    expect_throw([] { (void)ks::estimate_noise_level(ks::IndexedMesh{}); }, "no faces");
    expect_throw([&] { (void)ks::estimate_noise_level(noisy, {.rings = 0}); }, "rings = 0");
    auto bad = noisy;
    bad.vertices[2].y() = std::numeric_limits<double>::infinity();
    expect_throw([&] { (void)ks::estimate_noise_level(bad); }, "vertex 2");
    bad = noisy;
    bad.faces[1][2] = 100000;
    expect_throw([&] { (void)ks::estimate_noise_level(bad); }, "face 1 uses vertex 100000");

    std::stop_source stop;
    stop.request_stop();
    ks::NoiseLevelParams p;
    p.control.stop = stop.get_token();
    const auto c = ks::estimate_noise_level(noisy, p);
    CHECK(c.status == ks::Status::cancelled);
    CHECK(c.sigma == 0);

    ks::NoiseLevel one;
    {
        ks::ThreadLimit limit(1);
        one = ks::estimate_noise_level(noisy);
    }
    CHECK(one.sigma == e.sigma);
    CHECK(one.clean_edge_length == e.clean_edge_length);
    CHECK(one.difference_sigma == e.difference_sigma);
    CHECK(e.difference_sigma > 0);  // light noise: the umbrella differences were used
}

TEST_CASE("shared data: estimate_noise_level within 25 % at 0.1|e| on detailed meshes (armadillo, the elephant)") {
    // The quadric fits alone read their detail as noise (0.1|e| read 1.54 and 1.88 times
    // the truth); the umbrella differences take most of it off. Neither mesh chose a constant.
    const auto root = std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / "cgal" / "meshes";
    KINTSUGI_REQUIRE_DATA(root / "armadillo.off");
    for (const char* name : {"armadillo.off", "elephant-with-holes.off"}) {
        auto clean = ks::read_mesh(root / name);
        clean.normals.clear();
        const double L = ks::mean_edge_length(clean);
        for (double k : {0.1, 0.3}) {
            double truth = 0;
            const auto noisy = ss::add_gaussian_noise(clean, k * L, true, 11, &truth);
            const auto e = ks::estimate_noise_level(noisy);
            MESSAGE(std::string(name) << " at " << k << "|e|: truth " << truth / L << ", estimate " << e.sigma / L << " (quadric "
                         << e.quadric_sigma / L << ", differences " << e.difference_sigma / L << ") |e|");
            CHECK(e.sigma / truth > 0.75);
            CHECK(e.sigma / truth < 1.25);
        }
        // 10 % of the vertices moved: heavy-tailed differences, the quadric estimate alone.
        const auto impulsive = ss::add_impulsive_noise(clean, L, 11);
        const auto ei = ks::estimate_noise_level(impulsive);
        CHECK(ei.difference_sigma == 0);
        CHECK(ei.sigma == ei.quadric_sigma);
    }
}

TEST_CASE("smooth_feature_bilateral: d and face_iterations from the estimated noise unless given") {
    const auto clean = ss::box_mesh(16);
    const double L0 = ks::mean_edge_length(clean);
    SUBCASE("unset: estimated, reported, and growing with the noise") {
        double truth_low = 0, truth_high = 0;
        auto low = ss::add_gaussian_noise(clean, 0.1 * L0, true, 3, &truth_low);
        auto high = ss::add_gaussian_noise(clean, 0.8 * L0, true, 3, &truth_high);
        // The automatic low-pass off: the mapping itself (with it, the filters see ~0.2|e|).
        const auto rl = ks::smooth_feature_bilateral(low, {.lowpass_noise = 0});
        const auto rh = ks::smooth_feature_bilateral(high, {.lowpass_noise = 0});
        CHECK(rl.lowpass_iterations == 0);
        CHECK(rh.lowpass_iterations == 0);
        REQUIRE(rl.noise_estimated);
        REQUIRE(rh.noise_estimated);
        CHECK(rl.noise.sigma == doctest::Approx(truth_low).epsilon(0.25));
        CHECK(rh.noise.sigma == doctest::Approx(truth_high).epsilon(0.25));
        CHECK(rl.d == 0.14);  // low noise: the measured default
        CHECK(rl.face_iterations == 2);  // 0.1|e|: two face iterations (three from 0.125|e|)
        auto clean_copy = clean;  // clean: one iteration, and the box stays a box
        const auto rc0 = ks::smooth_feature_bilateral(clean_copy);
        CHECK(rc0.face_iterations == 1);
        CHECK(ks::denoise_metrics(clean_copy, clean).mean_normal_angle_deg < 0.5);
        CHECK(rh.d > 0.2);  // strong noise: a wider range, more passes
        CHECK(rh.face_iterations > 3);
        CHECK(rh.face_iterations <= 8);
    }
    SUBCASE("light noise: three normal passes (ten flattened curved detail), ten with the low-pass") {
        ks::IndexedMesh twelve = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "twelve.obj");
        twelve.normals.clear();
        const double L = ks::mean_edge_length(twelve);
        const auto light = ss::add_gaussian_noise(twelve, 0.1 * L, true, 11);
        // The filters' rule: without the risk selection, and without the straight-crease detection
        // as when the rule was set (with it, the creases are found and 10 passes read 1.04 deg
        // against 1.86: docs/methods/feature_bilateral.md, "Straight creases").
        auto ours = light, ten = light;
        ks::FeatureBilateralParams three;
        three.risk_selection = false;
        three.detection.straight_creases = false;
        ks::FeatureBilateralParams ten_passes = three;
        ten_passes.normal_iterations = 10;
        const auto r = ks::smooth_feature_bilateral(ours, three);
        const auto r10 = ks::smooth_feature_bilateral(ten, ten_passes);
        CHECK(r.noise.relative < 0.2);
        CHECK(r.normal_iterations == 3);
        CHECK(r10.normal_iterations == 10);
        CHECK(r10.face_iterations == r.face_iterations);
        const double e = ks::denoise_metrics(ours, twelve).mean_normal_angle_deg;
        const double e10 = ks::denoise_metrics(ten, twelve).mean_normal_angle_deg;
        MESSAGE("twelve.obj at 0.1|e|: 3 normal passes " << e << " deg, 10 passes " << e10);
        CHECK(e < e10 - 1.0);
        auto strong = ss::add_gaussian_noise(twelve, 0.5 * L, true, 11);
        const auto rs = ks::smooth_feature_bilateral(strong);
        CHECK(rs.lowpass_iterations > 0);
        CHECK(rs.normal_iterations == 10);
        // Both d and the face iterations given: no estimate, ten passes.
        auto given = light;
        CHECK(ks::smooth_feature_bilateral(given, {.d = 0.14, .face_iterations = 2}).normal_iterations == 10);
    }
    SUBCASE("explicit values win and skip the estimate; the output is that of the same values set by hand") {
        const auto noisy = ss::add_gaussian_noise(clean, 0.8 * L0, true, 3);
        auto a = noisy, b = noisy;
        const auto ra = ks::smooth_feature_bilateral(a, {.d = 0.14, .face_iterations = 3});
        CHECK_FALSE(ra.noise_estimated);
        CHECK(ra.noise.sigma == 0);
        CHECK(ra.d == 0.14);
        CHECK(ra.face_iterations == 3);
        // Only d given: the iterations still come from the estimate, d does not (the
        // low-pass off: with it the estimate after it, ~0.2|e|, gives 3 iterations).
        const auto rb = ks::smooth_feature_bilateral(b, {.d = 0.3, .lowpass_noise = 0});
        CHECK(rb.noise_estimated);
        CHECK(rb.d == 0.3);
        CHECK(rb.face_iterations > 3);
        // The automatic choice equals passing the values it reports, the detection
        // settings the strong-noise rule raised (low-pass off) or the low-pass steps included.
        for (const double lowpass : {0.0, 0.2}) {
            auto c = noisy, e = noisy;
            // (The filters alone: with the values given there is no estimate to select with.)
            const auto rc = ks::smooth_feature_bilateral(c, {.lowpass_noise = lowpass, .risk_selection = false});
            ks::FeatureBilateralParams same{.d = rc.d, .detection = rc.detection, .face_iterations = rc.face_iterations,
                                            .normal_iterations = rc.normal_iterations,
                                            .lowpass_iterations = rc.lowpass_iterations, .risk_selection = false};
            if (lowpass == 0) {
                CHECK(rc.strong_noise);
                CHECK(rc.normal_iterations == 20);
                CHECK(rc.detection.presmooth_iterations > ks::FeatureBilateralParams{}.detection.presmooth_iterations);
                CHECK(rc.lowpass_iterations == 0);
            } else {
                CHECK_FALSE(rc.strong_noise);
                CHECK(rc.lowpass_iterations > 0);
            }
            const auto re = ks::smooth_feature_bilateral(e, same);
            CHECK_FALSE(re.noise_estimated);
            CHECK(re.lowpass_iterations == rc.lowpass_iterations);
            CHECK(c.vertices == e.vertices);
        }
    }
}

// The best mean normal error (degrees) of Taubin smoothing at 10, 20 and 50 iterations: the
// peer the noise table compares with.
double best_taubin_error(const ks::IndexedMesh& noisy, const ks::IndexedMesh& clean) {
    double best = 1e9;
    for (std::size_t it : {10, 20, 50}) {
        auto t = noisy;
        (void)ks::smooth_taubin(t, {}, {.iterations = it});
        best = std::min(best, ks::denoise_metrics(t, clean).mean_normal_angle_deg);
    }
    return best;
}

namespace {
// block_clean.ply (Block0.4's original) or tests/data/twelve.obj with Gaussian noise of
// 0.7 mean edge lengths along the normals (seed 11), and the best normal error of Taubin
// at 10/20/50 iterations on it.
struct StrongNoiseShape {
    ks::IndexedMesh clean, noisy;
    double L = 0, best_taubin = 1e9;
};
StrongNoiseShape strong_noise_shape(bool block) {
    StrongNoiseShape s;
    s.clean = ks::read_mesh(block ? test_data("block_clean.ply") : std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "twelve.obj");
    s.clean.normals.clear();
    s.L = ks::mean_edge_length(s.clean);
    s.noisy = ss::add_gaussian_noise(s.clean, 0.7 * s.L, true, 11);
    s.best_taubin = best_taubin_error(s.noisy, s.clean);
    return s;
}
}  // namespace

TEST_CASE("strong noise (0.7|e|), low-pass off: more normal passes and a stronger pre-smoothing for the detection") {
    // Tuned on the Block (block_clean.ply = Block0.4's original); Twelve was a check before
    // adopting the rule (its threshold keeps it off at 0.5|e|, where Twelve and SharpSphere
    // lost 0.6-0.8°). Without the rule = the same d and face iterations given by hand.
    for (const char* name : {"block", "twelve"}) {
        const bool block = std::string(name) == "block";
        const auto [clean, noisy, L, taubin] = strong_noise_shape(block);
        auto ours = noisy, without = noisy;
        // The filters alone (risk_selection off): the rule is theirs.
        const auto r = ks::smooth_feature_bilateral(ours, {.lowpass_noise = 0, .risk_selection = false});
        REQUIRE(r.strong_noise);
        CHECK(r.normal_iterations == 20);
        const auto rw = ks::smooth_feature_bilateral(without, {.d = r.d, .face_iterations = r.face_iterations,
                                                               .risk_selection = false});
        CHECK_FALSE(rw.strong_noise);
        CHECK(rw.normal_iterations == 10);
        const double e_ours = ks::denoise_metrics(ours, clean).mean_normal_angle_deg;
        const double e_without = ks::denoise_metrics(without, clean).mean_normal_angle_deg;
        MESSAGE(std::string(name) << " at 0.7|e|: normal error " << e_ours << " deg, without the strong-noise rule " << e_without
                     << ", best Taubin (10/20/50) " << taubin);
        CHECK(e_ours < e_without - 2.0);
        if (block) CHECK(e_ours < taubin);  // twelve: still behind Taubin (docs/methods/feature_bilateral.md)
        if (block) {  // the same bytes with one thread
            auto one = noisy;
            {
                ks::ThreadLimit limit(1);
                (void)ks::smooth_feature_bilateral(one, {.lowpass_noise = 0, .risk_selection = false});
            }
            CHECK(one.vertices == ours.vertices);
        }
        // At 0.5|e| (estimated r ≈ 0.43) the rule stays off.
        auto mid = ss::add_gaussian_noise(clean, 0.5 * L, true, 11);
        CHECK_FALSE(ks::smooth_feature_bilateral(mid, {.lowpass_noise = 0}).strong_noise);
    }
}

TEST_CASE("strong noise: a Taubin low-pass first brings it to ~0.2|e|, then the filters; 0.7|e| on the Block under 10 degrees") {
    // The target (0.2|e|) was chosen on the Block and fertility at 0.1-0.8|e|
    // (docs/methods/feature_bilateral.md); twelve.obj here was not used for it.
    SUBCASE("0.7|e| on the Block and twelve.obj") for (const char* name : {"block", "twelve"}) {
        const bool block = std::string(name) == "block";
        const auto [clean, noisy, L, taubin] = strong_noise_shape(block);
        auto ours = noisy, off = noisy;
        // The defaults (with the risk selection: the filters' result on both shapes) against the
        // filters alone without the low-pass.
        const auto r = ks::smooth_feature_bilateral(ours);
        (void)ks::smooth_feature_bilateral(off, {.lowpass_noise = 0, .risk_selection = false});
        CHECK(r.risk.evaluated);
        CHECK_FALSE(r.risk.taubin);
        CHECK(r.lowpass_iterations >= 3);
        CHECK(r.lowpass_iterations <= 8);
        CHECK(r.noise.sigma == doctest::Approx(0.7 * L).epsilon(0.25));  // the input's noise, reported
        CHECK(r.noise_after_lowpass.sigma <= 0.2 * r.noise_after_lowpass.mean_edge_length);
        CHECK(r.noise_after_lowpass.sigma > 0.1 * r.noise_after_lowpass.mean_edge_length);  // not over-smoothed
        CHECK_FALSE(r.strong_noise);
        const auto m = ks::denoise_metrics(ours, clean), m_off = ks::denoise_metrics(off, clean);
        MESSAGE(std::string(name) << " at 0.7|e|: " << r.lowpass_iterations << " low-pass steps, normal error " << m.mean_normal_angle_deg
                     << " deg / rms " << m.vertex_rms / L << "|e|; low-pass off " << m_off.mean_normal_angle_deg << " / "
                     << m_off.vertex_rms / L << "; best Taubin (10/20/50) " << taubin);
        CHECK(m.mean_normal_angle_deg < m_off.mean_normal_angle_deg - 1.0);
        CHECK(m.vertex_rms < m_off.vertex_rms);
        if (block) CHECK(m.mean_normal_angle_deg < 10.0);  // issue goal: at most 10 degrees at 0.7|e| on a CAD part
        CHECK(m.mean_normal_angle_deg < taubin);
        // The face iterations follow the input's noise (r ≈ 0.7: 6), not the noise after
        // the low-pass (≈ 0.2, which gave 3 at every strong level): same d, same low-pass.
        CHECK(r.face_iterations == static_cast<std::size_t>(std::lround(1 + 7 * r.noise.relative)));
        CHECK(r.face_iterations >= 5);
        auto three = noisy;
        const auto r3 = ks::smooth_feature_bilateral(three, {.face_iterations = 3, .risk_selection = false});
        CHECK(r3.lowpass_iterations == r.lowpass_iterations);
        CHECK(r3.d == r.d);
        const double e3 = ks::denoise_metrics(three, clean).mean_normal_angle_deg;
        MESSAGE(std::string(name) << ": " << r.face_iterations << " face iterations " << m.mean_normal_angle_deg << " deg, 3 iterations " << e3);
        CHECK(m.mean_normal_angle_deg < e3 - 0.5);
    }
    SUBCASE("low noise: no step, the same bytes as no low-pass with the same face iterations") {
        const auto clean = ss::box_mesh(16);
        // 0.1|e| and 0.15|e|: the latter reads r ≈ 0.13-0.16, where the mapping without the
        // low-pass would give three face iterations and the input's-noise rule gives two.
        for (const double k : {0.1, 0.15}) {
            const auto noisy = ss::add_gaussian_noise(clean, k * ks::mean_edge_length(clean), true, 5);
            auto a = noisy, b = noisy;
            const auto ra = ks::smooth_feature_bilateral(a, {.risk_selection = false});
            const auto rb = ks::smooth_feature_bilateral(b, {.face_iterations = ra.face_iterations, .lowpass_iterations = 0,
                                                             .risk_selection = false});
            CHECK(ra.lowpass_iterations == 0);
            CHECK(ra.noise_after_lowpass.sigma == ra.noise.sigma);
            CHECK(ra.face_iterations == static_cast<std::size_t>(std::lround(1 + 7 * ra.noise.relative)));
            CHECK(rb.normal_iterations == ra.normal_iterations);
            CHECK(a.vertices == b.vertices);
        }
    }
    SUBCASE("steps given: run without an estimate, on any mesh type, whatever the thread count") {
        const auto clean = ss::box_mesh(12);
        const auto noisy = ss::add_gaussian_noise(clean, 0.6 * ks::mean_edge_length(clean), true, 5);
        const ks::FeatureBilateralParams p{.d = 0.14, .face_iterations = 3, .lowpass_iterations = 4};
        auto a = noisy, one = noisy;
        const auto ra = ks::smooth_feature_bilateral(a, p);
        CHECK_FALSE(ra.noise_estimated);
        CHECK(ra.lowpass_iterations == 4);
        {
            ks::ThreadLimit limit(1);
            (void)ks::smooth_feature_bilateral(one, p);
        }
        CHECK(one.vertices == a.vertices);
        ss::SurfaceMesh sm;
        ks::assign_mesh(sm, noisy);
        (void)ks::smooth_feature_bilateral(sm, p);
        for (std::size_t v = 0; v < a.vertices.size(); ++v) REQUIRE((ks::vertex_position(sm, v) - a.vertices[v]).norm() < 1e-12);
        // Rim vertices move in the low-pass along their normal only: their noise is smoothed,
        // and the rim is not pulled into the surface as moving them freely would pull it.
        // A square hole in the middle of the side x = 0 (its rim in that plane, normal -x).
        auto open = noisy;
        open.faces.clear();
        for (const auto& f : clean.faces) {
            const ks::Vec3 c = (clean.vertices[f[0]] + clean.vertices[f[1]] + clean.vertices[f[2]]) / 3;
            if (!(c.x() == 0 && c.y() > 0.3 && c.y() < 0.7 && c.z() > 0.3 && c.z() < 0.7)) open.faces.push_back(f);
        }
        REQUIRE(open.faces.size() < clean.faces.size());
        const ks::Vec3 n_side(-1, 0, 0);
        auto lp = open, free_rim = open;
        (void)ks::smooth_feature_bilateral(lp, {.d = 0.14, .face_iterations = 0, .features = false, .lowpass_iterations = 5});
        (void)ks::smooth_taubin(free_rim, {}, {.iterations = 5});  // every vertex moves with its umbrella
        const ks::MeshTopology topo(open.vertices.size(), open.faces);
        std::vector<char> on_rim(open.vertices.size(), 0);
        for (std::size_t e = 0; e < topo.num_edges(); ++e)
            if (topo.edge_faces(e).size() == 1)
                for (ks::Index v : topo.edges()[e]) on_rim[v] = 1;
        double err_noisy = 0, err_lp = 0, tangential_lp = 0, tangential_free = 0;
        std::size_t rim = 0;
        for (std::size_t v = 0; v < open.vertices.size(); ++v) {
            if (!on_rim[v]) continue;
            ++rim;
            const ks::Vec3& n = n_side;
            auto tangential = [&](const ks::Vec3& d) { return (d - n.dot(d) * n).squaredNorm(); };
            // the noise is along the clean normals, -x on the rim
            const double en = n.dot(open.vertices[v] - clean.vertices[v]), el = n.dot(lp.vertices[v] - clean.vertices[v]);
            err_noisy += en * en;
            err_lp += el * el;
            tangential_lp += tangential(lp.vertices[v] - open.vertices[v]);
            tangential_free += tangential(free_rim.vertices[v] - open.vertices[v]);
        }
        REQUIRE(rim > 0);
        MESSAGE("rim: normal error rms " << std::sqrt(err_noisy / rim) << " -> " << std::sqrt(err_lp / rim)
                                         << "; tangential motion rms " << std::sqrt(tangential_lp / rim)
                                         << " (moving freely " << std::sqrt(tangential_free / rim) << ")");
        CHECK(err_lp < 0.5 * err_noisy);
        CHECK(tangential_lp < 0.25 * tangential_free);
        auto lp_one = open;  // the rim step gives the same bytes with one thread
        {
            ks::ThreadLimit limit(1);
            (void)ks::smooth_feature_bilateral(lp_one, {.d = 0.14, .face_iterations = 0, .features = false, .lowpass_iterations = 5});
        }
        CHECK(lp_one.vertices == lp.vertices);
    }
}

namespace {
// Sum over the moved vertices of the squared error along the clean normals, (n·(p − x))².
double normal_error_sum(const ks::IndexedMesh& m, const ks::IndexedMesh& clean) {
    const auto n = ks::vertex_normals(clean);
    const ks::MeshTopology topo(clean.vertices.size(), clean.faces);
    double s = 0;
    for (std::size_t v = 0; v < clean.vertices.size(); ++v) {
        if (topo.vertex_neighbors(static_cast<ks::Index>(v)).empty()) continue;
        const double h = n[v].dot(m.vertices[v] - clean.vertices[v]);
        s += h * h;
    }
    return s;
}
ks::IndexedMesh repo_bunny() { return ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "bunny.off"); }
}  // namespace

TEST_CASE("taubin_risk_curves: Stein's estimate follows the true error of every step count") {
    // The repository's bunny (1,839 vertices) with Gaussian noise of 0.3|e| along the normals:
    // the estimate at k steps against the true squared error along the normals.
    const auto clean = repo_bunny();
    const double L = ks::mean_edge_length(clean);
    double sigma = 0;
    const auto noisy = ss::add_gaussian_noise(clean, 0.3 * L, true, 5, &sigma);
    const ks::MeshTopology topo(clean.vertices.size(), clean.faces);
    const auto normals = ks::vertex_normals(clean);
    ks::RunControl control;
    ks::detail::Progress progress(control);
    progress.stage("sweep", 0, 1);
    const auto curves = ks::detail::taubin_risk_curves(noisy.vertices, topo, normals, sigma, 60, {}, progress);
    REQUIRE(curves.residual.size() >= 31);
    CHECK(curves.moved == clean.vertices.size());
    CHECK(curves.trace[0] == doctest::Approx(double(curves.moved)));  // S_0 = I: exact
    const double m_s2 = double(curves.moved) * sigma * sigma;
    std::size_t true_best = 0;
    double true_best_err = 1e300;
    for (std::size_t k : {0u, 1u, 2u, 4u, 8u, 15u, 30u}) {
        auto t = noisy;
        (void)ks::smooth_taubin(t, {}, {.iterations = k});
        const double truth = normal_error_sum(t, clean);
        const double estimate = ks::detail::taubin_risk(curves, k, sigma);
        MESSAGE("k " << k << ": true " << truth / m_s2 << " estimate " << estimate / m_s2 << " (units of m sigma^2)");
        CHECK(std::abs(estimate - truth) < 0.06 * m_s2);
        if (truth < true_best_err) true_best_err = truth, true_best = k;
    }
    const std::size_t k = ks::detail::least_risk_steps(curves, sigma);
    auto t = noisy;
    (void)ks::smooth_taubin(t, {}, {.iterations = k});
    MESSAGE("least estimated risk at " << k << " steps (true best of those tried " << true_best << ")");
    CHECK(normal_error_sum(t, clean) < 1.05 * true_best_err);

    // Far from the origin (a georeferenced scan: 5e6 away, the bunny's extent ~0.15): the sweep
    // keeps positions in single precision relative to the box centre, so the curves stay those
    // of the mesh at the origin (cast without the centre, the residual at k = 0 read 0.07 mσ²
    // already at 1e4 and the least-risk count fell to 0).
    auto far = noisy.vertices;
    for (auto& v : far) v += ks::Vec3(5e6, -3e6, 2e6);
    const auto moved_curves = ks::detail::taubin_risk_curves(far, topo, normals, sigma, 60, {}, progress);
    REQUIRE(moved_curves.residual.size() == curves.residual.size());
    CHECK(moved_curves.residual[0] == 0);
    for (std::size_t j = 1; j < curves.residual.size(); ++j) {
        CHECK(std::abs(moved_curves.residual[j] - curves.residual[j]) < 1e-3 * m_s2);
        CHECK(moved_curves.trace[j] == doctest::Approx(curves.trace[j]).epsilon(1e-4));
    }
    CHECK(ks::detail::least_risk_steps(moved_curves, sigma) == k);

    // Renumbered (the vertices reversed, as select_by_risk holds them in its own order) with the
    // matching draw order: the same probes, so the same curves up to the single-precision sums
    // (the one-rings are summed in another order); without it the traces move by the
    // Monte-Carlo error (the draws change) and the count may follow.
    const std::size_t nv = clean.vertices.size();
    std::vector<ks::Index> to_new(nv);
    for (std::size_t v = 0; v < nv; ++v) to_new[v] = nv - 1 - v;
    ks::IndexedMesh renum{std::vector<ks::Vec3>(nv), clean.faces, {}};
    std::vector<ks::Vec3> renum_normals(nv), renum_y(nv);
    for (auto& f : renum.faces)
        for (auto& i : f) i = to_new[i];
    for (std::size_t v = 0; v < nv; ++v) {
        renum_y[to_new[v]] = noisy.vertices[v];
        renum_normals[to_new[v]] = normals[v];
    }
    const ks::MeshTopology renum_topo(nv, renum.faces);
    const auto same = ks::detail::taubin_risk_curves(renum_y, renum_topo, renum_normals, sigma, 60, {}, progress, to_new);
    const auto redrawn = ks::detail::taubin_risk_curves(renum_y, renum_topo, renum_normals, sigma, 60, {}, progress);
    REQUIRE(same.residual.size() == curves.residual.size());
    double redrawn_gap = 0;
    for (std::size_t j = 1; j < curves.residual.size(); ++j) {
        CHECK(same.residual[j] == doctest::Approx(curves.residual[j]).epsilon(1e-5));
        CHECK(same.trace[j] == doctest::Approx(curves.trace[j]).epsilon(1e-5));
        CHECK(same.trace_sq[j] == doctest::Approx(curves.trace_sq[j]).epsilon(1e-5));
        if (j < redrawn.trace.size())
            redrawn_gap = std::max(redrawn_gap, std::abs(redrawn.trace[j] / curves.trace[j] - 1));
    }
    MESSAGE("other draws: traces up to " << redrawn_gap << " relative from these");
    CHECK(redrawn_gap > 1e-3);  // the draw order matters: the check above is not vacuous
}

TEST_CASE_TEMPLATE("risk selection: Taubin's result on a smooth shape, the filters' on a box, on every mesh type", T,
                   ks::IndexedMesh, ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>, ss::SurfaceMesh) {
    SUBCASE("the bunny, 0.3|e| along the normals: Taubin, at least as good as its best of 10/20/50 steps") {
        const auto clean = repo_bunny();
        const double L = ks::mean_edge_length(clean);
        const auto noisy = ss::add_gaussian_noise(clean, 0.3 * L, true, 5);
        Holder<T> h(noisy);
        const auto r = ks::smooth_feature_bilateral(h.mesh(), {.risk_selection = true});
        REQUIRE(r.status == ks::Status::ok);
        REQUIRE(r.risk.evaluated);
        CHECK(r.risk.note.empty());
        CHECK(r.risk.taubin);
        CHECK(r.risk.taubin_rms * r.risk.taubin_rms < 0.75 * r.risk.filters_rms * r.risk.filters_rms);  // risks: squares
        CHECK(r.risk.sigma == doctest::Approx(0.3 * L).epsilon(0.15));
        const auto out = h.get();
        // Exactly smooth_taubin's result for that many steps (the bound only absorbs the mesh
        // types' conversions).
        auto taubin = noisy;
        (void)ks::smooth_taubin(taubin, {}, {.iterations = r.risk.taubin_iterations});
        for (std::size_t v = 0; v < out.vertices.size(); ++v)
            REQUIRE((out.vertices[v] - taubin.vertices[v]).norm() < 1e-12 * L);
        auto filters = noisy;
        (void)ks::smooth_feature_bilateral(filters, {.risk_selection = false});
        double best = 1e9;
        for (std::size_t it : {10u, 20u, 50u}) {
            auto t = noisy;
            (void)ks::smooth_taubin(t, {}, {.iterations = it});
            best = std::min(best, ks::denoise_metrics(t, clean).mean_normal_angle_deg);
        }
        const double e = ks::denoise_metrics(out, clean).mean_normal_angle_deg;
        const double ef = ks::denoise_metrics(filters, clean).mean_normal_angle_deg;
        MESSAGE("bunny 0.3|e|: selected " << e << " deg (" << r.risk.taubin_iterations << " Taubin steps), filters " << ef
                                          << ", best Taubin of 10/20/50 " << best << "; estimated rms "
                                          << r.risk.taubin_rms / L << " vs " << r.risk.filters_rms / L << " |e|");
        CHECK(e < ef);
        CHECK(e <= best + 0.05);
        CHECK(r.timings.back().stage == "risk: Taubin sweep");
    }
    SUBCASE("a box, 0.3|e| along the normals: the filters' result, unchanged") {
        const auto clean = ss::box_mesh(16);
        const auto noisy = ss::add_gaussian_noise(clean, 0.3 * ks::mean_edge_length(clean), true, 5);
        Holder<T> h(noisy);
        const auto r = ks::smooth_feature_bilateral(h.mesh(), {.risk_selection = true});
        REQUIRE(r.status == ks::Status::ok);
        CHECK(r.risk.evaluated);
        CHECK_FALSE(r.risk.taubin);
        MESSAGE("box 0.3|e|: estimated rms " << r.risk.taubin_rms << " (Taubin, " << r.risk.taubin_iterations
                                              << " steps) vs " << r.risk.filters_rms << " (filters)");
        auto reference = noisy;
        (void)ks::smooth_feature_bilateral(reference, {.risk_selection = false});
        const auto out = h.get();
        for (std::size_t v = 0; v < out.vertices.size(); ++v)
            REQUIRE((out.vertices[v] - reference.vertices[v]).norm() < 1e-12);
    }
}

namespace {
/// One cell of the risk-selection tests: the defaults on `noisy`, with the filters alone and
/// Taubin at the chosen count beside them, and the three mean normal errors against `clean`.
struct RiskCell {
    ks::FeatureBilateralResult r;
    ks::IndexedMesh out, filters, taubin;
    double e = 0, ef = 0, et = 0;
};
RiskCell risk_cell(const ks::IndexedMesh& clean, const ks::IndexedMesh& noisy) {
    RiskCell c{{}, noisy, noisy, noisy};
    c.r = ks::smooth_feature_bilateral(c.out);
    REQUIRE(c.r.status == ks::Status::ok);
    REQUIRE(c.r.risk.evaluated);
    (void)ks::smooth_feature_bilateral(c.filters, {.risk_selection = false});
    (void)ks::smooth_taubin(c.taubin, {}, {.iterations = c.r.risk.taubin_iterations});
    c.e = ks::denoise_metrics(c.out, clean).mean_normal_angle_deg;
    c.ef = ks::denoise_metrics(c.filters, clean).mean_normal_angle_deg;
    c.et = ks::denoise_metrics(c.taubin, clean).mean_normal_angle_deg;
    return c;
}
}  // namespace

TEST_CASE("risk selection on coarse and faceted meshes: Taubin's result where the filters flatten a curved surface, the filters' on a prism") {
    SUBCASE("a 24 x 12 torus (576 faces) at 0.8|e|: too coarse for the filters, Taubin's result") {
        const auto clean = fixtures::torus(24, 12, 1.0, 0.4);
        const double L = ks::mean_edge_length(clean);
        for (std::uint32_t seed : {11u, 12u}) {
            const auto [r, out, filters, taubin, e, ef, et] = risk_cell(clean, ss::add_gaussian_noise(clean, 0.8 * L, true, seed));
            MESSAGE("torus 24x12, 0.8|e|, seed " << seed << ": " << e << " deg (Taubin, " << r.risk.taubin_iterations
                                                 << " steps), filters " << ef << "; median angle "
                                                 << r.risk.median_dihedral * 180 / std::numbers::pi << " deg, risk ratio "
                                                 << r.risk.taubin_rms * r.risk.taubin_rms / (r.risk.filters_rms * r.risk.filters_rms));
            // The estimated risks favour the filters here; the coarseness keeps Taubin's result.
            CHECK(r.risk.taubin_rms > r.risk.filters_rms);
            CHECK(r.risk.coarse);
            CHECK(r.risk.taubin);
            CHECK(r.risk.median_dihedral > ks::detail::fbs::coarse_dihedral * r.d);
            CHECK(e < 10.0);   // 8.8 and 8.0 measured
            CHECK(ef > 18.0);  // 22.8 and 25.6: facets
            for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE((out.vertices[v] - taubin.vertices[v]).norm() == 0);
        }
    }
    SUBCASE("the same torus at 1.2|e|: the estimate under-reads strong noise, the selection still runs; Taubin's result") {
        // The input's estimate reads a relative noise of 0.73-0.74 (the quadric fits under-read
        // 1.2|e|); the Taubin residual implies 1.13 and 1.17 times it. Under the light-noise limit
        // (1.1) the selection was skipped and the filters' 23.7° and 26.5° returned;
        // risk_sigma_limit_strong accepts it.
        const auto clean = fixtures::torus(24, 12, 1.0, 0.4);
        const double L = ks::mean_edge_length(clean);
        for (std::uint32_t seed : {11u, 12u}) {
            const auto [r, out, filters, taubin, e, ef, et] = risk_cell(clean, ss::add_gaussian_noise(clean, 1.2 * L, true, seed));
            MESSAGE("torus 24x12, 1.2|e|, seed " << seed << ": " << e << " deg, filters " << ef << "; implied sigma / estimate "
                                                 << r.risk.sigma / r.noise.quadric_sigma);
            CHECK(r.noise.relative >= ks::detail::fbs::strong_noise_ratio);
            CHECK(r.risk.sigma > ks::detail::fbs::risk_sigma_limit * r.noise.quadric_sigma);
            CHECK(r.risk.sigma <= ks::detail::fbs::risk_sigma_limit_strong * r.noise.quadric_sigma);
            CHECK(r.risk.taubin);
            CHECK(e < 13.0);   // 11.4 and 9.7 measured
            CHECK(ef > 18.0);  // 23.7 and 26.5
            for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE((out.vertices[v] - taubin.vertices[v]).norm() == 0);
        }
    }
    SUBCASE("a 24 x 12 torus of radii 2 and 0.7 at 0.9|e|: the face-normal estimate reads Taubin worse, but the filters' height risk reads zero or below; no veto") {
        // The veto's estimate rests on the filters' probe response, which a non-positive height
        // risk shows to be outside the first-order regime: the veto would return the filters' 25.0°.
        const auto clean = fixtures::torus(24, 12, 2.0, 0.7);
        const double L = ks::mean_edge_length(clean);
        const auto [r, out, filters, taubin, e, ef, et] = risk_cell(clean, ss::add_gaussian_noise(clean, 0.9 * L, true, 12));
        MESSAGE("torus 24x12 (2, 0.7), 0.9|e|: " << e << " deg, filters " << ef << "; normal difference " << r.risk.normal_difference
                                                 << " rad^2 at z " << r.risk.normal_z);
        CHECK(r.risk.filters_rms == 0);
        CHECK(r.noise.relative >= ks::detail::fbs::strong_noise_ratio);
        CHECK(r.risk.normal_difference > ks::detail::fbs::normal_veto_min);  // 0.128 measured
        CHECK(r.risk.normal_z > ks::detail::fbs::normal_veto_z);             // 3.1
        CHECK_FALSE(r.risk.normal_veto);
        CHECK(r.risk.coarse);
        CHECK(r.risk.taubin);
        CHECK(e < 10.0);   // 8.2 measured
        CHECK(ef > 20.0);  // 25.0
        for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE((out.vertices[v] - taubin.vertices[v]).norm() == 0);
    }
    SUBCASE("a 30 x 15 torus (900 faces) at 0.5-0.8|e|: the filters' risk read again with the detection on the probes; Taubin's result") {
        // Below the coarseness bound, and the frozen estimate favours the filters (they flatten
        // the bending into facets along detected creases that follow the noise).
        const auto clean = fixtures::torus(30, 15);
        const double L = ks::mean_edge_length(clean);
        for (const double k : {0.5, 0.7, 0.8}) {
            CAPTURE(k);
            const auto [r, out, filters, taubin, e, ef, et] = risk_cell(clean, ss::add_gaussian_noise(clean, k * L, true, 11));
            const double ratio = r.risk.taubin_rms * r.risk.taubin_rms / (r.risk.filters_rms * r.risk.filters_rms);
            const double again = r.risk.taubin_rms * r.risk.taubin_rms / (r.risk.filters_rms_recheck * r.risk.filters_rms_recheck);
            MESSAGE("torus 30x15, " << k << "|e|: " << e << " deg (Taubin, " << r.risk.taubin_iterations << " steps), filters " << ef
                                    << "; median angle " << r.risk.median_dihedral / r.d << " d; risk ratio " << ratio
                                    << ", with the detection on " << r.risk.recheck_probes << " probes " << again);
            CHECK(ratio > ks::detail::fbs::risk_ratio);  // 1.09, 3.46, 0.88: the frozen estimate keeps the filters
            CHECK_FALSE(r.risk.coarse);
            CHECK(r.risk.median_dihedral > ks::detail::fbs::recheck_dihedral * r.d);
            CHECK(r.risk.recheck_probes == ks::detail::fbs::recheck_max_probes);
            CHECK(r.risk.filters_rms_recheck > 1.25 * r.risk.filters_rms);  // 2.0, 3.1, 1.4 times
            CHECK(again < ks::detail::fbs::recheck_ratio);  // 0.28, 0.35, 0.48
            CHECK(r.risk.recheck);
            CHECK_FALSE(r.risk.normal_veto);
            CHECK(r.risk.taubin);
            CHECK(e < 9.0);    // 6.2, 7.6, 8.4 measured
            CHECK(ef > 18.0);  // 19.7, 21.9, 22.6
            for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE((out.vertices[v] - taubin.vertices[v]).norm() == 0);
        }
    }
    SUBCASE("a 16-sided prism (352 faces) at 0.7|e|: not coarse, the filters' result") {
        const auto clean = ss::cylinder_mesh(16, 6, 2.0);
        const double L = ks::mean_edge_length(clean);
        const auto noisy = ss::add_gaussian_noise(clean, 0.7 * L, true, 11);
        auto out = noisy;
        const auto r = ks::smooth_feature_bilateral(out);
        REQUIRE(r.status == ks::Status::ok);
        REQUIRE(r.risk.evaluated);
        auto taubin = noisy;
        (void)ks::smooth_taubin(taubin, {}, {.iterations = r.risk.taubin_iterations});
        const double e = ks::denoise_metrics(out, clean).mean_normal_angle_deg;
        const double et = ks::denoise_metrics(taubin, clean).mean_normal_angle_deg;
        MESSAGE("prism 16, 0.7|e|: " << e << " deg (filters), Taubin " << et << "; median angle "
                                     << r.risk.median_dihedral * 180 / std::numbers::pi << " deg");
        CHECK_FALSE(r.risk.coarse);
        CHECK_FALSE(r.risk.taubin);
        // Read again with the detection on the probes: higher, not enough for Taubin (0.57).
        CHECK(r.risk.recheck_probes == ks::detail::fbs::recheck_max_probes);
        CHECK(r.risk.filters_rms_recheck > 0);
        CHECK_FALSE(r.risk.recheck);
        CHECK(r.risk.median_dihedral > 0);  // measured on Taubin's result, below the bound
        CHECK(r.risk.median_dihedral < ks::detail::fbs::coarse_dihedral * r.d);
        CHECK(e < 15.5);   // 14.8 measured
        CHECK(et > 15.8);  // 16.2
    }
    SUBCASE("a 16-sided prism with its caps wound against its sides: the heights choose Taubin, its face normals estimated far worse") {
        // Inconsistent orientation, as in meshes stitched from separately exported parts. Taubin's
        // heights are as good as the filters' (the height risks even favour it), its normals are not.
        auto clean = ss::cylinder_mesh(16, 6, 2.0);
        for (auto& f : clean.faces) {
            const bool cap = std::abs(clean.vertices[f[0]].z() - clean.vertices[f[1]].z()) < 1e-12 &&
                             std::abs(clean.vertices[f[0]].z() - clean.vertices[f[2]].z()) < 1e-12;
            if (cap) std::swap(f[1], f[2]);
        }
        const double L = ks::mean_edge_length(clean);
        for (const auto& [k, seed] : {std::pair{0.5, 12u}, std::pair{0.8, 11u}}) {
            CAPTURE(k);
            const auto [r, out, filters, taubin, e, ef, et] = risk_cell(clean, ss::add_gaussian_noise(clean, k * L, true, seed));
            MESSAGE("prism 16, caps reversed, " << k << "|e|, seed " << seed << ": " << e << " deg, Taubin " << et
                                                << "; normal difference " << r.risk.normal_difference << " rad^2 at z " << r.risk.normal_z);
            CHECK(r.risk.taubin_rms * r.risk.taubin_rms < ks::detail::fbs::risk_ratio * r.risk.filters_rms * r.risk.filters_rms);
            CHECK(r.risk.normal_veto);
            CHECK(r.risk.normal_difference > ks::detail::fbs::normal_veto_min);  // 0.087 and 0.073 measured
            CHECK(r.risk.normal_z > ks::detail::fbs::normal_veto_z);             // 5.2 and 2.8
            CHECK_FALSE(r.risk.taubin);
            CHECK_FALSE(r.risk.coarse);
            CHECK(e < 7.0);    // 5.5 and 5.6
            CHECK(et > 12.0);  // 15.1 and 16.1
            for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE((out.vertices[v] - filters.vertices[v]).norm() < 1e-12);
        }
    }
    SUBCASE("a 12-sided prism (216 faces) at 0.3|e|: coarse for the filters, yet Taubin's normals estimated far worse") {
        const auto clean = ss::cylinder_mesh(12, 4, 1.5);
        const double L = ks::mean_edge_length(clean);
        const auto noisy = ss::add_gaussian_noise(clean, 0.3 * L, true, 12);
        auto out = noisy, taubin = noisy;
        const auto r = ks::smooth_feature_bilateral(out);
        REQUIRE(r.risk.evaluated);
        (void)ks::smooth_taubin(taubin, {}, {.iterations = r.risk.taubin_iterations});
        const double e = ks::denoise_metrics(out, clean).mean_normal_angle_deg;
        const double et = ks::denoise_metrics(taubin, clean).mean_normal_angle_deg;
        MESSAGE("prism 12, 0.3|e|: " << e << " deg, Taubin " << et << "; median angle " << r.risk.median_dihedral * 180 / std::numbers::pi
                                     << " deg; normal difference " << r.risk.normal_difference << " rad^2 at z " << r.risk.normal_z);
        CHECK(r.risk.coarse);  // the median angle alone would keep Taubin's result
        CHECK(r.risk.filters_rms == 0);  // a non-positive height risk: the veto stands below strong noise
        CHECK(r.noise.relative < ks::detail::fbs::strong_noise_ratio);
        CHECK(r.risk.normal_veto);
        CHECK_FALSE(r.risk.taubin);
        CHECK(e < 7.0);    // 5.5 measured
        CHECK(et > 12.0);  // 13.7
    }
    SUBCASE("a 48 x 24 torus (2,304 faces) at 0.5|e|: Taubin's normals estimated better, Taubin's result") {
        const auto clean = fixtures::torus(48, 24, 1.0, 0.4);
        const double L = ks::mean_edge_length(clean);
        const auto noisy = ss::add_gaussian_noise(clean, 0.5 * L, true, 11);
        auto out = noisy, filters = noisy;
        const auto r = ks::smooth_feature_bilateral(out);
        REQUIRE(r.risk.evaluated);
        (void)ks::smooth_feature_bilateral(filters, {.risk_selection = false});
        const double e = ks::denoise_metrics(out, clean).mean_normal_angle_deg;
        const double ef = ks::denoise_metrics(filters, clean).mean_normal_angle_deg;
        MESSAGE("torus 48x24, 0.5|e|: " << e << " deg, filters " << ef << "; normal difference " << r.risk.normal_difference
                                        << " rad^2 at z " << r.risk.normal_z);
        CHECK(r.risk.taubin);
        CHECK_FALSE(r.risk.normal_veto);
        CHECK(r.risk.normal_difference < 0);  // -0.0026 measured
        CHECK(e < ef);                        // 3.5 against 4.1
    }
}

TEST_CASE("risk selection's second run on the first run's state: on the same input, the first run's result bit for bit") {
    // RunReuse hands the perturbed run the first run's vertex order, topology, workspace, filter-3
    // and filter-4 neighbour sets and edge length; given the same input, the values and the
    // sharp edges the first run used, it must redo exactly the first run (0.7|e|: low-pass steps).
    const auto clean = repo_bunny();
    const double L = ks::mean_edge_length(clean);
    for (const double k : {0.3, 0.7}) {
        CAPTURE(k);
        const auto noisy = ss::add_gaussian_noise(clean, k * L, true, 5);
        ks::IndexedMesh first = noisy, second = noisy;
        ks::detail::fbs::RunReuse reuse;
        ks::FeatureBilateralParams p;
        p.risk_selection = false;
        const auto r = ks::detail::fbs::smooth_run(first, p, nullptr, &reuse);
        REQUIRE(r.status == ks::Status::ok);
        REQUIRE(reuse.filled);
        CHECK(reuse.vertex_sets.size() == r.face_iterations);
        CHECK(r.feature_vertices > 0);
        if (k > 0.5) CHECK(r.lowpass_iterations > 0);
        const auto r2 = ks::detail::fbs::smooth_run(second, ks::detail::fbs::repeat_params(p, r), &r.features.sharp_edges,
                                                    &reuse);
        REQUIRE(r2.status == ks::Status::ok);
        CHECK(second.vertices == first.vertices);
        CHECK(first.vertices != noisy.vertices);
    }
}

TEST_CASE("risk selection far from the origin, with a duplicate face: the same choice, smooth_taubin's result bit for bit") {
    // The selection works in its own vertex order and frame; the result it returns is computed in
    // the input's, so that it is exactly what smooth_taubin gives for the chosen count (summed in
    // the internal order it was 2.8e-9|e| apart here).
    const auto clean = repo_bunny();
    const double L = ks::mean_edge_length(clean);
    auto noisy = ss::add_gaussian_noise(clean, 0.3 * L, true, 5);
    ks::IndexedMesh at_origin = noisy;
    const auto r0 = ks::smooth_feature_bilateral(at_origin, {.risk_selection = true});
    for (auto& v : noisy.vertices) v += ks::Vec3(1e6, -2e6, 5e5);
    noisy.faces.push_back(noisy.faces[7]);  // a duplicate: dropped inside, kept in the mesh
    ks::IndexedMesh out = noisy;
    const auto r = ks::smooth_feature_bilateral(out, {.risk_selection = true});
    REQUIRE(r.status == ks::Status::ok);
    REQUIRE(r.risk.taubin);
    CHECK(r0.risk.taubin);
    CHECK(r.duplicate_faces == 1);
    MESSAGE("Taubin pairs: " << r.risk.taubin_iterations << " far away, " << r0.risk.taubin_iterations << " at the origin");
    CHECK(std::abs(double(r.risk.taubin_iterations) - double(r0.risk.taubin_iterations)) <= 2);
    auto taubin = noisy;
    (void)ks::smooth_taubin(taubin, {}, {.iterations = r.risk.taubin_iterations});
    for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE(out.vertices[v] == taubin.vertices[v]);
}

TEST_CASE("risk selection: skipped where its estimates do not hold, bad values, cancellation, thread count") {
    const auto clean = repo_bunny();
    const double L = ks::mean_edge_length(clean);
    const auto noisy = ss::add_gaussian_noise(clean, 0.3 * L, true, 5);
    SUBCASE("impulsive noise on a box (vertices held): the filters' result, and why") {
        const auto box = ss::add_impulsive_noise(ss::box_mesh(16), 0.5 * ks::mean_edge_length(ss::box_mesh(16)), 3, nullptr, 4);
        auto a = box, b = box;
        const auto r = ks::smooth_feature_bilateral(a, {.risk_selection = true});
        (void)ks::smooth_feature_bilateral(b, {.risk_selection = false});
        CHECK(r.held_vertices > 0);
        CHECK_FALSE(r.risk.evaluated);
        CHECK(r.risk.note.find("held") != std::string::npos);
        CHECK(a.vertices == b.vertices);
    }
    SUBCASE("d and face_iterations given (no noise estimate): the filters' result, and why") {
        auto a = noisy, b = noisy;
        const auto r = ks::smooth_feature_bilateral(a, {.d = 0.2, .face_iterations = 2, .risk_selection = true});
        (void)ks::smooth_feature_bilateral(b, {.d = 0.2, .face_iterations = 2, .risk_selection = false});
        CHECK_FALSE(r.risk.evaluated);
        CHECK(r.risk.note.find("not estimated") != std::string::npos);
        CHECK(a.vertices == b.vertices);
    }
    SUBCASE("the clean mesh: its normals no further from the clean ones than with the filters alone") {
        // The noise estimate reads a coarse clean mesh's detail as noise, and the selection
        // compares the filters with Taubin on it like on a noisy one: Taubin here, 3.60 deg /
        // 0.087|e| against the filters' 4.37 deg / 0.053|e| (docs/methods/feature_bilateral.md,
        // "Faces coplanar by accident").
        auto a = clean, b = clean;
        const auto r = ks::smooth_feature_bilateral(a, {.risk_selection = true});
        REQUIRE(r.status == ks::Status::ok);
        (void)ks::smooth_feature_bilateral(b, {.risk_selection = false});
        const auto ma = ks::denoise_metrics(a, clean), mb = ks::denoise_metrics(b, clean);
        MESSAGE("clean bunny.off: " << ma.mean_normal_angle_deg << " deg / " << ma.vertex_rms / L << "|e| ("
                                    << std::string(r.risk.taubin ? "Taubin" : "filters") << "), filters alone "
                                    << mb.mean_normal_angle_deg << " deg / " << mb.vertex_rms / L << "|e|");
        CHECK(ma.mean_normal_angle_deg <= mb.mean_normal_angle_deg + 1e-9);
        CHECK(ma.vertex_rms < 0.1 * L);
        CHECK(mb.vertex_rms < 0.1 * L);
    }
    SUBCASE("bad values throw invalid_input and leave the mesh untouched") {
        for (std::size_t bad : {std::size_t{0}, std::size_t{10001}}) {
            auto m = noisy;
            ks::FeatureBilateralParams p;
            p.risk_selection = true;
            p.risk_taubin_max_iterations = bad;
            CHECK_THROWS_WITH_AS((void)ks::smooth_feature_bilateral(m, p),
                                 doctest::Contains("risk_taubin_max_iterations"), ks::invalid_input);
            CHECK(m.vertices == noisy.vertices);
        }
        auto m = noisy;
        m.vertices[3].x() = std::numeric_limits<double>::quiet_NaN();
        const auto before = m.vertices;
        CHECK_THROWS_AS((void)ks::smooth_feature_bilateral(m, {.risk_selection = true}), ks::invalid_input);
        CHECK(std::isnan(m.vertices[3].x()));
        CHECK(m.vertices[0] == before[0]);
    }
    SUBCASE("cancelled in each part, and by the final report: the mesh untouched") {
        // The first run reports into [0, 0.4], the perturbed run into [0.4, 0.8], the sweep
        // into [0.8, 0.9], the recheck (below) into [0.9, 1]; "done" comes once, before the
        // mesh is written.
        struct Part {
            const char* name;
            std::function<bool(const ks::ProgressEvent&)> at;
        };
        const std::vector<Part> parts = {
            {"first run", [](const ks::ProgressEvent& e) { return std::string(e.stage) == "face smoothing" && e.fraction < 0.4; }},
            {"perturbed run", [](const ks::ProgressEvent& e) { return e.fraction > 0.45 && e.fraction < 0.8; }},
            {"sweep", [](const ks::ProgressEvent& e) { return std::string(e.stage) == "risk: Taubin sweep"; }},
            {"done", [](const ks::ProgressEvent& e) { return std::string(e.stage) == "done"; }}};
        for (const auto& part : parts) {
            auto m = noisy;
            ks::FeatureBilateralParams p;
            p.risk_selection = true;
            bool seen = false;
            std::vector<double> fractions;
            int dones = 0;
            p.control.progress = [&](const ks::ProgressEvent& e) {
                fractions.push_back(e.fraction);
                dones += std::string(e.stage) == "done";
                if (part.at(e)) seen = true;
                return !seen;
            };
            const auto r = ks::smooth_feature_bilateral(m, p);
            CHECK_MESSAGE(seen, part.name);
            CHECK_MESSAGE(r.status == ks::Status::cancelled, part.name);
            CHECK_MESSAGE(m.vertices == noisy.vertices, part.name);
            CHECK(std::is_sorted(fractions.begin(), fractions.end()));
            CHECK(dones <= 1);
        }
        auto stopped = noisy;
        std::stop_source stop;
        ks::FeatureBilateralParams ps;
        ps.risk_selection = true;
        ps.control.stop = stop.get_token();
        ps.control.progress = [&](const ks::ProgressEvent& e) {
            if (std::string(e.stage) == "risk: Taubin sweep") stop.request_stop();
            return true;
        };
        CHECK(ks::smooth_feature_bilateral(stopped, ps).status == ks::Status::cancelled);
        CHECK(stopped.vertices == noisy.vertices);
    }
    SUBCASE("cancelled in the detection recheck (a 30 x 15 torus at 0.5|e|): the mesh untouched") {
        const auto torus = ss::add_gaussian_noise(fixtures::torus(30, 15), 0.5 * ks::mean_edge_length(fixtures::torus(30, 15)), true, 11);
        auto m = torus;
        ks::FeatureBilateralParams p;
        bool seen = false;
        std::vector<double> fractions;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            fractions.push_back(e.fraction);
            if (e.fraction > 0.9 && std::string(e.stage) != "done") seen = true;
            return !seen;
        };
        const auto r = ks::smooth_feature_bilateral(m, p);
        CHECK(seen);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(m.vertices == torus.vertices);
        CHECK(std::is_sorted(fractions.begin(), fractions.end()));
        auto full = torus;  // uncancelled, the recheck runs and chooses Taubin (the torus subcase above)
        CHECK(ks::smooth_feature_bilateral(full).risk.recheck);
    }
    SUBCASE("progress in order, once done, at most ~100 reports") {
        auto m = noisy;
        std::vector<double> fractions;
        ks::FeatureBilateralParams p;
        p.risk_selection = true;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            fractions.push_back(e.fraction);
            return true;
        };
        CHECK(ks::smooth_feature_bilateral(m, p).status == ks::Status::ok);
        CHECK(std::is_sorted(fractions.begin(), fractions.end()));
        CHECK(fractions.back() == 1.0);
        CHECK(fractions.size() <= 120);
    }
    SUBCASE("the same result with one and two threads") {
        auto a = noisy, b = noisy;
        ks::FeatureBilateralResult ra, rb;
        {
            ks::ThreadLimit one(1);
            ra = ks::smooth_feature_bilateral(a, {.risk_selection = true});
        }
        {
            ks::ThreadLimit two(2);
            rb = ks::smooth_feature_bilateral(b, {.risk_selection = true});
        }
        CHECK(ra.risk.taubin_iterations == rb.risk.taubin_iterations);
        CHECK(ra.risk.filters_rms == rb.risk.filters_rms);
        CHECK(a.vertices == b.vertices);
    }
}

namespace {
// The clean repository bunny with 10 % of its vertices moved along the normals by sigma = |e|
// (bench_smooth's impulsive model, seed 11).
struct ImpulsiveBunny {
    ks::IndexedMesh clean, noisy;
    double L = 0;
    double truth = 0;  // rms over the vertices of the moves along the clean normals
    std::size_t moved = 0;
    ImpulsiveBunny() {
        clean = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "bunny.off");
        clean.normals.clear();
        L = ks::mean_edge_length(clean);
        noisy = ss::add_impulsive_noise(clean, L, 11, &truth);
        for (std::size_t v = 0; v < clean.vertices.size(); ++v) moved += noisy.vertices[v] != clean.vertices[v];
    }
    // rms distance to the clean mesh over the vertices the noise moved
    double moved_rms(const ks::IndexedMesh& m) const {
        double s = 0;
        for (std::size_t v = 0; v < clean.vertices.size(); ++v)
            if (noisy.vertices[v] != clean.vertices[v]) s += (m.vertices[v] - clean.vertices[v]).squaredNorm();
        return std::sqrt(s / static_cast<double>(moved)) / L;
    }
};

/// remove_impulses on a copy of `in`, with at most `threads` worker threads.
ks::IndexedMesh impulses_removed(const ks::IndexedMesh& in, int threads) {
    ks::IndexedMesh m = in;
    ks::ThreadLimit limit(threads);
    (void)ks::remove_impulses(m);
    return m;
}
}  // namespace

TEST_CASE_TEMPLATE("remove_impulses puts the moved vertices back, the same on every mesh type and thread count", T,
                   ks::IndexedMesh, ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>, ss::SurfaceMesh) {
    const ImpulsiveBunny b;
    Holder<T> h(b.noisy);
    const auto r = ks::remove_impulses(h.mesh());
    REQUIRE(r.status == ks::Status::ok);
    const auto out = h.get();
    std::size_t changed = 0;
    for (std::size_t v = 0; v < out.vertices.size(); ++v) changed += out.vertices[v] != b.noisy.vertices[v];
    MESSAGE("bunny.off, " << b.moved << " of " << b.clean.vertices.size() << " vertices moved: " << r.moved_vertices
                          << " put back, " << r.unmoved_vertices << " taken as unmoved; rms of the moved "
                          << b.moved_rms(b.noisy) << " -> " << b.moved_rms(out) << " |e|; heights median "
                          << r.median_height / b.L << ", 99th percentile " << r.high_height / b.L << " |e|");
    CHECK(r.impulsive);
    CHECK_FALSE(r.dense);
    CHECK(r.moved_vertices >= b.moved * 6 / 10);
    CHECK(r.moved_vertices <= b.moved * 16 / 10);
    CHECK(changed == r.moved_vertices);  // only the flagged vertices move
    CHECK(b.moved_rms(out) < b.moved_rms(b.noisy) / 2.5);
    CHECK(r.unmoved_vertices > b.clean.vertices.size() / 2);
    ks::IndexedMesh reference = b.noisy;
    (void)ks::remove_impulses(reference);
    for (std::size_t v = 0; v < out.vertices.size(); ++v) REQUIRE((out.vertices[v] - reference.vertices[v]).norm() < 1e-12);
    const ks::IndexedMesh one = impulses_removed(b.noisy, 1), two = impulses_removed(b.noisy, 2);
    CHECK(one.vertices == two.vertices);
    CHECK(one.vertices == reference.vertices);
}

TEST_CASE("remove_impulses leaves clean meshes and Gaussian noise alone; the smoothing is then unchanged bit for bit") {
    auto twelve = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "twelve.obj");
    auto bunny = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "bunny.off");
    twelve.normals.clear();
    bunny.normals.clear();
    for (const auto* clean : {&twelve, &bunny}) {
        const double L = ks::mean_edge_length(*clean);
        for (double k : {0.0, 0.1, 0.3, 0.5, 0.8}) {
            const auto noisy = k > 0 ? ss::add_gaussian_noise(*clean, k * L, true, 5) : *clean;
            auto m = noisy;
            const auto r = ks::remove_impulses(m);
            INFO("noise " << k << "|e|, heights 99th percentile / median " << r.high_height / std::max(r.median_height, 0.01 * L));
            CHECK_FALSE(r.impulsive);
            CHECK(r.moved_vertices == 0);
            CHECK(r.spike_vertices == 0);
            CHECK(m.vertices == noisy.vertices);
        }
    }
    const double L = ks::mean_edge_length(bunny);
    const auto noisy = ss::add_gaussian_noise(bunny, 0.3 * L, true, 5);
    auto on = noisy, off = noisy;
    const auto r = ks::smooth_feature_bilateral(on);
    (void)ks::smooth_feature_bilateral(off, {.impulse_removal = false});
    CHECK_FALSE(r.impulsive_noise);
    CHECK(r.impulse_vertices == 0);
    CHECK(r.spike_vertices == 0);
    CHECK(r.input_noise.sigma == r.noise.sigma);
    CHECK(on.vertices == off.vertices);
}

namespace {
/// bunny.off with `count` vertices (every 367th from 100) moved `edges` mean edge lengths along
/// their clean normals: spikes, too few for the impulse removal's gate.
struct SpikyBunny {
    ks::IndexedMesh clean, spiky;
    std::vector<std::size_t> spikes;
    double L = 0;
    /// along_surface: moved along a tangent of the clean surface instead (a low height: found by
    /// the edge-length test, SpikeConstants::off_centre).
    SpikyBunny(std::size_t count, double edges, bool along_surface = false) {
        clean = ks::read_mesh(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "bunny.off");
        clean.normals.clear();
        L = ks::mean_edge_length(clean);
        spiky = clean;
        const auto n = ks::vertex_normals(clean);
        for (std::size_t k = 0; k < count; ++k) {
            const std::size_t v = 100 + 367 * k;
            spikes.push_back(v);
            const ks::Vec3 t = n[v].cross(std::abs(n[v].x()) < 0.9 ? ks::Vec3(1, 0, 0) : ks::Vec3(0, 1, 0)).normalized();
            spiky.vertices[v] += edges * L * (along_surface ? t : n[v]);
        }
    }
    /// The largest distance of a vertex of `m` from its clean place, in mean edge lengths.
    double worst(const ks::IndexedMesh& m) const {
        double d = 0;
        for (std::size_t v = 0; v < clean.vertices.size(); ++v) d = std::max(d, (m.vertices[v] - clean.vertices[v]).norm());
        return d / L;
    }
};
/// A unit box whose top is an n × n grid and whose four sides are fans from the bottom corners
/// to the top's border points: coarse corners beside a fine face, as CAD exports mesh them.
ks::IndexedMesh fan_box(int n) {
    ks::IndexedMesh m;
    auto idx = [&](int i, int j) { return static_cast<ks::Index>(i * (n + 1) + j); };
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) m.vertices.emplace_back(double(i) / n, double(j) / n, 1.0);
    const auto b00 = static_cast<ks::Index>(m.vertices.size()), b10 = b00 + 1, b01 = b00 + 2, b11 = b00 + 3;
    for (const ks::Vec3& c : {ks::Vec3(0, 0, 0), ks::Vec3(1, 0, 0), ks::Vec3(0, 1, 0), ks::Vec3(1, 1, 0)}) m.vertices.push_back(c);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            m.faces.push_back({idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)});
            m.faces.push_back({idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)});
        }
    auto side = [&](auto top, ks::Index a, ks::Index b) {  // top(t), t = 0..n, runs from above a to above b
        for (int t = 0; t < n; ++t) m.faces.push_back({t < n / 2 ? a : b, top(t + 1), top(t)});
        m.faces.push_back({a, b, top(n / 2)});
    };
    side([&](int t) { return idx(t, 0); }, b00, b10);
    side([&](int t) { return idx(n, t); }, b10, b11);
    side([&](int t) { return idx(n - t, n); }, b11, b01);
    side([&](int t) { return idx(0, n - t); }, b01, b00);
    m.faces.push_back({b00, b11, b10});
    m.faces.push_back({b00, b01, b11});
    return m;
}
}  // namespace

TEST_CASE("spikes: coarse corners beside a fine face are not spikes") {
    // The bottom corners' edges are 30 median edge lengths long and they lie off their
    // neighbours' mean; without the ring-radius test all four were taken for spikes and cut.
    const auto box = fan_box(30);
    auto m = box;
    const auto r = ks::remove_impulses(m);
    CHECK(r.spike_vertices == 0);
    CHECK(m.vertices == box.vertices);
    auto s = box;
    CHECK(ks::smooth_feature_bilateral(s).spike_vertices == 0);
}

TEST_CASE_TEMPLATE("spikes (a few vertices far off the surface) are put back before the smoothing, on every mesh type", T,
                   ks::IndexedMesh, ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>, ss::SurfaceMesh) {
    // Without the stage one spike of 50|e| stayed in place and dragged its neighbours by 13.6|e|
    // (10^4|e|: 1,598|e|); the gate's 99th percentile does not see a few vertices.
    ks::IndexedMesh reference_clean = SpikyBunny(0, 0).clean;
    (void)ks::smooth_feature_bilateral(reference_clean);
    for (const auto& [count, edges] : {std::pair<std::size_t, double>{1, 50.0}, {5, 1e4}}) {
        CAPTURE(count);
        CAPTURE(edges);
        const SpikyBunny b(count, edges);
        Holder<T> h(b.spiky);
        const auto r = ks::smooth_feature_bilateral(h.mesh());
        REQUIRE(r.status == ks::Status::ok);
        const auto out = h.get();
        double from_clean_run = 0;
        for (std::size_t v = 0; v < out.vertices.size(); ++v)
            from_clean_run = std::max(from_clean_run, (out.vertices[v] - reference_clean.vertices[v]).norm() / b.L);
        MESSAGE(count << " spike(s) of " << edges << "|e|: " << r.spike_vertices << " put back; every vertex within "
                      << b.worst(out) << "|e| of the clean mesh, " << from_clean_run << "|e| of the clean mesh smoothed");
        CHECK(r.spike_vertices == count);
        CHECK(r.timings.front().stage == "spikes");
        CHECK(b.worst(out) < 1.0);         // the clean mesh smoothed moves by up to about 0.5|e|
        CHECK(from_clean_run < 0.5);
        for (std::size_t v : b.spikes) CHECK((out.vertices[v] - b.clean.vertices[v]).norm() < 0.5 * b.L);
    }
}

TEST_CASE("spikes: remove_impulses puts back only them; the paper preset and a stop request leave them") {
    const SpikyBunny b(5, 50.0);
    SUBCASE("remove_impulses") {
        auto m = b.spiky;
        const auto r = ks::remove_impulses(m);
        REQUIRE(r.status == ks::Status::ok);
        CHECK(r.spike_vertices == 5);
        CHECK_FALSE(r.impulsive);
        CHECK(r.moved_vertices == 0);
        for (std::size_t v = 0; v < m.vertices.size(); ++v) {
            const bool spike = std::find(b.spikes.begin(), b.spikes.end(), v) != b.spikes.end();
            if (spike)
                CHECK((m.vertices[v] - b.clean.vertices[v]).norm() < 0.3 * b.L);
            else
                REQUIRE(m.vertices[v] == b.spiky.vertices[v]);
        }
    }
    SUBCASE("moved along the surface (a low height): found by their long edges") {
        const SpikyBunny t(5, 50.0, true);
        auto m = t.spiky;
        const auto r = ks::remove_impulses(m);
        CHECK(r.spike_vertices == 5);
        for (std::size_t v : t.spikes) CHECK((m.vertices[v] - t.clean.vertices[v]).norm() < 0.5 * t.L);
        CHECK(impulses_removed(t.spiky, 1).vertices == impulses_removed(t.spiky, 2).vertices);
    }
    SUBCASE("the paper preset (no impulse removal): the spikes stay") {
        auto m = b.spiky;
        const auto r = ks::smooth_feature_bilateral(m, ks::FeatureBilateralParams::paper());
        CHECK(r.spike_vertices == 0);
        for (std::size_t v : b.spikes) CHECK((m.vertices[v] - b.clean.vertices[v]).norm() > 40 * b.L);
    }
    SUBCASE("a stop request: cancelled, the mesh untouched") {
        auto m = b.spiky;
        std::stop_source stop;
        stop.request_stop();
        ks::FeatureBilateralParams p;
        p.control.stop = stop.get_token();
        CHECK(ks::smooth_feature_bilateral(m, p).status == ks::Status::cancelled);
        CHECK(m.vertices == b.spiky.vertices);
    }
}

TEST_CASE("impulsive noise on a curved shape: put back, the rest held, ahead of Taubin and of the filters on the impulses") {
    const ImpulsiveBunny b;
    auto ours = b.noisy, without = b.noisy;
    const auto r = ks::smooth_feature_bilateral(ours);
    const auto ro = ks::smooth_feature_bilateral(without, {.impulse_removal = false});
    const double best_taubin = best_taubin_error(b.noisy, b.clean);
    const double e = ks::denoise_metrics(ours, b.clean).mean_normal_angle_deg,
                 eo = ks::denoise_metrics(without, b.clean).mean_normal_angle_deg,
                 ei = ks::denoise_metrics(b.noisy, b.clean).mean_normal_angle_deg;
    MESSAGE("bunny.off + 10 % impulsive: input " << ei << " deg, defaults " << e << " (" << r.impulse_vertices
                                               << " put back, " << r.held_vertices << " held), without the removal "
                                               << eo << ", best Taubin of 10/20/50 " << best_taubin
                                               << "; noise estimated " << r.input_noise.sigma / b.L << " (truth " << b.truth / b.L << ") -> "
                                               << r.noise.relative << " |e|");
    CHECK(r.impulsive_noise);
    CHECK(r.impulse_vertices > 0);
    CHECK(r.held_vertices > b.clean.vertices.size() / 2);
    CHECK(ro.impulse_vertices == 0);
    // The untangling leaves impulsive noise to the impulse removal (its ratio reads high on this
    // irregular mesh, the unmoved majority's offsets being mostly tangential).
    CHECK(r.untangle.impulsive == (r.untangle.ratio > ks::detail::untangle::ratio_gate));
    CHECK(r.untangle.moved_vertices == 0);
    CHECK(e < best_taubin);
    CHECK(e < eo - 1);
    // The input's noise is reported; the filters' scales come from what is left.
    CHECK(r.input_noise.sigma > 2 * r.noise.sigma);
    // The input's level: the repaired mesh's with the repair's moves, against the impulses' rms.
    CHECK(r.input_noise.sigma / b.truth > 0.75);
    CHECK(r.input_noise.sigma / b.truth < 1.25);
    // The risk selection does not compare (its estimates assume Gaussian noise) and says why.
    CHECK_FALSE(r.risk.evaluated);
    CHECK(r.risk.note.find("impulsive") != std::string::npos);
    // The paper preset has no such stage.
    CHECK_FALSE(ks::FeatureBilateralParams::paper().impulse_removal);
    auto paper = b.noisy;
    CHECK(ks::smooth_feature_bilateral(paper, ks::FeatureBilateralParams::paper()).impulse_vertices == 0);
}

TEST_CASE("impulses on top of Gaussian noise: put back, and the noisy rest not held") {
    // bunny.off + 10 % × |e| + Gaussian noise along the normals. Holding the unmoved vertices
    // kept their Gaussian noise: 11.2° at 0.1|e| (7.9° without the removal); the repaired
    // mesh now reads as Gaussian noise (umbrella differences ≥ 0.1|e|), so nothing is held.
    const ImpulsiveBunny b;
    const auto gaussian = ss::add_gaussian_noise(b.clean, 0.1 * b.L, true, 5);
    auto noisy = b.noisy;
    for (std::size_t v = 0; v < noisy.vertices.size(); ++v) noisy.vertices[v] += gaussian.vertices[v] - b.clean.vertices[v];
    auto ours = noisy, without = noisy;
    const auto r = ks::smooth_feature_bilateral(ours);
    (void)ks::smooth_feature_bilateral(without, {.impulse_removal = false});
    const double e = ks::denoise_metrics(ours, b.clean).mean_normal_angle_deg,
                 eo = ks::denoise_metrics(without, b.clean).mean_normal_angle_deg,
                 ei = ks::denoise_metrics(noisy, b.clean).mean_normal_angle_deg;
    MESSAGE("bunny.off + 10 % impulsive + 0.1|e| Gaussian: input " << ei << " deg, defaults " << e << " ("
                                                                 << r.impulse_vertices << " put back, " << r.held_vertices
                                                                 << " held), without the removal " << eo
                                                                 << "; repaired mesh: differences "
                                                                 << r.noise.difference_sigma / r.noise.mean_edge_length
                                                                 << ", quadrics " << r.noise.quadric_sigma / r.noise.mean_edge_length);
    CHECK(r.impulse_vertices > 0);
    CHECK(r.held_vertices == 0);
    CHECK(e < ei - 2);
    CHECK(e < eo + 0.5);  // 8.2° against 7.9°
    // Impulses of 3|e| on 0.3|e| of Gaussian noise: the quadric fits of the repaired mesh read
    // over 0.3|e| (the differences are not computed there): not held (25.0° held, 12.7° not).
    {
        double unused = 0;
        const auto big = ss::add_impulsive_noise(b.clean, 3 * b.L, 11, &unused);
        const auto strong = ss::add_gaussian_noise(b.clean, 0.3 * b.L, true, 5);
        auto m = big;
        for (std::size_t v = 0; v < m.vertices.size(); ++v) m.vertices[v] += strong.vertices[v] - b.clean.vertices[v];
        const auto input = m;
        const auto rs = ks::smooth_feature_bilateral(m);
        const double es = ks::denoise_metrics(m, b.clean).mean_normal_angle_deg;
        MESSAGE("bunny.off + 10 % x 3|e| + 0.3|e| Gaussian: input " << ks::denoise_metrics(input, b.clean).mean_normal_angle_deg
                                                                  << " deg, defaults " << es << " (" << rs.impulse_vertices
                                                                  << " put back, " << rs.held_vertices << " held)");
        CHECK(rs.impulse_vertices > 0);
        CHECK(rs.held_vertices == 0);
        CHECK(es < 14);  // 12.7°
    }
    // The same impulses alone: held (an exact majority; the differences are not read).
    auto clean_majority = b.noisy;
    const auto rc = ks::smooth_feature_bilateral(clean_majority);
    CHECK(rc.held_vertices > b.clean.vertices.size() / 2);
    CHECK(rc.noise.difference_sigma == 0);
}

TEST_CASE("remove_impulses: dense noise, bad values and cancellation leave the mesh untouched") {
    const ImpulsiveBunny b;
    SUBCASE("more than max_fraction flagged: nothing put back") {
        auto m = b.noisy;
        const auto r = ks::remove_impulses(m, {.max_fraction = 0.02});
        CHECK(r.impulsive);
        CHECK(r.dense);
        CHECK(r.moved_vertices == 0);
        CHECK(m.vertices == b.noisy.vertices);
    }
    SUBCASE("bad values name themselves") {
        auto m = b.noisy;
        auto bad = [&](const ks::ImpulseParams& p, const char* name) {
            CHECK_THROWS_WITH_AS((void)ks::remove_impulses(m, p), doctest::Contains(name), ks::invalid_input);
            CHECK(m.vertices == b.noisy.vertices);
        };
        bad({.gate = 1}, "gate");
        bad({.threshold = 0}, "threshold");
        bad({.floor = -0.5}, "floor");
        bad({.passes = 0}, "passes");
        bad({.passes = 101}, "passes");
        bad({.max_fraction = 0}, "max_fraction");
        bad({.max_fraction = 1.5}, "max_fraction");
        bad({.keep = -1}, "keep");
        bad({.gate = std::numeric_limits<double>::infinity()}, "gate");
        m.vertices[7].x() = std::nan("");
        CHECK_THROWS_WITH_AS((void)ks::remove_impulses(m), doctest::Contains("vertex 7"), ks::invalid_input);
        m = b.noisy;
        m.faces[3][2] = static_cast<ks::Index>(m.vertices.size());
        CHECK_THROWS_AS((void)ks::remove_impulses(m), ks::invalid_input);
    }
    SUBCASE("cancelled: status cancelled, the mesh untouched") {
        auto m = b.noisy;
        std::stop_source stop;
        stop.request_stop();
        ks::ImpulseParams p;
        p.control.stop = stop.get_token();
        CHECK(ks::remove_impulses(m, p).status == ks::Status::cancelled);
        CHECK(m.vertices == b.noisy.vertices);
        int calls = 0;
        ks::ImpulseParams p2;
        p2.control.progress = [&](const ks::ProgressEvent&) { return ++calls < 3; };
        CHECK(ks::remove_impulses(m, p2).status == ks::Status::cancelled);
        CHECK(m.vertices == b.noisy.vertices);
        // Stopped as the smoothing's stage starts: the run ends there or at the next check, the
        // mesh untouched.
        std::stop_source stop2;
        bool seen = false;
        ks::FeatureBilateralParams fp;
        fp.risk_selection = false;  // every stage reported (the selection forwards at most one event per 1 %)
        fp.control.stop = stop2.get_token();
        fp.control.progress = [&](const ks::ProgressEvent& e) {
            if (e.stage == "impulses") {
                seen = true;
                stop2.request_stop();
            }
            return true;
        };
        auto s = b.noisy;
        CHECK(ks::smooth_feature_bilateral(s, fp).status == ks::Status::cancelled);
        CHECK(s.vertices == b.noisy.vertices);
        CHECK(seen);
    }
    SUBCASE("an empty mesh and a mesh without faces: nothing to do") {
        ks::IndexedMesh empty;
        CHECK(ks::remove_impulses(empty).moved_vertices == 0);
        ks::IndexedMesh points = b.noisy;
        points.faces.clear();
        CHECK(ks::remove_impulses(points).moved_vertices == 0);
        CHECK(points.vertices == b.noisy.vertices);
    }
}

TEST_CASE("shared data: impulsive noise on fertility and armadillo, ahead of the best Taubin and smooth_shape") {
    const auto root = std::filesystem::path(KINTSUGI_SHARED_DATA_DIR);
    KINTSUGI_REQUIRE_DATA(root / "libigl" / "fertility.off");
    for (const auto& path : {root / "libigl" / "fertility.off", root / "cgal" / "meshes" / "armadillo.off"}) {
        if (!std::filesystem::exists(path)) continue;
        auto clean = ks::read_mesh(path);
        clean.normals.clear();
        const double L = ks::mean_edge_length(clean);
        const auto noisy = ss::add_impulsive_noise(clean, L, 11);
        auto ours = noisy;
        const auto r = ks::smooth_feature_bilateral(ours);
        const double best_taubin = best_taubin_error(noisy, clean);
        const auto shape = ss::best_smooth_shape(noisy, clean);
        const double e = ks::denoise_metrics(ours, clean).mean_normal_angle_deg,
                     es = ks::denoise_metrics(shape, clean).mean_normal_angle_deg;
        MESSAGE(path.filename().string() << " + 10 % impulsive: " << e << " deg (" << r.impulse_vertices
                                         << " put back), best Taubin " << best_taubin << ", best smooth_shape " << es);
        CHECK(r.impulse_vertices > 0);
        CHECK(e < best_taubin);
        CHECK(e < es);
    }
}

TEST_CASE("a clean plate with a half-cylinder across its grid: the smoothing puts nothing back, remove_impulses moves little") {
    // Exact planes (median height 0) and a clean curved strip whose heights all pass the gate's
    // 99th percentile: the strip must not be taken for impulses.
    const int N = 60;
    const double R = 3, a = 0.5, c = N / 2.0;
    ks::IndexedMesh plate;
    for (int j = 0; j <= N; ++j)
        for (int i = 0; i <= N; ++i) {
            const double d = -(i - c) * std::sin(a) + (j - c) * std::cos(a);
            plate.vertices.push_back({double(i), double(j), std::abs(d) < R ? std::sqrt(R * R - d * d) : 0.0});
        }
    auto id = [&](int i, int j) { return static_cast<ks::Index>(j * (N + 1) + i); };
    for (int j = 0; j < N; ++j)
        for (int i = 0; i < N; ++i) {
            plate.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            plate.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    auto m = plate;
    const auto r = ks::remove_impulses(m);
    double most = 0;
    for (std::size_t v = 0; v < m.vertices.size(); ++v) most = std::max(most, (m.vertices[v] - plate.vertices[v]).norm());
    MESSAGE("plate + half-cylinder: gate " << std::string(r.impulsive ? "passed" : "not passed") << ", " << r.moved_vertices
                                           << " of " << plate.vertices.size() << " vertices moved, at most " << most);
    CHECK(r.moved_vertices <= plate.vertices.size() / 100);  // 22 of 3,721 (before the neighbour test: 294, by 2.1)
    CHECK(most < 1.0);
    auto on = plate, off = plate;
    const auto rs = ks::smooth_feature_bilateral(on);
    (void)ks::smooth_feature_bilateral(off, {.impulse_removal = false});
    CHECK(rs.impulse_vertices == 0);
    CHECK(on.vertices == off.vertices);
}

namespace {
// Faces whose normal points away from the clean face's (over 90°): folded over.
std::size_t flipped_faces(const ks::IndexedMesh& m, const ks::IndexedMesh& clean) {
    const auto a = ks::face_normals(m), b = ks::face_normals(clean);
    std::size_t n = 0;
    for (std::size_t f = 0; f < a.size(); ++f) n += a[f].dot(b[f]) < 0;
    return n;
}
}  // namespace

TEST_CASE_TEMPLATE("noise in random directions: the folded faces are unfolded first, on every mesh type", T,
                   ks::IndexedMesh, ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>, ss::SurfaceMesh) {
    // The box (1,536 faces) with Gaussian noise of 0.5|e| in uniformly random directions: the
    // tangential part folds faces over, which the filters' vertex updates along face normals
    // cannot undo (docs/methods/feature_bilateral.md, "Noise in random directions").
    const auto clean = ss::box_mesh(16);
    const double L = ks::mean_edge_length(clean);
    const auto noisy = ss::add_gaussian_noise(clean, 0.5 * L, false, 11);
    Holder<T> h(noisy);
    const auto r = ks::smooth_feature_bilateral(h.mesh());
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.timings[1].stage == "untangle");  // after "spikes"
    CHECK(r.untangle.tangential_noise);
    CHECK(r.untangle.ratio > ks::detail::untangle::ratio_gate);
    CHECK(r.untangle.folded_faces > 10);
    CHECK(r.untangle.moved_vertices >= r.untangle.folded_faces / 2);
    const auto out = h.get();
    REQUIRE(all_finite(out));
    ks::IndexedMesh off = noisy;
    const auto r_off = ks::smooth_feature_bilateral(off, {.untangle = false});
    CHECK(r_off.untangle.ratio == 0);  // the stage did not run
    const double e_in = ks::denoise_metrics(noisy, clean).mean_normal_angle_deg,
                 e_on = ks::denoise_metrics(out, clean).mean_normal_angle_deg,
                 e_off = ks::denoise_metrics(off, clean).mean_normal_angle_deg;
    MESSAGE("box, 0.5|e| in random directions: normal error noisy " << e_in << ", untangled " << e_on << ", not "
                                                                    << e_off << " deg; folded faces noisy "
                                                                    << flipped_faces(noisy, clean) << ", untangled "
                                                                    << flipped_faces(out, clean) << ", not "
                                                                    << flipped_faces(off, clean) << "; ratio "
                                                                    << r.untangle.ratio << ", " << r.untangle.folded_faces
                                                                    << " found, " << r.untangle.moved_vertices << " moved");
    CHECK(e_on < 0.8 * e_off);  // 2.86 against 3.96 deg
    CHECK(flipped_faces(out, clean) * 4 < flipped_faces(off, clean));
    // Same result whatever the container.
    ks::IndexedMesh reference = noisy;
    (void)ks::smooth_feature_bilateral(reference);
    for (std::size_t v = 0; v < out.vertices.size(); ++v)
        REQUIRE((out.vertices[v] - reference.vertices[v]).norm() < 1e-12 * L);
}

TEST_CASE("untangling: noise along the normals does not pass its gate; thread count, cancellation") {
    const auto clean = ss::box_mesh(16);
    const double L = ks::mean_edge_length(clean);
    SUBCASE("along the normals, 0.5|e|: nothing moves, and the result is the stage-off result bit for bit") {
        const auto noisy = ss::add_gaussian_noise(clean, 0.5 * L, true, 11);
        auto on = noisy, off = noisy;
        const auto r = ks::smooth_feature_bilateral(on);
        (void)ks::smooth_feature_bilateral(off, {.untangle = false});
        CHECK(r.untangle.ratio > 0);
        CHECK(r.untangle.ratio < ks::detail::untangle::ratio_gate);
        CHECK_FALSE(r.untangle.tangential_noise);
        CHECK(r.untangle.folded_faces == 0);
        CHECK(r.untangle.moved_vertices == 0);
        CHECK(on.vertices == off.vertices);
    }
    const auto noisy = ss::add_gaussian_noise(clean, 0.5 * L, false, 11);
    SUBCASE("random directions: the same with 1 and 2 threads") {
        auto a = noisy, b = noisy;
        ks::FeatureBilateralResult ra, rb;
        {
            ks::ThreadLimit one(1);
            ra = ks::smooth_feature_bilateral(a);
        }
        {
            ks::ThreadLimit two(2);
            rb = ks::smooth_feature_bilateral(b);
        }
        CHECK(ra.untangle.moved_vertices > 0);
        CHECK(ra.untangle.moved_vertices == rb.untangle.moved_vertices);
        CHECK(a.vertices == b.vertices);
    }
    SUBCASE("cancelled before the run or during it: the mesh untouched") {
        for (int at : {0, 5}) {
            auto m = noisy;
            std::stop_source stop;
            ks::FeatureBilateralParams p;
            int calls = 0;
            if (at == 0) stop.request_stop();
            p.control.stop = stop.get_token();
            p.control.progress = [&](const ks::ProgressEvent&) { return ++calls < at; };
            const auto r = ks::smooth_feature_bilateral(m, p);
            CHECK(r.status == ks::Status::cancelled);
            CHECK(m.vertices == noisy.vertices);
        }
    }
}
