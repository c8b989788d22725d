// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file control.hpp
/// @brief Progress, cancellation, status and timing shared by every algorithm.
///
/// Every Params aggregate has a `RunControl control` member. The progress callback
/// runs on the calling thread, at most about 100 times per run; returning `false`
/// from it cancels the run, as does a stop request on `stop`. One rule for every
/// algorithm: on cancel the inputs are untouched and the result's
/// `status == Status::cancelled`.

#include <algorithm>
#include <chrono>
#include <functional>
#include <stop_token>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace kintsugi {

/// Outcome of a run.
enum class Status {
    ok,         ///< finished; the output is complete
    cancelled,  ///< stopped through RunControl; inputs untouched, output empty
};

/// Text form of a Status ("ok", "cancelled").
[[nodiscard]] inline std::string_view to_string(Status s) {
    switch (s) {
        case Status::ok: return "ok";
        case Status::cancelled: return "cancelled";
    }
    return "unknown";
}

/// What the progress callback receives.
struct ProgressEvent {
    std::string_view stage;  ///< name of the running stage, e.g. "octree"
    double fraction = 0.0;   ///< overall progress in [0, 1]
};

/// Progress reporting and cancellation for one run.
struct RunControl {
    /// Called on the calling thread; return false to cancel. May be empty.
    std::function<bool(const ProgressEvent&)> progress = {};
    /// A stop request on this token cancels the run. Default: no stop possible.
    std::stop_token stop = {};
};

/// Wall-clock time of one stage, in seconds.
struct StageTiming {
    std::string stage;
    double seconds = 0.0;
};

namespace detail {

/// Thrown inside an algorithm when the run is cancelled; caught at the API
/// boundary and turned into Status::cancelled. Never escapes a public function.
struct cancelled_exception {};

/// Helper an algorithm uses to report progress, check for cancellation and
/// time its stages. Calls the user callback at most ~100 times per run.
class Progress {
public:
    explicit Progress(const RunControl& control) : control_(control) {}

    /// Starts a stage covering [begin, end) of the overall fraction.
    void stage(std::string_view name, double begin, double end) {
        finish_stage();
        name_ = std::string(name);
        begin_ = begin;
        end_ = end;
        start_ = Clock::now();
        report(0.0, true);
    }

    /// Reports progress within the current stage (local in [0, 1]) and throws
    /// cancelled_exception when the run has been cancelled. Cheap to call often.
    void update(double local) { report(local, false); }

    /// Throws cancelled_exception when cancelled; does not call the callback.
    void check() const {
        if (control_.stop.stop_requested()) throw cancelled_exception{};
    }

    /// The run's stop token, for helpers that poll it themselves.
    [[nodiscard]] const std::stop_token& stop() const { return control_.stop; }

    /// Ends the current stage and returns all timings so far.
    std::vector<StageTiming> finish() {
        finish_stage();
        report_raw("done", 1.0);
        return timings_;
    }

private:
    using Clock = std::chrono::steady_clock;

    void finish_stage() {
        if (name_.empty()) return;
        timings_.push_back({name_, std::chrono::duration<double>(Clock::now() - start_).count()});
        name_.clear();
    }
    void report(double local, bool force) {
        check();
        const double overall = begin_ + (end_ - begin_) * std::clamp(local, 0.0, 1.0);
        if (!force && overall < last_ + 0.01) return;
        report_raw(name_, overall);
    }
    void report_raw(std::string_view name, double overall) {
        last_ = overall;
        if (control_.progress && !control_.progress(ProgressEvent{name, overall}))
            throw cancelled_exception{};
    }

    const RunControl& control_;
    std::string name_;
    double begin_ = 0.0, end_ = 0.0, last_ = -1.0;
    Clock::time_point start_{};
    std::vector<StageTiming> timings_;
};

/// The result of a cancelled run: `Result{}` with status Status::cancelled.
template <class Result>
[[nodiscard]] Result cancelled_result() {
    Result r{};
    r.status = Status::cancelled;
    return r;
}

/// Forwards a part's progress into [a, b] of the whole run, at most once per 1 % of
/// the run (`last`: the last fraction forwarded, shared by the parts); the parts' own
/// "done" is dropped (the caller reports the whole run's). `outer` and `last` must
/// outlive the returned control.
inline RunControl part_control(const RunControl& outer, double a, double b, double& last) {
    RunControl c;
    c.stop = outer.stop;
    if (outer.progress)
        c.progress = [&outer, a, b, &last](const ProgressEvent& e) {
            const double f = a + (b - a) * e.fraction;
            if (e.stage == "done" || f < last + 0.01) return true;
            last = f;
            return outer.progress(ProgressEvent{e.stage, f});
        };
    return c;
}

/// Runs `body(progress)`, `progress` reporting to `control`, and returns its result; when the
/// run is cancelled inside (cancelled_exception), returns `Result{}` with status cancelled.
/// The one place where an algorithm's cancellation becomes its Status.
template <class Result, class Body>
Result run_cancellable(const RunControl& control, Body&& body) {
    Progress progress(control);
    try {
        return std::forward<Body>(body)(progress);
    } catch (const cancelled_exception&) {
        return cancelled_result<Result>();
    }
}

}  // namespace detail
}  // namespace kintsugi
