// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Normal estimation and orientation: every point-set adapter, known surfaces,
// several components, bad input, cancellation, thread-count determinism,
// agreement with CGAL's own functions, accuracy on real scans.
#include "test_data.hpp"
#include <doctest/doctest.h>

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/normals/estimate_normals.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/uniform_grid.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/pca_estimate_normals.h>
#include <CGAL/property_map.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numbers>
#include <random>
#include <stop_token>
#include <string>
#include <vector>

namespace ks = kintsugi;
namespace fs = std::filesystem;

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using PointSet3 = CGAL::Point_set_3<K::Point_3, K::Vector_3>;

struct Oriented {
    std::vector<ks::Vec3> points, normals;
};

// Positions and unit reference normals of an oriented point file, through kintsugi's reader.
Oriented read_xyz(const fs::path& path) {
    const ks::PointCloud c = ks::read_point_cloud(path);
    REQUIRE_MESSAGE(c.normals.size() == c.points.size(), path << " has no normals");
    Oriented o{c.points, c.normals};
    for (auto& n : o.normals) n.normalize();
    return o;
}

const fs::path kTestData = KINTSUGI_TEST_DATA_DIR;
const fs::path kShared = KINTSUGI_SHARED_DATA_DIR;

// Fibonacci sphere: near-uniform samples, exact outward normals.
Oriented sphere(std::size_t n, const ks::Vec3& centre, double radius) {
    Oriented o;
    const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
    for (std::size_t i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
        const double r = std::sqrt(1.0 - z * z);
        const double t = golden * static_cast<double>(i);
        const ks::Vec3 u(r * std::cos(t), r * std::sin(t), z);
        o.points.push_back(centre + radius * u);
        o.normals.push_back(u);
    }
    return o;
}

// Torus (major R, minor r) sampled on a jittered grid, outward normals.
Oriented torus(std::size_t nu, std::size_t nv, double R, double r) {
    Oriented o;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> jitter(-0.3, 0.3);
    for (std::size_t i = 0; i < nu; ++i)
        for (std::size_t j = 0; j < nv; ++j) {
            const double u = 2 * std::numbers::pi * (static_cast<double>(i) + jitter(rng)) / static_cast<double>(nu);
            const double v = 2 * std::numbers::pi * (static_cast<double>(j) + jitter(rng)) / static_cast<double>(nv);
            const ks::Vec3 n(std::cos(u) * std::cos(v), std::sin(u) * std::cos(v), std::sin(v));
            o.points.push_back(ks::Vec3(R * std::cos(u), R * std::sin(u), 0) + r * n);
            o.normals.push_back(n);
        }
    return o;
}

// Bitwise equality (NaN-safe, empty-safe).
bool same_bits(const std::vector<ks::Vec3>& a, const std::vector<ks::Vec3>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(ks::Vec3)) == 0);
}

struct Agreement {
    double same_sign = 0;       // fraction with n·ref > 0
    double mean_angle_deg = 0;  // unsigned angle to the reference
};
Agreement agreement(const std::vector<ks::Vec3>& n, const std::vector<ks::Vec3>& ref) {
    REQUIRE(n.size() == ref.size());
    Agreement a;
    for (std::size_t i = 0; i < n.size(); ++i) {
        const double c = n[i].normalized().dot(ref[i].normalized());
        a.same_sign += c > 0 ? 1 : 0;
        a.mean_angle_deg += std::acos(std::min(1.0, std::abs(c))) * 180.0 / std::numbers::pi;
    }
    a.same_sign /= static_cast<double>(n.size());
    a.mean_angle_deg /= static_cast<double>(n.size());
    return a;
}

// ---- containers, all filled with the same positions; normals read back as vectors.
struct UserSample {
    float xyz[3];
    std::array<float, 3> n;
    int label;
};

