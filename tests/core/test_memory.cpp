// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// core/memory.hpp: which glibc settings the program runs with decide whether the
// reconstruction trims the heap; huge_vector's contents.
#include <doctest/doctest.h>

#include <kintsugi/core/memory.hpp>

#include <cstdlib>
#include <optional>
#include <string>

namespace ks = kintsugi;

namespace {
// Sets GLIBC_TUNABLES (nullptr: unsets it) for one scope; the reading functions look at
// the environment on every call (glibc itself read it at start).
class TunablesScope {
public:
    explicit TunablesScope(const char* value) {
        if (const char* old = std::getenv("GLIBC_TUNABLES")) saved_ = std::string(old);
        if (value != nullptr)
            setenv("GLIBC_TUNABLES", value, 1);
        else
            unsetenv("GLIBC_TUNABLES");
    }
    ~TunablesScope() {
        if (saved_)
            setenv("GLIBC_TUNABLES", saved_->c_str(), 1);
        else
            unsetenv("GLIBC_TUNABLES");
    }
    TunablesScope(const TunablesScope&) = delete;
    TunablesScope& operator=(const TunablesScope&) = delete;

private:
    std::optional<std::string> saved_;
};
}  // namespace

TEST_CASE("memory: the heap counts as kept exactly when the program set glibc's trim threshold") {
    {
        const TunablesScope t(nullptr);
        CHECK_FALSE(ks::detail::heap_kept());
        CHECK_FALSE(ks::kept_heap_malloc_on());
    }
    {
        const TunablesScope t("glibc.malloc.hugetlb=1");  // huge pages alone: every trim runs
        CHECK_FALSE(ks::detail::heap_kept());
        CHECK_FALSE(ks::kept_heap_malloc_on());
    }
    {
        // What use_kept_heap_malloc sets, after a caller's own tunable.
        const std::string all = std::string("glibc.malloc.check=0:") + ks::detail::kept_heap_tunables;
        const TunablesScope t(all.c_str());
        CHECK(ks::detail::heap_kept());
        CHECK(ks::kept_heap_malloc_on());
    }
    // The tunables keep blocks below 128 MiB and one arena (docs/methods/pu_graphcut.md).
    const std::string kept = ks::detail::kept_heap_tunables;
    CHECK(kept.find("glibc.malloc.mmap_threshold=134217728") != std::string::npos);
    CHECK(kept.find("glibc.malloc.arena_max=1") != std::string::npos);
    // Not every allocation on huge pages: measured slower here (core/memory.hpp).
    CHECK(kept.find("hugetlb") == std::string::npos);
}

TEST_CASE("memory: huge_vector holds n copies of the value, whatever the pages") {
    const auto small = ks::detail::huge_vector<int>(5, 7);
    CHECK(small == std::vector<int>(5, 7));
    const std::size_t n = std::size_t{3} << 20;  // 12 MiB of ints: past the advice's 8 MiB floor
    const auto big = ks::detail::huge_vector<int>(n, -3);
    REQUIRE(big.size() == n);
    CHECK(big.front() == -3);
    CHECK(big[n / 2] == -3);
    CHECK(big.back() == -3);
    ks::detail::release_free_memory();  // callable at any time; a no-op off glibc
}
