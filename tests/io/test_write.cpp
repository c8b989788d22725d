// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Writers: exact round trips on real data in every format, writing from every adapter,
// and failures that leave no output and no temporary file.
#include "io_test_util.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <array>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace ks = kintsugi;
using namespace io_test;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;
using PointSet3 = CGAL::Point_set_3<K::Point_3, K::Vector_3>;

namespace {

struct Sample {  // a user's own point struct
    double p[3];
    std::array<double, 3> n;
    int label;
};

bool contains(const std::string& haystack, const std::string& needle) { return haystack.find(needle) != std::string::npos; }

}  // namespace

TEST_CASE("mesh round trips on real data are exact in every format") {
    TempDir dir;
    for (const char* source : {"bun000_part.ply", "bun_zipper_res4.ply", "eight.off"}) {
        CAPTURE(source);
        const ks::IndexedMesh m = ks::read_mesh(data(source));
        const bool normals = !m.normals.empty();
        struct Case {
            std::string name;
            ks::WriteOptions options;
            std::string format;
        };
        const std::vector<Case> cases = {
            {"le.ply", {}, "ply-binary-le"},
            {"be.ply", {.binary = true, .big_endian = true}, "ply-binary-be"},
            {"ascii.ply", {.binary = false}, "ply-ascii"},
            {"m.off", {}, "off"},
            {"m.OBJ", {}, "obj"},
        };
        for (const Case& c : cases) {
            CAPTURE(c.name);
            const fs::path f = dir / c.name;
            ks::write_mesh(f, m, c.options);
            ks::ReadInfo info;
            const ks::IndexedMesh back = ks::read_mesh(f, {}, &info);
            CHECK(info.format == c.format);
            CHECK(info.has_normals == normals);
            CHECK(back.vertices == m.vertices);
            CHECK(back.faces == m.faces);
            CHECK(back.normals == m.normals);
            CHECK(info.ignored_properties.empty());
        }
        CHECK(contains(read_file(dir / "be.ply"), "format binary_big_endian 1.0"));
        CHECK(contains(read_file(dir / "ascii.ply"), "format ascii 1.0"));
        CHECK(dir.entries() == cases.size());  // no temporary file left
    }
}

TEST_CASE("point cloud round trips: positions, normals, radii") {
    TempDir dir;
    const ks::PointCloud kitten = ks::read_point_cloud(data("kitten.xyz"));
    REQUIRE(kitten.normals.size() == 5210);
    for (const char* name : {"k.xyz", "k.pwn", "k.ply", "k.off", "k.obj"}) {
        CAPTURE(name);
        ks::write_point_cloud(dir / name, kitten);
        const ks::PointCloud back = ks::read_point_cloud(dir / name);
        CHECK(back.points == kitten.points);
        CHECK(back.normals == kitten.normals);
    }
    // ascii text is exact too: each double is written in its shortest round-trip form.
    ks::write_point_cloud(dir / "k_ascii.ply", kitten, {.binary = false});
    CHECK(ks::read_point_cloud(dir / "k_ascii.ply").points == kitten.points);

    ks::PointCloud surfels = kitten;
    surfels.radii.resize(surfels.points.size());
    for (std::size_t i = 0; i < surfels.radii.size(); ++i) surfels.radii[i] = 1e-3 * static_cast<double>(i % 17) + 1.0 / 3.0;
    for (const bool binary : {true, false}) {
        ks::write_point_cloud(dir / "s.ply", surfels, {.binary = binary});
        ks::ReadInfo info;
        const ks::PointCloud back = ks::read_point_cloud(dir / "s.ply", &info);
        CHECK(info.has_radii);
        CHECK(back.radii == surfels.radii);
        CHECK(back.points == surfels.points);
    }
    // Points without normals: XYZ has 3 columns.
    ks::PointCloud bare;
    bare.points = kitten.points;
    ks::write_point_cloud(dir / "bare.xyz", bare);
    ks::ReadInfo info;
    CHECK(ks::read_point_cloud(dir / "bare.xyz", &info).points == kitten.points);
    CHECK_FALSE(info.has_normals);
}

