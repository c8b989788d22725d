// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file test_data.hpp
/// @brief Where the tests find their data, and how a test whose data is missing
/// reports itself as skipped.
///
/// tests/data (KINTSUGI_TEST_DATA_DIR) ships with the repository. ../shared/data
/// (KINTSUGI_SHARED_DATA_DIR) exists only beside a developer's or CI's checkout: a test
/// that needs it calls KINTSUGI_REQUIRE_DATA(path) first. When the path is missing the
/// macro prints the marker below and returns from the test case; CTest matches the
/// marker (SKIP_REGULAR_EXPRESSION, tests/CMakeLists.txt) and counts the test as
/// skipped, never as passed.

#include <filesystem>
#include <iostream>
#include <string>

namespace kintsugi::test {

/// Printed by a test whose data is missing; CTest reports such a test as skipped.
inline constexpr const char* skip_marker = "KINTSUGI_TEST_SKIPPED";

/// A file or folder under ../shared/data.
inline std::filesystem::path shared_data(const std::string& rel) {
    return std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / rel;
}
/// A file or folder under tests/data.
inline std::filesystem::path test_data(const std::string& rel) {
    return std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / rel;
}

/// True when `p` exists; otherwise prints the skip marker with the missing path.
inline bool data_present(const std::filesystem::path& p) {
    if (std::filesystem::exists(p)) return true;
    std::cout << skip_marker << ": " << p.string() << " not found (../shared/data is present only beside a developer's or CI's checkout)\n"
              << std::flush;
    return false;
}

}  // namespace kintsugi::test

/// Returns from the enclosing test case, reported as skipped, when `path` is missing.
#define KINTSUGI_REQUIRE_DATA(path)                                   \
    do {                                                              \
        if (!::kintsugi::test::data_present(path)) return;            \
    } while (false)