struct VecHolder {
    std::vector<Eigen::Vector3d> p, n;
    explicit VecHolder(const std::vector<ks::Vec3>& x) : p(x.begin(), x.end()) {}
    auto view() { return ks::with_normals(p, n); }
    std::vector<ks::Vec3> normals() const { return {n.begin(), n.end()}; }
};
struct CloudHolder {
    ks::PointCloud c;
    explicit CloudHolder(const std::vector<ks::Vec3>& x) { c.points = x; }
    ks::PointCloud& view() { return c; }
    std::vector<ks::Vec3> normals() const { return c.normals; }
};
struct CgalHolder {
    PointSet3 c;
    explicit CgalHolder(const std::vector<ks::Vec3>& x) {
        for (const auto& p : x) c.insert(K::Point_3(p.x(), p.y(), p.z()));
    }
    PointSet3& view() { return c; }
    std::vector<ks::Vec3> normals() const { return ks::gather_normals(c); }
};
struct EigenHolder {
    Eigen::MatrixXd P, N;
    explicit EigenHolder(const std::vector<ks::Vec3>& x) : P(static_cast<Eigen::Index>(x.size()), 3) {
        for (std::size_t i = 0; i < x.size(); ++i) P.row(static_cast<Eigen::Index>(i)) = x[i].transpose();
    }
    auto view() { return ks::eigen_points(P, N); }
    std::vector<ks::Vec3> normals() const {
        std::vector<ks::Vec3> out(static_cast<std::size_t>(N.rows()));
        for (std::size_t i = 0; i < out.size(); ++i) out[i] = N.row(static_cast<Eigen::Index>(i)).transpose();
        return out;
    }
};
struct UserHolder {
    std::vector<UserSample> s;
    explicit UserHolder(const std::vector<ks::Vec3>& x) {
        for (std::size_t i = 0; i < x.size(); ++i)
            s.push_back({{float(x[i].x()), float(x[i].y()), float(x[i].z())}, {0, 0, 0}, int(i)});
    }
    auto view() { return ks::project_points(s, &UserSample::xyz, &UserSample::n); }
    std::vector<ks::Vec3> normals() const {
        std::vector<ks::Vec3> out;
        for (const auto& e : s) out.emplace_back(e.n[0], e.n[1], e.n[2]);
        return out;
    }
};

}  // namespace

static_assert(ks::NormalWritablePointSet<decltype(std::declval<VecHolder&>().view())>);
static_assert(ks::NormalWritablePointSet<decltype(std::declval<EigenHolder&>().view())>);
static_assert(ks::NormalWritablePointSet<decltype(std::declval<UserHolder&>().view())>);

TEST_CASE_TEMPLATE("estimate_normals on a sphere through every container: accurate, unit, outward", H, VecHolder,
                   CloudHolder, CgalHolder, EigenHolder, UserHolder) {
    const Oriented s = sphere(2000, ks::Vec3(0.5, -0.25, 2.0), 1.5);
    for (auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
        CAPTURE(static_cast<int>(method));
        H h(s.points);
        auto&& v = h.view();
        const auto r = ks::estimate_normals(v, {.k = 18, .method = method});
        CHECK(r.status == ks::Status::ok);
        CHECK(r.points == s.points.size());
        CHECK(r.components == 1);
        REQUIRE(r.timings.size() == 4);
        CHECK(r.timings[0].stage == "kd-tree");
        CHECK(r.timings[3].stage == "orient");
        const auto n = h.normals();
        REQUIRE(n.size() == s.points.size());
        for (const auto& x : n) REQUIRE(std::abs(x.norm() - 1.0) < 1e-5);
        const auto a = agreement(n, s.normals);
        CHECK(a.same_sign == 1.0);
        // On a sphere of radius 1.5 sampled every ~0.06, the plane/quadric fits are
        // within a fraction of a degree (float containers round to ~1e-5 degrees).
        CHECK(a.mean_angle_deg < (method == ks::NormalMethod::jet ? 0.05 : 1.0));
    }
}