// ---- writing from every mesh adapter
template <class M>
struct MeshHolder;
template <>
struct MeshHolder<ks::IndexedMesh> {
    ks::IndexedMesh m;
    explicit MeshHolder(const ks::IndexedMesh& src) : m(src) {}
    const ks::IndexedMesh& get() const { return m; }
};
template <>
struct MeshHolder<SurfaceMesh> {
    SurfaceMesh m;
    explicit MeshHolder(const ks::IndexedMesh& src) { ks::assign_mesh(m, src); }
    const SurfaceMesh& get() const { return m; }
};
using EigenView = ks::EigenMeshView<const Eigen::MatrixXd, Eigen::MatrixXi>;
template <>
struct MeshHolder<EigenView> {
    Eigen::MatrixXd V;
    Eigen::MatrixXi F;
    EigenView view;
    explicit MeshHolder(const ks::IndexedMesh& src)
        : V(static_cast<Eigen::Index>(src.vertices.size()), 3), F(static_cast<Eigen::Index>(src.faces.size()), 3) {
        for (std::size_t i = 0; i < src.vertices.size(); ++i) V.row(static_cast<Eigen::Index>(i)) = src.vertices[i].transpose();
        for (std::size_t f = 0; f < src.faces.size(); ++f)
            for (int c = 0; c < 3; ++c) F(static_cast<Eigen::Index>(f), c) = static_cast<int>(src.faces[f][c]);
        view = ks::eigen_mesh(std::as_const(V), F);
    }
    const EigenView& get() const { return view; }
};

TEST_CASE_TEMPLATE("write_mesh from any TriangleMesh", M, ks::IndexedMesh, EigenView, SurfaceMesh) {
    TempDir dir;
    const ks::IndexedMesh src = ks::read_mesh(data("eight.off"));  // closed, manifold: fits Surface_mesh
    const MeshHolder<M> holder(src);
    for (const char* name : {"out.ply", "out.off", "out.obj"}) {
        ks::write_mesh(dir / name, holder.get());
        const ks::IndexedMesh back = ks::read_mesh(dir / name);
        CHECK(back.vertices == src.vertices);
        CHECK(back.faces.size() == src.faces.size());
        // Surface_mesh may start a face at another corner: compare as rotations.
        std::size_t same = 0;
        for (std::size_t f = 0; f < src.faces.size(); ++f) {
            const ks::Face a = src.faces[f], b = back.faces[f];
            same += (a == b) || (a == ks::Face{b[1], b[2], b[0]}) || (a == ks::Face{b[2], b[0], b[1]});
        }
        CHECK(same == src.faces.size());
    }
}

// ---- writing from every point adapter
template <class P>
struct CloudHolder;
using VecPts = std::vector<Eigen::Vector3d>;
template <>
struct CloudHolder<VecPts> {
    VecPts p;
    explicit CloudHolder(const ks::PointCloud& c) : p(c.points) {}
    const VecPts& get() const { return p; }
    static constexpr bool normals = false;
};
using WithNormals = ks::PointsWithNormals<const VecPts, const VecPts>;
template <>
struct CloudHolder<WithNormals> {
    VecPts p, n;
    WithNormals view;
    explicit CloudHolder(const ks::PointCloud& c) : p(c.points), n(c.normals), view(ks::with_normals(std::as_const(p), std::as_const(n))) {}
    const WithNormals& get() const { return view; }
    static constexpr bool normals = true;
};
template <>
struct CloudHolder<PointSet3> {
    PointSet3 ps;
    explicit CloudHolder(const ks::PointCloud& c) {
        ps.add_normal_map();
        for (std::size_t i = 0; i < c.points.size(); ++i)
            ps.insert(K::Point_3(c.points[i].x(), c.points[i].y(), c.points[i].z()),
                      K::Vector_3(c.normals[i].x(), c.normals[i].y(), c.normals[i].z()));
    }
    const PointSet3& get() const { return ps; }
    static constexpr bool normals = true;
};
using UserView = decltype(ks::project_points(std::declval<const std::vector<Sample>&>(), &Sample::p, &Sample::n));
template <>
struct CloudHolder<UserView> {
    std::vector<Sample> s;
    UserView view;
    explicit CloudHolder(const ks::PointCloud& c)
        : s(make(c)), view(ks::project_points(std::as_const(s), &Sample::p, &Sample::n)) {}
    static std::vector<Sample> make(const ks::PointCloud& c) {
        std::vector<Sample> out(c.points.size());
        for (std::size_t i = 0; i < out.size(); ++i) {
            for (int k = 0; k < 3; ++k) out[i].p[k] = c.points[i][k];
            out[i].n = {c.normals[i].x(), c.normals[i].y(), c.normals[i].z()};
            out[i].label = 0;
        }
        return out;
    }
    const UserView& get() const { return view; }
    static constexpr bool normals = true;
};

TEST_CASE_TEMPLATE("write_point_cloud from any PointSet", P, VecPts, WithNormals, PointSet3, UserView) {
    TempDir dir;
    const ks::PointCloud src = ks::read_point_cloud(data("kitten.xyz"));
    const CloudHolder<P> holder(src);
    for (const char* name : {"out.ply", "out.xyz"}) {
        ks::write_point_cloud(dir / name, holder.get());
        const ks::PointCloud back = ks::read_point_cloud(dir / name);
        CHECK(back.points == src.points);
        if (CloudHolder<P>::normals) CHECK(back.normals == src.normals);
        else CHECK(back.normals.empty());
    }
}

