// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file triangle_index.hpp
/// @brief Closest-point and ray queries on a triangle mesh: closest points through a
/// tree of oriented boxes, rays through CGAL's AABB tree (CGAL types stay inside).
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
///
/// Closest points use a bounding-volume tree of oriented boxes (principal axes of the
/// vertices, split at the median of the face centroids; Gottschalk et al., "OBBTree",
/// SIGGRAPH 1996), not axis-aligned ones: the axis-aligned box of a long thin face
/// across the axes is as large as the face is long, so on a fan of N slivers around
/// one vertex a query met about N/10 of them (`compare` on 20K faces: 27.7 s CPU);
/// an oriented box stays as thin as its faces (0.72 s; docs/methods/spatial.md).
/// The ray queries' CGAL AABB tree is built on the first ray query.
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

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
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
        std::vector<Corners> corners;
        std::vector<Index> faces;
        corners.reserve(m.faces.size());
        faces.reserve(m.faces.size());
        for (Index f = 0; f < m.faces.size(); ++f) {
            const Face& t = m.faces[f];
            const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
            if ((b - a).cross(c - a).squaredNorm() <= 0) continue;
            corners.push_back({a, b, c});
            faces.push_back(f);
        }
        std::vector<Index> order(corners.size());
        std::vector<Vec3> sum(corners.size());
        for (Index i = 0; i < order.size(); ++i) {
            order[i] = i;
            sum[i] = corners[i][0] + corners[i][1] + corners[i][2];
        }
        impl_->nodes.reserve(corners.size());
        build_node(corners, sum, order, 0, order.size());
        // Triangles in tree order: a leaf's triangles are contiguous.
        impl_->triangles.reserve(order.size());
        impl_->face_of.reserve(order.size());
        for (const Index i : order) {
            const Corners& t = corners[i];
            impl_->triangles.emplace_back(point3(t[0]), point3(t[1]), point3(t[2]));
            impl_->face_of.push_back(faces[i]);
        }
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
        const auto found = ray_tree().first_intersection(ray);
        if (!found) return std::nullopt;
        return to_hit(found->first, found->second, origin, direction);
    }

    /// Every point where the ray meets the surface, by increasing t (ties by face).
    /// A face the ray lies in (coplanar) counts once, at its nearest point.
    /// @throws invalid_input as first_hit.
    [[nodiscard]] std::vector<RayHit> all_hits(const Vec3& origin, const Vec3& direction) const {
        const K::Ray_3 ray = make_ray(origin, direction, "all_hits");
        std::vector<typename Tree::template Intersection_and_primitive_id<K::Ray_3>::Type> found;
        ray_tree().all_intersections(ray, std::back_inserter(found));
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
    using Corners = std::array<Vec3, 3>;
    static constexpr Index leaf_size = 4;

    /// A node of the closest-point tree: an oriented box holding its triangles.
    struct Node {
        Eigen::Matrix3d axes;  ///< rows: the box's orthonormal axes
        Vec3 centre;           ///< the box's centre
        Vec3 half;             ///< half extents along the axes, rounded up
        Index first = 0;       ///< leaf: first triangle; inner node: the second child (the first is next)
        Index count = 0;       ///< leaf: number of triangles; inner node: 0
    };
    struct Impl {  // on the heap: the ray tree points into `triangles`
        std::vector<K::Triangle_3> triangles;  ///< in tree order
        std::vector<Index> face_of;            ///< input face of each triangle
        std::vector<Node> nodes;               ///< depth first; the root is nodes[0]
        std::once_flag ray_once;
        std::unique_ptr<Tree> ray_tree;        ///< built on the first ray query
    };

    static K::Point_3 point3(const Vec3& p) { return {p.x(), p.y(), p.z()}; }

    /// Squared distance from q to the box of `n` (a lower bound of its triangles' distances).
    static double box_distance2(const Node& n, const Vec3& q) {
        const Vec3 t = n.axes * (q - n.centre);
        return (t.cwiseAbs() - n.half).cwiseMax(0.0).squaredNorm();
    }

    /// Builds the subtree of the triangles order[first, last) (`sum`: each triangle's
    /// corner sum, three times its centroid); returns its node.
    Index build_node(const std::vector<Corners>& tri, const std::vector<Vec3>& sum, std::vector<Index>& order,
                     Index first, Index last) {
        const Index id = impl_->nodes.size();
        impl_->nodes.emplace_back();
        // Covariance of the corners, about the first one (no cancellation far from the origin).
        const Vec3 ref = tri[order[first]][0];
        Vec3 s1 = Vec3::Zero();
        Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
        for (Index i = first; i < last; ++i)
            for (const Vec3& v : tri[order[i]]) {
                const Vec3 d = v - ref;
                s1 += d;
                s2.noalias() += d * d.transpose();
            }
        const double corners = 3.0 * static_cast<double>(last - first);
        const Vec3 mean = s1 / corners;
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
        eig.computeDirect(s2 / corners - mean * mean.transpose());
        // Axes: the principal directions, made exactly orthonormal (the box must hold its
        // triangles whatever the eigenvectors' accuracy).
        Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
        const Vec3 e2 = eig.eigenvectors().col(2), e1 = eig.eigenvectors().col(1);
        if (e2.allFinite() && e1.allFinite() && e2.norm() > 0.5) {
            const Vec3 a0 = e2.normalized();
            const Vec3 r1 = e1 - e1.dot(a0) * a0;
            if (r1.norm() > 0.5) {
                const Vec3 a1 = r1.normalized();
                axes.row(0) = a0.transpose();
                axes.row(1) = a1.transpose();
                axes.row(2) = a0.cross(a1).normalized().transpose();
            }
        }
        Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
        for (Index i = first; i < last; ++i)
            for (const Vec3& v : tri[order[i]]) {
                const Vec3 t = axes * v;
                lo = lo.cwiseMin(t);
                hi = hi.cwiseMax(t);
            }
        const Vec3 mid = (lo + hi) / 2;
        Vec3 half = (hi - lo) / 2;
        // Round-off of the projections: grow the box by far more than it.
        half.array() += 1e-10 * (mid.cwiseAbs().maxCoeff() + half.maxCoeff());
        {
            Node& n = impl_->nodes[id];
            n.axes = axes;
            n.centre = axes.transpose() * mid;
            n.half = half;
        }
        if (last - first <= leaf_size) {
            impl_->nodes[id].first = first;
            impl_->nodes[id].count = last - first;
            return id;
        }
        // Split at the median of the centroids along the axis where they spread most.
        Vec3 clo = Vec3::Constant(std::numeric_limits<double>::infinity()), chi = -clo;
        for (Index i = first; i < last; ++i) {
            const Vec3 t = axes * sum[order[i]];
            clo = clo.cwiseMin(t);
            chi = chi.cwiseMax(t);
        }
        Eigen::Index axis = 0;
        (chi - clo).maxCoeff(&axis);
        std::vector<std::pair<double, Index>> key(last - first);
        for (Index i = first; i < last; ++i) key[i - first] = {axes.row(axis).dot(sum[order[i]]), order[i]};
        const Index half_count = (last - first) / 2;
        std::nth_element(key.begin(), key.begin() + static_cast<std::ptrdiff_t>(half_count), key.end());
        for (Index i = first; i < last; ++i) order[i] = key[i - first].second;
        build_node(tri, sum, order, first, first + half_count);
        const Index second = build_node(tri, sum, order, first + half_count, last);
        impl_->nodes[id].first = second;
        return id;
    }

    static constexpr Index no_triangle = std::numeric_limits<Index>::max();

    /// The closest point to q among the triangles, improving on `best` (squared
    /// distance `best_d2`, triangle `best_tri` or no_triangle, point `best_point`).
    void closest_in_tree(const Vec3& q, double& best_d2, Index& best_tri, Vec3& best_point) const {
        const std::vector<Node>& nodes = impl_->nodes;
        const K::Point_3 p = point3(q);
        const K::Construct_projected_point_3 project;
        // Depth first, nearer child first: at most one pending sibling per level, and the
        // median split keeps the depth under 64 for any size that fits in memory.
        std::array<std::pair<Index, double>, 128> stack;
        std::size_t top = 0;
        stack[top++] = {0, box_distance2(nodes[0], q)};
        while (top > 0) {
            const auto [n, d2] = stack[--top];
            if (d2 >= best_d2 && best_tri != no_triangle) continue;  // (d2 may overflow to infinity)
            const Node& node = nodes[n];
            if (node.count > 0) {
                for (Index i = node.first; i < node.first + node.count; ++i) {
                    const K::Point_3 c = project(impl_->triangles[i], p);
                    const Vec3 cv(c.x(), c.y(), c.z());
                    const double e2 = (cv - q).squaredNorm();
                    if (e2 < best_d2 || best_tri == no_triangle) {
                        best_d2 = e2;
                        best_tri = i;
                        best_point = cv;
                    }
                }
                continue;
            }
            const Index a = n + 1, b = node.first;
            const double da = box_distance2(nodes[a], q), db = box_distance2(nodes[b], q);
            if (da <= db) {
                stack[top++] = {b, db};
                stack[top++] = {a, da};
            } else {
                stack[top++] = {a, da};
                stack[top++] = {b, db};
            }
        }
    }

    /// CGAL's AABB tree over the triangles, for the ray queries (built once, on first use).
    const Tree& ray_tree() const {
        std::call_once(impl_->ray_once, [this] {
            impl_->ray_tree = std::make_unique<Tree>(impl_->triangles.cbegin(), impl_->triangles.cend());
            impl_->ray_tree->build();
        });
        return *impl_->ray_tree;
    }

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
        const K::Construct_projected_point_3 project;
        Index tri = no_triangle;
        for (std::size_t i = 0; i < n; ++i) {
            double d2 = std::numeric_limits<double>::infinity();
            Vec3 point = Vec3::Zero();
            if (tri != no_triangle) {  // the previous answer's triangle bounds the search
                const K::Point_3 c = project(impl_->triangles[tri], point3(q[i]));
                point = Vec3(c.x(), c.y(), c.z());
                d2 = (point - q[i]).squaredNorm();
            }
            closest_in_tree(q[i], d2, tri, point);
            out[i].point = point;
            out[i].distance = (point - q[i]).norm();
            out[i].face = impl_->face_of[tri];
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
