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
/// File names and file content quoted in a message are escaped (detail::printable), so
/// that a message is one line of printable ASCII whatever the name or the bytes.

#include <kintsugi/core/types.hpp>

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace kintsugi {

namespace detail {
/// `s` with every byte outside printable ASCII escaped (\t, \r, \n, \xHH), so that a
/// file name or file content quoted in a message shows no invisible or raw bytes.
[[nodiscard]] inline std::string printable(std::string_view s) {
    static constexpr char hex[] = "0123456789ABCDEF";
    std::string out;
    out.reserve(s.size());
    for (const char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        if (c >= 0x20 && c < 0x7F) out += ch;
        else if (c == '\t') out += "\\t";
        else if (c == '\r') out += "\\r";
        else if (c == '\n') out += "\\n";
        else {
            out += "\\x";
            out += hex[c >> 4];
            out += hex[c & 15];
        }
    }
    return out;
}
}  // namespace detail

/// Bad input at an API boundary: empty set, NaN/Inf coordinates, missing normals,
/// index out of range, non-triangle faces, parameters out of range.
class invalid_input : public std::invalid_argument {
public:
    using std::invalid_argument::invalid_argument;
};

/// A file could not be read or written. The message names the file.
class io_error : public std::runtime_error {
public:
    /// The message is "PATH: WHAT", PATH escaped by detail::printable (a name holding a
    /// newline or a control character stays on one line); `what` must be escaped already.
    io_error(const std::string& path, const std::string& what)
        : std::runtime_error(detail::printable(path) + ": " + what), path_(path) {}
    /// The file the error is about, as given (not escaped).
    [[nodiscard]] const std::string& path() const noexcept { return path_; }

private:
    std::string path_;
};

namespace detail {

/// Throws invalid_input "<prefix><name> = <value> must lie in [0, 1]<tail>" unless
/// 0 <= value <= 1 (NaN fails): the one check of a fraction parameter.
inline void check_fraction(const std::string& prefix, const char* name, double value, const std::string& tail = {}) {
    if (!(value >= 0 && value <= 1))
        throw invalid_input(prefix + name + " = " + std::to_string(value) + " must lie in [0, 1]" + tail);
}

/// Throws invalid_input "<prefix><i> has a NaN or infinite coordinate<tail>" for the
/// first i whose pts[i] has one: the one finiteness check of an input's positions
/// (prefix e.g. "kintsugi::estimate_normals: point ", tail e.g. "; remove it first").
inline void check_finite_points(const std::vector<Vec3>& pts, const std::string& prefix,
                                const char* tail = "; remove it first") {
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (!pts[i].allFinite())
            throw invalid_input(prefix + std::to_string(i) + " has a NaN or infinite coordinate" + tail);
}

}  // namespace detail
}  // namespace kintsugi
