// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
// Shared pieces of the `kintsugi` command-line tool: the subcommand registry,
// the options common to every subcommand, JSON output, the progress bar and
// error conventions.
//
// Adding a subcommand: write examples/kintsugi/cmd_<name>.cpp with
//
//   static kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
//       auto opt = std::make_shared<Options>();           // options live past setup
//       cmd.add_option("input", opt->input, "...")->required();
//       return [opt, &ctx] { ... };                        // run after parsing; throw on error
//   }
//   KINTSUGI_REGISTER_COMMAND(name, "one-line description", setup)
//
// Options: bind them to the library's Params (default-constructed, so the help shows
// the library's defaults) and check each with kcli::real / kcli::count, which reject
// NaN, Inf, negative counts and out-of-range values while parsing (exit 2, the option
// named). Checks that involve several options go at the top of the action, before any
// input is read; so does ctx.check_output(...) for every output path.
//
// Inside the callback: `ctx.doing("reading X")` names what runs (for an out-of-memory
// message); `ctx.control("stage label")` gives a RunControl with the progress bar and
// Ctrl-C cancellation (on Status::cancelled, throw kcli::interrupted); `ctx.json()` is
// the JSON object printed on stdout when --json is given; `ctx.info(...)` prints a
// human line unless --quiet or --json. Write every output with ctx.write_options():
// the files wait in a batch that main renames into place once the action succeeded,
// so a failed or interrupted command writes nothing. Long loops of the tool itself
// call ctx.check_interrupted().
// Errors: throw (kintsugi::invalid_input, io_error, kcli::usage_error or any
// std::exception): main prints `kintsugi: error: <message>` and exits 1
// (2 for usage errors, 128 + signal number when interrupted by SIGINT/SIGTERM/SIGHUP).

// First, so that no translation unit of the tool compiles the Eigen solvers that
// eigen_dense.cpp and eigen_sparse.cpp instantiate once (docs/build.md).
#include <kintsugi/core/eigen_instances.hpp>

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/write.hpp>

#include <CLI/CLI.hpp>

#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <stop_token>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace kcli {

/// Bad command-line usage detected after parsing (exit code 2).
struct usage_error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// The run was stopped by SIGINT/SIGTERM/SIGHUP (exit code 128 + the signal).
struct interrupted : std::runtime_error {
    interrupted() : std::runtime_error("interrupted") {}
};

/// Stop token of the whole run: requested on SIGINT, SIGTERM or SIGHUP.
std::stop_token interrupt_token();

/// `s` with control characters, invalid UTF-8 and invisible characters (byte-order
/// mark, zero-width and bidirectional marks) escaped as \xNN or \uNNNN, so that
/// text taken from an input file or the command line prints as what it is.
std::string printable(const std::string& s);

/// A finite real number in [lo, hi]; with `lo_open`, in (lo, hi]. Rejects NaN and Inf
/// (which pass CLI::Range: every comparison with NaN is false).
inline CLI::Validator real(double lo, double hi, bool lo_open = false) {
    char desc[96];
    if (hi == std::numeric_limits<double>::max() && lo_open && lo == 0)
        std::snprintf(desc, sizeof desc, "positive finite number");
    else if (hi == std::numeric_limits<double>::max())
        std::snprintf(desc, sizeof desc, "finite number %s %.6g", lo_open ? ">" : ">=", lo);
    else
        std::snprintf(desc, sizeof desc, "number in %c%.6g, %.6g]", lo_open ? '(' : '[', lo, hi);
    const std::string d = desc;
    return CLI::Validator(
        [lo, hi, lo_open, d](std::string& in) -> std::string {
            const char* b = in.c_str();
            char* e = nullptr;
            errno = 0;
            const double v = std::strtod(b, &e);
            const bool whole = e != b && *e == '\0';
            if (!whole || !std::isfinite(v) || (lo_open ? !(v > lo) : !(v >= lo)) || !(v <= hi))
                return "must be a " + d + ", got '" + in + "'";
            return {};
        },
        d);
}

