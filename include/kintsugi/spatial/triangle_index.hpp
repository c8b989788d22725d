// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file triangle_index.hpp
/// @brief Closest-point and ray queries on a triangle mesh, over CGAL's AABB tree
/// (CGAL types stay inside).
///
/// @code
/// const kintsugi::TriangleIndex index(mesh);                // any TriangleMesh
/// kintsugi::ClosestPoint c = index.closest(q);             // c.point, c.face, c.distance
/// auto all = index.closest_points(queries);                  // many, in parallel
/// if (auto hit = index.first_hit(origin, direction)) { hit->t; hit->face; hit->point; }
/// std::vector<kintsugi::RayHit> hits = index.all_hits(origin, direction);  // by t
/// @endcode
///
/// Faces of zero area are left out (their edges belong to their neighbours), so they
/// are never returned. Queries are const and thread-safe; the index is movable, not
/// copyable. Distances are exact up to double round-off (CGAL's closest point on a
/// triangle in double precision); a ray through an edge or a vertex shared by several
/// faces reports one of them, or each of them in all_hits.
/// CGAL's AABB_tree is GPL-free (LGPL-3.0+).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/spatial/morton.hpp>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// The point of the surface closest to a query.
struct ClosestPoint {
    Scalar distance = 0;          ///< |point - query|
    Index face = 0;               ///< the face the point lies on (input numbering)
    Vec3 point = Vec3::Zero();    ///< the closest point
};

/// Where a ray meets the surface: point = origin + t * direction.
struct RayHit {
    Scalar t = 0;                 ///< ray parameter (>= 0), in units of |direction|
    Index face = 0;               ///< the face hit (input numbering)
    Vec3 point = Vec3::Zero();
};

namespace detail {
/// Checks a mesh for the triangle queries; throws invalid_input starting with `where`
/// (the function and the argument).
inline void validate_triangle_mesh(const IndexedMesh& m, const std::string& where) {
    if (m.vertices.empty() || m.faces.empty())
        throw invalid_input(where + " is empty (" + std::to_string(m.vertices.size()) + " vertices, " +
                            std::to_string(m.faces.size()) + " faces); pass a mesh with faces");
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
        if (!m.vertices[v].allFinite())
            throw invalid_input(where + " has a NaN or infinite coordinate at vertex " + std::to_string(v) +
                                "; remove or fix it");
    double area = 0;
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Face& t = m.faces[f];
        for (int k = 0; k < 3; ++k)
            if (t[k] >= m.vertices.size())
                throw invalid_input(where + ": face " + std::to_string(f) + " uses vertex " + std::to_string(t[k]) +
                                    " but there are " + std::to_string(m.vertices.size()) +
                                    " vertices; fix or remove the face");
        area += (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]).norm();
    }
    if (!(area > 0))
        throw invalid_input(where + " has zero surface area (every face is degenerate); pass a real surface");
}
}  // namespace detail

/// Closest-point and ray queries on a triangle mesh (see the file comment).
class TriangleIndex {
public:
    /// Indexes any TriangleMesh (positions copied).
    /// @throws invalid_input if the mesh has no vertices or no faces, a NaN or
    ///   infinite coordinate, a face index out of range, or zero total area.
    template <TriangleMesh M>
    explicit TriangleIndex(const M& mesh) : TriangleIndex(to_indexed_mesh(mesh)) {}
    /// Indexes the built-in mesh (no copy of it kept). @throws as above.
    explicit TriangleIndex(const IndexedMesh& m) : impl_(std::make_unique<Impl>()) {
        detail::validate_triangle_mesh(m, "kintsugi::TriangleIndex: the mesh");
        impl_->triangles.reserve(m.faces.size());
        impl_->face_of.reserve(m.faces.size());
        auto P = [&](Index v) {
            const Vec3& p = m.vertices[v];
            return K::Point_3(p.x(), p.y(), p.z());
        };
        for (Index f = 0; f < m.faces.size(); ++f) {
            const Face& t = m.faces[f];
            const Vec3& a = m.vertices[t[0]];
            if ((m.vertices[t[1]] - a).cross(m.vertices[t[2]] - a).squaredNorm() <= 0) continue;
            impl_->triangles.emplace_back(P(t[0]), P(t[1]), P(t[2]));
            impl_->face_of.push_back(f);
        }
        impl_->tree.insert(impl_->triangles.cbegin(), impl_->triangles.cend());
        impl_->tree.build();
        impl_->tree.accelerate_distance_queries();  // built now, so that queries may run in parallel
    }
    TriangleIndex(TriangleIndex&&) noexcept = default;
    TriangleIndex& operator=(TriangleIndex&&) noexcept = default;

