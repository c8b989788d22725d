// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Readers: real files cross-checked against CGAL's readers, every supported variant of
// every format on small generated files, every kind of bad file, and a little fuzzing.
#include "io_test_util.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/IO/polygon_soup_io.h>
#include <CGAL/IO/read_xyz_points.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace ks = kintsugi;
using namespace io_test;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;

namespace {

// Reference: CGAL's polygon-soup reader.
void check_against_cgal_soup(const fs::path& file, const ks::IndexedMesh& m) {
    std::vector<K::Point_3> pts;
    std::vector<std::vector<std::size_t>> polys;
    REQUIRE(CGAL::IO::read_polygon_soup(file.string(), pts, polys));
    REQUIRE(pts.size() == m.vertices.size());
    REQUIRE(polys.size() == m.faces.size());  // all real files here are triangle meshes
    std::size_t vertex_mismatch = 0, face_mismatch = 0;
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (pts[i].x() != m.vertices[i].x() || pts[i].y() != m.vertices[i].y() || pts[i].z() != m.vertices[i].z())
            ++vertex_mismatch;
    for (std::size_t f = 0; f < polys.size(); ++f)
        if (polys[f].size() != 3 || polys[f][0] != m.faces[f][0] || polys[f][1] != m.faces[f][1] ||
            polys[f][2] != m.faces[f][2])
            ++face_mismatch;
    CHECK(vertex_mismatch == 0);
    CHECK(face_mismatch == 0);
}

bool has_entry(const ks::ReadInfo& info, const std::string& s) {
    return std::find(info.ignored_properties.begin(), info.ignored_properties.end(), s) !=
           info.ignored_properties.end();
}

// A small binary PLY built byte by byte (to test types and byte orders independently of the writer).
struct BinaryPly {
    bool big = false;
    std::string body;
    template <class T>
    void put(T v) {
        char b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (big == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof(T));
        body.append(b, sizeof(T));
    }
};

}  // namespace

TEST_CASE("read real files: counts, formats, ignored properties, agreement with CGAL") {
    SUBCASE("ascii PLY with extra vertex properties (bun_zipper_res4)") {
        const fs::path f = data("bun_zipper_res4.ply");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        CHECK(info.format == "ply-ascii");
        CHECK(m.vertices.size() == 453);
        CHECK(m.faces.size() == 948);
        CHECK(info.vertices == 453);
        CHECK(info.faces == 948);
        CHECK_FALSE(info.has_normals);
        CHECK(m.normals.empty());
        CHECK(has_entry(info, "vertex.confidence"));
        CHECK(has_entry(info, "vertex.intensity"));
        // Declared `float`: the value is the float nearest to the text, as CGAL and a binary copy give.
        CHECK(m.vertices[0] == ks::Vec3(double(-0.0312216f), double(0.126304f), double(0.00514924f)));
        check_against_cgal_soup(f, m);
    }
    SUBCASE("binary little-endian PLY scan with normals (bun000 part)") {
        const fs::path f = data("bun000_part.ply");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        CHECK(info.format == "ply-binary-le");
        CHECK(m.vertices.size() == 8000);
        CHECK(m.faces.size() == 15313);
        CHECK(info.has_normals);
        REQUIRE(m.normals.size() == 8000);
        std::size_t unit = 0;
        for (const ks::Vec3& n : m.normals) unit += std::abs(n.norm() - 1.0) < 1e-5;
        CHECK(unit == 8000);
        CHECK(info.ignored_properties.empty());
        check_against_cgal_soup(f, m);
        // read_point_cloud gives the same vertices and normals.
        const ks::PointCloud c = ks::read_point_cloud(f);
        CHECK(c.points == m.vertices);
        CHECK(c.normals == m.normals);
        CHECK(c.radii.empty());
    }
    SUBCASE("OFF meshes (eight, npm bunny)") {
        for (const auto& [name, nv, nf] : {std::tuple{"eight.off", 315, 634}, std::tuple{"bunny.off", 1839, 3674}}) {
            const fs::path f = data(name);
            ks::ReadInfo info;
            const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
            CHECK(info.format == "off");
            CHECK(m.vertices.size() == std::size_t(nv));
            CHECK(m.faces.size() == std::size_t(nf));
            check_against_cgal_soup(f, m);
        }
    }
    SUBCASE("OBJ written by MeshLab (twelve)") {
        const fs::path f = data("twelve.obj");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        CHECK(info.format == "obj");
        CHECK(m.vertices.size() == 4610);
        CHECK(m.faces.size() == 9216);
        check_against_cgal_soup(f, m);
    }
    SUBCASE("XYZ with normals (kitten), against CGAL::IO::read_XYZ") {
        const fs::path f = data("kitten.xyz");
        ks::ReadInfo info;
        const ks::PointCloud c = ks::read_point_cloud(f, &info);
        CHECK(info.format == "xyz");
        CHECK(info.has_normals);
        REQUIRE(c.points.size() == 5210);
        REQUIRE(c.normals.size() == 5210);
        std::vector<std::pair<K::Point_3, K::Vector_3>> ref;
        REQUIRE(CGAL::IO::read_XYZ(f.string(), std::back_inserter(ref),
                                   CGAL::parameters::point_map(CGAL::First_of_pair_property_map<std::pair<K::Point_3, K::Vector_3>>())
                                       .normal_map(CGAL::Second_of_pair_property_map<std::pair<K::Point_3, K::Vector_3>>())));
        REQUIRE(ref.size() == 5210);
        std::size_t mismatch = 0;
        for (std::size_t i = 0; i < ref.size(); ++i)
            mismatch += ref[i].first.x() != c.points[i].x() || ref[i].first.z() != c.points[i].z() ||
                        ref[i].second.y() != c.normals[i].y();
        CHECK(mismatch == 0);
        // A point file read as a mesh: vertices, no faces.
        const ks::IndexedMesh m = ks::read_mesh(f);
        CHECK(m.vertices.size() == 5210);
        CHECK(m.faces.empty());
        CHECK(m.normals.size() == 5210);
    }
}

