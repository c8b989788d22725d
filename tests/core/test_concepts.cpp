// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Concepts and adapters: static_asserts both ways, and run-time access through
// every shipped adapter.
#include <doctest/doctest.h>

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <array>
#include <list>
#include <vector>

namespace ks = kintsugi;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;
using PointSet3 = CGAL::Point_set_3<K::Point_3, K::Vector_3>;

namespace user {
// A user's own point type, plugged in through projections.
struct Sample {
    float xyz[3];
    std::array<float, 3> n;
    int label;
};
// A user's own mesh type, plugged in by specialising mesh_traits.
struct Soup {
    std::vector<std::array<float, 3>> v;
    std::vector<std::array<int, 3>> t;
};
}  // namespace user

template <>
struct kintsugi::mesh_traits<user::Soup> {
    static std::size_t num_vertices(const user::Soup& m) { return m.v.size(); }
    static std::size_t num_faces(const user::Soup& m) { return m.t.size(); }
    static Vec3 position(const user::Soup& m, Index i) { return detail::to_vec3(m.v[i]); }
    static Face face(const user::Soup& m, Index f) {
        return {Index(m.t[f][0]), Index(m.t[f][1]), Index(m.t[f][2])};
    }
};

using VecPts = std::vector<Eigen::Vector3d>;
using VecPtsF = std::vector<Eigen::Vector3f>;
using UserView = decltype(ks::project_points(std::declval<std::vector<user::Sample>&>(), &user::Sample::xyz,
                                             &user::Sample::n));
using UserViewConst = decltype(ks::project_points(std::declval<const std::vector<user::Sample>&>(),
                                                  &user::Sample::xyz, &user::Sample::n));
using EigenMeshRW = ks::EigenMeshView<Eigen::MatrixXd, Eigen::MatrixXi>;
using EigenMeshRO = ks::EigenMeshView<const Eigen::MatrixXd, Eigen::MatrixXi>;

// ---- positive
static_assert(ks::PointSet<VecPts> && ks::PointSet<VecPtsF> && ks::GrowablePointSet<VecPts>);
static_assert(ks::OrientedPointSet<ks::PointsWithNormals<VecPts, VecPts>>);
static_assert(ks::NormalWritablePointSet<ks::PointsWithNormals<const VecPts, VecPts>>);
static_assert(ks::OrientedPointSet<ks::PointCloud> && ks::NormalWritablePointSet<ks::PointCloud> &&
              ks::GrowablePointSet<ks::PointCloud>);
static_assert(ks::OrientedPointSet<PointSet3> && ks::NormalWritablePointSet<PointSet3> &&
              ks::GrowablePointSet<PointSet3>);
static_assert(ks::OrientedPointSet<UserView> && ks::NormalWritablePointSet<UserView>);
static_assert(ks::OrientedPointSet<ks::EigenPointsView<Eigen::MatrixXd, Eigen::MatrixXd>>);
static_assert(ks::TopologyMutableMesh<ks::IndexedMesh> && ks::MutableTriangleMesh<ks::IndexedMesh>);
static_assert(ks::TopologyMutableMesh<SurfaceMesh> && ks::MutableTriangleMesh<SurfaceMesh>);
static_assert(ks::MutableTriangleMesh<EigenMeshRW>);
static_assert(ks::TriangleMesh<user::Soup>);
static_assert(ks::SpatialIndex<ks::KdTree>);

// ---- negative
static_assert(!ks::PointSet<int> && !ks::PointSet<std::vector<double>> && !ks::PointSet<ks::IndexedMesh>);
static_assert(!ks::OrientedPointSet<VecPts>);
static_assert(!ks::NormalWritablePointSet<ks::PointsWithNormals<VecPts, const VecPts>>);
static_assert(!ks::NormalWritablePointSet<UserViewConst>);
static_assert(!ks::GrowablePointSet<ks::PointsWithNormals<VecPts, VecPts>>);
static_assert(!ks::TriangleMesh<ks::PointCloud> && !ks::TriangleMesh<VecPts>);
static_assert(!ks::MutableTriangleMesh<EigenMeshRO> && !ks::MutableTriangleMesh<user::Soup>);
static_assert(!ks::TopologyMutableMesh<EigenMeshRW>);
static_assert(!ks::SpatialIndex<VecPts>);
static_assert(ks::ScalarField<double (*)(const ks::Vec3&)>);
static_assert(!ks::DifferentiableScalarField<double (*)(const ks::Vec3&)>);