    /// Number of faces indexed (the faces of positive area).
    [[nodiscard]] std::size_t size() const { return impl_ ? impl_->face_of.size() : 0; }

    /// The closest point of the surface to q.
    /// @throws invalid_input if q has a NaN or infinite coordinate, or the index was moved from.
    [[nodiscard]] ClosestPoint closest(const Vec3& q) const {
        require_index("closest");
        require_finite(q, "closest", "the query point");
        ClosestPoint out;
        closest_run(&q, 1, &out);
        return out;
    }

    /// The closest points of many queries, in their order, computed in parallel: the
    /// queries are visited along a Morton curve and each starts from the previous
    /// answer (CGAL's hint, as CGAL's own Hausdorff code does), in fixed runs of 256,
    /// so the answers do not depend on the thread count. Distances equal closest()'s;
    /// among equidistant faces the one reported may differ.
    /// @param between_blocks called as between_blocks(fraction done) before each block
    ///        of 16,384 queries, on the calling thread (report progress, or throw to stop)
    /// @throws invalid_input if a query has a NaN or infinite coordinate.
    template <class BetweenBlocks>
    [[nodiscard]] std::vector<ClosestPoint> closest_points(const std::vector<Vec3>& q,
                                                           BetweenBlocks&& between_blocks) const {
        require_index("closest_points");
        for (std::size_t i = 0; i < q.size(); ++i) require_finite(q[i], "closest_points", "query " + std::to_string(i));
        constexpr std::size_t run = 256, block = 64 * run;
        const std::vector<Index> order = morton_order(q);
        std::vector<Vec3> sorted(q.size());
        for (std::size_t i = 0; i < q.size(); ++i) sorted[i] = q[order[i]];
        std::vector<ClosestPoint> hits(q.size());
        for (std::size_t b = 0; b < q.size(); b += block) {
            between_blocks(static_cast<double>(b) / static_cast<double>(q.size()));
            const std::size_t e = std::min(q.size(), b + block);
            parallel_for(
                0, (e - b + run - 1) / run,
                [&](std::size_t c) {
                    const std::size_t first = b + c * run, last = std::min(e, first + run);
                    closest_run(sorted.data() + first, last - first, hits.data() + first);
                },
                1);
        }
        std::vector<ClosestPoint> out(q.size());
        for (std::size_t i = 0; i < q.size(); ++i) out[order[i]] = hits[i];
        return out;
    }
    /// As above, without progress reports.
    [[nodiscard]] std::vector<ClosestPoint> closest_points(const std::vector<Vec3>& q) const {
        return closest_points(q, [](double) {});
    }

    /// The first point where the ray origin + t·direction (t >= 0) meets the surface,
    /// or nothing.
    /// @throws invalid_input if origin or direction has a NaN or infinite coordinate,
    ///   or direction is zero.
    [[nodiscard]] std::optional<RayHit> first_hit(const Vec3& origin, const Vec3& direction) const {
        const K::Ray_3 ray = make_ray(origin, direction, "first_hit");
        const auto found = impl_->tree.first_intersection(ray);
        if (!found) return std::nullopt;
        return to_hit(found->first, found->second, origin, direction);
    }

