// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The `kintsugi` command-line tool: subcommands register themselves in
// cmd_*.cpp (see common.hpp).
#include "common.hpp"

#include <kintsugi/core/error.hpp>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <unistd.h>

#ifndef KINTSUGI_VERSION_STRING
#define KINTSUGI_VERSION_STRING "0.1.0"
#endif

namespace kcli {
namespace {
volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_sigint(int) { g_interrupted = 1; }
}  // namespace

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
    const bool draw = !common.quiet && !common.json && ::isatty(2);
    rc.progress = [this, draw, label](const kintsugi::ProgressEvent& e) {
        if (g_interrupted) return false;
        if (draw) {
            const int width = 30;
            const int filled = static_cast<int>(std::clamp(e.fraction, 0.0, 1.0) * width + 0.5);
            std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% %-24.24s", label.c_str(), filled,
                         "##############################", width - filled, "",
                         static_cast<int>(e.fraction * 100 + 0.5), std::string(e.stage).c_str());
            std::fflush(stderr);
            progress_drawn_ = true;
        }
        return true;
    };
    return rc;
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
    if (!common.quiet) std::cerr << "kintsugi: " << line << '\n';
}

void Context::add_timings(const std::vector<kintsugi::StageTiming>& t, const std::string& prefix) {
    for (const auto& s : t) add_timing(prefix + s.stage, s.seconds);
}

void Context::add_timing(const std::string& stage, double seconds) { json_["timings"][stage] = seconds; }

}  // namespace kcli

int main(int argc, char** argv) {
    using namespace kcli;
    std::signal(SIGINT, on_sigint);

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
        sub->add_option("--threads", ctx.common.threads, "Worker threads (0 = all cores)")
            ->check(CLI::Range(0, 1024));
        sub->add_option("--seed", ctx.common.seed, "Seed for every random choice");
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
            std::cerr << "kintsugi: usage error: " << e.what() << "\n"
                      << "Run 'kintsugi --help' or 'kintsugi <command> --help'.\n";
            return 2;
        }
        const kintsugi::ThreadLimit limit(ctx.common.threads);
        for (auto& [sub, action] : actions)
            if (sub->parsed()) action();
    } catch (const usage_error& e) {
        ctx.end_progress();
        std::cerr << "kintsugi: usage error: " << e.what() << '\n';
        return 2;
    } catch (const std::exception& e) {
        ctx.end_progress();
        std::cerr << "kintsugi: error: " << e.what() << '\n';
        return 1;
    }
    ctx.end_progress();
    if (ctx.common.json) std::cout << ctx.json().dump() << '\n';
    return 0;
}
