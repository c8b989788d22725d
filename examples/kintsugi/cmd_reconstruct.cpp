// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi reconstruct IN OUT --method pu-graphcut [--max-level 8] [--epsilon E]
// [--k 10] [--labeling graphcut|sign] [--inward-normals] [--json]`: a closed,
// outward-oriented manifold surface from (possibly outlier-ridden) points.
#include "common.hpp"

#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/normals/estimate_normals.hpp>
#include <kintsugi/reconstruct/pu_graphcut.hpp>

#include <memory>
#include <string>

namespace {

struct ReconstructOptions {
    std::string input, output;
    std::string method = "pu-graphcut";
    kintsugi::PUGraphcutParams params;  // the library's defaults
    std::string labeling = params.labeling == kintsugi::Labeling::sign ? "sign" : "graphcut";
    bool inward = params.normals == kintsugi::NormalConvention::inward;
};

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<ReconstructOptions>();
    cmd.add_option("input", o->input, "Oriented points (PLY, XYZ, PWN, OFF, OBJ); normals estimated when missing")
        ->required();
    cmd.add_option("output", o->output, "Mesh to write (PLY, OFF, OBJ)")->required();
    cmd.add_option("--method", o->method, "Reconstruction method")
        ->capture_default_str()
        ->check(CLI::IsMember({"pu-graphcut"}));
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
    cmd.add_option("--smoothing", p.smoothing_iterations, "Selective Taubin iterations (0 = none)")
        ->capture_default_str()
        ->check(kcli::count(0, 10000));
    cmd.add_option("--labeling", o->labeling, "graphcut, or sign (the PU field's sign, for comparison)")
        ->capture_default_str()
        ->check(CLI::IsMember({"graphcut", "sign"}));
    cmd.add_flag("--inward-normals", o->inward, "Input normals point into the object (the paper's convention)");
    return [o, &ctx] {
        ctx.check_output(o->output, kintsugi::OutputKind::mesh);
        kcli::Stopwatch sw;
        kintsugi::ReadInfo info;
        ctx.doing("reading " + o->input);
        kintsugi::PointCloud cloud = kintsugi::read_point_cloud(o->input, &info);
        ctx.add_timing("read", sw.seconds());
        bool estimated = false;
        if (!kintsugi::has_normals(cloud)) {
            kintsugi::NormalParams np;  // the library's defaults
            ctx.notice(o->input + " has no normals; estimating and orienting them (" +
                       (np.method == kintsugi::NormalMethod::jet ? "jet" : "PCA") + ", k = " + std::to_string(np.k) +
                       ", outward)");
            np.control = ctx.control("normals");
            ctx.doing("estimating the normals of " + kcli::grouped(cloud.points.size()) + " points of " + o->input);
            const auto nr = kintsugi::estimate_normals(cloud, np);
            ctx.end_progress();
            if (nr.status == kintsugi::Status::cancelled) throw kcli::interrupted();
            ctx.add_timings(nr.timings, "normals_");
            estimated = true;
        }

        kintsugi::PUGraphcutParams p = o->params;
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

        const kintsugi::TopologyReport rep = kintsugi::topology_report(r.mesh);
        sw = kcli::Stopwatch();
        ctx.check_interrupted();
        ctx.doing("writing " + o->output);
        kintsugi::write_mesh(o->output, r.mesh, ctx.write_options());
        ctx.add_timing("write", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "reconstruct";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["method"] = o->method;
        j["parameters"]["max_level"] = p.max_level;
        j["parameters"]["epsilon"] = p.epsilon;
        j["parameters"]["k"] = p.k;
        j["parameters"]["triangulation_weight_scale"] = p.triangulation_weight_scale;
        j["parameters"]["smoothing_iterations"] = p.smoothing_iterations;
        j["parameters"]["labeling"] = o->labeling;
        j["parameters"]["inward_normals"] = o->inward;
        j["parameters"]["seed"] = ctx.common.seed;
        j["normals_estimated"] = estimated;
        j["points"] = r.points;
        j["octree_cells"] = r.octree_cells;
        j["supports"] = r.supports;
        j["hidden_supports"] = r.hidden_supports;
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
        j["vertices"] = rep.vertices;
        j["faces"] = rep.faces;
        j["components"] = rep.components;
        j["genus"] = rep.genus;
        j["closed"] = rep.closed;
        j["manifold"] = rep.manifold;
        ctx.info("reconstructed " + std::to_string(r.points) + " points (" + std::to_string(r.supports) +
                 " supports, " + std::to_string(r.hidden_supports) + " hidden, graph " +
                 std::to_string(r.graph_nodes) + " nodes / " + std::to_string(r.graph_edges) + " edges) -> " +
                 std::to_string(rep.vertices) + " vertices, " + std::to_string(rep.faces) + " faces, " +
                 std::to_string(rep.components) + " component(s), genus " + std::to_string(rep.genus) +
                 (rep.closed && rep.manifold ? ", closed manifold" : "") + " -> " + o->output);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(reconstruct, "Closed surface from oriented points (PU + graph cut), robust to outliers",
                          setup)
