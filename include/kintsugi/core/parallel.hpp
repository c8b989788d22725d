// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file parallel.hpp
/// @brief Deterministic parallel loops: oneTBB when available, serial otherwise.
///
/// Results never depend on the number of threads: `parallel_for` bodies write to
/// their own slots, and `parallel_reduce` splits the range into fixed chunks whose
/// size depends only on the range (not on the thread count) and combines the
/// partial results in chunk order.
///
/// Define KINTSUGI_NO_TBB to force the serial backend. The CMake target defines
/// KINTSUGI_HAS_TBB when oneTBB was found.

#include <algorithm>
#include <cstddef>
#include <functional>
#include <vector>

#if defined(KINTSUGI_HAS_TBB) && !defined(KINTSUGI_NO_TBB)
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>
#define KINTSUGI_PARALLEL_TBB 1
#endif

#include <memory>

namespace kintsugi {

/// Number of worker threads parallel loops may use.
[[nodiscard]] inline int max_threads() {
#ifdef KINTSUGI_PARALLEL_TBB
    return static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
#else
    return 1;
#endif
}

/// Limits the threads used by kintsugi (and anything else on oneTBB) while alive.
/// `ThreadLimit limit(1);` makes every parallel loop serial. 0 means no limit.
class ThreadLimit {
public:
    explicit ThreadLimit(int threads) {
#ifdef KINTSUGI_PARALLEL_TBB
        if (threads > 0)
            control_ = std::make_unique<tbb::global_control>(
                tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
#else
        (void)threads;
#endif
    }

private:
#ifdef KINTSUGI_PARALLEL_TBB
    std::unique_ptr<tbb::global_control> control_;
#endif
};

namespace detail {
/// Sorts v by `less` (in parallel when TBB is on and v is large). Only for orders that
/// are total and unique (e.g. (key, index) pairs), so that the result is one.
template <class T, class Less = std::less<>>
void sort_maybe_parallel(std::vector<T>& v, Less less = {}) {
#ifdef KINTSUGI_PARALLEL_TBB
    if (v.size() > 100000) {
        tbb::parallel_sort(v.begin(), v.end(), less);
        return;
    }
#endif
    std::sort(v.begin(), v.end(), less);
}
}  // namespace detail

/// Calls `body(i)` for every i in [begin, end), possibly in parallel. `grain` is
/// the smallest chunk worth a task. Bodies must only write state owned by i.
template <class Body>
void parallel_for(std::size_t begin, std::size_t end, Body&& body, std::size_t grain = 256) {
    if (end <= begin) return;
#ifdef KINTSUGI_PARALLEL_TBB
    if (end - begin > grain) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end, grain),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i) body(i);
                          });
        return;
    }
#else
    (void)grain;
#endif
    for (std::size_t i = begin; i != end; ++i) body(i);
}

/// Runs `a()` and `b()`, concurrently when TBB is on and more than one thread is
/// allowed; `a` then `b` otherwise. For a sequential step beside independent work: `b`
/// runs on the calling thread (give it the step that reports progress), `a` on a free
/// worker, and parallel loops inside `a` use whatever threads are free. The two must be
/// independent (neither reads what the other writes), or share only state accessed
/// atomically whose interleaving cannot change the result (pu_cover's uncovered set), so
/// the results do not depend on the threads. An exception from either is rethrown here.
template <class A, class B>
void parallel_invoke(A&& a, B&& b) {
#ifdef KINTSUGI_PARALLEL_TBB
    if (max_threads() > 1) {
        tbb::parallel_invoke(a, b);
        return;
    }
#endif
    a();
    b();
}

/// Deterministic reduction: splits [begin, end) into chunks of `chunk` indices
/// (fixed, independent of the thread count), computes
/// `acc = chunk_body(first, last, identity)` for each chunk in parallel, then
/// folds the partial results left to right with `combine`.
template <class T, class ChunkBody, class Combine>
[[nodiscard]] T parallel_reduce(std::size_t begin, std::size_t end, T identity, ChunkBody&& chunk_body,
                                Combine&& combine, std::size_t chunk = 4096) {
    if (end <= begin) return identity;
    chunk = std::max<std::size_t>(chunk, 1);
    const std::size_t n_chunks = (end - begin + chunk - 1) / chunk;
    std::vector<T> partial(n_chunks, identity);
    parallel_for(
        0, n_chunks,
        [&](std::size_t c) {
            const std::size_t first = begin + c * chunk;
            const std::size_t last = std::min(end, first + chunk);
            partial[c] = chunk_body(first, last, identity);
        },
        1);
    T result = identity;
    for (auto& p : partial) result = combine(std::move(result), std::move(p));
    return result;
}

}  // namespace kintsugi
