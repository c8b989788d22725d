// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file error.hpp
/// @brief The two exception types of kintsugi.
///
/// Rule for every public function: bad input at the API boundary throws
/// `invalid_input` naming the function, the element and the fix; a failure to read
/// or write a file throws `io_error` naming the file and what is wrong. The library
/// never prints, never aborts, and never leaves a half-written output file.

#include <stdexcept>
#include <string>

namespace kintsugi {

/// Bad input at an API boundary: empty set, NaN/Inf coordinates, missing normals,
/// index out of range, non-triangle faces, parameters out of range.
class invalid_input : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

/// A file could not be read or written. The message names the file.
class io_error : public std::runtime_error {
public:
    io_error(const std::string& path, const std::string& what)
        : std::runtime_error(path + ": " + what), path_(path) {}
    /// The file the error is about.
    [[nodiscard]] const std::string& path() const noexcept { return path_; }

private:
    std::string path_;
};

}  // namespace kintsugi
