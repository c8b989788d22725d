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
// Inside the callback: `ctx.control("stage label")` gives a RunControl with the
// progress bar and Ctrl-C cancellation; `ctx.json()` is the JSON object printed
// on stdout when --json is given; `ctx.info(...)` prints a human line unless
// --quiet or --json; write output files last (kintsugi writers are atomic).
// Errors: throw (kintsugi::invalid_input, io_error, kcli::usage_error or any
// std::exception): main prints `kintsugi: error: <message>` and exits 1
// (2 for usage errors).

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/parallel.hpp>

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace kcli {

/// Bad command-line usage detected after parsing (exit code 2).
struct usage_error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

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
    Json(unsigned i) : v_(static_cast<std::int64_t>(i)) {}
    Json(unsigned long i) : v_(static_cast<std::int64_t>(i)) {}
    Json(unsigned long long i) : v_(static_cast<std::int64_t>(i)) {}
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
    std::variant<std::nullptr_t, bool, double, std::int64_t, std::string, Array, Object> v_;
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
    /// and neither --quiet nor --json) and cancels on Ctrl-C.
    kintsugi::RunControl control(const std::string& label);

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

/// Throws kcli::usage_error when `value` is outside [lo, hi].
template <class T>
void require_range(const char* option, T value, T lo, T hi) {
    if (value < lo || value > hi) {
        std::ostringstream os;
        os << option << " must be in [" << lo << ", " << hi << "], got " << value;
        throw usage_error(os.str());
    }
}

}  // namespace kcli

#define KINTSUGI_REGISTER_COMMAND(name, description, setup) \
    static const bool kintsugi_command_registered_##name = ::kcli::register_command(#name, description, setup);
