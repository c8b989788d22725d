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

#include <stdexcept>
#include <string>
#include <string_view>

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

}  // namespace kintsugi
