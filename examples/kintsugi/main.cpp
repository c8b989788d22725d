// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The `kintsugi` command-line tool: subcommands register themselves in
// cmd_*.cpp (see common.hpp).
#include "common.hpp"

#include <kintsugi/core/error.hpp>
#include <kintsugi/core/memory.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <new>
#include <pthread.h>
#include <string_view>
#include <thread>
#include <unistd.h>

#ifndef KINTSUGI_VERSION_STRING
#define KINTSUGI_VERSION_STRING "0.1.0"
#endif

namespace kcli {
namespace {

// Signals: SIGINT, SIGTERM and SIGHUP are blocked in every thread and taken by one
// watcher thread (sigwait), which requests a stop on the run's stop token: the
// algorithms poll it and return Status::cancelled, a write under way throws, and main
// exits with 128 + the signal, nothing written. If the run has not ended 3 s later, or
// on a second signal, the watcher removes the temporary output files itself and exits.
std::stop_source g_stop;
std::atomic<int> g_signal{0};
std::atomic<bool> g_done{false};
constexpr int kWakeSignal = SIGUSR1;  // main -> watcher: the run is over
constexpr double kGraceSeconds = 3.0;

sigset_t watched_signals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGHUP);
    sigaddset(&set, kWakeSignal);
    return set;
}

const char* signal_name(int sig) {
    switch (sig) {
        case SIGINT: return "SIGINT";
        case SIGTERM: return "SIGTERM";
        case SIGHUP: return "SIGHUP";
        default: return "a signal";
    }
}

void watch_signals() {
    const sigset_t set = watched_signals();
    int sig = 0;
    for (;;) {
        if (sigwait(&set, &sig) != 0) continue;
        if (sig == kWakeSignal) {
            if (g_done) return;
            continue;
        }
        break;
    }
    g_signal = sig;
    g_stop.request_stop();
    timespec end{};
    clock_gettime(CLOCK_MONOTONIC, &end);
    end.tv_sec += static_cast<time_t>(kGraceSeconds);
    for (;;) {
        timespec now{};
        clock_gettime(CLOCK_MONOTONIC, &now);
        long long left_ns = (static_cast<long long>(end.tv_sec) - now.tv_sec) * 1000000000LL + (end.tv_nsec - now.tv_nsec);
        if (left_ns <= 0) break;
        const timespec left{static_cast<time_t>(left_ns / 1000000000LL), static_cast<long>(left_ns % 1000000000LL)};
        const int s = sigtimedwait(&set, nullptr, &left);
        if (s == kWakeSignal && g_done) return;
        if (s == SIGINT || s == SIGTERM || s == SIGHUP) break;
        if (s < 0 && errno == EAGAIN) break;
    }
    kintsugi::remove_temporary_outputs();
    std::fprintf(stderr, "\nkintsugi: interrupted by %s; stopped without writing any output\n", signal_name(g_signal));
    std::fflush(stderr);
    ::_exit(128 + g_signal);
}

/// Starts the watcher; on destruction tells it the run is over and joins it.
class SignalWatcher {
public:
    SignalWatcher() {
        const sigset_t set = watched_signals();
        pthread_sigmask(SIG_BLOCK, &set, nullptr);  // before any other thread exists
        thread_ = std::thread(watch_signals);
    }
    ~SignalWatcher() {
        g_done = true;
        pthread_kill(thread_.native_handle(), kWakeSignal);
        thread_.join();
    }
    SignalWatcher(const SignalWatcher&) = delete;
    SignalWatcher& operator=(const SignalWatcher&) = delete;

private:
    std::thread thread_;
};

void append_utf8_escape(std::string& out, unsigned cp) {
    char buf[12];
    std::snprintf(buf, sizeof buf, "\\u%04X", cp);
    out += buf;
}

}  // namespace

std::stop_token interrupt_token() { return g_stop.get_token(); }