TEST_CASE("PLY variants: scalar types, byte orders, vertex_index, radius, element order, polygons") {
    TempDir dir;
    SUBCASE("every scalar type in both byte orders gives the same values") {
        for (const bool big : {false, true}) {
            BinaryPly b;
            b.big = big;
            // vertex: char x, uchar y, short z, ushort a, int nx, uint ny, float nz, double radius
            for (int i = 0; i < 3; ++i) {
                b.put<std::int8_t>(static_cast<std::int8_t>(-5 + i));
                b.put<std::uint8_t>(static_cast<std::uint8_t>(200 + i));
                b.put<std::int16_t>(static_cast<std::int16_t>(-30000 + i));
                b.put<std::uint16_t>(static_cast<std::uint16_t>(60000 + i));
                b.put<std::int32_t>(-2000000000 + i);
                b.put<std::uint32_t>(4000000000u + static_cast<std::uint32_t>(i));
                b.put<float>(0.25f + static_cast<float>(i));
                b.put<double>(0.1 + i);
            }
            // one quad face with ushort count and uint indices, plus an ignored float property
            b.put<std::uint16_t>(4);
            for (std::uint32_t v : {0u, 1u, 2u, 0u}) b.put<std::uint32_t>(v);
            b.put<float>(7.f);
            const std::string header = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                                       " 1.0\ncomment generated\nobj_info test\n"
                                       "element vertex 3\nproperty char x\nproperty uchar y\nproperty short z\n"
                                       "property ushort a\nproperty int nx\nproperty uint ny\nproperty float nz\n"
                                       "property double radius\n"
                                       "element face 1\nproperty list ushort uint vertex_index\nproperty float quality\n"
                                       "end_header\n";
            const fs::path f = dir / (big ? "types_be.ply" : "types_le.ply");
            write_file(f, header + b.body);
            ks::ReadInfo info;
            const ks::PointCloud c = ks::read_point_cloud(f, &info);
            CHECK(info.format == (big ? "ply-binary-be" : "ply-binary-le"));
            REQUIRE(c.points.size() == 3);
            REQUIRE(c.normals.size() == 3);
            REQUIRE(c.radii.size() == 3);
            CHECK(info.has_radii);
            CHECK(c.points[2] == ks::Vec3(-3, 202, -29998));
            CHECK(c.normals[1] == ks::Vec3(-1999999999, 4000000001.0, 1.25));
            CHECK(c.radii[2] == 0.1 + 2);
            CHECK(has_entry(info, "vertex.a"));
            CHECK(has_entry(info, "face.quality"));
            const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
            REQUIRE(m.faces.size() == 2);
            CHECK(info.polygons_triangulated == 1);
            CHECK(m.faces[0] == ks::Face{0, 1, 2});
            CHECK(m.faces[1] == ks::Face{0, 2, 0});
        }
    }
    SUBCASE("ascii: faces before vertices, extra elements, incomplete normals ignored, CRLF") {
        const fs::path f = dir / "order.ply";
        write_file(f,
                   "ply\r\nformat ascii 1.0\r\nelement face 2\r\nproperty list uchar int vertex_indices\r\n"
                   "element vertex 4\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\n"
                   "property float nx\r\nproperty list uchar float junk\r\n"
                   "element material 1\r\nproperty uchar red\r\nend_header\r\n"
                   "3 0 1 2\r\n3 +2 1 3.0\r\n"
                   "0 0 0 1 0\r\n1 0 0 1 2 5 6\r\n0 1 0 1 1 9\r\n1e0 1 0 1 0\r\n7\r\n");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        REQUIRE(m.vertices.size() == 4);
        REQUIRE(m.faces.size() == 2);
        CHECK(m.faces[1] == ks::Face{2, 1, 3});
        CHECK(m.vertices[3] == ks::Vec3(1, 1, 0));
        CHECK_FALSE(info.has_normals);
        CHECK(has_entry(info, "vertex.nx"));
        CHECK(has_entry(info, "vertex.junk"));
        CHECK(has_entry(info, "material.red"));
    }
    SUBCASE("points-only binary PLY (no face element)") {
        BinaryPly b;
        for (int i = 0; i < 5; ++i)
            for (int c = 0; c < 3; ++c) b.put<float>(static_cast<float>(i * 3 + c));
        const fs::path f = dir / "points.ply";
        write_file(f, "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                      "property float z\nend_header\n" + b.body);
        const ks::IndexedMesh m = ks::read_mesh(f);
        CHECK(m.vertices.size() == 5);
        CHECK(m.faces.empty());
        CHECK(m.vertices[4] == ks::Vec3(12, 13, 14));
    }
}

TEST_CASE("OFF, OBJ, XYZ, PWN variants") {
    TempDir dir;
    SUBCASE("NOFF with comments and counts on the header line") {
        const fs::path f = dir / "n.off";
        write_file(f, "# leading comment\nNOFF 4 2 0\n0 0 0  0 0 1\n1 0 0 0 0 1 # trailing\n\n0 1 0 0 0 1\n"
                      "1 1 0 0 0 1\n3 0 1 2\n3 1 3 2\n");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        CHECK(m.vertices.size() == 4);
        CHECK(m.faces.size() == 2);
        CHECK(info.has_normals);
        CHECK(m.normals[1] == ks::Vec3(0, 0, 1));
    }
    SUBCASE("COFF with vertex and face colours, a quad") {
        const fs::path f = dir / "c.off";
        write_file(f, "COFF\n4 1 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n1 1 0 0 0 0 255\n0 1 0 1 1 1 255\n"
                      "4 0 1 2 3 200 10 10\n");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        CHECK(m.faces.size() == 2);
        CHECK(info.polygons_triangulated == 1);
        CHECK_FALSE(info.has_normals);
        CHECK(has_entry(info, "vertex colors"));
        CHECK(has_entry(info, "face colors"));
    }
    SUBCASE("OBJ: v/vt/vn forms, negative indices, polygons, statements ignored") {
        const fs::path f = dir / "m.obj";
        write_file(f, "mtllib x.mtl\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                      "vt 0 0\nvn 0 0 1\nvn 0 0 2\ng group\nusemtl m\ns off\n"
                      "f 1/1/1 2/1/1 3/1/1\nf -4//2 -2//2 -1//2\nf 1/1 2/1 3/1 4/1\nf 2 3 4\nl 1 2\n");
        ks::ReadInfo info;
        const ks::IndexedMesh m = ks::read_mesh(f, {}, &info);
        REQUIRE(m.vertices.size() == 4);
        REQUIRE(m.faces.size() == 5);
        CHECK(m.faces[1] == ks::Face{0, 2, 3});
        CHECK(info.polygons_triangulated == 1);
        CHECK(has_entry(info, "vt"));
        CHECK(has_entry(info, "usemtl"));
        CHECK(has_entry(info, "l"));
        // Vertices 0 and 2 use both normals -> unit mean; 1 uses vn 1 only; 3 uses vn 2 only.
        REQUIRE(info.has_normals);
        CHECK(m.normals[0] == ks::Vec3(0, 0, 1));
        CHECK(m.normals[1] == ks::Vec3(0, 0, 1));
        CHECK(m.normals[3] == ks::Vec3(0, 0, 2));
    }
    SUBCASE("OBJ points with vn in the same order") {
        const fs::path f = dir / "p.obj";
        write_file(f, "v 1 2 3\nv 4 5 6\nvn 0 0 1\nvn 0 1 0\n");
        const ks::PointCloud c = ks::read_point_cloud(f);
        REQUIRE(c.normals.size() == 2);
        CHECK(c.normals[1] == ks::Vec3(0, 1, 0));
    }
    SUBCASE("XYZ: 3 columns, a count line, comments, tabs; PWN") {
        const fs::path f = dir / "p.xyz";
        write_file(f, "3\n# comment\n0 0 0\n1\t2\t3\n\n  4 5 6  \n");
        ks::ReadInfo info;
        const ks::PointCloud c = ks::read_point_cloud(f, &info);
        CHECK(c.points.size() == 3);
        CHECK(c.normals.empty());
        CHECK(c.points[2] == ks::Vec3(4, 5, 6));
        const fs::path g = dir / "p.PWN";
        write_file(g, "0 0 0 0 0 1\n1 2 3 0 1 0\n");
        const ks::PointCloud d = ks::read_point_cloud(g, &info);
        CHECK(info.format == "pwn");
        CHECK(d.normals.size() == 2);
    }
}

TEST_CASE("reading into other containers") {
    SUBCASE("CGAL::Surface_mesh, and untouched when it rejects a non-manifold file") {
        CGAL::Surface_mesh<K::Point_3> sm;
        ks::read_mesh(data("eight.off"), sm);
        CHECK(sm.number_of_vertices() == 315);
        CHECK(sm.number_of_faces() == 634);
        // bun_zipper_res4 has non-manifold edges: Surface_mesh refuses some faces.
        check_io_error([&] { ks::read_mesh(data("bun_zipper_res4.ply"), sm); }, data("bun_zipper_res4.ply"),
                       "rejects");
        CHECK(sm.number_of_vertices() == 315);
        CHECK(sm.number_of_faces() == 634);
    }
    SUBCASE("CGAL::Point_set_3 gets a normal map only when the file has normals") {
        CGAL::Point_set_3<K::Point_3, K::Vector_3> ps;
        ks::read_point_cloud(data("kitten.xyz"), ps);
        CHECK(ps.size() == 5210);
        CHECK(ps.has_normal_map());
        ks::read_point_cloud(data("bunny.off"), ps);
        CHECK(ps.size() == 1839);
        CHECK_FALSE(ps.has_normal_map());
    }
    SUBCASE("std::vector<Eigen::Vector3f>, untouched on error") {
        std::vector<Eigen::Vector3f> pts{Eigen::Vector3f(1, 2, 3)};
        CHECK_THROWS_AS(ks::read_point_cloud(data("missing.ply"), pts), ks::io_error);
        CHECK(pts.size() == 1);
        ks::read_point_cloud(data("bun000_part.ply"), pts);
        CHECK(pts.size() == 8000);
    }
}

TEST_CASE("bad files give io_error naming the file and the problem") {
    TempDir dir;
    auto expect = [&](const std::string& name, const std::string& content, const std::string& what,
                      ks::ReadOptions options = {}) {
        const fs::path f = dir / name;
        write_file(f, content);
        CAPTURE(name);
        check_io_error([&] { (void)ks::read_mesh(f, options); }, f, what);
    };
    const std::string vbody = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    const std::string vhead = "ply\nformat ascii 1.0\n" + vbody;
    const std::string fhead = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const std::string tri = "0 0 0\n1 0 0\n0 1 0\n";

    SUBCASE("missing, empty, directory, unknown extension") {
        check_io_error([&] { (void)ks::read_mesh(dir / "missing.ply"); }, dir / "missing.ply", "does not exist");
        expect("empty.off", "", "empty");
        fs::create_directory(dir / "d.ply");
        check_io_error([&] { (void)ks::read_point_cloud(dir / "d.ply"); }, dir / "d.ply", "directory");
        expect("m.stl", "solid x\n", "unsupported file extension");
    }
    SUBCASE("malformed PLY headers") {
        expect("a.ply", "plyx\nformat ascii 1.0\n", "not a PLY file");
        expect("b.ply", vhead + fhead.substr(0, fhead.size() - 11), "no 'end_header'");
        expect("c.ply", "ply\nformat ascii 2.0x\nformat utf8 1.0\nend_header\n", "unknown format");
        expect("d.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "unknown type");
        expect("e.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\nproperty float z\nend_header\n1 2\n",
               "needs scalar properties x, y and z");
        expect("f.ply", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", "not a non-negative integer");
        expect("g.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n", "before any 'element'");
        expect("h.ply", vhead + "element face 1\nproperty list float int vertex_indices\nend_header\n" + tri + "3 0 1 2\n",
               "count type of a list must be an integer");
        expect("i.ply", vhead + "element face 1\nproperty list uchar int corners\nend_header\n" + tri + "3 0 1 2\n",
               "no list property 'vertex_indices'");
        expect("j.ply", "ply\nelement vertex 0\nend_header\n", "no 'format' line");
        expect("k.ply", "ply\nformat ascii 1.0\nfoo bar\nend_header\n", "unknown keyword 'foo'");
        expect("l.ply", "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
               "no 'vertex' element");
    }
    SUBCASE("truncated PLY bodies, huge counts") {
        expect("a.ply", vhead + fhead + tri, "truncated PLY body");
        expect("b.ply", vhead + fhead + tri + "3 0 1", "truncated PLY body");
        expect("c.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
                        "property float y\nproperty float z\nend_header\n" + std::string(24, '\0'),
               "truncated PLY body");
        expect("d.ply", "ply\nformat ascii 1.0\nelement vertex 999999999999999\nproperty float x\nproperty float y\n"
                        "property float z\nend_header\n1 2 3\n",
               "truncated PLY body");
        BinaryPly b;
        for (int i = 0; i < 9; ++i) b.put<float>(1.f);
        b.put<std::uint8_t>(3);
        b.put<std::int32_t>(0);
        expect("e.ply", "ply\nformat binary_little_endian 1.0\n" + vbody + fhead + b.body,
               "truncated PLY body: the file ends inside face 0 of 1 declared in the header");
        // A quad then a cut triangle: passes the size bound, fails inside face 1.
        BinaryPly q;
        for (int i = 0; i < 9; ++i) q.put<float>(1.f);
        q.put<std::uint8_t>(4);
        for (int v : {0, 1, 2, 0}) q.put<std::int32_t>(v);
        q.put<std::uint8_t>(3);
        q.put<std::int32_t>(0);
        q.put<std::int32_t>(1);
        expect("e2.ply", "ply\nformat binary_little_endian 1.0\n" + vbody +
                             "element face 2\nproperty list uchar int vertex_indices\nend_header\n" + q.body,
               "the file ends inside face 1 of 2");
        expect("f.ply", "ply\nformat binary_little_endian 1.0\n" + vbody + fhead + b.body.substr(0, 20),
               "truncated PLY body");
    }
    SUBCASE("non-finite coordinates") {
        expect("a.ply", vhead + fhead + "0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", "vertex 1 (counting from 0) on line 11 has a non-finite");
        expect("b.ply", vhead + fhead + "0 0 0\n1 0 0\n0 1 inf\n3 0 1 2\n", "non-finite coordinate");
        expect("c.ply", vhead + fhead + "0 0 0\n1 0 0\n0 1 1e999\n3 0 1 2\n", "non-finite coordinate");
        BinaryPly b;
        for (float v : {0.f, 0.f, 0.f, 1.f, std::numeric_limits<float>::quiet_NaN(), 0.f, 0.f, 1.f, 0.f}) b.put<float>(v);
        expect("d.ply", "ply\nformat binary_little_endian 1.0\n" + vbody + "end_header\n" + b.body,
               "vertex 1 (counting from 0) has a non-finite coordinate");
        expect("e.off", "OFF\n3 1 0\n0 0 0\n1 NaN 0\n0 1 0\n3 0 1 2\n", "non-finite coordinate");
        expect("f.obj", "v 0 0 0\nv 1 0 -inf\nv 0 1 0\nf 1 2 3\n", "non-finite coordinate");
        expect("g.xyz", "0 0 0\n1 0 nan\n", "line 2: point 1 has a non-finite coordinate");
        expect("h.xyz", "0 0 0 0 0 1\n1 0 0 0 inf 0\n", "non-finite normal");
        expect("i.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                        "property float nx\nproperty float ny\nproperty float nz\nend_header\n0 0 0 nan 0 0\n",
               "non-finite normal");
    }
    SUBCASE("face indices out of range, negative, too few vertices") {
        expect("a.ply", vhead + "element face 2\nproperty list uchar int vertex_indices\nend_header\n" + tri +
                            "3 0 1 2\n3 0 1 3\n",
               "face 1 (counting from 0) on line 14 uses vertex index 3, out of range: the file has 3 vertices");
        expect("b.ply", vhead + fhead + tri + "3 0 -1 2\n", "negative vertex index");
        expect("c.ply", vhead + fhead + tri + "2 0 1\n", "face 0 (counting from 0) on line 13 has 2 vertices");
        expect("d.ply", "ply\nformat ascii 1.0\n" + fhead.substr(0, fhead.size() - 11) + vbody +
                            "end_header\n3 0 1 7\n" + tri,
               "face 0 (counting from 0) uses vertex index 7, out of range");
        expect("e.off", "OFF\n3 1 0\n" + tri + "3 0 1 3\n", "face 0 (counting from 0) on line 6 uses vertex index 3");
        expect("f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n", "face 1 (counting from 0) on line 5 uses vertex 4");
        expect("g.obj", "v 0 0 0\nf 1 0 1\n", "index 0 (OBJ indices start at 1)");
        expect("h.obj", "v 0 0 0\nf 1 -2 1\n", "points before the first vertex");
        expect("i.obj", "v 0 0 0\nv 0 0 0\nv 0 0 0\nvn 0 0 1\nf 1//1 2//2 3//1\n", "normal index 2 is out of range");
    }
    SUBCASE("polygons when triangles are required") {
        const ks::ReadOptions strict{.triangulate = false};
        expect("a.ply", std::string("ply\nformat ascii 1.0\n") + "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n" +
                            fhead + tri + "1 1 0\n4 0 1 3 2\n",
               "face 0 (counting from 0) on line 14 has 4 vertices, but triangles are required", strict);
        expect("b.off", "OFF\n4 1 0\n" + tri + "1 1 0\n4 0 1 3 2\n", "has 4 vertices, but triangles are required", strict);
        expect("c.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n", "triangulate is false", strict);
    }
    SUBCASE("malformed OFF, OBJ, XYZ, PWN") {
        expect("a.off", "# only a comment\n", "holds only comments");
        expect("b.off", "PLY\n", "not an OFF file");
        expect("c.off", "4OFF\n1 0 0\n0 0 0 1\n", "only 3D OFF");
        expect("d.off", "OFF BINARY\n", "binary OFF is not supported");
        expect("e.off", "OFF\n3 x 0\n", "expected the counts");
        expect("f.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n", "truncated OFF");
        expect("g.off", "OFF\n300000000 1 0\n0 0 0\n", "truncated OFF: the header declares 300000000 vertices");
        expect("h.off", "OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n# padding\n", "vertex 1 (counting from 0) has 2 numbers");
        expect("i.off", "OFF\n3 1 0\n" + tri + "3 0 1\n# padding\n", "declares 3 vertices but lists 2");
        expect("j.off", "OFF\n3 2 0\n" + tri + "3 0 1 2\n# padding padding\n", "the file ends after 1 of 2 faces");
        expect("k.obj", "# nothing\ng x\n", "no 'v' or 'f'");
        expect("l.obj", "v 0 0\n", "needs 3 numbers");
        expect("m.obj", "v 0 0 zero\n", "'zero' is not a number");
        expect("n.xyz", "0 0 0\n1 1\n", "line 2): found 2 numbers, but the first point has 3");
        expect("o.xyz", "0 0 0 1\n", "expected 3 numbers (x y z) or 6");
        expect("p.xyz", "0 0 0\n1 1 one\n", "'one' is not a number");
        expect("q.pwn", "0 0 0\n", "expected 6 numbers");
        expect("r.xyz", "# none\n\n", "no points");
    }
}

// Truncate real files at random offsets and flip random header bytes: the readers must
// either succeed or throw io_error (never crash, never throw anything else, never
// allocate from a corrupt count: ASan/UBSan runs of this test check the rest).
TEST_CASE("fuzz: truncated and corrupted real files never crash") {
    TempDir dir;
    std::mt19937_64 rng(12345);
    const std::vector<std::string> files = {"bun000_part.ply", "bun_zipper_res4.ply", "eight.off", "twelve.obj",
                                            "kitten.xyz"};
    std::size_t errors = 0, successes = 0;
    for (const std::string& name : files) {
        const std::string content = read_file(data(name));
        REQUIRE(!content.empty());
        const fs::path f = dir / name;
        const bool binary = name == "bun000_part.ply";
        const std::size_t header_end = content.find("end_header") != std::string::npos
                                           ? content.find("end_header") + 11
                                           : std::min<std::size_t>(content.size(), 200);
        for (int trial = 0; trial < 60; ++trial) {
            std::string bad;
            const bool truncate = trial % 2 == 0;
            if (truncate) {
                bad = content.substr(0, std::uniform_int_distribution<std::size_t>(0, content.size() - 1)(rng));
            } else {
                bad = content;
                for (int k = 0; k < 3; ++k) {
                    const std::size_t pos = std::uniform_int_distribution<std::size_t>(0, header_end - 1)(rng);
                    bad[pos] = static_cast<char>(std::uniform_int_distribution<int>(0, 255)(rng));
                }
            }
            write_file(f, bad);
            try {
                const ks::IndexedMesh m = ks::read_mesh(f);
                ++successes;
                for (const ks::Face& t : m.faces)
                    for (const ks::Index v : t) REQUIRE(v < m.vertices.size());
                for (const ks::Vec3& p : m.vertices) REQUIRE(p.allFinite());
                // A truncated binary PLY is always detected.
                if (binary && truncate) FAIL("truncated binary PLY was accepted");
            } catch (const ks::io_error& e) {
                ++errors;
                CHECK(std::string(e.what()).find(f.string()) == 0);
            }
        }
    }
    CHECK(errors > 100);  // most corruptions are detected
    MESSAGE("fuzz: ", errors, " io_errors, ", successes, " files still valid after corruption");
}
