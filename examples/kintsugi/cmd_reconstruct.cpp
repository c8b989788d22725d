// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi reconstruct IN OUT --method pu-graphcut [--max-level 8] [--epsilon E]
// [--k 10] [--labeling graphcut|sign] [--inward-normals] [--json]`: a closed,
// outward-oriented manifold surface from (possibly outlier-ridden) points.
// `--method rbf [--n-max 100] [--overlap 1.35] [--activity 1.05] [--smoothing L]
// [--resolution N] [--no-blend]`: the octree triharmonic RBF surface (clean points).
#include "reconstruct_cli.hpp"

#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/reconstruct/pu_graphcut.hpp>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace {

struct ReconstructOptions {
    std::string input, output;
    std::string method = "pu-graphcut";
    kintsugi::PUGraphcutParams params;  // the library's defaults
    std::string labeling = params.labeling == kintsugi::Labeling::sign ? "sign" : "graphcut";
    bool inward = params.normals == kintsugi::NormalConvention::inward;
    std::shared_ptr<kcli::reconstruct::RbfOptions> rbf;  // cmd_reconstruct_rbf.cpp
    /// --smoothing: Taubin iterations for pu-graphcut, λ for rbf (each method's default when not given)
    double smoothing = static_cast<double>(params.smoothing_iterations);
    CLI::Option* smoothing_option = nullptr;
    std::vector<CLI::Option*> pu_only, rbf_only;  ///< refused with the other method
};

std::string real_text(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

}  // namespace

namespace kcli::reconstruct {

kintsugi::TopologyReport write_surface(Context& ctx, const std::string& output, const kintsugi::IndexedMesh& m) {
    const kintsugi::TopologyReport rep = kintsugi::topology_report(m);
    Stopwatch sw;
    ctx.check_interrupted();
    ctx.doing("writing " + output);
    kcli::write_mesh(output, m, ctx.write_options());
    ctx.add_timing("write", sw.seconds());
    return rep;
}

}  // namespace kcli::reconstruct