TEST_CASE("without orientation the normals are unit and along the true normal, and no component is counted") {
    const Oriented s = sphere(1500, ks::Vec3::Zero(), 1.0);
    std::vector<ks::Vec3> pts = s.points, nrm;
    auto v = ks::with_normals(pts, nrm);
    const auto r = ks::estimate_normals(v, {.orient = false});
    CHECK(r.components == 0);
    CHECK(r.timings.size() == 3);
    const auto a = agreement(nrm, s.normals);
    CHECK(a.mean_angle_deg < 1.0);
    for (const auto& x : nrm) CHECK(std::abs(x.norm() - 1.0) < 1e-12);
    // The smallest case: 3 points, k = 3 (all of them) gives their plane's normal.
    std::vector<ks::Vec3> tri = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}}, tn;
    auto tv = ks::with_normals(tri, tn);
    CHECK(ks::estimate_normals(tv, {.k = 3}).components == 1);
    for (const auto& x : tn) CHECK((x - ks::Vec3(0, 0, 1)).norm() < 1e-12);  // +z: the seed rule
}

TEST_CASE("degenerate neighbourhoods (collinear, coincident points) still give finite unit normals") {
    std::vector<ks::Vec3> pts;
    for (int i = 0; i < 20; ++i) pts.emplace_back(0.1 * i, 0.2 * i, -0.05 * i);  // a line
    for (int i = 0; i < 10; ++i) pts.emplace_back(5, 5, 5);                        // one place, ten times
    for (auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
        std::vector<ks::Vec3> nrm;
        auto v = ks::with_normals(pts, nrm);
        const auto r = ks::estimate_normals(v, {.k = 6, .method = method});
        CHECK(r.components == 2);
        for (std::size_t i = 0; i < nrm.size(); ++i) {
            REQUIRE(nrm[i].allFinite());
            CHECK(std::abs(nrm[i].norm() - 1.0) < 1e-9);
        }
        // On the line, any normal is perpendicular to it.
        const ks::Vec3 dir = ks::Vec3(0.1, 0.2, -0.05).normalized();
        for (std::size_t i = 0; i < 20; ++i) CHECK(std::abs(nrm[i].dot(dir)) < 1e-6);
    }
}

TEST_CASE("every kNN-graph component is oriented, each by its top-most point (CGAL orients only one)") {
    // Two spheres and a torus far apart: three components, all closed, all outward.
    Oriented all = sphere(1200, ks::Vec3(0, 0, 0), 1.0);
    const Oriented b = sphere(800, ks::Vec3(10, 0, 0), 0.5);
    const Oriented t = torus(60, 24, 2.0, 0.6);
    for (const Oriented* o : {&b, &t})
        for (std::size_t i = 0; i < o->points.size(); ++i) {
            all.points.push_back(o->points[i] + (o == &t ? ks::Vec3(0, 10, 3) : ks::Vec3::Zero()));
            all.normals.push_back(o->normals[i]);
        }
    for (auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
        std::vector<ks::Vec3> pts = all.points, nrm;
        auto v = ks::with_normals(pts, nrm);
        const auto r = ks::estimate_normals(v, {.k = 12, .method = method});
        CHECK(r.components == 3);
        CHECK(agreement(nrm, all.normals).same_sign == 1.0);
    }
}

TEST_CASE_TEMPLATE("orient_normals fixes signs only, keeps directions and lengths", H, VecHolder, CloudHolder,
                   CgalHolder, EigenHolder, UserHolder) {
    const Oriented s = torus(80, 30, 2.0, 0.7);
    H h(s.points);
    auto&& v = h.view();
    using Traits = ks::point_set_traits<std::remove_cvref_t<decltype(v)>>;
    if constexpr (requires { Traits::prepare_normals(v); }) Traits::prepare_normals(v);
    std::mt19937 rng(5);
    std::vector<ks::Vec3> given(s.points.size());
    for (std::size_t i = 0; i < given.size(); ++i) {
        given[i] = s.normals[i] * 2.0 * ((rng() & 1) ? 1.0 : -1.0);  // length 2, random sign
        Traits::set_normal(v, i, given[i]);
    }
    const auto r = ks::orient_normals(v, {.k = 10});
    CHECK(r.status == ks::Status::ok);
    CHECK(r.components == 1);
    const auto n = h.normals();
    for (std::size_t i = 0; i < n.size(); ++i) {
        REQUIRE(n[i].cross(given[i]).norm() < 1e-5);            // same line
        REQUIRE(std::abs(n[i].norm() - 2.0) < 1e-5);             // same length
        REQUIRE(n[i].dot(s.normals[i]) > 0);                     // outward
    }
}

