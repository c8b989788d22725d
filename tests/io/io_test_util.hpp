// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
// Helpers shared by the io tests: a scratch directory removed at the end, file
// writing/reading, and the exception-message check.
#include <doctest/doctest.h>

#include <kintsugi/core/error.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

namespace io_test {

namespace fs = std::filesystem;

inline fs::path data(const std::string& name) { return fs::path(KINTSUGI_TEST_DATA_DIR) / name; }

/// A fresh directory under the system temp dir, removed with its content on destruction.
struct TempDir {
    fs::path path;
    TempDir() {
        std::random_device rd;
        for (;;) {
            path = fs::temp_directory_path() / ("kintsugi_io_test_" + std::to_string(rd()));
            if (fs::create_directory(path)) break;
        }
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    [[nodiscard]] fs::path operator/(const std::string& name) const { return path / name; }
    /// Number of entries in the directory (to check that no temporary file is left).
    [[nodiscard]] std::size_t entries() const {
        return static_cast<std::size_t>(std::distance(fs::directory_iterator(path), fs::directory_iterator()));
    }
};

inline void write_file(const fs::path& p, const std::string& content) {
    std::ofstream f(p, std::ios::binary);
    f << content;
}

inline std::string read_file(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

/// Runs `fn`, expects kintsugi::io_error whose message names `file` and contains `what`.
template <class Fn>
void check_io_error(Fn&& fn, const fs::path& file, const std::string& what) {
    bool thrown = false;
    try {
        fn();
    } catch (const kintsugi::io_error& e) {
        thrown = true;
        const std::string msg = e.what();
        INFO("message: ", msg);
        CHECK(msg.find(file.string()) != std::string::npos);
        CHECK(msg.find(what) != std::string::npos);
        CHECK(e.path() == file.string());
    }
    CHECK_MESSAGE(thrown, "expected kintsugi::io_error containing '", what, "'");
}

}  // namespace io_test