std::string printable(const std::string& s) {
    std::string out;
    out.reserve(s.size());
    const auto* p = reinterpret_cast<const unsigned char*>(s.data());
    const std::size_t n = s.size();
    for (std::size_t i = 0; i < n;) {
        const unsigned c = p[i];
        if (c < 0x80) {
            if (c < 0x20 || c == 0x7f) {
                char buf[8];
                std::snprintf(buf, sizeof buf, "\\x%02X", c);
                out += buf;
            } else {
                out += static_cast<char>(c);
            }
            ++i;
            continue;
        }
        // A well-formed UTF-8 sequence (no overlong forms, no surrogates) is kept unless it
        // encodes an invisible or control character; any other byte is shown as \xNN.
        std::size_t len = c >= 0xc2 && c <= 0xdf ? 2 : c >= 0xe0 && c <= 0xef ? 3 : c >= 0xf0 && c <= 0xf4 ? 4 : 0;
        unsigned cp = len == 2 ? c & 0x1f : len == 3 ? c & 0x0f : c & 0x07;
        bool ok = len > 0 && i + len <= n;
        for (std::size_t k = 1; ok && k < len; ++k) {
            ok = (p[i + k] & 0xc0) == 0x80;
            cp = (cp << 6) | (p[i + k] & 0x3f);
        }
        if (ok && ((len == 3 && (cp < 0x800 || (cp >= 0xd800 && cp <= 0xdfff))) || (len == 4 && (cp < 0x10000 || cp > 0x10ffff))))
            ok = false;
        if (!ok) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02X", c);
            out += buf;
            ++i;
            continue;
        }
        const bool invisible = (cp >= 0x80 && cp <= 0x9f) || cp == 0xad || (cp >= 0x200b && cp <= 0x200f) ||
                               (cp >= 0x2028 && cp <= 0x202e) || (cp >= 0x2060 && cp <= 0x2069) || cp == 0xfeff;
        if (invisible)
            append_utf8_escape(out, cp);
        else
            out.append(s, i, len);
        i += len;
    }
    return out;
}

std::vector<CommandEntry>& registry() {
    static std::vector<CommandEntry> r;
    return r;
}

bool register_command(const char* name, const char* description, SetupFn setup) {
    registry().push_back({name, description, setup});
    return true;
}

kintsugi::RunControl Context::control(const std::string& label) {
    kintsugi::RunControl rc;
    rc.stop = g_stop.get_token();
    const bool draw = !common.quiet && !common.json && ::isatty(2);
    if (draw)
        rc.progress = [this, label](const kintsugi::ProgressEvent& e) {
            const int width = 30;
            const int filled = static_cast<int>(std::clamp(e.fraction, 0.0, 1.0) * width + 0.5);
            std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% %-24.24s", label.c_str(), filled,
                         "##############################", width - filled, "",
                         static_cast<int>(e.fraction * 100 + 0.5), std::string(e.stage).c_str());
            std::fflush(stderr);
            progress_drawn_ = true;
            return true;
        };
    return rc;
}

void Context::check_interrupted() const {
    if (g_stop.stop_requested()) throw interrupted();
}

void Context::check_output(const std::string& path, kintsugi::OutputKind kind) const {
    kintsugi::check_writable(path, kind);
}

kintsugi::WriteOptions Context::write_options() {
    kintsugi::WriteOptions w;
    w.batch = &outputs_;
    return w;
}

void Context::commit_outputs() {
    check_interrupted();
    outputs_.commit();
}

void Context::end_progress() {
    if (progress_drawn_) {
        std::fprintf(stderr, "\n");
        progress_drawn_ = false;
    }
}

void Context::info(const std::string& line) const {
    if (!common.quiet && !common.json) std::cout << line << '\n';
}

void Context::notice(const std::string& line) const {
    if (!common.quiet) std::cerr << "kintsugi: " << printable(line) << '\n';
}