TEST_CASE("bit-identical output whatever the thread count") {
    const Oriented k = read_xyz(kTestData / "normals" / "kitten.xyz");
    for (auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
        std::vector<ks::Vec3> n1, n2;
        {
            ks::ThreadLimit one(1);
            auto v = ks::with_normals(k.points, n1);
            (void)ks::estimate_normals(v, {.method = method});
        }
        {
            ks::ThreadLimit two(2);
            auto v = ks::with_normals(k.points, n2);
            (void)ks::estimate_normals(v, {.method = method});
        }
        REQUIRE(n1.size() == k.points.size());
        CHECK(same_bits(n1, n2));
    }
}

// A user's own spatial index (brute force), modelling SpatialIndex; `shift` corrupts the
// indices it returns, to test the checks.
struct BruteIndex {
    std::vector<ks::Vec3> pts;
    std::size_t shift = 0;
    std::size_t size() const { return pts.size(); }
    void radius_search_squared(const ks::Vec3& q, ks::Scalar r2, std::vector<ks::Neighbor>& out) const {
        out.clear();
        for (std::size_t i = 0; i < pts.size(); ++i) {
            const ks::Scalar d = (pts[i] - q).squaredNorm();
            if (d <= r2) out.push_back({static_cast<ks::Index>(i + shift), d});
        }
        std::sort(out.begin(), out.end(), [](const ks::Neighbor& a, const ks::Neighbor& b) {
            return a.squared_distance < b.squared_distance ||
                   (a.squared_distance == b.squared_distance && a.index < b.index);
        });
    }
    void knn(const ks::Vec3& q, std::size_t k, std::vector<ks::Neighbor>& out) const {
        radius_search_squared(q, std::numeric_limits<ks::Scalar>::infinity(), out);
        out.resize(std::min(k, out.size()));
    }
    ks::Neighbor nearest(const ks::Vec3& q) const {
        std::vector<ks::Neighbor> nn;
        knn(q, 1, nn);
        return nn.at(0);
    }
};
static_assert(ks::SpatialIndex<BruteIndex>);

TEST_CASE("estimate_normals over any SpatialIndex (KdTree, UniformGrid, a user's type) gives the plain call's normals") {
    const Oriented t = torus(40, 20, 1.0, 0.3);
    for (const double scale : {1.0, std::ldexp(1.0, 40)}) {  // also a frame rescaled inside
        std::vector<ks::Vec3> pts = t.points;
        for (auto& p : pts) p *= scale;
        const ks::KdTree tree(pts);
        const ks::UniformGrid grid(pts, 0.1 * scale);
        const BruteIndex brute{pts};
        for (auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
            CAPTURE(scale);
            CAPTURE(static_cast<int>(method));
            const ks::NormalParams p{.k = 12, .method = method};
            std::vector<ks::Vec3> plain, by_tree, by_grid, by_user;
            auto v0 = ks::with_normals(pts, plain);
            const ks::NormalResult r0 = ks::estimate_normals(v0, p);
            auto v1 = ks::with_normals(pts, by_tree);
            const ks::NormalResult r1 = ks::estimate_normals(v1, tree, p);
            auto v2 = ks::with_normals(pts, by_grid);
            const ks::NormalResult r2 = ks::estimate_normals(v2, grid, p);
            auto v3 = ks::with_normals(pts, by_user);
            const ks::NormalResult r3 = ks::estimate_normals(v3, brute, p);
            REQUIRE(plain.size() == pts.size());
            CHECK(same_bits(plain, by_tree));
            CHECK(same_bits(plain, by_grid));
            CHECK(same_bits(plain, by_user));
            CHECK(r1.components == r0.components);
            CHECK(r3.components == r0.components);
            CHECK(r3.points == pts.size());
            CHECK(r3.timings.front().stage == "neighbours");
            CHECK(agreement(plain, t.normals).same_sign > 0.99);
            // A coarse torus (40 x 20): measured 3.48 deg mean error with PCA, less with jet.
            CHECK(agreement(plain, t.normals).mean_angle_deg < (method == ks::NormalMethod::pca ? 4.0 : 3.0));
        }
    }
}