/// A whole number in [lo, hi] written in decimal digits: "-1" is refused (it would
/// wrap to 2^64 - 1 in an unsigned option), as are "1e3", "0x10" and "nan".
inline CLI::Validator count(std::uint64_t lo, std::uint64_t hi) {
    const std::string d = hi == std::numeric_limits<std::uint64_t>::max()
                              ? "whole number >= " + std::to_string(lo)
                              : "whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return CLI::Validator(
        [lo, hi, d](std::string& in) -> std::string {
            std::uint64_t v = 0;
            const char* b = in.data() + (in.size() > 1 && in[0] == '+' ? 1 : 0);
            const char* e = in.data() + in.size();
            const auto r = std::from_chars(b, e, v);
            if (r.ec != std::errc() || r.ptr != e || b == e || v < lo || v > hi)
                return "must be a " + d + ", got '" + in + "'";
            return {};
        },
        d);
}

/// A small ordered JSON value (objects keep insertion order).
class Json {
public:
    using Object = std::vector<std::pair<std::string, Json>>;
    using Array = std::vector<Json>;

    Json() : v_(nullptr) {}
    Json(std::nullptr_t) : v_(nullptr) {}
    Json(bool b) : v_(b) {}
    Json(double d) : v_(d) {}
    Json(int i) : v_(static_cast<std::int64_t>(i)) {}
    Json(long i) : v_(static_cast<std::int64_t>(i)) {}
    Json(long long i) : v_(static_cast<std::int64_t>(i)) {}
    Json(unsigned i) : v_(static_cast<std::uint64_t>(i)) {}
    Json(unsigned long i) : v_(static_cast<std::uint64_t>(i)) {}
    Json(unsigned long long i) : v_(static_cast<std::uint64_t>(i)) {}
    Json(const char* s) : v_(std::string(s)) {}
    Json(std::string s) : v_(std::move(s)) {}
    Json(Array a) : v_(std::move(a)) {}

    static Json object() {
        Json j;
        j.v_ = Object{};
        return j;
    }
    /// Object member access; inserts (in order) when missing.
    Json& operator[](const std::string& key) {
        if (!std::holds_alternative<Object>(v_)) v_ = Object{};
        auto& obj = std::get<Object>(v_);
        for (auto& [k, v] : obj)
            if (k == key) return v;
        obj.emplace_back(key, Json());
        return obj.back().second;
    }
    [[nodiscard]] std::string dump() const {
        std::ostringstream os;
        write(os);
        return os.str();
    }

private:
    static void write_string(std::ostringstream& os, const std::string& s) {
        os << '"';
        for (const char c : s) {
            switch (c) {
                case '"': os << "\\\""; break;
                case '\\': os << "\\\\"; break;
                case '\n': os << "\\n"; break;
                case '\t': os << "\\t"; break;
                case '\r': os << "\\r"; break;
                default:
                    if (static_cast<unsigned char>(c) < 0x20) {
                        char buf[8];
                        std::snprintf(buf, sizeof buf, "\\u%04x", c);
                        os << buf;
                    } else {
                        os << c;
                    }
            }
        }
        os << '"';
    }
    void write(std::ostringstream& os) const {
        if (std::holds_alternative<std::nullptr_t>(v_)) {
            os << "null";
        } else if (const bool* b = std::get_if<bool>(&v_)) {
            os << (*b ? "true" : "false");
        } else if (const double* d = std::get_if<double>(&v_)) {
            if (!std::isfinite(*d)) {
                os << "null";
            } else {
                char buf[32];
                std::snprintf(buf, sizeof buf, "%.9g", *d);
                os << buf;
            }
        } else if (const auto* i = std::get_if<std::int64_t>(&v_)) {
            os << *i;
        } else if (const auto* u = std::get_if<std::uint64_t>(&v_)) {
            os << *u;
        } else if (const auto* s = std::get_if<std::string>(&v_)) {
            write_string(os, *s);
        } else if (const auto* a = std::get_if<Array>(&v_)) {
            os << '[';
            for (std::size_t k = 0; k < a->size(); ++k) {
                if (k) os << ", ";
                (*a)[k].write(os);
            }
            os << ']';
        } else if (const auto* o = std::get_if<Object>(&v_)) {
            os << '{';
            for (std::size_t k = 0; k < o->size(); ++k) {
                if (k) os << ", ";
                write_string(os, (*o)[k].first);
                os << ": ";
                (*o)[k].second.write(os);
            }
            os << '}';
        }
    }
    std::variant<std::nullptr_t, bool, double, std::int64_t, std::uint64_t, std::string, Array, Object> v_;
};

