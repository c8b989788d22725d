// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file disjoint_sets.hpp
/// @brief Disjoint sets (union-find) over the integers 0..n-1, the one the library's
/// connected-component labellings share (the components and fans of
/// metrics/topology_report.hpp, the boundary-loop components of mesh/holes.hpp, the
/// completion's patch labels, the normal orientation's seeds).
///
/// @code
/// kintsugi::detail::DisjointSets<std::size_t> sets(5);
/// sets.unite(3, 1);
/// sets.unite(1, 4);
/// // sets.find(4) == 1: a set is named by its smallest element
/// @endcode
///
/// Written here rather than taken from Boost: boost/pending/disjoint_sets.hpp fails to
/// compile with plain pointer maps once boost/graph/compressed_sparse_row_graph.hpp is
/// included first (its boost::detail::get hides boost::get from link_sets, Boost 1.74),
/// it needs a rank array besides the parents, its headers take 1.4 s more to parse (GCC
/// 12, -fsyntax-only: 1.65 s against 0.25 s for <vector> alone), and it names a set by an element that
/// depends on the order of the unions, where this one names it by its smallest element.

#include <kintsugi/core/types.hpp>

#include <concepts>
#include <cstddef>
#include <numeric>
#include <vector>

namespace kintsugi::detail {

/// @brief Union-find over the elements 0..size()-1 with path halving; each set is
/// represented by its smallest element.
///
/// unite() links the larger of the two representatives under the smaller, so find(x) is
/// the smallest element of x's set whatever the order of the unions: labels built from
/// it are deterministic. Path halving (each visited element skips to its grandparent)
/// keeps the trees shallow; with this linking rule a sequence of m operations on n
/// elements costs O(m log_(1+m/n) n) (Tarjan and van Leeuwen, 1984), in practice a few
/// steps per call.
/// @tparam I an unsigned integer type that holds size() (Index, or std::uint32_t to
///           halve the memory of large sets).
template <std::unsigned_integral I = Index>
class DisjointSets {
public:
    DisjointSets() = default;
    /// n singletons {0}, {1}, ..., {n-1}.
    explicit DisjointSets(std::size_t n) { reset(n); }

    /// Back to n singletons, keeping the storage (for many small labellings in a loop).
    void reset(std::size_t n) {
        parent_.resize(n);
        std::iota(parent_.begin(), parent_.end(), I{0});
    }

    /// Number of elements (not of sets).
    [[nodiscard]] std::size_t size() const { return parent_.size(); }

    /// The representative of x's set: its smallest element. @pre x < size().
    [[nodiscard]] I find(I x) {
        while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
        return x;
    }

    /// Merges the sets of a and b; returns whether they were different sets.
    /// @pre a, b < size().
    bool unite(I a, I b) {
        a = find(a);
        b = find(b);
        if (a == b) return false;
        if (a < b) parent_[b] = a;
        else parent_[a] = b;
        return true;
    }

    /// Whether a and b lie in the same set. @pre a, b < size().
    [[nodiscard]] bool same(I a, I b) { return find(a) == find(b); }

private:
    std::vector<I> parent_;
};

}  // namespace kintsugi::detail
