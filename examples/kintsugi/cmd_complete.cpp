// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi complete IN OUT [--max-hole-size F] [--max-hole-edges N] [--initial fan]`:
// example-based hole completion (docs/methods/example_completion.md); --json reports
// the energy after every iteration of every level, and per hole the weight λ of the
// blend and the explosion guard's status.
#include "common.hpp"

#include <kintsugi/complete/example_completion.hpp>

#include <limits>
#include <memory>
#include <string>

namespace {

struct CompleteOptions {
    std::string input, output, initial = "thin-plate";
    kintsugi::CompletionParams params;
};

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<CompleteOptions>();
    auto& p = o->params;
    cmd.add_option("input", o->input, "Triangle mesh with holes (PLY, OFF, OBJ)")->required();
    cmd.add_option("output", o->output, "Completed mesh to write (PLY, OFF, OBJ)")->required();
    const auto positive = kcli::real(0.0, std::numeric_limits<double>::max(), true);
    cmd.add_option("--max-hole-size", p.max_hole_size,
                   "Fill holes up to this extent, as a fraction of the mesh's diagonal")
        ->capture_default_str()
        ->check(positive);
    cmd.add_option("--max-hole-edges", p.max_hole_edges, "Fill holes with at most this many edges (0: no limit)")
        ->capture_default_str()
        ->check(kcli::count(0, std::numeric_limits<std::uint32_t>::max()));
    cmd.add_option("--outer-border", p.outer_border_extent,
                   "Outer-border rule: the largest loop spanning this fraction of its part's diagonal stays open")
        ->capture_default_str()
        ->check(kcli::real(0.0, std::numeric_limits<double>::max()));
    cmd.add_option("--initial", o->initial, "Initial patch: thin-plate or fan (the paper's)")
        ->capture_default_str()
        ->check(CLI::IsMember({"thin-plate", "fan"}));
    cmd.add_option("--s", p.s, "Weight base s of w = 1/s^m inside the hole (> 1)")
        ->capture_default_str()
        ->check(kcli::real(1.0, 1e6, true));
    cmd.add_option("--top-percent", p.top_percent, "Candidates tested, % of the data by curvature likeness")
        ->capture_default_str()
        ->check(kcli::real(0.0, 100.0, true));
    cmd.add_option("--b-radius", p.b_radius, "Radius of the frame fits, in mean edge lengths")
        ->capture_default_str()
        ->check(positive);
    cmd.add_option("--max-iterations", p.max_iterations, "Most iterations per level")
        ->capture_default_str()
        ->check(kcli::count(1, 10000));
    cmd.add_option("--max-patch-growth", p.max_patch_growth,
                   "Explosion guard: most patch vertices per hole, as a multiple of a disk of its perimeter; "
                   "a hole beyond it keeps its thin-plate fill")
        ->capture_default_str()
        ->check(positive);
    return [o, &ctx] {
        ctx.check_output(o->output, kintsugi::OutputKind::mesh);
        kcli::Stopwatch sw;
        ctx.doing("reading " + o->input);
        kintsugi::IndexedMesh mesh = kcli::read_mesh(o->input);
        ctx.add_timing("read", sw.seconds());

        kintsugi::CompletionParams params = o->params;
        params.initial = o->initial == "fan" ? kintsugi::InitialPatch::fan : kintsugi::InitialPatch::thin_plate;
        params.seed = ctx.common.seed;
        params.control = ctx.control("complete");
        ctx.doing("completing the holes of " + o->input);
        const kintsugi::CompletionResult r = kintsugi::complete_holes_example_based(mesh, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw kcli::interrupted();
        ctx.add_timings(r.timings);

        sw = kcli::Stopwatch();
        ctx.doing("writing " + o->output);
        kcli::write_mesh(o->output, mesh, ctx.write_options());
        ctx.add_timing("write", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "complete";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["max_hole_size"] = params.max_hole_size;
        j["parameters"]["max_hole_edges"] = params.max_hole_edges;
        j["parameters"]["outer_border_extent"] = params.outer_border_extent;
        j["parameters"]["initial"] = o->initial;
        j["parameters"]["s"] = params.s;
        j["parameters"]["top_percent"] = params.top_percent;
        j["parameters"]["b_radius"] = params.b_radius;
        j["parameters"]["max_iterations"] = params.max_iterations;
        j["parameters"]["seed"] = static_cast<unsigned long long>(params.seed);
        j["filled_holes"] = r.filled_holes;
        j["unfilled_holes"] = r.unfilled_holes.size();
        j["new_vertices"] = r.new_vertices;
        j["new_faces"] = r.new_faces;
        j["vertices"] = mesh.vertices.size();
        j["faces"] = mesh.faces.size();
        j["mean_edge_length"] = r.mean_edge_length;
        kcli::Json::Array levels;
        for (const auto& level : r.energy) {
            kcli::Json::Array e;
            for (const double x : level) e.emplace_back(x);
            levels.emplace_back(std::move(e));
        }
        j["energy"] = kcli::Json(std::move(levels));
        // Per filled hole: λ of the blend with the smooth fill, and whether the explosion
        // guard kept it (completed) or reverted it to the thin-plate fill (and why).
        kcli::Json::Array weights, status;
        for (const double w : r.example_weight) weights.emplace_back(w);
        for (const auto s : r.hole_status) status.emplace_back(kintsugi::to_string(s));
        j["example_weight"] = kcli::Json(std::move(weights));
        j["hole_status"] = kcli::Json(std::move(status));
        j["parameters"]["max_patch_growth"] = params.max_patch_growth;
        ctx.info("filled " + std::to_string(r.filled_holes) + " holes with " + std::to_string(r.new_vertices) +
                 " new vertices, " + std::to_string(r.new_faces) + " faces -> " + o->output);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(complete, "Example-based hole completion (Kawai et al.)", setup)