TEST_CASE("estimate_normals over an index: an index of other points is refused, the normals untouched") {
    const Oriented s = sphere(500, ks::Vec3::Zero(), 1.0);
    const ks::Vec3 sentinel(7, 7, 7);
    std::vector<ks::Vec3> pts = s.points, nrm(pts.size(), sentinel);
    auto v = ks::with_normals(pts, nrm);
    const std::vector<ks::Vec3> fewer(s.points.begin(), s.points.begin() + 499);
    const ks::KdTree small(fewer);
    CHECK_THROWS_WITH_AS(ks::estimate_normals(v, small),
                         "kintsugi::estimate_normals: the spatial index holds 499 points and the point set 500; "
                         "build the index over the same points",
                         ks::invalid_input);
    const BruteIndex shifted{pts, 1};  // point 499's own index comes out as 500
    CHECK_THROWS_WITH_AS(ks::estimate_normals(v, shifted),
                         doctest::Contains("neighbours or an index out of range; build it over the same points"),
                         ks::invalid_input);
    CHECK(nrm == std::vector<ks::Vec3>(pts.size(), sentinel));
}

TEST_CASE("bad input throws invalid_input naming the problem and leaves the input untouched") {
    const ks::Vec3 sentinel(7, 7, 7);
    auto expect_throw = [&](std::vector<ks::Vec3> pts, const ks::NormalParams& p, const char* what) {
        CAPTURE(what);
        std::vector<ks::Vec3> nrm(pts.size(), sentinel);
        const auto before = pts;
        auto v = ks::with_normals(pts, nrm);
        CHECK_THROWS_WITH_AS(ks::estimate_normals(v, p), doctest::Contains(what), ks::invalid_input);
        CHECK(same_bits(pts, before));  // NaN-safe
        CHECK(nrm == std::vector<ks::Vec3>(pts.size(), sentinel));
    };
    const auto s = sphere(50, ks::Vec3::Zero(), 1.0).points;
    expect_throw({}, {}, "empty");
    expect_throw({s[0], s[1]}, {.k = 2}, "at least 3");
    expect_throw(s, {.k = 2}, "params.k = 2");
    expect_throw(s, {.k = 51}, "[3, 50]");
    expect_throw(s, {.k = 4, .method = ks::NormalMethod::jet}, "k >= 5");
    expect_throw({s[0], s[1], s[2], s[3], s[4]}, {.k = 5, .method = ks::NormalMethod::jet}, "at least 6");
    expect_throw(s, {.k = 0}, "out of range");
    expect_throw(s, {.method = static_cast<ks::NormalMethod>(9)}, "method");
    auto nan = s;
    nan[17].x() = std::numeric_limits<double>::quiet_NaN();
    expect_throw(nan, {}, "point 17");
    auto inf = s;
    inf[3].z() = -std::numeric_limits<double>::infinity();
    expect_throw(inf, {}, "point 3");
    // No normal to fit: every point at one place, or all on one line (a plane is fine).
    expect_throw(std::vector<ks::Vec3>(20, ks::Vec3(1, 2, 3)), {.k = 5}, "all points coincide");
    std::vector<ks::Vec3> line;
    for (int i = 0; i < 20; ++i) line.emplace_back(1e6 + i, 2.0 * i, -0.5 * i);
    expect_throw(line, {.k = 5}, "all points are collinear");

    // CGAL::Point_set_3 without a normal map: still none after a failed call.
    PointSet3 ps;
    ps.insert(K::Point_3(0, 0, 0));
    ps.insert(K::Point_3(1, 0, 0));
    CHECK_THROWS_AS(ks::estimate_normals(ps), ks::invalid_input);
    CHECK_FALSE(ps.has_normal_map());

    // orient_normals needs normals, non-zero and finite.
    std::vector<ks::Vec3> pts = s, none;
    auto v0 = ks::with_normals(pts, none);
    CHECK_THROWS_WITH_AS(ks::orient_normals(v0), doctest::Contains("no normals"), ks::invalid_input);
    std::vector<ks::Vec3> nrm(s.size(), ks::Vec3(0, 0, 1));
    nrm[9] = ks::Vec3::Zero();
    const auto before = nrm;
    auto v1 = ks::with_normals(pts, nrm);
    CHECK_THROWS_WITH_AS(ks::orient_normals(v1), doctest::Contains("normal 9"), ks::invalid_input);
    nrm[9] = ks::Vec3(std::nan(""), 0, 0);
    CHECK_THROWS_WITH_AS(ks::orient_normals(v1), doctest::Contains("normal 9"), ks::invalid_input);
    nrm[9] = before[9];
    CHECK_THROWS_WITH_AS(ks::orient_normals(v1, {.k = 1}), doctest::Contains("params.k = 1"), ks::invalid_input);
    CHECK(nrm == before);
}

