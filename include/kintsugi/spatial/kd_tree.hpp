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
    void knn(const Vec3& q, std::size_t k, std::vector<Neighbor>& out) const {
        out.clear();
        k = std::min(k, pts().size());
        if (k == 0) return;
        // Ask for one more than needed so that equal-distance ties at the k-th
        // place are resolved by index, independently of the tree's layout.
        const std::size_t kq = std::min(k + 1, pts().size());
        thread_local std::vector<std::size_t> idx;
        thread_local std::vector<Scalar> d2;
        idx.resize(kq);
        d2.resize(kq);
        const std::size_t found = impl_->index->knnSearch(q.data(), kq, idx.data(), d2.data());
        out.resize(found);
        for (std::size_t i = 0; i < found; ++i) out[i] = {idx[i], d2[i]};
        detail::sort_neighbors(out);
        out.resize(std::min(k, found));
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Neighbor> knn(const Vec3& q, std::size_t k) const {
        std::vector<Neighbor> out;
        knn(q, k, out);
        return out;
    }

    /// All points whose squared distance to q is at most `squared_radius`,
    /// by increasing distance (ties by index).
    void radius_search_squared(const Vec3& q, Scalar squared_radius, std::vector<Neighbor>& out) const {
        out.clear();
        if (pts().empty() || !(squared_radius >= 0)) return;
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

    /// The nearest point to q. @pre size() > 0
    [[nodiscard]] Neighbor nearest(const Vec3& q) const {
        if (pts().empty()) throw invalid_input("kintsugi::KdTree::nearest: the tree is empty");
        std::size_t i = 0;
        Scalar d2 = 0;
        impl_->index->knnSearch(q.data(), 1, &i, &d2);
        return {i, d2};
    }

private:
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