TEST_CASE("write_polylines: PLY vertex + edge elements, OBJ lines") {
    TempDir dir;
    const std::vector<ks::Vec3> pts = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.5}, {0.1, 0.2, 0.3}};
    const std::vector<std::array<ks::Index, 2>> edges = {{0, 1}, {1, 2}, {2, 0}};
    for (const bool binary : {true, false}) {
        ks::write_polylines(dir / "loop.ply", pts, edges, {.binary = binary});
        const std::string text = read_file(dir / "loop.ply");
        CHECK(contains(text, "element edge 3\nproperty int vertex1\nproperty int vertex2\n"));
        ks::ReadInfo info;
        const ks::PointCloud back = ks::read_point_cloud(dir / "loop.ply", &info);
        CHECK(back.points == pts);
        CHECK(std::find(info.ignored_properties.begin(), info.ignored_properties.end(), "edge.vertex1") !=
              info.ignored_properties.end());
    }
    CHECK(contains(read_file(dir / "loop.ply"), "0 1\n1 2\n2 0\n"));
    ks::write_polylines(dir / "loop.obj", pts, edges);
    CHECK(contains(read_file(dir / "loop.obj"), "l 1 2\nl 2 3\nl 3 1\n"));
    CHECK(ks::read_point_cloud(dir / "loop.obj").points == pts);

    const std::vector<std::array<ks::Index, 2>> bad = {{0, 4}};
    CHECK_THROWS_WITH_AS(ks::write_polylines(dir / "bad.ply", pts, bad),
                         doctest::Contains("edge 0 uses point 4, out of range"), ks::invalid_input);
    CHECK_FALSE(fs::exists(dir / "bad.ply"));
    check_io_error([&] { ks::write_polylines(dir / "loop.xyz", pts, edges); }, dir / "loop.xyz", "unsupported extension");
}

TEST_CASE("io_error messages escape the file name; path() keeps it as given") {
    TempDir dir;
    const ks::IndexedMesh mesh = ks::read_mesh(data("bun_zipper_res4.ply"));
    const std::string odd = "a\nb\tc\r\x1B[31m\x01\xFF";  // a newline, a tab, a terminal escape, raw bytes
    const std::string shown = "a\\nb\\tc\\r\\x1B[31m\\x01\\xFF";
    auto message_of = [](auto&& fn, const fs::path& path) {
        try {
            fn();
        } catch (const ks::io_error& e) {
            CHECK(e.path() == path.string());
            return std::string(e.what());
        }
        return std::string("(nothing thrown)");
    };
    auto printable = [](const std::string& s) {
        return std::all_of(s.begin(), s.end(), [](char c) { return c >= 0x20 && c < 0x7F; });
    };
    const std::vector<std::pair<fs::path, std::string>> cases = {
        {dir / (odd + ".ply"), "file does not exist"},                          // reading: the file
        {dir / (odd + ".off"), "is not a number"},                              // reading: its content
        {dir / odd / "m.ply", "' does not exist"},                              // writing: the directory
        {dir / ("m.p" + odd), "unsupported extension '.p" + shown + "' for"},  // writing: the extension
    };
    write_file(dir / (odd + ".off"), "OFF\n1 0 0\nx 0 0\n");
    for (std::size_t i = 0; i < cases.size(); ++i) {
        const fs::path& p = cases[i].first;
        const std::string msg = i < 2 ? message_of([&] { (void)ks::read_mesh(p); }, p)
                                      : message_of([&] { ks::write_mesh(p, mesh); }, p);
        INFO("message: ", msg);
        CHECK(printable(msg));
        CHECK(msg.find(shown) != std::string::npos);
        CHECK(msg.find(cases[i].second) != std::string::npos);
    }
    // The directory named inside the message is escaped too.
    const std::string dir_msg = message_of([&] { ks::write_mesh(dir / odd / "m.ply", mesh); }, dir / odd / "m.ply");
    CHECK(dir_msg.find("directory '" + (dir / "").string() + shown + "' does not exist") != std::string::npos);
}