/// Options shared by every subcommand.
struct CommonOptions {
    bool json = false;
    int threads = 0;  // 0: all cores
    std::uint64_t seed = 0;
    bool quiet = false;
};

/// Per-run context handed to each subcommand.
class Context {
public:
    CommonOptions common;

    /// The JSON object printed on stdout with --json.
    Json& json() { return json_; }

    /// A RunControl that draws a progress bar on stderr (when it is a terminal
    /// and neither --quiet nor --json) and cancels on Ctrl-C / SIGTERM.
    kintsugi::RunControl control(const std::string& label);
    /// Throws kcli::interrupted when a stop was requested (Ctrl-C, SIGTERM).
    void check_interrupted() const;
    /// Says what runs now (e.g. "smoothing 3,674 faces of bunny.off"), for the
    /// message when memory runs out.
    void doing(std::string what) { doing_ = std::move(what); }
    [[nodiscard]] const std::string& doing() const { return doing_; }

    /// Checks before any input is read that `path` can be written as `kind`
    /// (extension, directory, permissions, name length); throws io_error otherwise.
    void check_output(const std::string& path, kintsugi::OutputKind kind) const;
    /// Write options for every output file: interrupted by Ctrl-C, and batched so that
    /// the files appear only once the whole command has succeeded (commit_outputs).
    kintsugi::WriteOptions write_options();
    /// Renames the outputs written so far into place (main calls it after the action).
    void commit_outputs();

    /// Prints a human-readable line on stdout unless --quiet or --json.
    void info(const std::string& line) const;
    /// Prints a notice on stderr unless --quiet.
    void notice(const std::string& line) const;
    /// Records stage timings under "timings" in the JSON output.
    void add_timings(const std::vector<kintsugi::StageTiming>& t, const std::string& prefix = "");
    /// Records one timing.
    void add_timing(const std::string& stage, double seconds);

    /// Ends the progress line, if one is drawn.
    void end_progress();

private:
    Json json_ = Json::object();
    bool progress_drawn_ = false;
    std::string doing_;
    kintsugi::OutputBatch outputs_{interrupt_token()};
};

/// Wall-clock stopwatch in seconds.
class Stopwatch {
public:
    Stopwatch() : start_(std::chrono::steady_clock::now()) {}
    [[nodiscard]] double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }

private:
    std::chrono::steady_clock::time_point start_;
};

/// What a subcommand does once the command line is parsed (with --threads applied).
using Action = std::function<void()>;
/// Declares a subcommand's options and returns its action.
using SetupFn = Action (*)(CLI::App& cmd, Context& ctx);
struct CommandEntry {
    std::string name;
    std::string description;
    SetupFn setup;
};
/// All registered subcommands, sorted by name when the tool starts.
std::vector<CommandEntry>& registry();
bool register_command(const char* name, const char* description, SetupFn setup);

// The readers and writers, compiled once in io.cpp (about 10 s of CPU per
// translation unit that calls them at -O3): a command's file holds its method only.
kintsugi::IndexedMesh read_mesh(const std::string& path, kintsugi::ReadInfo* info = nullptr);
kintsugi::PointCloud read_point_cloud(const std::string& path, kintsugi::ReadInfo* info = nullptr);
void write_mesh(const std::string& path, const kintsugi::IndexedMesh& mesh, const kintsugi::WriteOptions& options);
void write_point_cloud(const std::string& path, const kintsugi::PointCloud& cloud,
                       const kintsugi::WriteOptions& options);
void write_polylines(const std::string& path, const std::vector<kintsugi::Vec3>& points,
                     const std::vector<std::array<kintsugi::Index, 2>>& edges, const kintsugi::WriteOptions& options);

/// `n` with thousands separators (1,234,567), for messages.
inline std::string grouped(std::size_t n) {
    const std::string digits = std::to_string(n);
    std::string out;
    for (std::size_t i = 0; i < digits.size(); ++i) {
        if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

}  // namespace kcli

#define KINTSUGI_REGISTER_COMMAND(name, description, setup) \
    static const bool kintsugi_command_registered_##name = ::kcli::register_command(#name, description, setup);
