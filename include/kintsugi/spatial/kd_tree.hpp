// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file kd_tree.hpp
/// @brief A static 3D kd-tree over any PointSet: k-nearest, radius and nearest
/// queries. Models SpatialIndex. nanoflann is used inside and never shows in the API.
///
/// @code
/// kintsugi::KdTree tree(points);                 // any PointSet
/// std::vector<kintsugi::Neighbor> nn;
/// tree.knn(q, 10, nn);                            // sorted, squared distances
/// tree.knn_within(q, 10, r * r, nn);             // the same, cut at distance r
/// tree.radius_search_squared(q, r * r, nn);      // all within distance r, sorted
/// tree.radius_search_squared(q, r * r, nn, false);  // same set, tree order (faster)
/// kintsugi::KdTree coarse(points, {.leaf_size = 32});  // other bucket size
/// auto owned = kintsugi::KdTree::adopt(std::move(positions));  // a vector<Vec3>, not copied
/// @endcode
/// Queries are const and thread-safe. Ties are broken by index, so results are
/// deterministic; the unsorted radius search returns the same set in an order that
/// depends only on the points and the leaf size (not on threads or earlier queries).

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace kintsugi {

namespace detail {
/// nanoflann dataset adaptor over a contiguous vector of Vec3.
struct KdDataset {
    const std::vector<Vec3>* pts;
    [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts->size(); }
    [[nodiscard]] Scalar kdtree_get_pt(std::size_t i, std::size_t d) const { return (*pts)[i][static_cast<Eigen::Index>(d)]; }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const {
        return false;
    }
};
using NanoKdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<Scalar, KdDataset>, KdDataset,
                                                       3, std::size_t>;

/// nanoflann result set of an inclusive radius search that writes straight into a
/// vector of Neighbor (no intermediate copy, no sort).
struct KdRadiusCollector {
    Scalar squared_radius;
    Scalar bound;  // squared_radius widened by one ulp: nanoflann's leaf test is strict (<)
    std::vector<Neighbor>* out;
    [[nodiscard]] std::size_t size() const { return out->size(); }
    [[nodiscard]] bool full() const { return true; }
    bool addPoint(Scalar d2, std::size_t i) {
        if (d2 <= squared_radius) out->push_back({i, d2});
        return true;
    }
    [[nodiscard]] Scalar worstDist() const { return bound; }
};
/// nanoflann result set that stops at the first point other than `exclude` strictly
/// within the squared radius.
struct KdAnyOther {
    Scalar squared_radius;
    std::size_t exclude;
    bool found = false;
    [[nodiscard]] std::size_t size() const { return found ? 1 : 0; }
    [[nodiscard]] bool full() const { return true; }
    bool addPoint(Scalar d2, std::size_t i) {
        if (i == exclude || !(d2 < squared_radius)) return true;
        found = true;
        return false;
    }
    [[nodiscard]] Scalar worstDist() const { return squared_radius; }
};
}  // namespace detail

/// Options of the KdTree (aggregate; field order is API, append only).
struct KdTreeParams {
    /// Most points in a leaf (bucket). Smaller leaves make deeper trees (slower build,
    /// more memory) and cheaper small queries. 12 measured fastest for 10-NN of 1M
    /// bunny-scan points (bench_spatial, CPU time per run of 1M queries: leaf 6 2.20 s,
    /// 8 1.95 s, 10 2.11 s, 12 1.68-1.71 s, 16 (the former default) 1.90-1.92 s, 24
    /// 1.74-1.78 s; CGAL's Kd_tree 1.36-1.45 s). Query results never depend on it
    /// (except the order of an unsorted radius search). Must be >= 1.
    std::size_t leaf_size = 12;
};

/// Static kd-tree over a copy of the input positions.
class KdTree {
public:
    KdTree() = default;

    /// Builds the tree over any PointSet (positions are copied).
    /// @throws invalid_input if a coordinate is NaN or infinite.
    template <PointSet P>
    explicit KdTree(const P& points) {
        init(kintsugi::gather_points(points), KdTreeParams{});
    }

    /// Builds the tree over any PointSet with the given options.
    /// @throws invalid_input if a coordinate is NaN or infinite, or leaf_size is 0.
    template <PointSet P>
    KdTree(const P& points, const KdTreeParams& params) {
        init(kintsugi::gather_points(points), params);
    }

    /// Builds the tree over positions it takes over (no copy when moved in):
    /// `auto tree = KdTree::adopt(std::move(positions));`.
    /// @throws invalid_input if a coordinate is NaN or infinite, or leaf_size is 0.
    [[nodiscard]] static KdTree adopt(std::vector<Vec3> points, const KdTreeParams& params = {}) {
        KdTree tree;
        tree.init(std::move(points), params);
        return tree;
    }

    KdTree(KdTree&&) noexcept = default;
    KdTree& operator=(KdTree&&) noexcept = default;

    /// Number of points in the tree.
    [[nodiscard]] std::size_t size() const { return pts().size(); }
    /// The indexed positions, in input order.
    [[nodiscard]] const std::vector<Vec3>& points() const { return pts(); }
    /// Position of point i.
    [[nodiscard]] const Vec3& point(std::size_t i) const { return pts()[i]; }

    /// The min(k, size()) nearest points to q, by increasing distance (ties by index).
    /// @throws invalid_input if q has a NaN or infinite coordinate.
    void knn(const Vec3& q, std::size_t k, std::vector<Neighbor>& out) const {
        require_finite(q, "knn");
        knn_bounded(q, k, std::numeric_limits<Scalar>::max(), out);
    }
    /// The min(k, size()) nearest points to q among those at squared distance at most
    /// `squared_radius` (fewer when fewer lie that close), by increasing distance (ties by
    /// index): the same points as knn() followed by a cut at the radius. A hybrid search
    /// (Open3D's SearchHybrid, PCL's nearestKSearch with a radius). With a bound close to
    /// the k-th distance (the farthest of any k points, e.g. a nearby query's neighbours)
    /// it prunes much more of the tree than knn() when q lies far from the points.
    /// A negative radius finds nothing.
    /// @throws invalid_input if q has a NaN or infinite coordinate or the radius is NaN.
    void knn_within(const Vec3& q, std::size_t k, Scalar squared_radius, std::vector<Neighbor>& out) const {
        require_finite(q, "knn_within");
        if (std::isnan(squared_radius))
            throw invalid_input("kintsugi::KdTree::knn_within: the squared radius is NaN");
        if (squared_radius < 0) {
            out.clear();
            return;
        }
        knn_bounded(q, k, squared_radius, out);
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Neighbor> knn(const Vec3& q, std::size_t k) const {
        std::vector<Neighbor> out;
        knn(q, k, out);
        return out;
    }

    /// All points whose squared distance to q is at most `squared_radius`.
    /// A negative radius finds nothing.
    /// @param q query position (the points' units)
    /// @param squared_radius squared search radius (squared units)
    /// @param out replaced by the neighbours with their squared distances
    /// @param sorted true (default): by increasing distance, ties by index; false: the
    ///        same set in the tree's order (deterministic: it depends only on the
    ///        points, the leaf size and q), for callers that do not need the order
    ///        (no sort: cheaper for large balls)
    /// @throws invalid_input if q has a NaN or infinite coordinate or the radius is NaN.
    void radius_search_squared(const Vec3& q, Scalar squared_radius, std::vector<Neighbor>& out,
                               bool sorted = true) const {
        out.clear();
        require_finite(q, "radius_search_squared");
        if (std::isnan(squared_radius))
            throw invalid_input("kintsugi::KdTree::radius_search_squared: the squared radius is NaN");
        if (pts().empty() || squared_radius < 0) return;
        detail::KdRadiusCollector collect{squared_radius,
                                          std::nextafter(squared_radius, std::numeric_limits<Scalar>::max()), &out};
        impl_->index->findNeighbors(collect, q.data(), nanoflann::SearchParams(32, 0, false));
        if (sorted) detail::sort_neighbors(out);
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Neighbor> radius_search_squared(const Vec3& q, Scalar squared_radius) const {
        std::vector<Neighbor> out;
        radius_search_squared(q, squared_radius, out);
        return out;
    }

    /// Whether a point other than `exclude` lies strictly within `squared_radius` of q
    /// (squared distance < squared_radius): a radius search that stops at the first such
    /// point, e.g. "is another point nearer to q than point i is" (pass i's squared
    /// distance and i). False for an empty tree.
    /// @throws invalid_input if q has a NaN or infinite coordinate.
    [[nodiscard]] bool any_other_within_squared(const Vec3& q, Scalar squared_radius, std::size_t exclude) const {
        require_finite(q, "any_other_within_squared");
        if (pts().empty()) return false;
        detail::KdAnyOther rs{squared_radius, exclude};
        impl_->index->findNeighbors(rs, q.data(), nanoflann::SearchParams(32, 0, false));
        return rs.found;
    }

    /// The leaf (bucket) size the tree was built with.
    [[nodiscard]] std::size_t leaf_size() const { return impl_ ? impl_->leaf_size : KdTreeParams{}.leaf_size; }

    /// The nearest point to q (ties by index). @pre size() > 0
    /// @throws invalid_input if the tree is empty or q has a NaN or infinite coordinate.
    [[nodiscard]] Neighbor nearest(const Vec3& q) const {
        if (pts().empty()) throw invalid_input("kintsugi::KdTree::nearest: the tree is empty");
        thread_local std::vector<Neighbor> nn;
        knn(q, 1, nn);
        return nn.front();
    }

private:
    // knn() and knn_within(): nanoflann's k-nearest search with its worst distance started
    // at the bound (std::numeric_limits<Scalar>::max() for none).
    void knn_bounded(const Vec3& q, std::size_t k, Scalar squared_radius, std::vector<Neighbor>& out) const {
        out.clear();
        k = std::min(k, pts().size());
        if (k == 0) return;
        const bool bounded = squared_radius < std::numeric_limits<Scalar>::max();
        // Ask for one more than needed: when the k-th and (k+1)-th distances
        // differ, the k found are exactly the points within the k-th distance.
        // When they tie, the tie may extend beyond what nanoflann returned (it
        // keeps an arbitrary subset of equidistant points), so every point at
        // most that far is collected and the tie resolved by index. (With a bound,
        // fewer than k + 1 found means that no other point lies within it, so
        // none ties with the k-th either.)
        const std::size_t kq = std::min(k + 1, pts().size());
        thread_local std::vector<std::size_t> idx;
        thread_local std::vector<Scalar> d2;
        idx.resize(kq);
        d2.resize(kq);
        nanoflann::KNNResultSet<Scalar, std::size_t> rs(kq);
        rs.init(idx.data(), d2.data());
        // The set's worst distance is its last slot until it is full; nanoflann's leaf
        // test is strict (<), so the bound is widened by one ulp to stay inclusive.
        if (bounded) d2[kq - 1] = std::nextafter(squared_radius, std::numeric_limits<Scalar>::max());
        impl_->index->findNeighbors(rs, q.data(), nanoflann::SearchParams());
        const std::size_t found = rs.size();
        if (!bounded && found < kq)  // nanoflann drops points at an infinite squared distance
            throw invalid_input("kintsugi::KdTree::knn: the query point is so far from the points that their "
                                "squared distances overflow double precision; query nearer the points");
        out.resize(found);
        // nanoflann returns them by increasing distance; only equal distances need
        // the sort (by index), so it is skipped when there are none.
        bool sorted = true;
        for (std::size_t i = 0; i < found; ++i) {
            out[i] = {idx[i], d2[i]};
            if (i > 0 && !(d2[i - 1] < d2[i])) sorted = false;
        }
        if (!sorted) detail::sort_neighbors(out);
        if (found > k && out[k - 1].squared_distance == out[k].squared_distance)
            radius_search_squared(q, out[k - 1].squared_distance, out);
        out.resize(std::min(k, out.size()));
    }

    void init(std::vector<Vec3> points, const KdTreeParams& params) {
        if (params.leaf_size == 0)
            throw invalid_input("kintsugi::KdTree: leaf_size is 0; pass at least 1 (12 is the default)");
        for (std::size_t i = 0; i < points.size(); ++i)
            if (!points[i].allFinite())
                throw invalid_input("kintsugi::KdTree: point " + std::to_string(i) +
                                    " has a NaN or infinite coordinate; remove it first");
        // Squared distances must stay finite and above the normal range: the box's
        // longest side within [2^-480, 2^510] (about 1e-144 to 3e153), or all points equal.
        BoundingBox box;
        for (const Vec3& p : points) box.extend(p);
        if (!points.empty()) {
            const Scalar half = (box.max / 2 - box.min / 2).maxCoeff();
            if (half > std::ldexp(Scalar(1), 509) || (half > 0 && half < std::ldexp(Scalar(1), -481)))
                throw invalid_input("kintsugi::KdTree: the points span " + detail::format_number(2 * half) +
                                    " units, so their squared distances would " +
                                    (half > 1 ? "overflow" : "underflow") +
                                    " double precision; scale them into [1e-140, 1e150] first (kintsugi's "
                                    "algorithms rescale their own copy)");
        }
        impl_ = std::make_unique<Impl>();
        impl_->points = std::move(points);
        impl_->dataset.pts = &impl_->points;
        impl_->leaf_size = params.leaf_size;
        if (!impl_->points.empty())
            impl_->index = std::make_unique<detail::NanoKdTree>(
                3, impl_->dataset, nanoflann::KDTreeSingleIndexAdaptorParams(params.leaf_size));
    }
    static void require_finite(const Vec3& q, const char* fn) {
        if (!q.allFinite())
            throw invalid_input(std::string("kintsugi::KdTree::") + fn +
                                ": the query point has a NaN or infinite coordinate");
    }
    // Held behind a pointer so that moving a KdTree keeps nanoflann's pointer to
    // the dataset valid.
    struct Impl {
        std::vector<Vec3> points;
        detail::KdDataset dataset{nullptr};
        std::unique_ptr<detail::NanoKdTree> index;
        std::size_t leaf_size = KdTreeParams{}.leaf_size;
    };
    [[nodiscard]] const std::vector<Vec3>& pts() const {
        static const std::vector<Vec3> empty;
        return impl_ ? impl_->points : empty;
    }
    std::unique_ptr<Impl> impl_;
};

static_assert(SpatialIndex<KdTree>);

}  // namespace kintsugi
