// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Selective Taubin λ/μ smoothing over several mesh containers.
#include <doctest/doctest.h>

#include "mesh/mt_test_util.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/mesh/marching_tetrahedra.hpp>
#include <kintsugi/mesh/taubin.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stop_token>

namespace ks = kintsugi;

namespace {

// A sphere of radius 0.6 from marching tetrahedra, with radial noise on every vertex.
ks::IndexedMesh noisy_sphere(double noise, std::uint64_t seed) {
    const auto g = kintsugi_test::make_tet_grid(16, -1, 1);
    std::vector<double> f;
    std::vector<std::uint8_t> in;
    for (const auto& p : g.vertices) {
        f.push_back(0.6 - p.norm());
        in.push_back(f.back() > 0);
    }
    auto m = ks::marching_tetrahedra(g.vertices, g.tets, in, f).mesh;
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> n(0, noise);
    for (auto& v : m.vertices) v *= 1 + n(rng);
    return m;
}

double radial_rms(const ks::IndexedMesh& m, const std::vector<std::uint8_t>& which = {}) {
    double s = 0;
    std::size_t c = 0;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
        if (!which.empty() && !which[i]) continue;
        const double d = m.vertices[i].norm() - 0.6;
        s += d * d;
        ++c;
    }
    return std::sqrt(s / static_cast<double>(c));
}

using Kernel = CGAL::Simple_cartesian<double>;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

template <class M>
struct Wrap;
template <>
struct Wrap<ks::IndexedMesh> {
    ks::IndexedMesh m;
    explicit Wrap(const ks::IndexedMesh& src) : m(src) {}
    ks::IndexedMesh& mesh() { return m; }
    ks::IndexedMesh get() { return m; }
};
template <>
struct Wrap<SurfaceMesh> {
    SurfaceMesh m;
    explicit Wrap(const ks::IndexedMesh& src) { ks::assign_mesh(m, src); }
    SurfaceMesh& mesh() { return m; }
    ks::IndexedMesh get() { return ks::to_indexed_mesh(m); }
};
struct EigenTag {};
template <>
struct Wrap<EigenTag> {
    Eigen::MatrixXd V;
    Eigen::MatrixXi F;
    ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi> view;
    explicit Wrap(const ks::IndexedMesh& src)
        : V(static_cast<Eigen::Index>(src.vertices.size()), 3), F(static_cast<Eigen::Index>(src.faces.size()), 3),
          view{&V, &F} {
        for (std::size_t i = 0; i < src.vertices.size(); ++i) V.row(static_cast<Eigen::Index>(i)) = src.vertices[i];
        for (std::size_t i = 0; i < src.faces.size(); ++i)
            for (int c = 0; c < 3; ++c) F(static_cast<Eigen::Index>(i), c) = static_cast<int>(src.faces[i][c]);
    }
    ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>& mesh() { return view; }
    ks::IndexedMesh get() { return ks::to_indexed_mesh(view); }
};

}  // namespace

TEST_CASE_TEMPLATE("smooth_taubin: denoises a sphere without shrinking it", M, ks::IndexedMesh, SurfaceMesh, EigenTag) {
    const auto src = noisy_sphere(0.02, 1);
    Wrap<M> w(src);
    const double before = radial_rms(src);
    const auto r = ks::smooth_taubin(w.mesh(), {}, {.iterations = 30});
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.moved_vertices == src.vertices.size());
    const auto out = w.get();
    const double after = radial_rms(out);
    CHECK(after < 0.5 * before);
    // mean radius stays near 0.6 (λ/μ does not shrink like plain Laplacian smoothing)
    double mean = 0;
    for (const auto& v : out.vertices) mean += v.norm();
    mean /= static_cast<double>(out.vertices.size());
    CHECK(mean == doctest::Approx(0.6).epsilon(0.01));
    auto canonical = [](std::vector<ks::Face> fs) {  // same triangles, up to rotation of each face
        for (auto& f : fs) std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
        return fs;
    };
    CHECK(canonical(out.faces) == canonical(src.faces));
}

TEST_CASE("smooth_taubin: only the selected vertices move and blend into the fixed ones") {
    auto m = noisy_sphere(0.0, 2);
    // Displace a cap of vertices outwards and select only them.
    std::vector<std::uint8_t> movable(m.vertices.size(), 0);
    for (std::size_t i = 0; i < m.vertices.size(); ++i)
        if (m.vertices[i].z() > 0.45) {
            movable[i] = 1;
            m.vertices[i] *= (i % 2 ? 1.08 : 0.93);
        }
    const auto before = m;
    const double err_before = radial_rms(m, movable);
    const auto r = ks::smooth_taubin(m, movable);
    CHECK(r.moved_vertices == static_cast<std::size_t>(std::count(movable.begin(), movable.end(), 1)));
    for (std::size_t i = 0; i < m.vertices.size(); ++i)
        if (!movable[i]) REQUIRE(m.vertices[i] == before.vertices[i]);
    CHECK(radial_rms(m, movable) < 0.35 * err_before);
    // Deterministic.
    auto again = before;
    (void)ks::smooth_taubin(again, movable);
    CHECK(again.vertices == m.vertices);
    // Zero iterations change nothing.
    auto same = before;
    (void)ks::smooth_taubin(same, movable, {.iterations = 0});
    CHECK(same.vertices == before.vertices);
}

TEST_CASE("smooth_taubin: bad input and cancellation leave the mesh untouched") {
    const auto src = noisy_sphere(0.01, 3);
    auto m = src;
    CHECK_THROWS_WITH_AS((void)ks::smooth_taubin(m, {}, {.lambda = 0}), doctest::Contains("lambda"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::smooth_taubin(m, {}, {.mu = 0.3}), doctest::Contains("mu"), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::smooth_taubin(m, std::vector<std::uint8_t>(3, 1)),
                         doctest::Contains("movable"), ks::invalid_input);
    m.vertices[5].y() = std::nan("");
    CHECK_THROWS_WITH_AS((void)ks::smooth_taubin(m), doctest::Contains("vertex 5"), ks::invalid_input);
    m = src;
    m.faces[0][1] = m.vertices.size();
    CHECK_THROWS_AS((void)ks::smooth_taubin(m), ks::invalid_input);
    m = src;
    std::stop_source stop;
    stop.request_stop();
    ks::TaubinParams p;
    p.control.stop = stop.get_token();
    CHECK(ks::smooth_taubin(m, {}, p).status == ks::Status::cancelled);
    CHECK(m.vertices == src.vertices);
    int calls = 0;
    ks::TaubinParams p2;
    p2.control.progress = [&](const ks::ProgressEvent&) { return ++calls < 3; };
    CHECK(ks::smooth_taubin(m, {}, p2).status == ks::Status::cancelled);
    CHECK(m.vertices == src.vertices);
}