TEST_CASE("point-set adapters read the same points") {
    const std::vector<ks::Vec3> ref = {{0, 0, 0}, {1, 2, 3}, {-1, 0.5, 2}};
    const std::vector<ks::Vec3> nref = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}};

    VecPts pts(ref.begin(), ref.end());
    VecPts nrm(nref.begin(), nref.end());
    auto oriented = ks::with_normals(pts, nrm);
    ks::PointCloud cloud{ref, nref, {}};
    PointSet3 ps;
    ps.add_normal_map();
    for (std::size_t i = 0; i < ref.size(); ++i)
        ps.insert(K::Point_3(ref[i].x(), ref[i].y(), ref[i].z()), K::Vector_3(nref[i].x(), nref[i].y(), nref[i].z()));
    std::vector<user::Sample> samples;
    for (std::size_t i = 0; i < ref.size(); ++i)
        samples.push_back({{float(ref[i].x()), float(ref[i].y()), float(ref[i].z())},
                           {float(nref[i].x()), float(nref[i].y()), float(nref[i].z())},
                           int(i)});
    auto user_view = ks::project_points(samples, &user::Sample::xyz, &user::Sample::n);
    Eigen::MatrixXd P(3, 3), N(3, 3);
    for (int i = 0; i < 3; ++i) {
        P.row(i) = ref[i].transpose();
        N.row(i) = nref[i].transpose();
    }
    auto eig = ks::eigen_points(P, N);

    auto check = [&](const auto& set) {
        REQUIRE(ks::num_points(set) == 3);
        REQUIRE(ks::has_normals(set));
        for (std::size_t i = 0; i < 3; ++i) {
            CHECK((ks::point_at(set, i) - ref[i]).norm() < 1e-6);
            CHECK((ks::normal_at(set, i) - nref[i]).norm() < 1e-6);
        }
    };
    check(oriented);
    check(cloud);
    check(ps);
    check(user_view);
    check(eig);
    CHECK(!ks::has_normals(pts));
    CHECK(ks::gather_points(pts).size() == 3);

    // Writing normals through the views reaches the user's storage.
    ks::point_set_traits<decltype(user_view)>::set_normal(user_view, 1, ks::Vec3(0, 0, -1));
    CHECK(samples[1].n[2] == -1.0f);
    ks::point_set_traits<PointSet3>::set_normal(ps, 2, ks::Vec3(0, 0, -1));
    CHECK(ps.normal(*(ps.begin() + 2)).z() == -1.0);
    ks::point_set_traits<decltype(eig)>::set_normal(eig, 0, ks::Vec3(1, 1, 1));
    CHECK(N(0, 2) == 1.0);
}

TEST_CASE("point sets without normals report none") {
    PointSet3 ps;
    ps.insert(K::Point_3(0, 0, 0));
    CHECK_FALSE(ks::has_normals(ps));
    ks::PointCloud cloud;
    cloud.points = {ks::Vec3(0, 0, 0)};
    CHECK_FALSE(ks::has_normals(cloud));
    CHECK(ks::gather_normals(cloud).empty());
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(4, 3);
    CHECK_FALSE(ks::has_normals(ks::eigen_points(P)));
}

namespace {
ks::IndexedMesh tetrahedron() {
    ks::IndexedMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
}
}  // namespace