TEST_CASE("cancellation by the progress callback or the stop token leaves the normals untouched") {
    const Oriented s = sphere(30000, ks::Vec3::Zero(), 1.0);
    const ks::Vec3 sentinel(7, 7, 7);
    for (const char* stop_in : {"kd-tree", "neighbours", "fit", "orient", "done"}) {
        CAPTURE(stop_in);
        std::vector<ks::Vec3> pts = s.points, nrm(pts.size(), sentinel);
        auto v = ks::with_normals(pts, nrm);
        int calls = 0;
        double last = -1;
        bool monotonic = true;
        ks::NormalParams p;
        p.method = ks::NormalMethod::jet;
        p.control.progress = [&](const ks::ProgressEvent& e) {
            ++calls;
            monotonic = monotonic && e.fraction >= last;
            last = e.fraction;
            return e.stage != stop_in;
        };
        const auto r = ks::estimate_normals(v, p);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(r.components == 0);
        CHECK(nrm == std::vector<ks::Vec3>(pts.size(), sentinel));
        CHECK(monotonic);
        CHECK(calls <= 110);
    }
    // Stop requested before the run.
    std::stop_source source;
    source.request_stop();
    std::vector<ks::Vec3> pts = s.points, nrm(pts.size(), sentinel);
    auto v = ks::with_normals(pts, nrm);
    ks::NormalParams p;
    p.control.stop = source.get_token();
    CHECK(ks::estimate_normals(v, p).status == ks::Status::cancelled);
    CHECK(nrm == std::vector<ks::Vec3>(pts.size(), sentinel));
    // Stop requested from the callback in the middle of the fit; orient_normals too.
    std::stop_source mid;
    ks::NormalParams q;
    q.control.stop = mid.get_token();
    q.control.progress = [&](const ks::ProgressEvent& e) {
        if (e.stage == "orient" && e.fraction > 0.85) mid.request_stop();
        return true;
    };
    CHECK(ks::estimate_normals(v, q).status == ks::Status::cancelled);
    CHECK(nrm == std::vector<ks::Vec3>(pts.size(), sentinel));
    std::vector<ks::Vec3> flipped = s.normals;
    for (std::size_t i = 0; i < flipped.size(); i += 2) flipped[i] = -flipped[i];
    const auto before = flipped;
    auto w = ks::with_normals(pts, flipped);
    ks::NormalParams c;
    c.control.progress = [](const ks::ProgressEvent& e) { return e.stage != "orient"; };
    CHECK(ks::orient_normals(w, c).status == ks::Status::cancelled);
    CHECK(flipped == before);
    // An uncancelled run reports progress up to 1 and finishes.
    double final_fraction = 0;
    ks::NormalParams ok;
    ok.control.progress = [&](const ks::ProgressEvent& e) {
        final_fraction = e.fraction;
        return true;
    };
    CHECK(ks::orient_normals(w, ok).status == ks::Status::ok);
    CHECK(final_fraction == 1.0);
    CHECK(agreement(flipped, s.normals).same_sign == 1.0);
}