TEST_CASE("failed writes leave no output and no temporary file") {
    TempDir dir;
    const ks::IndexedMesh mesh = ks::read_mesh(data("bun_zipper_res4.ply"));
    const ks::PointCloud cloud = ks::read_point_cloud(data("kitten.xyz"));

    SUBCASE("missing directory, parent is a file, target is a directory") {
        check_io_error([&] { ks::write_mesh(dir / "no" / "such" / "m.ply", mesh); }, dir / "no" / "such" / "m.ply",
                       "does not exist");
        CHECK_FALSE(fs::exists(dir / "no"));
        write_file(dir / "file", "x");
        check_io_error([&] { ks::write_point_cloud(dir / "file" / "c.xyz", cloud); }, dir / "file" / "c.xyz",
                       "does not exist");
        fs::create_directory(dir / "m.ply");
        check_io_error([&] { ks::write_mesh(dir / "m.ply", mesh); }, dir / "m.ply", "is a directory");
        CHECK(dir.entries() == 2);
    }
    SUBCASE("an unwritable directory") {
        fs::create_directory(dir / "ro");
        fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
        bool threw = false;
        try {
            ks::write_mesh(dir / "ro" / "m.ply", mesh);
        } catch (const ks::io_error& e) {
            threw = true;
            CHECK(contains(e.what(), "cannot create a temporary file"));
            CHECK(contains(e.what(), "Permission denied"));
        }
        if (!threw) MESSAGE("running with privileges that ignore directory permissions: check skipped");
        CHECK(fs::is_empty(dir / "ro") != !threw);
        fs::permissions(dir / "ro", fs::perms::owner_all);
    }
    SUBCASE("bad data: invalid_input before anything is written, an existing file is kept") {
        write_file(dir / "keep.ply", "old content");
        ks::IndexedMesh nan_mesh = mesh;
        nan_mesh.vertices[7].y() = std::numeric_limits<double>::quiet_NaN();
        CHECK_THROWS_WITH_AS(ks::write_mesh(dir / "keep.ply", nan_mesh),
                             doctest::Contains("kintsugi::write_mesh: vertex 7 is not finite"), ks::invalid_input);
        ks::IndexedMesh bad_face = mesh;
        bad_face.faces[3][1] = 453;
        CHECK_THROWS_WITH_AS(ks::write_mesh(dir / "keep.ply", bad_face),
                             doctest::Contains("face 3 uses vertex 453, out of range"), ks::invalid_input);
        ks::IndexedMesh short_normals = mesh;
        short_normals.normals.assign(3, ks::Vec3::UnitZ());
        CHECK_THROWS_AS(ks::write_mesh(dir / "keep.ply", short_normals), ks::invalid_input);
        ks::PointCloud no_normals;
        no_normals.points = cloud.points;
        CHECK_THROWS_WITH_AS(ks::write_point_cloud(dir / "keep.pwn", no_normals), doctest::Contains(".pwn file needs normals"),
                             ks::invalid_input);
        ks::PointCloud inf_radius = cloud;
        inf_radius.radii.assign(cloud.points.size(), 1.0);
        inf_radius.radii[9] = std::numeric_limits<double>::infinity();
        CHECK_THROWS_AS(ks::write_point_cloud(dir / "keep.ply", inf_radius), ks::invalid_input);
        check_io_error([&] { ks::write_mesh(dir / "keep.stl", mesh); }, dir / "keep.stl", "unsupported extension");
        check_io_error([&] { ks::write_mesh(dir / "keep.xyz", mesh); }, dir / "keep.xyz", "unsupported extension");
        // A CGAL mesh with a quad is refused by its adapter while being read, before any file exists.
        SurfaceMesh quad;
        const auto a = quad.add_vertex(K::Point_3(0, 0, 0)), b = quad.add_vertex(K::Point_3(1, 0, 0)),
                   c = quad.add_vertex(K::Point_3(1, 1, 0)), d = quad.add_vertex(K::Point_3(0, 1, 0));
        quad.add_face(a, b, c, d);
        CHECK_THROWS_AS(ks::write_mesh(dir / "keep.ply", quad), ks::invalid_input);
        CHECK(read_file(dir / "keep.ply") == "old content");
        CHECK(dir.entries() == 1);
    }
    SUBCASE("an uncommitted output file removes its temporary file; a committed one replaces the target") {
        write_file(dir / "t.ply", "old");
        {
            ks::detail::io::AtomicOutputFile out(dir / "t.ply");
            out.write("partial");
            CHECK(fs::exists(out.temporary_path()));
            CHECK(out.temporary_path().parent_path() == dir.path);
            CHECK(dir.entries() == 2);
        }
        CHECK(dir.entries() == 1);
        CHECK(read_file(dir / "t.ply") == "old");
        ks::write_mesh(dir / "t.ply", mesh);
        CHECK(ks::read_mesh(dir / "t.ply").vertices == mesh.vertices);
        CHECK(dir.entries() == 1);
    }
}