    /// Every point where the ray meets the surface, by increasing t (ties by face).
    /// A face the ray lies in (coplanar) counts once, at its nearest point.
    /// @throws invalid_input as first_hit.
    [[nodiscard]] std::vector<RayHit> all_hits(const Vec3& origin, const Vec3& direction) const {
        const K::Ray_3 ray = make_ray(origin, direction, "all_hits");
        std::vector<typename Tree::template Intersection_and_primitive_id<K::Ray_3>::Type> found;
        impl_->tree.all_intersections(ray, std::back_inserter(found));
        std::vector<RayHit> out;
        out.reserve(found.size());
        for (const auto& f : found) out.push_back(to_hit(f.first, f.second, origin, direction));
        std::sort(out.begin(), out.end(), [](const RayHit& a, const RayHit& b) {
            return a.t < b.t || (a.t == b.t && a.face < b.face);
        });
        return out;
    }

private:
    using K = CGAL::Simple_cartesian<double>;
    using Iterator = std::vector<K::Triangle_3>::const_iterator;
    using Primitive = CGAL::AABB_triangle_primitive<K, Iterator>;
    using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
    struct Impl {  // on the heap: the tree points into `triangles`
        std::vector<K::Triangle_3> triangles;
        std::vector<Index> face_of;
        Tree tree;
    };

    void require_index(const char* fn) const {
        if (!impl_) throw invalid_input(std::string("kintsugi::TriangleIndex::") + fn + ": the index was moved from");
    }
    static void require_finite(const Vec3& p, const char* fn, const std::string& what) {
        if (!p.allFinite())
            throw invalid_input(std::string("kintsugi::TriangleIndex::") + fn + ": " + what +
                                " has a NaN or infinite coordinate");
    }
    K::Ray_3 make_ray(const Vec3& origin, const Vec3& direction, const char* fn) const {
        require_index(fn);
        require_finite(origin, fn, "the ray origin");
        require_finite(direction, fn, "the ray direction");
        if (direction.squaredNorm() == 0)
            throw invalid_input(std::string("kintsugi::TriangleIndex::") + fn + ": the ray direction is zero");
        return {K::Point_3(origin.x(), origin.y(), origin.z()),
                K::Vector_3(direction.x(), direction.y(), direction.z())};
    }
    /// Closest points of a run of queries, each starting from the previous answer.
    void closest_run(const Vec3* q, std::size_t n, ClosestPoint* out) const {
        typename Tree::Point_and_primitive_id hint;
        for (std::size_t i = 0; i < n; ++i) {
            const K::Point_3 p(q[i].x(), q[i].y(), q[i].z());
            hint = i == 0 ? impl_->tree.closest_point_and_primitive(p) : impl_->tree.closest_point_and_primitive(p, hint);
            const K::Point_3& c = hint.first;
            out[i].point = Vec3(c.x(), c.y(), c.z());
            out[i].distance = (out[i].point - q[i]).norm();
            out[i].face = impl_->face_of[static_cast<std::size_t>(hint.second - impl_->triangles.cbegin())];
        }
    }
    /// A CGAL ray intersection (a point, or a segment for a ray in a face's plane) as
    /// a RayHit at its nearest point.
    template <class Variant>
    RayHit to_hit(const Variant& v, Iterator id, const Vec3& origin, const Vec3& direction) const {
        Vec3 p = origin;
        if (const K::Point_3* pt = boost::get<K::Point_3>(&v)) {
            p = Vec3(pt->x(), pt->y(), pt->z());
        } else if (const K::Segment_3* s = boost::get<K::Segment_3>(&v)) {
            const Vec3 a(s->source().x(), s->source().y(), s->source().z()),
                b(s->target().x(), s->target().y(), s->target().z());
            p = (a - origin).dot(direction) <= (b - origin).dot(direction) ? a : b;
        }
        return {std::max(Scalar(0), (p - origin).dot(direction) / direction.squaredNorm()),
                impl_->face_of[static_cast<std::size_t>(id - impl_->triangles.cbegin())], p};
    }

    std::unique_ptr<Impl> impl_;
};

}  // namespace kintsugi