void Context::add_timings(const std::vector<kintsugi::StageTiming>& t, const std::string& prefix) {
    for (const auto& s : t) add_timing(prefix + s.stage, s.seconds);
}

void Context::add_timing(const std::string& stage, double seconds) { json_["timings"][stage] = seconds; }

}  // namespace kcli

int main(int argc, char** argv) {
    // Large inputs: glibc's allocator keeps freed memory for later stages (re-executes once;
    // core/memory.hpp).
    kintsugi::use_kept_heap_malloc(argv);
    using namespace kcli;
    const SignalWatcher watcher;

    CLI::App app{"kintsugi: repair and rebuild scanned 3D geometry", "kintsugi"};
    app.set_version_flag("--version", KINTSUGI_VERSION_STRING);
    app.require_subcommand(1);

    Context ctx;
    std::vector<std::pair<CLI::App*, Action>> actions;
    auto& cmds = registry();
    std::sort(cmds.begin(), cmds.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
    for (const auto& c : cmds) {
        CLI::App* sub = app.add_subcommand(c.name, c.description);
        sub->add_flag("--json", ctx.common.json, "Print one JSON object on stdout (parameters, counts, timings)");
        sub->add_option("--threads", ctx.common.threads, "Worker threads (0 = all cores)")->check(count(0, 1024));
        sub->add_option("--seed", ctx.common.seed, "Seed for every random choice")->check(count(0, UINT64_MAX));
        sub->add_flag("--quiet,-q", ctx.common.quiet, "Print nothing but errors (and --json output)");
        actions.emplace_back(sub, c.setup(*sub, ctx));
    }

    try {
        try {
            app.parse(argc, argv);
        } catch (const CLI::CallForHelp& e) {
            return app.exit(e);
        } catch (const CLI::CallForAllHelp& e) {
            return app.exit(e);
        } catch (const CLI::CallForVersion& e) {
            return app.exit(e);
        } catch (const CLI::ParseError& e) {
            // Parse errors (unknown option, missing argument, bad value) are usage errors.
            std::cerr << "kintsugi: usage error: " << printable(e.what()) << "\n"
                      << "Run 'kintsugi --help' or 'kintsugi <command> --help'.\n";
            return 2;
        }
        const kintsugi::ThreadLimit limit(ctx.common.threads);
        ctx.json()["kept_heap_malloc"] = kintsugi::kept_heap_malloc_on();  // use_kept_heap_malloc above
        for (auto& [sub, action] : actions)
            if (sub->parsed()) {
                action();
                ctx.commit_outputs();
            }
    } catch (const usage_error& e) {
        ctx.end_progress();
        std::cerr << "kintsugi: usage error: " << printable(e.what()) << '\n';
        return 2;
    } catch (const std::bad_alloc&) {
        ctx.end_progress();
        std::cerr << "kintsugi: error: out of memory"
                  << (ctx.doing().empty() ? std::string() : " while " + printable(ctx.doing()))
                  << "; nothing written (the input may be too large for this machine, or an option asks for "
                     "too much)\n";
        return 1;
    } catch (const kintsugi::invalid_input& e) {
        ctx.end_progress();
        // The library names the function and the element; say which file it was about.
        std::cerr << "kintsugi: error: " << printable(e.what())
                  << (ctx.doing().empty() || std::string_view(e.what()).substr(0, 10) != "kintsugi::"
                          ? std::string()
                          : " (while " + printable(ctx.doing()) + ")")
                  << '\n';
        return 1;
    } catch (const std::exception& e) {
        ctx.end_progress();
        if (const int sig = g_signal.load()) {
            std::cerr << "kintsugi: interrupted by " << signal_name(sig) << "; nothing written\n";
            return 128 + sig;
        }
        std::cerr << "kintsugi: error: " << printable(e.what()) << '\n';
        return 1;
    }
    ctx.end_progress();
    if (ctx.common.json) std::cout << ctx.json().dump() << '\n';
    return 0;
}
