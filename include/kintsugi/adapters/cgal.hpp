// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file cgal.hpp
/// @brief CGAL::Surface_mesh as a TopologyMutableMesh and CGAL::Point_set_3 as an
/// oriented, growable point set. The only kintsugi header whose public types
/// mention CGAL.
///
/// Precondition for Surface_mesh: no removed elements (call `collect_garbage()`
/// after removals), so that vertex and face indices are dense; num_vertices /
/// num_faces throw invalid_input otherwise. kintsugi calls its own accessors
/// qualified (`kintsugi::num_vertices`), never CGAL's BGL overloads found by
/// argument-dependent lookup, which count removed elements. Faces must be
/// triangles; the accessors throw kintsugi::invalid_input otherwise.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>

#include <CGAL/Point_set_3.h>
#include <CGAL/Surface_mesh.h>

#include <string>

namespace kintsugi {

template <class P>
struct mesh_traits<CGAL::Surface_mesh<P>> {
    using SM = CGAL::Surface_mesh<P>;
    using size_type = typename SM::size_type;
    using VI = typename SM::Vertex_index;
    using FI = typename SM::Face_index;

    static void require_dense(const SM& m) {
        if (m.has_garbage())
            throw invalid_input("kintsugi: CGAL::Surface_mesh has removed elements (" +
                                std::to_string(m.number_of_removed_vertices()) + " vertices, " +
                                std::to_string(m.number_of_removed_faces()) +
                                " faces) that would leave holes in its indices; call collect_garbage() before "
                                "passing it");
    }
    static std::size_t num_vertices(const SM& m) {
        require_dense(m);
        return m.number_of_vertices();
    }
    static std::size_t num_faces(const SM& m) {
        require_dense(m);
        return m.number_of_faces();
    }
    static Vec3 position(const SM& m, Index v) { return detail::to_vec3(m.point(VI(static_cast<size_type>(v)))); }
    static Face face(const SM& m, Index f) {
        const auto h = m.halfedge(FI(static_cast<size_type>(f)));
        const auto h1 = m.next(h), h2 = m.next(m.next(h));
        if (m.next(h2) != h)
            throw invalid_input("kintsugi: CGAL::Surface_mesh face " + std::to_string(f) +
                                " is not a triangle; triangulate it first "
                                "(CGAL::Polygon_mesh_processing::triangulate_faces)");
        return {static_cast<Index>(m.source(h)), static_cast<Index>(m.target(h)), static_cast<Index>(m.target(h1))};
    }
    static void set_position(SM& m, Index v, const Vec3& p) { m.point(VI(static_cast<size_type>(v))) = P(p.x(), p.y(), p.z()); }
    static void clear(SM& m) { m.clear(); }
    static void reserve(SM& m, std::size_t nv, std::size_t nf) {
        m.reserve(static_cast<size_type>(nv), static_cast<size_type>(nv + nf), static_cast<size_type>(nf));
    }
    static Index add_vertex(SM& m, const Vec3& p) { return static_cast<Index>(m.add_vertex(P(p.x(), p.y(), p.z()))); }
    static void add_face(SM& m, const Face& f) {
        const auto r = m.add_face(VI(static_cast<size_type>(f[0])), VI(static_cast<size_type>(f[1])),
                                  VI(static_cast<size_type>(f[2])));
        if (r == SM::null_face())
            throw invalid_input("kintsugi: CGAL::Surface_mesh rejected face (" + std::to_string(f[0]) + ", " +
                                std::to_string(f[1]) + ", " + std::to_string(f[2]) +
                                "): it would make the mesh non-manifold or inconsistently oriented");
    }
};

template <class P, class V>
struct point_set_traits<CGAL::Point_set_3<P, V>> {
    using PS = CGAL::Point_set_3<P, V>;
    static auto idx(const PS& ps, std::size_t i) { return ps.begin()[static_cast<std::ptrdiff_t>(i)]; }
    static std::size_t size(const PS& ps) { return ps.size(); }
    static Vec3 point(const PS& ps, std::size_t i) { return detail::to_vec3(ps.point(idx(ps, i))); }
    static Vec3 normal(const PS& ps, std::size_t i) { return detail::to_vec3(ps.normal(idx(ps, i))); }
    static bool has_normals(const PS& ps) { return ps.has_normal_map() && !ps.empty(); }
    static void prepare_normals(PS& ps) { ps.add_normal_map(); }
    static void set_normal(PS& ps, std::size_t i, const Vec3& n) { ps.normal(idx(ps, i)) = V(n.x(), n.y(), n.z()); }
    static void clear(PS& ps) { ps.clear(); }
    static void push_back(PS& ps, const Vec3& p, const Vec3& n) {
        if (!ps.has_normal_map()) ps.add_normal_map();
        ps.insert(P(p.x(), p.y(), p.z()), V(n.x(), n.y(), n.z()));
    }
};

}  // namespace kintsugi