namespace {
using PV = std::pair<K::Point_3, K::Vector_3>;
std::vector<PV> to_cgal(const std::vector<ks::Vec3>& pts) {
    std::vector<PV> out;
    for (const auto& p : pts) out.emplace_back(K::Point_3(p.x(), p.y(), p.z()), K::Vector_3(0, 0, 0));
    return out;
}
// Largest unsigned angle (radians) between our normals and CGAL's, over the
// fraction `quantile` of points that agree best.
double unsigned_angle_quantile(const std::vector<ks::Vec3>& ours, const std::vector<PV>& cgal, double quantile) {
    std::vector<double> a(ours.size());
    for (std::size_t i = 0; i < ours.size(); ++i) {
        const ks::Vec3 c(cgal[i].second.x(), cgal[i].second.y(), cgal[i].second.z());
        a[i] = std::acos(std::min(1.0, std::abs(ours[i].dot(c.normalized()))));
    }
    std::sort(a.begin(), a.end());
    return a[static_cast<std::size_t>(quantile * static_cast<double>(a.size() - 1))];
}
}  // namespace

TEST_CASE("the fits agree with CGAL's pca_estimate_normals and jet_estimate_normals") {
    const Oriented k = read_xyz(kTestData / "normals" / "kitten.xyz");
    std::vector<ks::Vec3> pca, jet;
    {
        auto v = ks::with_normals(k.points, pca);
        (void)ks::estimate_normals(v, {.k = 18, .orient = false});
        auto w = ks::with_normals(k.points, jet);
        (void)ks::estimate_normals(v, {.k = 18, .orient = false});
        (void)ks::estimate_normals(w, {.k = 18, .method = ks::NormalMethod::jet, .orient = false});
    }
    auto cp = to_cgal(k.points);
    CGAL::pca_estimate_normals<CGAL::Sequential_tag>(
        cp, 18, CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PV>())
                    .normal_map(CGAL::Second_of_pair_property_map<PV>()));
    auto cj = to_cgal(k.points);
    CGAL::jet_estimate_normals<CGAL::Sequential_tag>(
        cj, 18, CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PV>())
                    .normal_map(CGAL::Second_of_pair_property_map<PV>())
                    .svd_traits(CGAL::Eigen_svd()));
    // Same neighbourhoods, same fit: equal to rounding, everywhere.
    MESSAGE("largest angle to CGAL's normals: pca " << unsigned_angle_quantile(pca, cp, 1.0) << " rad, jet "
                                                    << unsigned_angle_quantile(jet, cj, 1.0) << " rad");
    CHECK(unsigned_angle_quantile(pca, cp, 1.0) < 1e-6);
    CHECK(unsigned_angle_quantile(jet, cj, 1.0) < 1e-6);
}

namespace {
void check_real_scan(const fs::path& file, double min_same_sign) {
    const Oriented ref = read_xyz(file);
    REQUIRE(ref.points.size() > 1000);
    for (auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
        std::vector<ks::Vec3> nrm;
        auto v = ks::with_normals(ref.points, nrm);
        const auto r = ks::estimate_normals(v, {.k = 18, .method = method});
        REQUIRE(r.status == ks::Status::ok);
        const auto a = agreement(nrm, ref.normals);
        MESSAGE(file.filename().string() << " " << (method == ks::NormalMethod::pca ? "pca" : "jet") << ": "
                                         << ref.points.size() << " points, " << r.components
                                         << " component(s), same sign as reference " << 100.0 * a.same_sign
                                         << " %, mean unsigned angle " << a.mean_angle_deg << " deg");
        CHECK(a.same_sign > min_same_sign);
        CHECK(a.mean_angle_deg < 10.0);
    }
}
}  // namespace

TEST_CASE("real scan of a closed object (kitten, genus 1): > 99 % of normals oriented as the reference") {
    check_real_scan(kTestData / "normals" / "kitten.xyz", 0.99);
}

TEST_CASE("real data from ../shared: bunny and a sharp-edged CAD block") {
    const fs::path bunny = kShared / "stanford_bunny" / "reconstruction" / "bun_zipper_points_normals.xyz";
    const fs::path block = kShared / "guided_denoising" / "Block0.4" / "Original_points_normals.xyz";
    KINTSUGI_REQUIRE_DATA(bunny);
    KINTSUGI_REQUIRE_DATA(block);
    check_real_scan(bunny, 0.99);
    check_real_scan(block, 0.99);
}