namespace {

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<ReconstructOptions>();
    cmd.add_option("input", o->input, "Oriented points (PLY, XYZ, PWN, OFF, OBJ); normals estimated when missing")
        ->required();
    cmd.add_option("output", o->output, "Mesh to write (PLY, OFF, OBJ)")->required();
    cmd.add_option("--method", o->method, "Reconstruction method")
        ->capture_default_str()
        ->check(CLI::IsMember({"pu-graphcut", "rbf"}));
    auto& p = o->params;
    cmd.add_option("--max-level", p.max_level, "Octree depth")->capture_default_str()->check(kcli::count(1, 12));
    cmd.add_option("--epsilon", p.epsilon, "PU error tolerance, fraction of the longest bounding-box side")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1.0, true));
    cmd.add_option("--k", p.k, "Terminal/edge capacity ratio of the graph cut (paper: 5-15)")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1e6, true));
    cmd.add_option("--triangulation-weight-scale", p.triangulation_weight_scale,
                   "Regular-triangulation weights (s r)^2: 1 is the paper (small supports hidden), 0 keeps all")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1.0));
    o->smoothing_option =
        cmd.add_option("--smoothing", o->smoothing,
                       "pu-graphcut: selective Taubin iterations (0 = none); rbf: Carr's smoothing lambda (default " +
                           real_text(kcli::reconstruct::rbf_default_smoothing()) + ", 0 interpolates)")
            ->capture_default_str()
            ->check(kcli::real(0.0, 1e6));
    cmd.add_option("--far-site-band", p.far_site_band,
                   "Thin the untrusted supports farther than this many trusted radii from the surface (0 keeps all)")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1e6));
    cmd.add_option("--max-handle-loop", p.max_handle_loop,
                   "Cut handles/tunnels a loop of at most this many median mesh edges goes around (0 keeps all)")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1e6));
    cmd.add_option("--refine-spacing", p.refine_spacing,
                   "Refine the surface to this many times the local sample spacing and move it onto the data "
                   "(0: off, else at least 0.25)")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1e6) & CLI::Validator(
                                          [](std::string& in) -> std::string {
                                              const double v = std::strtod(in.c_str(), nullptr);
                                              return v == 0 || v >= kintsugi::min_refine_spacing
                                                         ? std::string()
                                                         : "must be 0 (off) or at least 0.25, got '" + in + "'";
                                          },
                                          "0 or >= 0.25"));
    cmd.add_option("--refine-neighbors", p.refine_neighbors, "Neighbours of the MLS fit of the refinement")
        ->capture_default_str()
        ->check(kcli::count(4, 100000));
    cmd.add_option("--labeling", o->labeling, "graphcut, or sign (the PU field's sign, for comparison)")
        ->capture_default_str()
        ->check(CLI::IsMember({"graphcut", "sign"}));
    cmd.add_flag("--inward-normals", o->inward, "Input normals point into the object (the paper's convention)");
    for (const char* name :
         {"--max-level", "--epsilon", "--k", "--triangulation-weight-scale", "--far-site-band", "--max-handle-loop",
          "--refine-spacing",
          "--refine-neighbors", "--labeling"})
        o->pu_only.push_back(cmd.get_option(name));
    o->rbf = kcli::reconstruct::add_rbf_options(cmd, o->rbf_only);
    return [o, &ctx] {
        for (const CLI::Option* opt : o->method == "rbf" ? o->pu_only : o->rbf_only)
            if (opt->count() > 0)
                throw kcli::usage_error(opt->get_name() + " does not apply to --method " + o->method);
        if (o->method == "pu-graphcut" && (o->smoothing != std::floor(o->smoothing) || o->smoothing > 10000))
            throw kcli::usage_error("--smoothing " + real_text(o->smoothing) +
                                    ": pu-graphcut takes a whole number of Taubin iterations in [0, 10000]");
        ctx.check_output(o->output, kintsugi::OutputKind::mesh);
        kcli::Stopwatch sw;
        kintsugi::ReadInfo info;
        ctx.doing("reading " + o->input);
        kintsugi::PointCloud cloud = kcli::read_point_cloud(o->input, &info);
        ctx.add_timing("read", sw.seconds());
        const bool estimated = kcli::reconstruct::estimate_missing_normals(ctx, cloud, o->input);

        if (o->method == "rbf") {
            kcli::reconstruct::RbfRun run;
            run.input = o->input;
            run.output = o->output;
            run.inward = o->inward;
            if (o->smoothing_option->count() > 0) run.smoothing = o->smoothing;
            run.normals_estimated = estimated;
            kcli::reconstruct::run_rbf(*o->rbf, run, ctx, cloud);
            return;
        }
        kintsugi::PUGraphcutParams p = o->params;
        p.smoothing_iterations = static_cast<std::size_t>(o->smoothing);
        p.seed = ctx.common.seed;
        p.normals = o->inward ? kintsugi::NormalConvention::inward : kintsugi::NormalConvention::outward;
        p.labeling = o->labeling == "sign" ? kintsugi::Labeling::sign : kintsugi::Labeling::graphcut;
        p.control = ctx.control("reconstruct");
        ctx.doing("reconstructing a surface from the " + kcli::grouped(cloud.points.size()) + " points of " +
                  o->input + " (--max-level " + std::to_string(p.max_level) + ")");
        kintsugi::PUGraphcutResult r = kintsugi::reconstruct_pu_graphcut(cloud, p);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw kcli::interrupted();
        ctx.add_timings(r.timings);
        if (r.far_points > 0)
            ctx.notice(std::to_string(r.far_points) + " of the " + std::to_string(r.points) +
                       " points lie apart from the rest in groups too small to be an object; they were left out");
        if (r.refine_budget_reached)
            ctx.notice("the refinement stopped at its vertex budget where the points' spacing reads far below the "
                       "rest (near-duplicate points or a dense cluster); the surface there is coarser than the points");

        const kintsugi::TopologyReport rep = kcli::reconstruct::write_surface(ctx, o->output, r.mesh);

        auto& j = ctx.json();
        j["command"] = "reconstruct";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["method"] = o->method;
        j["parameters"]["max_level"] = p.max_level;
        j["parameters"]["epsilon"] = p.epsilon;
        j["parameters"]["k"] = p.k;
        j["parameters"]["triangulation_weight_scale"] = p.triangulation_weight_scale;
        j["parameters"]["far_site_band"] = p.far_site_band;
        j["parameters"]["smoothing_iterations"] = p.smoothing_iterations;
        j["parameters"]["max_handle_loop"] = p.max_handle_loop;
        j["parameters"]["refine_spacing"] = p.refine_spacing;
        j["parameters"]["refine_neighbors"] = p.refine_neighbors;
        j["parameters"]["labeling"] = o->labeling;
        j["parameters"]["inward_normals"] = o->inward;
        j["parameters"]["seed"] = ctx.common.seed;
        j["normals_estimated"] = estimated;
        j["points"] = r.points;
        j["octree_cells"] = r.octree_cells;
        j["supports"] = r.supports;
        j["hidden_supports"] = r.hidden_supports;
        j["thinned_supports"] = r.thinned_supports;
        j["outer_vertices"] = r.outer_vertices;
        j["tetrahedra"] = r.tetrahedra;
        j["graph_nodes"] = r.graph_nodes;
        j["graph_edges"] = r.graph_edges;
        j["cut_value"] = r.cut_value;
        j["inside_vertices"] = r.inside_vertices;
        j["sign_disagreements"] = r.sign_disagreements;
        j["same_sign_vertices"] = r.same_sign_vertices;
        j["smoothed_vertices"] = r.smoothed_vertices;
        j["far_points"] = r.far_points;
        j["parts"] = r.parts;
        j["handles_removed"] = r.handles_removed;
        j["refined_vertices"] = r.refined_vertices;
        j["refine_noise_ratio"] = r.refine_noise_ratio;
        j["refine_neighbors_used"] = r.refine_neighbors_used;
        j["refine_budget_reached"] = r.refine_budget_reached;
        j["vertices"] = rep.vertices;
        j["faces"] = rep.faces;
        j["components"] = rep.components;
        j["genus"] = rep.genus;
        j["closed"] = rep.closed;
        j["manifold"] = rep.manifold;
        ctx.info("reconstructed " + std::to_string(r.points) + " points (" + std::to_string(r.supports) +
                 " supports, " + std::to_string(r.hidden_supports) + " hidden, " +
                 std::to_string(r.thinned_supports) + " thinned, graph " +
                 std::to_string(r.graph_nodes) + " nodes / " + std::to_string(r.graph_edges) + " edges) -> " +
                 std::to_string(rep.vertices) + " vertices, " + std::to_string(rep.faces) + " faces, " +
                 std::to_string(rep.components) + " component(s), genus " + std::to_string(rep.genus) +
                 (r.handles_removed > 0 ? " (" + std::to_string(r.handles_removed) + " small handle(s) cut)" : "") +
                 (rep.closed && rep.manifold ? ", closed manifold" : "") + " -> " + o->output);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(reconstruct,
                          "Closed surface from oriented points: PU + graph cut (robust to outliers) or octree RBF",
                          setup)
