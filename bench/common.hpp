// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file common.hpp
/// @brief What every bench/bench_*.cpp shares: a console reporter that keeps each
/// run so that a summary printed at the end can put kintsugi and its peer (measured
/// in the same run) side by side as ratios, the peak resident set size, and a main().
///
/// @code
/// int main(int argc, char** argv) {
///     return kintsugi::bench::run(argc, argv, [](const kintsugi::bench::RatioReporter& r) {
///         r.print_ratio("BM_kintsugi_build", "BM_cgal_build");
///     });
/// }
/// @endcode

#include <benchmark/benchmark.h>

#include <kintsugi/core/memory.hpp>

#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi::bench {

/// Which allocator this run uses, for a summary (benchmarks that call use_kept_heap_malloc).
inline const char* allocator_description() {
    return kept_heap_malloc_on() ? "glibc keeping freed memory (use_kept_heap_malloc)"
                                 : "default (KINTSUGI_DEFAULT_MALLOC set, or not Linux/glibc)";
}

/// Peak resident set size of this process so far (VmHWM), in MB; 0 when unknown.
inline double peak_rss_mb() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    return 0;
}

/// Resets the peak resident set (VmHWM) to the present one (Linux: /proc/self/clear_refs,
/// "5"), so that peak_rss_mb() then gives the peak of what follows: per-stage peaks.
/// Returns false when the kernel does not allow it.
inline bool reset_peak_rss() {
    std::ofstream out("/proc/self/clear_refs");
    out << "5";
    out.flush();
    return static_cast<bool>(out);
}

/// Console output as usual, plus a summary callback at the end that reads the runs
/// back by name (to print ratios against a peer measured in the same run).
class RatioReporter : public benchmark::ConsoleReporter {
public:
    using Summary = std::function<void(const RatioReporter&)>;

    explicit RatioReporter(Summary summary = {}) : summary_(std::move(summary)) {}

    void ReportRuns(const std::vector<Run>& runs) override {
        for (const Run& r : runs)
            if (!r.error_occurred) runs_.insert_or_assign(r.benchmark_name(), r);
        ConsoleReporter::ReportRuns(runs);
    }
    void Finalize() override {
        ConsoleReporter::Finalize();
        if (summary_) summary_(*this);
        std::fflush(stdout);
    }

    /// The first successful run (in name order) called `name` exactly or `name/...`
    /// (so "BM_a" matches "BM_a/iterations:3" but not "BM_ab"); nullptr when none.
    [[nodiscard]] const Run* find(const std::string& name) const {
        for (auto it = runs_.lower_bound(name); it != runs_.end() && it->first.rfind(name, 0) == 0; ++it)
            if (it->first.size() == name.size() || it->first[name.size()] == '/') return &it->second;
        return nullptr;
    }
    /// Real time per iteration of `name` (in its benchmark's time unit); -1 when absent.
    [[nodiscard]] double real(const std::string& name) const {
        const Run* r = find(name);
        return r ? r->GetAdjustedRealTime() : -1;
    }
    /// CPU time (of the calling thread) per iteration of `name`; -1 when absent.
    [[nodiscard]] double cpu(const std::string& name) const {
        const Run* r = find(name);
        return r ? r->GetAdjustedCPUTime() : -1;
    }
    /// User counter `counter` of run `name`; NaN when either is absent.
    [[nodiscard]] double counter(const std::string& name, const std::string& counter) const {
        const Run* r = find(name);
        if (!r) return std::numeric_limits<double>::quiet_NaN();
        const auto it = r->counters.find(counter);
        return it == r->counters.end() ? std::numeric_limits<double>::quiet_NaN() : double(it->second.value);
    }
    /// Prints one line "ours  t  peer  t  ratio (peer / kintsugi)" with real times;
    /// nothing when either run is missing (skipped or failed).
    void print_ratio(const std::string& ours, const std::string& peer, const char* unit = "ms") const {
        print(ours, real(ours), peer, real(peer), unit, "");
    }
    /// Same with CPU times (of the benchmark's thread): steadier than real time on a
    /// loaded machine, meaningful for single-threaded runs only.
    void print_cpu_ratio(const std::string& ours, const std::string& peer, const char* unit = "ms") const {
        print(ours, cpu(ours), peer, cpu(peer), unit, " CPU");
    }

private:
    static void print(const std::string& ours, double a, const std::string& peer, double b, const char* unit,
                      const char* what) {
        if (a > 0 && b > 0)
            std::printf("  %-34s %9.1f %s%s   %-32s %9.1f %s%s   ratio (peer / kintsugi) %.2fx\n", ours.c_str(), a,
                        unit, what, peer.c_str(), b, unit, what, b / a);
    }

public:

private:
    Summary summary_;
    std::map<std::string, Run> runs_;
};

/// The body of every benchmark main(): initialise, run with a RatioReporter that
/// calls `summary` at the end, shut down. Returns the process exit code.
inline int run(int argc, char** argv, RatioReporter::Summary summary = {}) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    RatioReporter reporter(std::move(summary));
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();
    return 0;
}

}  // namespace kintsugi::bench
