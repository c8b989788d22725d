// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi smooth IN OUT [--a 2 --b 0.1 --c 1 --d D] [--edge-threshold T] [--voting-cube 3]
// [--edge-iterations N] [--face-iterations N] [--no-features] [--no-coplanar-creases] [--no-straight-creases] [--features FEATURES.ply]
// [--preset default|paper] [--lowpass-noise F] [--lowpass-iterations N] [--risk-selection | --no-risk-selection]
// [--no-impulse-removal] [--no-untangle]`: feature-aware bilateral smoothing (faces folded over by
// noise along the surface unfolded first, unless --no-untangle; vertices impulsive noise moved put
// back, unless --no-impulse-removal; a Taubin low-pass first under strong noise; Taubin's result
// instead where its estimated error is clearly lower, unless --no-risk-selection); the
// sharp edges can be written as PLY polylines. `--preset paper` starts from the paper's published
// parameters and detection (FeatureBilateralParams::paper()); options given win.
#include "common.hpp"

#include <kintsugi/smooth/feature_bilateral.hpp>

#include <limits>
#include <memory>
#include <numbers>
#include <string>

namespace {

struct SmoothOptions {
    std::string input, output, features;
    kintsugi::FeatureBilateralParams params;
    bool no_features = false;
    bool no_coplanar = false;
    bool no_straight = false;
    bool risk_selection = false;     // --risk-selection: the default; kept for older command lines
    bool no_risk_selection = false;  // --no-risk-selection: the filters' result always
    bool no_impulse_removal = false; // --no-impulse-removal: the filters see impulsive noise as it is
    bool no_untangle = false;        // --no-untangle: faces folded by tangential noise left folded
    // --d and --face-iterations: given, or left to the noise estimate (unset optionals).
    double d = 0;
    std::size_t face_iterations = 0;
    std::size_t lowpass_iterations = 0;
    CLI::Option* d_option = nullptr;
    CLI::Option* face_iterations_option = nullptr;
    CLI::Option* lowpass_iterations_option = nullptr;
    CLI::Option* lowpass_noise_option = nullptr;
    std::string preset = "default";
    // The options that override a preset's values when given.
    CLI::Option *a_option = nullptr, *b_option = nullptr, *c_option = nullptr, *threshold_option = nullptr,
                *cube_option = nullptr, *edge_iterations_option = nullptr;
};

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<SmoothOptions>();
    auto& p = o->params;
    cmd.add_option("input", o->input, "Triangle mesh (PLY, OFF, OBJ)")->required();
    cmd.add_option("output", o->output, "Smoothed mesh to write (PLY, OFF, OBJ)")->required();
    // Ranges are those kintsugi::smooth_feature_bilateral accepts: scales positive and
    // finite, the threshold in [0, 1], at most 10000 passes.
    const auto positive = kcli::real(0.0, std::numeric_limits<double>::max(), true);
    o->a_option = cmd.add_option("--a", p.a, "Edge spatial scale (sigma = a|e|/2, a|e|)")->capture_default_str()->check(positive);
    o->b_option = cmd.add_option("--b", p.b, "Edge range scale (sigma = b|e|)")->capture_default_str()->check(positive);
    o->c_option = cmd.add_option("--c", p.c, "Face spatial scale (sigma = c|e|/2, c|e|)")->capture_default_str()->check(positive);
    o->d_option = cmd.add_option("--d", o->d, "Face range scale (sigma = d|e|; default: from the estimated noise level)")
                      ->check(positive);
    o->threshold_option = cmd.add_option("--edge-threshold", p.detection.edge_threshold, "Edge strength threshold (paper: 0.251; scans 0.102)")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1.0));
    o->cube_option = cmd.add_option("--voting-cube", p.detection.voting_cube, "Voting cube side in mean edge lengths (paper: 3; scans 9)")
        ->capture_default_str()
        ->check(positive);
    o->edge_iterations_option = cmd.add_option("--edge-iterations", p.edge_iterations, "Passes of the sharp-edge filters")
        ->capture_default_str()
        ->check(kcli::count(0, 10000));
    o->face_iterations_option = cmd.add_option("--face-iterations", o->face_iterations,
                                               "Passes of the face filters (default: from the estimated noise level)")
                                    ->check(kcli::count(0, 10000));
    o->lowpass_noise_option =
        cmd.add_option("--lowpass-noise", p.lowpass_noise,
                       "Noise level (sigma/|e|) down to which Taubin steps low-pass the mesh first, when the "
                       "noise is estimated; 0 disables")
            ->capture_default_str()
            ->check(kcli::real(0.0, 1.0));
    o->lowpass_iterations_option =
        cmd.add_option("--lowpass-iterations", o->lowpass_iterations,
                       "Taubin steps run first (default: from the estimated noise, see --lowpass-noise)")
            ->check(kcli::count(0, 10000));
    cmd.add_option("--preset", o->preset,
                   "Starting values: default (measured, d and face iterations from the noise) or paper (the "
                   "paper's published parameters and detection); options given override them")
        ->capture_default_str()
        ->check(CLI::IsMember({"default", "paper"}));
    cmd.add_flag("--no-features", o->no_features, "Run the face filters alone, without sharp-edge handling");
    cmd.add_flag("--no-coplanar-creases", o->no_coplanar,
                 "Do not read creases from faces that impulsive noise left exactly in their planes (the voting "
                 "tensor alone; the paper preset never reads them)");
    cmd.add_flag("--no-straight-creases", o->no_straight,
                 "Skip the second detection with a narrow normal kernel that adds creases on straight runs with "
                 "two distinct sides (the paper preset never runs it)");
    cmd.add_flag("--no-risk-selection", o->no_risk_selection,
                 "Keep the filters' result always: skip the Taubin run (step count of least estimated risk) whose "
                 "result is otherwise kept where its estimated error along the normals is clearly lower (smooth "
                 "organic shapes; the sharp edges reported stay the filters'); about 0.75x the time");
    cmd.add_flag("--risk-selection", o->risk_selection,
                 "The risk selection: the default, accepted so that older command lines keep working (with "
                 "--preset paper, which gives d and the face iterations, nothing is estimated to compare with)");
    cmd.add_flag("--no-impulse-removal", o->no_impulse_removal,
                 "Do not put back the vertices impulsive noise moved far off the surface (found only when the "
                 "vertices' heights above their neighbours are heavy-tailed, or a few are over 10 median edge "
                 "lengths off; the paper preset never does)");
    cmd.add_flag("--no-untangle", o->no_untangle,
                 "Do not unfold the faces that noise along the surface folded over (done only when the vertices' "
                 "offsets from their neighbours read as noise in random directions; the paper preset never does)");
    cmd.add_option("--features", o->features, "Write the sharp edges found as PLY polylines (vertex + edge elements)");
    return [o, &ctx] {
        if (o->risk_selection && o->no_risk_selection)
            throw kcli::usage_error("--risk-selection and --no-risk-selection contradict each other; pass one");
        if (o->no_features && !o->features.empty())
            throw kcli::usage_error("--features needs feature detection; drop --no-features");
        ctx.check_output(o->output, kintsugi::OutputKind::mesh);
        if (!o->features.empty()) ctx.check_output(o->features, kintsugi::OutputKind::polylines);
        kcli::Stopwatch sw;
        ctx.doing("reading " + o->input);
        kintsugi::IndexedMesh mesh = kcli::read_mesh(o->input);
        mesh.normals.clear();  // positions move; stale normals would be written
        ctx.add_timing("read", sw.seconds());

        kintsugi::FeatureBilateralParams params = o->params;
        if (o->preset == "paper") {
            params = kintsugi::FeatureBilateralParams::paper();
            if (o->a_option->count() > 0) params.a = o->params.a;
            if (o->b_option->count() > 0) params.b = o->params.b;
            if (o->c_option->count() > 0) params.c = o->params.c;
            if (o->threshold_option->count() > 0) params.detection.edge_threshold = o->params.detection.edge_threshold;
            if (o->cube_option->count() > 0) params.detection.voting_cube = o->params.detection.voting_cube;
            if (o->edge_iterations_option->count() > 0) params.edge_iterations = o->params.edge_iterations;
            if (o->lowpass_noise_option->count() > 0) params.lowpass_noise = o->params.lowpass_noise;
        }
        params.features = !o->no_features;
        if (o->no_coplanar) params.detection.coplanar_creases = false;
        if (o->no_straight) params.detection.straight_creases = false;
        if (o->d_option->count() > 0) params.d = o->d;
        if (o->face_iterations_option->count() > 0) params.face_iterations = o->face_iterations;
        if (o->lowpass_iterations_option->count() > 0) params.lowpass_iterations = o->lowpass_iterations;
        if (o->risk_selection) params.risk_selection = true;
        if (o->no_risk_selection) params.risk_selection = false;
        if (o->no_impulse_removal) params.impulse_removal = false;
        if (o->no_untangle) params.untangle = false;
        params.control = ctx.control("smooth");
        ctx.doing("smoothing the " + kcli::grouped(mesh.faces.size()) + " faces of " + o->input);
        const kintsugi::FeatureBilateralResult r = kintsugi::smooth_feature_bilateral(mesh, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw kcli::interrupted();
        ctx.add_timings(r.timings);

        sw = kcli::Stopwatch();
        // Both files appear together once the command has succeeded (ctx.write_options).
        if (!o->features.empty()) {
            // The features were found on the input: write them at the smoothed positions.
            ctx.doing("writing " + o->features);
            kcli::write_polylines(o->features, mesh.vertices, r.features.sharp_edges, ctx.write_options());
        }
        ctx.doing("writing " + o->output);
        kcli::write_mesh(o->output, mesh, ctx.write_options());
        ctx.add_timing("write", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "smooth";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["preset"] = o->preset;
        j["parameters"]["a"] = params.a;
        j["parameters"]["b"] = params.b;
        j["parameters"]["c"] = params.c;
        j["parameters"]["d"] = r.d;
        j["parameters"]["edge_threshold"] = params.detection.edge_threshold;
        j["parameters"]["voting_cube"] = params.detection.voting_cube;
        j["parameters"]["coplanar_creases"] = params.detection.coplanar_creases;
        j["parameters"]["straight_creases"] = params.detection.straight_creases;
        j["parameters"]["edge_iterations"] = params.edge_iterations;
        j["parameters"]["face_iterations"] = r.face_iterations;
        j["parameters"]["normal_iterations"] = r.normal_iterations;
        j["parameters"]["strong_noise"] = r.strong_noise;
        j["parameters"]["detection_presmooth_iterations"] = r.detection.presmooth_iterations;
        j["parameters"]["detection_prefilter_scale"] = r.detection.prefilter_scale;
        j["parameters"]["d_from_noise"] = !params.d.has_value();
        j["parameters"]["face_iterations_from_noise"] = !params.face_iterations.has_value();
        j["parameters"]["normal_iterations_from_noise"] = !params.normal_iterations.has_value() && r.noise_estimated;
        j["parameters"]["lowpass_noise"] = params.lowpass_noise;
        j["parameters"]["lowpass_iterations"] = r.lowpass_iterations;
        j["parameters"]["lowpass_iterations_from_noise"] = !params.lowpass_iterations.has_value();
        if (r.noise_estimated) {
            j["noise"]["sigma"] = r.noise.sigma;
            j["noise"]["relative"] = r.noise.relative;
            j["noise"]["clean_edge_length"] = r.noise.clean_edge_length;
            j["noise"]["vertices_used"] = r.noise.vertices_used;
            j["noise"]["quadric_sigma"] = r.noise.quadric_sigma;
            j["noise"]["difference_sigma"] = r.noise.difference_sigma;
            j["noise"]["after_lowpass"]["sigma"] = r.noise_after_lowpass.sigma;
            j["noise"]["after_lowpass"]["relative"] = r.noise_after_lowpass.relative;
        }
        j["parameters"]["impulse_removal"] = params.impulse_removal;
        if (params.impulse_removal) {
            auto& im = j["impulses"];
            im["spikes_put_back"] = r.spike_vertices;
            im["impulsive"] = r.impulsive_noise;
            im["put_back"] = r.impulse_vertices;
            im["dense"] = r.impulses_dense;
            if (r.noise_estimated) {
                im["input_noise"]["sigma"] = r.input_noise.sigma;
                im["input_noise"]["relative"] = r.input_noise.relative;
            }
        }
        j["parameters"]["untangle"] = params.untangle;
        if (params.untangle) {
            auto& un = j["untangle"];
            un["ratio"] = r.untangle.ratio;
            un["tangential_noise"] = r.untangle.tangential_noise;
            un["impulsive"] = r.untangle.impulsive;
            un["reference_angle_deg"] = r.untangle.reference_angle * 180 / std::numbers::pi;
            un["folded_faces"] = r.untangle.folded_faces;
            un["moved_vertices"] = r.untangle.moved_vertices;
        }
        j["parameters"]["features"] = params.features;
        j["parameters"]["risk_selection"] = params.risk_selection;
        if (params.risk_selection) {
            auto& rs = j["risk_selection"];
            rs["evaluated"] = r.risk.evaluated;
            rs["result"] = r.risk.taubin ? "taubin" : "filters";
            rs["taubin_iterations"] = r.risk.taubin_iterations;
            rs["sigma"] = r.risk.sigma;
            rs["filters_rms"] = r.risk.filters_rms;
            rs["taubin_rms"] = r.risk.taubin_rms;
            rs["coarse"] = r.risk.coarse;
            rs["median_dihedral_deg"] = r.risk.median_dihedral * 180 / std::numbers::pi;
            rs["normal_veto"] = r.risk.normal_veto;
            rs["normal_difference"] = r.risk.normal_difference;
            rs["normal_z"] = r.risk.normal_z;
            rs["recheck"] = r.risk.recheck;
            rs["recheck_probes"] = r.risk.recheck_probes;
            rs["filters_rms_recheck"] = r.risk.filters_rms_recheck;
            rs["note"] = r.risk.note;
        }
        j["vertices"] = r.vertices;
        j["faces"] = r.faces;
        j["sharp_edges"] = r.features.sharp_edges.size();
        j["feature_vertices"] = r.feature_vertices;
        j["anchored_faces"] = r.features.anchored_faces;
        j["coplanar_sharp_edges"] = r.features.coplanar_sharp_edges;
        j["straight_sharp_edges"] = r.features.straight_sharp_edges;
        j["held_vertices"] = r.held_vertices;
        j["degenerate_faces"] = r.degenerate_faces;
        j["mean_edge_length"] = r.features.mean_edge_length;
        if (!o->features.empty()) j["features"] = o->features;
        std::string how;
        if (params.risk_selection) {
            const std::string steps = std::to_string(r.risk.taubin_iterations) + " steps; ";
            how = r.risk.taubin ? ", Taubin's result kept (" + steps +
                                      (r.risk.coarse     ? "a mesh too coarse for the filters)"
                                       : r.risk.recheck ? "lower estimated error once the filters' sharp edges were detected again on the probes)"
                                                        : "lower estimated error)")
                  : r.risk.normal_veto ? ", the filters' result kept (Taubin's face normals estimated far worse)"
                  : r.risk.evaluated   ? ", the filters' result kept (lower estimated error)"
                                       : ", the filters' result kept (risks not compared: " + r.risk.note + ")";
        }
        if (r.spike_vertices > 0)
            how += "; " + std::to_string(r.spike_vertices) + " spikes (vertices far off the surface) put back";
        if (r.untangle.moved_vertices > 0)
            how += "; " + std::to_string(r.untangle.folded_faces) + " faces folded over by noise along the surface unfolded";
        if (r.impulse_vertices > 0)
            how += "; " + std::to_string(r.impulse_vertices) + " vertices moved by impulsive noise put back";
        else if (r.impulses_dense)
            how += "; impulsive noise too dense to put back (more than a fifth of the vertices)";
        ctx.info("smoothed " + std::to_string(r.vertices) + " vertices, " + std::to_string(r.faces) + " faces (" +
                 std::to_string(r.features.sharp_edges.size()) + " sharp edges" + how + ") -> " + o->output +
                 (o->features.empty() ? "" : ", features -> " + o->features));
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(smooth, "Feature-aware bilateral mesh smoothing", setup)