TEST_CASE_TEMPLATE("mesh adapters round-trip through IndexedMesh", M, ks::IndexedMesh, SurfaceMesh) {
    const ks::IndexedMesh ref = tetrahedron();
    M m;
    ks::assign_mesh(m, ref);
    REQUIRE(ks::num_vertices(m) == 4);
    REQUIRE(ks::num_faces(m) == 4);
    const ks::IndexedMesh back = ks::to_indexed_mesh(m);
    for (std::size_t v = 0; v < 4; ++v) CHECK(back.vertices[v] == ref.vertices[v]);
    for (std::size_t f = 0; f < 4; ++f) {
        // Same cyclic order (a Surface_mesh may start a face at another corner).
        const auto& a = back.faces[f];
        const auto& b = ref.faces[f];
        const bool same = (a == b) || (a == ks::Face{b[1], b[2], b[0]}) || (a == ks::Face{b[2], b[0], b[1]});
        CHECK(same);
    }
    ks::set_vertex_position(m, 3, ks::Vec3(0, 0, 2));
    CHECK(ks::vertex_position(m, 3).z() == 2.0);
}

TEST_CASE("Eigen V/F view is a writable, non-owning mesh") {
    Eigen::MatrixXd V(4, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
    Eigen::MatrixXi F(4, 3);
    F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
    auto view = ks::eigen_mesh(V, F);
    CHECK(ks::num_vertices(view) == 4);
    CHECK(ks::face_at(view, 3) == ks::Face{1, 2, 3});
    ks::set_vertex_position(view, 1, ks::Vec3(5, 0, 0));
    CHECK(V(1, 0) == 5.0);
    const Eigen::MatrixXd& Vc = V;
    auto ro = ks::eigen_mesh(Vc, F);
    static_assert(!ks::MutableTriangleMesh<decltype(ro)>);
    CHECK(ks::vertex_position(ro, 1).x() == 5.0);
}

TEST_CASE("user mesh through mesh_traits") {
    user::Soup s{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 1, 2}}};
    const auto m = ks::to_indexed_mesh(s);
    CHECK(m.faces.size() == 1);
    CHECK(m.vertices[1].x() == 1.0);
}

TEST_CASE("Surface_mesh with removed elements or polygons is rejected") {
    SurfaceMesh sm;
    auto a = sm.add_vertex(K::Point_3(0, 0, 0)), b = sm.add_vertex(K::Point_3(1, 0, 0)),
         c = sm.add_vertex(K::Point_3(1, 1, 0)), d = sm.add_vertex(K::Point_3(0, 1, 0));
    sm.add_face(a, b, c, d);
    CHECK_THROWS_WITH_AS(ks::to_indexed_mesh(sm), doctest::Contains("not a triangle"), ks::invalid_input);
    sm.remove_vertex(sm.add_vertex(K::Point_3(5, 5, 5)));
    CHECK_THROWS_WITH_AS((void)ks::num_vertices(sm), doctest::Contains("collect_garbage"), ks::invalid_input);
}

TEST_CASE("to_indexed_mesh refuses a Surface_mesh with a removed face or vertex (CGAL's counts include them)") {
    for (const bool remove_face : {true, false}) {
        CAPTURE(remove_face);
        SurfaceMesh sm;
        std::vector<SurfaceMesh::Vertex_index> v;
        for (int i = 0; i < 4; ++i) v.push_back(sm.add_vertex(K::Point_3(i & 1, (i >> 1) & 1, i == 3)));
        sm.add_face(v[0], v[1], v[2]);
        const auto last = sm.add_face(v[1], v[3], v[2]);
        if (remove_face)
            sm.remove_face(last);
        else
            sm.remove_vertex(sm.add_vertex(K::Point_3(5, 5, 5)));
        CHECK_THROWS_WITH_AS((void)ks::to_indexed_mesh(sm), doctest::Contains("call collect_garbage()"),
                             ks::invalid_input);
        sm.collect_garbage();
        const ks::IndexedMesh m = ks::to_indexed_mesh(sm);
        CHECK(m.vertices.size() == 4);
        CHECK(m.faces.size() == (remove_face ? 1u : 2u));
    }
}
