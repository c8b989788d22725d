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
/// tree.radius_search_squared(q, r * r, nn);      // all within distance r
/// @endcode
/// Queries are const and thread-safe. Ties are broken by index, so results are
/// deterministic.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>

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

inline void sort_neighbors(std::vector<Neighbor>& out) {
    std::sort(out.begin(), out.end(), [](const Neighbor& a, const Neighbor& b) {
        return a.squared_distance < b.squared_distance ||
               (a.squared_distance == b.squared_distance && a.index < b.index);
    });
}
}  // namespace detail

/// Static kd-tree over a copy of the input positions.
class KdTree {
public:
    KdTree() = default;

    /// Builds the tree over any PointSet (positions are copied).
    /// @throws invalid_input if a coordinate is NaN or infinite.
    template <PointSet P>
    explicit KdTree(const P& points) : KdTree(gather_points(points), 0) {}

    /// Builds the tree over positions moved in.
    explicit KdTree(std::vector<Vec3> points, int /*tag*/ = 0) : impl_(std::make_unique<Impl>()) {
        for (std::size_t i = 0; i < points.size(); ++i)
            if (!points[i].allFinite())
                throw invalid_input("kintsugi::KdTree: point " + std::to_string(i) +
                                    " has a NaN or infinite coordinate; remove it first");
        impl_->points = std::move(points);
        impl_->dataset.pts = &impl_->points;
        if (!impl_->points.empty())
            impl_->index = std::make_unique<detail::NanoKdTree>(3, impl_->dataset,
                                                                nanoflann::KDTreeSingleIndexAdaptorParams(16));
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
        out.clear();
        require_finite(q, "knn");
        k = std::min(k, pts().size());
        if (k == 0) return;
        // Ask for one more than needed: when the k-th and (k+1)-th distances
        // differ, the k found are exactly the points within the k-th distance.
        // When they tie, the tie may extend beyond what nanoflann returned (it
        // keeps an arbitrary subset of equidistant points), so every point at
        // most that far is collected and the tie resolved by index.
        const std::size_t kq = std::min(k + 1, pts().size());
        thread_local std::vector<std::size_t> idx;
        thread_local std::vector<Scalar> d2;
        idx.resize(kq);
        d2.resize(kq);
        const std::size_t found = impl_->index->knnSearch(q.data(), kq, idx.data(), d2.data());
        out.resize(found);
        for (std::size_t i = 0; i < found; ++i) out[i] = {idx[i], d2[i]};
        detail::sort_neighbors(out);
        if (found > k && out[k - 1].squared_distance == out[k].squared_distance)
            radius_search_squared(q, out[k - 1].squared_distance, out);
        out.resize(std::min(k, out.size()));
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Neighbor> knn(const Vec3& q, std::size_t k) const {
        std::vector<Neighbor> out;
        knn(q, k, out);
        return out;
    }

    /// All points whose squared distance to q is at most `squared_radius`,
    /// by increasing distance (ties by index).
    /// A negative radius finds nothing.
    /// @throws invalid_input if q has a NaN or infinite coordinate or the radius is NaN.
    void radius_search_squared(const Vec3& q, Scalar squared_radius, std::vector<Neighbor>& out) const {
        out.clear();
        require_finite(q, "radius_search_squared");
        if (std::isnan(squared_radius))
            throw invalid_input("kintsugi::KdTree::radius_search_squared: the squared radius is NaN");
        if (pts().empty() || squared_radius < 0) return;
        thread_local std::vector<std::pair<std::size_t, Scalar>> hits;
        hits.clear();
        nanoflann::SearchParams params;
        params.sorted = false;
        // nanoflann's radius test is strict (<); widen by one ulp to make it inclusive.
        impl_->index->radiusSearch(q.data(), std::nextafter(squared_radius, std::numeric_limits<Scalar>::max()), hits, params);
        out.reserve(hits.size());
        for (const auto& [i, d] : hits)
            if (d <= squared_radius) out.push_back({i, d});
        detail::sort_neighbors(out);
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Neighbor> radius_search_squared(const Vec3& q, Scalar squared_radius) const {
        std::vector<Neighbor> out;
        radius_search_squared(q, squared_radius, out);
        return out;
    }

    /// The nearest point to q (ties by index). @pre size() > 0
    /// @throws invalid_input if the tree is empty or q has a NaN or infinite coordinate.
    [[nodiscard]] Neighbor nearest(const Vec3& q) const {
        if (pts().empty()) throw invalid_input("kintsugi::KdTree::nearest: the tree is empty");
        thread_local std::vector<Neighbor> nn;
        knn(q, 1, nn);
        return nn.front();
    }

private:
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
    };
    [[nodiscard]] const std::vector<Vec3>& pts() const {
        static const std::vector<Vec3> empty;
        return impl_ ? impl_->points : empty;
    }
    std::unique_ptr<Impl> impl_;
};

static_assert(SpatialIndex<KdTree>);

}  // namespace kintsugi
