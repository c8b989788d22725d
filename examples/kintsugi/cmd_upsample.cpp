// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi upsample IN OUT (--radius R | --radius-rel F) [--adaptive EPS] [--levels L]`:
// fill every gap between surfels at the given radius (kintsugi::fill_surfel_gaps).
// IN: oriented points or surfels (a PLY `radius` vertex property is read; points without
// one take the given radius). OUT: PLY (or any point format) with a `radius` property.
#include "common.hpp"

#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>
#include <kintsugi/upsample/surfel_fill.hpp>

#include <limits>
#include <memory>
#include <string>

namespace {

struct UpsampleOptions {
    std::string input, output;
    kintsugi::SurfelFillParams params;  // the library's defaults
};

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<UpsampleOptions>();
    auto& p = o->params;
    cmd.add_option("input", o->input, "Oriented points or surfels (PLY with radius, XYZ/PWN with normals, ...)")
        ->required();
    cmd.add_option("output", o->output, "Surfels to write (PLY: x y z nx ny nz radius)")->required();
    const auto positive = kcli::real(0.0, std::numeric_limits<double>::max(), true);
    auto* r = cmd.add_option("--radius", p.radius, "Radius of the new surfels, model units")->check(positive);
    auto* rr = cmd.add_option("--radius-rel", p.radius_rel, "Radius as a fraction of the bounding-box diagonal")
                   ->check(kcli::real(0.0, 1.0, true));
    r->excludes(rr);
    rr->excludes(r);
    cmd.add_option("--adaptive", p.epsilon_r, "Curvature-adaptive radii r = EPS / sqrt(curvature), at most the radius")
        ->check(positive);
    cmd.add_option("--levels", p.levels, "Levels of detail (each halves the radius), stored coarse to fine")
        ->capture_default_str()
        ->check(kcli::count(1, 16));
    cmd.add_option("--max-iterations", p.max_iterations, "Most rounds per level")
        ->capture_default_str()
        ->check(kcli::count(1, 1000));
    return [o, &ctx] {
        if (o->params.radius == 0 && o->params.radius_rel == 0)
            throw kcli::usage_error("give the radius: --radius R (model units) or --radius-rel F (of the diagonal)");
        ctx.check_output(o->output, kintsugi::OutputKind::point_cloud);
        kcli::Stopwatch sw;
        ctx.doing("reading " + o->input);
        const kintsugi::PointCloud cloud = kintsugi::read_point_cloud(o->input);
        ctx.add_timing("read", sw.seconds());
        if (!kintsugi::has_normals(cloud))
            throw kintsugi::invalid_input(o->input + " has no normals; surfels need them (kintsugi normals IN OUT first)");

        kintsugi::SurfelFillParams params = o->params;
        params.control = ctx.control("upsample");
        ctx.doing("filling the gaps between " + kcli::grouped(cloud.points.size()) + " surfels of " + o->input);
        const kintsugi::SurfelFillResult r = kintsugi::fill_surfel_gaps(cloud, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw kcli::interrupted();
        ctx.add_timings(r.timings);

        sw = kcli::Stopwatch();
        ctx.doing("writing " + o->output);
        kintsugi::write_point_cloud(o->output, r.surfels, ctx.write_options());
        ctx.add_timing("write", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "upsample";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["radius"] = r.radius;
        j["parameters"]["adaptive"] = o->params.epsilon_r;
        j["parameters"]["levels"] = o->params.levels;
        j["input_surfels"] = r.input_surfels;
        j["input_had_radii"] = kintsugi::has_radii(cloud);
        j["duplicates_removed"] = r.duplicates_removed;
        j["surfels"] = r.surfels.points.size();
        j["new_surfels"] = r.surfels.points.size() - r.input_surfels;
        kcli::Json::Array levels;
        for (std::size_t c : r.level_counts) levels.emplace_back(c);
        j["level_counts"] = levels;
        j["rounds"] = r.rounds;
        j["not_placed"] = r.not_placed;
        j["coverage_verified"] = r.coverage_verified;
        // Indices into OUT of the surfels whose boundary keeps an uncovered arc (empty
        // exactly when coverage_verified): an open border, a rim, a sharp crease.
        kcli::Json::Array uncovered;
        for (std::size_t i : r.uncovered_surfels) uncovered.emplace_back(i);
        j["uncovered_surfels"] = uncovered;
        ctx.info("filled " + kcli::grouped(r.input_surfels) + " surfels to " + kcli::grouped(r.surfels.points.size()) +
                 " (radius " + kintsugi::detail::format_number(r.radius) + ", " + std::to_string(o->params.levels) +
                 " level(s), coverage " + (r.coverage_verified ? "verified" : "not verified: open border or rim") +
                 ") -> " + o->output);
        if (!r.coverage_verified)
            ctx.notice(kcli::grouped(r.uncovered_surfels.size()) + " surfel(s) keep an uncovered arc of their boundary (" +
                       std::to_string(r.not_placed) +
                       " new surfel(s) not placed: an open border, a thin rim or a sharp crease); --json lists them "
                       "as uncovered_surfels");
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(upsample, "Fill the gaps between surfels (oriented disks) at a given radius", setup)
