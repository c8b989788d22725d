// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file memory.hpp
/// @brief Large buffers backed by transparent huge pages where the system allows it
/// (internal), and use_kept_heap_malloc for programs (public).
///
/// A buffer of hundreds of megabytes filled once (an octree's cells, a flow network)
/// pays one page fault per 4 KiB page on first touch. On the 2-core VM the benchmarks run
/// on, that is about 1 s per 384 MB (2M points at octree level 9: 12M cells), more than
/// filling them costs; with 2 MiB pages it is about 0.05 s. Linux's default THP mode,
/// "madvise", gives huge pages only to ranges marked MADV_HUGEPAGE, so the buffers are
/// reserved, marked, then filled. Elsewhere (other systems, THP "never", small
/// buffers) this does nothing. The contents and the results never depend on it.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace kintsugi::detail {

/// Marks the whole 2 MiB pages inside [p, p + bytes) for transparent huge pages. A no-op
/// below 8 MiB, off Linux, and when the kernel refuses (the advice is a hint).
inline void advise_huge_pages(const void* p, std::size_t bytes) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    constexpr std::size_t huge = std::size_t{2} << 20;
    if (p == nullptr || bytes < 4 * huge) return;
    const auto a = reinterpret_cast<std::uintptr_t>(p);
    const std::uintptr_t first = (a + huge - 1) & ~(std::uintptr_t{huge} - 1);
    const std::uintptr_t last = (a + bytes) & ~(std::uintptr_t{huge} - 1);
    if (last > first) (void)madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
    (void)p;
    (void)bytes;
#endif
}

/// Reserves room for n elements in an empty vector and marks it (advise_huge_pages),
/// before the caller fills it (push_back, resize, assign).
template <class T, class A>
void reserve_huge(std::vector<T, A>& v, std::size_t n) {
    v.reserve(n);
    advise_huge_pages(v.data(), v.capacity() * sizeof(T));
}

/// A vector of n value-initialised elements on marked pages (reserve_huge, then resize).
template <class T>
[[nodiscard]] std::vector<T> huge_vector(std::size_t n, const T& value = T()) {
    std::vector<T> v;
    reserve_huge(v, n);
    v.resize(n, value);
    return v;
}

/// The glibc tunables use_kept_heap_malloc sets (see there).
inline constexpr const char* kept_heap_tunables =
    "glibc.malloc.mmap_threshold=134217728:glibc.malloc.trim_threshold=4294967296:glibc.malloc.arena_max=1";

/// Whether GLIBC_TUNABLES (glibc reads it only at start) holds `text`.
[[nodiscard]] inline bool glibc_tunables_contain(const char* text) noexcept {
    const char* tunables = std::getenv("GLIBC_TUNABLES");
    return tunables != nullptr && std::strstr(tunables, text) != nullptr;
}

/// Whether the program asked glibc to keep freed memory (GLIBC_TUNABLES sets
/// glibc.malloc.trim_threshold, as use_kept_heap_malloc does).
[[nodiscard]] inline bool heap_kept() noexcept { return glibc_tunables_contain("glibc.malloc.trim_threshold="); }

/// Gives the pages of freed heap memory back to the system (glibc's malloc_trim). glibc
/// keeps the memory of freed small blocks resident (a triangulation's cells, per-thread
/// buffers), and the next stage's large buffers come from new pages, so both count in the
/// peak: 2M points at level 9 had 355 MB free but resident before the graph cut (983 ->
/// 658 MB resident after the call). Called where a stage that frees many small blocks
/// ends and one that allocates large buffers starts; elsewhere, when the heap is kept
/// (heap_kept()), a trim would only make the next allocations fault in new pages. A
/// no-op on other C libraries.
inline void release_free_memory() noexcept {
#if defined(__GLIBC__)
    (void)malloc_trim(0);
#endif
}

}  // namespace kintsugi::detail

namespace kintsugi {

/// Whether glibc's allocator keeps freed memory in this process (GLIBC_TUNABLES sets
/// glibc.malloc.trim_threshold, as use_kept_heap_malloc does); what a program reports.
[[nodiscard]] inline bool kept_heap_malloc_on() noexcept { return detail::heap_kept(); }

/// @brief For programs, called first in main: on Linux with glibc, runs the program
/// again (execv of /proc/self/exe, same arguments) with glibc's allocator keeping the
/// memory it is given (GLIBC_TUNABLES, read only at start: detail::kept_heap_tunables):
/// mmap_threshold 128 MiB, trim_threshold 4 GiB, arena_max 1. Freed blocks below 128 MiB
/// stay in one heap and later stages reuse them, instead of faulting in new pages that the
/// system has to clear (on the benchmark VM, memory first touched after some idle time comes
/// at 0.4-0.6 GB/s, against 5-15 GB/s when it was used a moment before); larger blocks still
/// go back when freed, and the reconstruction trims the heap where a peak would otherwise grow
/// (detail::release_free_memory). kintsugi's own large buffers are on huge pages either way
/// (advise_huge_pages).
///
/// Until 2026-12-07 (as use_huge_page_malloc) it also put every glibc allocation on
/// transparent huge pages; on the 2-core VM that made the smoothing's first call at 590K faces
/// 0.6-2 s slower and the reconstruction no faster (docs/methods/feature_bilateral.md, "The
/// allocator revisited").
///
/// The `kintsugi` CLI, bench_reconstruct and bench_smooth call it. Does nothing (and returns)
/// off Linux/glibc, when GLIBC_TUNABLES already sets glibc.malloc.trim_threshold (as after
/// the execv), when KINTSUGI_DEFAULT_MALLOC is set (e.g. under valgrind, which would not
/// follow the execv), or when the execv fails. The results never depend on it.
/// @param argv main's argv (argv[0] first, null-terminated)
inline void use_kept_heap_malloc(char** argv) noexcept {
#if defined(__linux__) && defined(__GLIBC__)
    if (argv == nullptr || argv[0] == nullptr || std::getenv("KINTSUGI_DEFAULT_MALLOC") != nullptr) return;
    if (detail::heap_kept()) return;
    const char* tunables = std::getenv("GLIBC_TUNABLES");
    try {
        const std::string value = tunables != nullptr && *tunables != 0
                                      ? std::string(tunables) + ":" + detail::kept_heap_tunables
                                      : std::string(detail::kept_heap_tunables);
        if (setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
    } catch (...) {
        return;
    }
    (void)execv("/proc/self/exe", argv);  // returns only on failure: go on as we are
#else
    (void)argv;
#endif
}

}  // namespace kintsugi
