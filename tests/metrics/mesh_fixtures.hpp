// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
// Small meshes with known topology and holders that present one mesh through each
// shipped adapter (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh), for the mesh and
// metrics tests.
#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/io/read.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <Eigen/Core>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace fixtures {

namespace ks = kintsugi;
using ks::Face;
using ks::IndexedMesh;
using ks::Vec3;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

// ------------------------------------------------------------------ shapes

/// Regular-ish tetrahedron, outward oriented: V 4, E 6, F 4, genus 0.
inline IndexedMesh tetrahedron() {
    IndexedMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
}

/// Unit cube [0,1]^3 triangulated, outward: V 8, E 18, F 12.
inline IndexedMesh cube(const Vec3& offset = Vec3::Zero()) {
    IndexedMesh m;
    for (int i = 0; i < 8; ++i) m.vertices.push_back(Vec3(i & 1, (i >> 1) & 1, (i >> 2) & 1) + offset);
    // quads given counter-clockwise seen from outside
    const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
        m.faces.push_back({Face::value_type(q[0]), Face::value_type(q[1]), Face::value_type(q[2])});
        m.faces.push_back({Face::value_type(q[0]), Face::value_type(q[2]), Face::value_type(q[3])});
    }
    return m;
}

/// Torus as an n x m grid with wrap-around: V nm, E 3nm, F 2nm, genus 1, outward.
inline IndexedMesh torus(int n = 12, int m = 8, double R = 2.0, double r = 0.5) {
    IndexedMesh t;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) {
            const double u = 2 * std::numbers::pi * i / n, v = 2 * std::numbers::pi * j / m;
            t.vertices.push_back(Vec3((R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                                      r * std::sin(v)));
        }
    auto id = [&](int i, int j) { return ks::Index(((i + n) % n) * m + (j + m) % m); };
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) {
            t.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            t.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return t;
}

/// Flat (nx x ny)-cell grid in the z = 0 plane, faces counter-clockwise seen from +z.
/// Cells listed in `skip` (as i + nx*j) are left out (holes).
inline IndexedMesh grid(int nx, int ny, const std::set<int>& skip = {}) {
    IndexedMesh g;
    for (int j = 0; j <= ny; ++j)
        for (int i = 0; i <= nx; ++i) g.vertices.push_back(Vec3(i, j, 0));
    auto id = [&](int i, int j) { return ks::Index(j * (nx + 1) + i); };
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            if (skip.count(i + nx * j)) continue;
            g.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            g.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return g;
}

/// A disk of n long thin faces around one vertex (a fan): the centre (vertex 0) and n
/// rim vertices on the circle of radius r in the plane z = 0, faces (0, i, i + 1).
inline IndexedMesh fan(int n, double r = 1.0) {
    IndexedMesh m;
    m.vertices.push_back(Vec3::Zero());
    for (int i = 0; i < n; ++i) {
        const double a = 2 * std::numbers::pi * i / n;
        m.vertices.push_back(Vec3(r * std::cos(a), r * std::sin(a), 0));
    }
    for (int i = 0; i < n; ++i) m.faces.push_back({0, ks::Index(1 + i), ks::Index(1 + (i + 1) % n)});
    return m;
}

/// UV sphere of radius r around c with `stacks` x `slices` cells, outward. Every
/// vertex lies exactly on the sphere.
inline IndexedMesh uv_sphere(int stacks, int slices, double r = 1.0, const Vec3& c = Vec3::Zero()) {
    IndexedMesh s;
    s.vertices.push_back(c + Vec3(0, 0, r));
    for (int i = 1; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const double th = std::numbers::pi * i / stacks, ph = 2 * std::numbers::pi * j / slices;
            s.vertices.push_back(c + r * Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
        }
    s.vertices.push_back(c + Vec3(0, 0, -r));
    const ks::Index south = s.vertices.size() - 1;
    auto id = [&](int i, int j) { return ks::Index(1 + (i - 1) * slices + (j % slices)); };
    for (int j = 0; j < slices; ++j) s.faces.push_back({0, id(1, j), id(1, j + 1)});
    for (int i = 1; i + 1 < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            s.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            s.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    for (int j = 0; j < slices; ++j) s.faces.push_back({south, id(stacks - 1, j + 1), id(stacks - 1, j)});
    return s;
}

/// Appends b to a (vertex indices of b shifted).
inline IndexedMesh concat(IndexedMesh a, const IndexedMesh& b) {
    const ks::Index off = a.vertices.size();
    a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (Face f : b.faces) a.faces.push_back({f[0] + off, f[1] + off, f[2] + off});
    return a;
}

// ------------------------------------------------------------------ files

/// Reads a mesh with kintsugi's reader (polygons fan-triangulated).
inline IndexedMesh load(const std::filesystem::path& p) { return ks::read_mesh(p); }

inline std::filesystem::path shared_data(const std::string& rel) {
    return std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / rel;
}
inline std::filesystem::path test_data(const std::string& rel) {
    return std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / rel;
}

// ------------------------------------------------------------------ one mesh, three containers

/// Holds an IndexedMesh.
struct IndexedHolder {
    IndexedMesh m;
    explicit IndexedHolder(const IndexedMesh& src) : m(src) {}
    const IndexedMesh& mesh() const { return m; }
    static constexpr const char* name = "IndexedMesh";
};

/// Holds Eigen V (double) / F (int) matrices and a view of them.
struct EigenHolder {
    Eigen::MatrixXd V;
    Eigen::MatrixXi F;
    ks::EigenMeshView<const Eigen::MatrixXd, Eigen::MatrixXi> view;
    explicit EigenHolder(const IndexedMesh& src)
        : V(static_cast<Eigen::Index>(src.vertices.size()), 3), F(static_cast<Eigen::Index>(src.faces.size()), 3) {
        for (std::size_t i = 0; i < src.vertices.size(); ++i) V.row(Eigen::Index(i)) = src.vertices[i].transpose();
        for (std::size_t f = 0; f < src.faces.size(); ++f)
            for (int k = 0; k < 3; ++k) F(Eigen::Index(f), k) = static_cast<int>(src.faces[f][k]);
        view = ks::eigen_mesh(std::as_const(V), F);
    }
    EigenHolder(const EigenHolder&) = delete;
    const auto& mesh() const { return view; }
    static constexpr const char* name = "Eigen V/F";
};

/// `src` as a CGAL::Surface_mesh with one removed element left in place (no
/// collect_garbage()): its last face when `remove_face`, else an extra isolated vertex.
/// CGAL's own num_vertices/num_faces count removed elements; kintsugi must refuse it.
inline SurfaceMesh surface_mesh_with_garbage(const IndexedMesh& src, bool remove_face) {
    SurfaceMesh sm;
    ks::assign_mesh(sm, src);
    if (remove_face)
        sm.remove_face(SurfaceMesh::Face_index(static_cast<SurfaceMesh::size_type>(src.faces.size() - 1)));
    else
        sm.remove_vertex(sm.add_vertex(Kernel::Point_3(7, 7, 7)));
    return sm;
}

/// Holds a CGAL::Surface_mesh (the source must be representable: manifold).
struct SurfaceMeshHolder {
    SurfaceMesh sm;
    explicit SurfaceMeshHolder(const IndexedMesh& src) { ks::assign_mesh(sm, src); }
    const SurfaceMesh& mesh() const { return sm; }
    static constexpr const char* name = "CGAL::Surface_mesh";
};

}  // namespace fixtures
