#include "commands.hpp"
#include "print.hpp"

#include "core/matrix_checks.hpp"
#include "core/numbers.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/compare.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/subdivide.hpp"
#include "curvenet/transfer.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>

#include <unistd.h>

namespace curvenet::cli {
namespace {

/// A mesh, with a line for each repair made on load that changes the
/// surface the engine works on (degenerate faces left out, faces turned).
SurfaceMesh load_mesh_noting(const std::string& path, std::ostream& notes = std::cout) {
  SurfaceMesh m = load_mesh(path);
  for (const auto& n : load_notes(m, path))
    notes << "note: " << n << "\n";
  return m;
}

Coverage parse_coverage(const std::string& s) {
  if (s == "full")
    return Coverage::Full;
  if (s == "local")
    return Coverage::Local;
  return Coverage::Auto;
}

/// Progress on stderr: one line per stage, rewritten in place on a terminal.
struct Progress {
  bool enabled;
  bool tty = ::isatty(2) != 0;
  void operator()(std::string_view stage, double fraction) const {
    if (!enabled)
      return;
    std::cerr << (tty ? "\r" : "") << "curvenet: " << stage << " " << std::setw(3) << static_cast<int>(100 * fraction)
              << "%" << (tty ? "" : "\n") << std::flush;
    if (tty && fraction >= 1.0)
      std::cerr << "\n";
  }
  void stage(const std::string& what) const {
    if (enabled)
      std::cerr << "curvenet: " << what << "\n";
  }
};

/// An embedding failure names the rig file it came from.
template <class F> auto naming_rig(const std::string& rig_path, F&& f) {
  try {
    return f();
  } catch (const EmbedError& e) {
    throw EmbedError(rig_path + ": " + e.what());
  }
}

/// A refinement refused for its levels names the option that gave them.
template <class F> auto naming_levels_option(const std::string& cage_file, const std::string& option, F&& f) {
  try {
    return f();
  } catch (const InputError& e) {
    if (e.element().rfind("levels ", 0) != 0 || (!cage_file.empty() && e.file() != cage_file))
      throw;
    throw InputError(e.file(), option + " " + e.element().substr(7), e.reason());
  }
}

} // namespace

int run_embed(const EmbedArgs& a) {
  const Progress progress{a.progress.value_or(::isatty(2) != 0)};
  const auto t0 = std::chrono::steady_clock::now();
  progress.stage("reading " + a.mesh);
  const SurfaceMesh mesh = load_mesh_noting(a.mesh);
  progress.stage("reading " + a.rig);
  const Rig rig = read_rig(a.rig);
  const double load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EmbedOptions opt;
  opt.density = a.density;
  opt.max_samples = a.max_samples;
  if (!a.coverage.empty())
    opt.coverage = parse_coverage(a.coverage);
  opt.progress = [&](std::string_view s, double f) { progress(s, f); };
  const Embedding emb = naming_rig(a.rig, [&] { return embed(mesh, rig, opt); });
  EmbedReport rep = emb.report();
  rep.timings_ms.insert(rep.timings_ms.begin(), {"load", load_ms}); // reading happens here, outside the library
  // All or nothing: everything is computed and written to temporary files
  // before any output is moved into place.
  OutputFiles files;
  if (!a.report.empty())
    files.add(a.report, report_to_json(rep));
  if (!a.regions.empty())
    files.add(a.regions, emb.regions_ply());
  if (!a.cut_mesh.empty())
    files.add(a.cut_mesh, emb.cut_mesh_obj());
  files.commit();
  print_embed(std::cout, std::filesystem::path(a.mesh).filename().string(), rep);
  return rep.ok ? 0 : 1;
}

namespace {

LayerSpec layer_spec(const DeformArgs& a) {
  return {a.over_skin, a.skinning == "dq" ? Skinning::DualQuaternion : Skinning::Linear, a.envelope, a.mask};
}

SceneFiles scene_files(const DeformArgs& a) {
  return {a.mesh, a.rig, a.skeleton, a.binding_cache};
}

BindOptions bind_options(const DeformArgs& a) {
  BindOptions o;
  o.laplacian = a.laplacian == "uniform" ? LaplacianChoice::Uniform : LaplacianChoice::IntrinsicDelaunay;
  o.rigid = a.rigid == "horn" ? RigidMode::Horn : RigidMode::PerVertex;
  parse_deform_method(a.method, o.method); // the CLI checks the spelling
  parse_interior_weights(a.interior, o.interior);
  o.rotation_blend =
      a.rotation == "quaternion" ? BindOptions::RotationBlend::Quaternion : BindOptions::RotationBlend::Polar;
  o.curve_frames = a.curve_frames;
  return o;
}

} // namespace

int run_bind(const BindArgs& a) {
  const JobSummary j = run(BindJob{scene_files(a), bind_options(a), a.out});
  print_job(std::cout, "bind", j);
  std::cout << "rig: " << a.out << "\n";
  return 0;
}

int run_pose(const PoseArgs& a) {
  const JobSummary j = run(PoseJob{scene_files(a), bind_options(a), a.pose, a.out, a.cut_mesh, layer_spec(a)});
  print_job(std::cout, "pose", j);
  std::cout << "output: " << a.out << " (" << j.vertices << " vertices)\n";
  return 0;
}

AnimateJob animate_job(const AnimateArgs& a) {
  AnimateJob job{scene_files(a), bind_options(a), a.clip_file, a.clip, a.frames, a.fps, a.max_frames};
  job.pc2 = a.obj_sequence.empty() ? a.out : "";
  job.obj_sequence = a.obj_sequence;
  job.cut_mesh_sequence = a.cut_mesh_sequence;
  job.layer = layer_spec(a);
  job.node_keys = a.node_keys;
  return job;
}

int run_animate(const AnimateArgs& a) {
  const AnimateSummary j = run(animate_job(a));
  print_job(std::cout, "animate", j);
  std::cout << "clip: " << j.clip_name << " (" << j.clip << "), frames " << j.range.first << ":" << j.range.last
            << " at " << a.fps << " fps\n";
  std::cout << "output: " << (a.obj_sequence.empty() ? a.out : a.obj_sequence) << " (" << j.range.count() << " frames, "
            << j.vertices << " vertices)\n";
  return 0;
}

int run_bake(const BakeArgs& a) {
  BakeJob job{scene_files(a), bind_options(a), a.out, a.weights_csv, a.clip_file, a.clip_names, a.fit};
  job.max_influences = a.max_influences;
  job.helpers = a.helpers;
  job.fps = a.fps;
  job.max_frames = a.max_frames;
  job.up = a.up == "z" ? GltfBakeOptions::Up::Z : GltfBakeOptions::Up::Y;
  job.weights = a.weights == "harmonic" ? BakeJob::Weights::Harmonic : BakeJob::Weights::Fitted;
  job.layer = layer_spec(a);
  const BakeSummary j = run(job);
  print_job(std::cout, "bake", j);
  const std::string over = a.fit.empty() ? "" : " and the clips of " + a.fit;
  std::cout << "weights: "
            << (a.weights == "fitted" ? "fitted to the rig over " + std::to_string(j.training_poses) +
                                            " poses of the skeleton" + over + ", top " + std::to_string(j.influences)
                : a.fit.empty() ? std::string("harmonic, top ") + std::to_string(j.influences)
                                : "fitted to the deformation over " + a.fit)
            << ", " << std::fixed << std::setprecision(2) << j.mean_joints << std::defaultfloat << std::setprecision(6)
            << " joints per vertex on average, " << j.most_joints << " at most, " << j.joints << " joints";
  if (a.helpers > 0)
    std::cout << " (" << j.helpers << (j.helpers == 1 ? " helper" : " helpers") << " of the " << a.helpers
              << " allowed, each keyed half way between two joints)";
  std::cout << "\n";
  if (!j.helper_joints.empty()) {
    const size_t shown = std::min<size_t>(j.helper_joints.size(), 8);
    std::cout << "helpers:";
    for (size_t i = 0; i < shown; ++i)
      std::cout << (i ? ", " : " ") << j.helper_joints[i];
    if (shown < j.helper_joints.size())
      std::cout << " and " << j.helper_joints.size() - shown << " more";
    std::cout << " (each node's extras name its two joints)\n";
  }
  if (!a.clip_file.empty()) {
    std::cout << "clips: " << j.clips << " from " << a.clip_file << " at " << a.fps << " keys per second\n";
    print_bake_fidelity(std::cout, j.fidelity, j.helpers > 0);
  }
  if (!a.out.empty())
    std::cout << "glTF: " << a.out << " (" << j.vertices << " vertices, Y-up"
              << (a.up == "z" ? ", turned from Z-up" : "") << ")\n";
  if (!a.weights_csv.empty())
    std::cout << "weights: " << a.weights_csv << "\n";
  return 0;
}

namespace {
Mat4 parse_matrix(const std::string& text, const char* option) {
  std::string t = text;
  std::replace(t.begin(), t.end(), ',', ' ');
  std::istringstream in(t);
  std::vector<double> v;
  std::string token;
  while (in >> token) {
    double x = 0;
    if (!detail::parse_finite(token, x))
      throw InputError(option, text, "'" + token + "' is not a finite number");
    v.push_back(x);
  }
  if (v.size() != 16)
    throw InputError(option, text, "expected 16 numbers (a 4x4 matrix, row by row)");
  Mat4 m;
  for (int k = 0; k < 16; ++k)
    m(k / 4, k % 4) = v[k];
  if (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || m(3, 3) != 1)
    throw InputError(option, text, "the last row of the matrix must be 0 0 0 1");
  if (!detail::invertible(m))
    throw InputError(option, text, "the matrix is singular");
  return m;
}
} // namespace

int run_transfer(const TransferArgs& a) {
  const Rig rig = read_rig(a.rig);
  const SurfaceMesh source = load_mesh_noting(a.from), target = load_mesh_noting(a.to);
  TransferOptions opt;
  if (!a.source_frame.empty())
    opt.source_frame = parse_matrix(a.source_frame, "--source-frame");
  if (!a.target_frame.empty())
    opt.target_frame = parse_matrix(a.target_frame, "--target-frame");
  if ((opt.alignment = parse_alignment(a.align, "--align")) != Alignment::Frames) // skins' joints, in mesh space
    std::tie(opt.source_skeleton, opt.target_skeleton) =
        std::pair(skin_joints_if_any(a.from), skin_joints_if_any(a.to));
  opt.source_cage_levels = a.from_cage;
  opt.target_cage_levels = a.to_cage;
  opt.max_faces = a.max_faces;
  // Which cage option gave the levels a refusal names.
  const std::string cage_option = a.from_cage == 0           ? "--to-cage"
                                  : a.to_cage == 0           ? "--from-cage"
                                  : a.from_cage == a.to_cage ? "--to-cage/--from-cage"
                                                             : "";
  const TransferResult r =
      cage_option.empty() ? naming_levels_option(a.to, "--to-cage",
                                                 [&] {
                                                   return naming_levels_option(a.from, "--from-cage", [&] {
                                                     return transfer(rig, source, target, opt);
                                                   });
                                                 })
                          : naming_levels_option("", cage_option, [&] { return transfer(rig, source, target, opt); });
  const TransferReport& rep = r.report;
  OutputFiles files; // the report and the rig, all or nothing
  if (!a.report.empty())
    files.add(a.report, transfer_report_json(rep));
  if (rep.ok)
    files.add(a.out, rig_to_json(r.rig));
  files.commit();
  for (const auto& n : rep.notes)
    std::cerr << "note: " << n << "\n";
  print_transfer(std::cout, a.from, source.num_faces(), a.to, target.num_faces(), rep, a.out);
  if (!rep.ok && !rep.problems.empty()) // the refusal in one line, beside the report
    std::cerr << "curvenet: error: " << a.to << ": " << rep.problems.front() << "\n";
  return rep.ok ? 0 : 1;
}

int run_subdivide(const SubdivideArgs& a) {
  const SurfaceMesh cage = load_mesh_noting(a.cage);
  const SurfaceMesh s =
      naming_levels_option("", "--levels", [&] { return catmull_clark(cage, a.levels, a.max_faces); });
  write_file_atomic(a.out, mesh_to_obj(s.positions, s.face_offsets, s.face_vertices));
  std::cout << "Catmull-Clark, " << a.levels << (a.levels == 1 ? " level: " : " levels: ") << cage.num_faces()
            << " faces -> " << s.num_faces() << " quads, " << s.num_vertices() << " vertices\n"
            << "mesh: " << a.out << "\n";
  return 0;
}

int run_compare(const CompareArgs& a) {
  std::ostream& notes = a.json ? std::cerr : std::cout; // JSON alone on standard output
  const SurfaceMesh ma = load_mesh_noting(a.a, notes), mb = load_mesh_noting(a.b, notes);
  const SurfaceDistance d = surface_distance(ma, mb);
  std::ostringstream out;
  out << std::setprecision(6);
  if (a.json) {
    auto one = [&](const char* key, const OneWayDistance& o) {
      out << "  \"" << key << "\": {\"mean\": " << o.mean << ", \"rms\": " << o.rms << ", \"max\": " << o.max << "},\n";
    };
    out << "{\n";
    one("a_to_b", d.a_to_b);
    one("b_to_a", d.b_to_a);
    out << "  \"mean\": " << d.mean << ", \"rms\": " << d.rms << ", \"max\": " << d.max << ",\n";
    out << "  \"diagonal\": " << d.diagonal << ",\n";
    out << "  \"mean_percent\": " << d.percent(d.mean) << ", \"rms_percent\": " << d.percent(d.rms)
        << ", \"max_percent\": " << d.percent(d.max) << "\n}\n";
  } else {
    out << "A: " << a.a << " (diagonal " << d.diagonal << ")\nB: " << a.b << "\n";
    out << "mean: " << d.mean << " (" << d.percent(d.mean) << "% of A's diagonal)\n";
    out << "rms: " << d.rms << " (" << d.percent(d.rms) << "%)\n";
    out << "max: " << d.max << " (" << d.percent(d.max) << "%, Hausdorff)\n";
  }
  std::cout << out.str();
  return 0;
}

int run_starter(const StarterArgs& a) {
  const SurfaceMesh mesh = load_mesh_noting(a.mesh);
  if (a.skeleton.empty() && !is_skinned_file(a.mesh))
    throw InputError(
        a.mesh, "",
        "has no skin to take a skeleton from: give one with --skeleton (a rig file, or a skinned glTF or FBX)");
  const SkeletonFile skeleton =
      a.skeleton.empty() ? read_skeleton_file(a.mesh) : read_skeleton_file(a.skeleton, mesh);
  if (!skeleton.note.empty())
    std::cout << "note: " << skeleton.note << "\n";
  const std::vector<Joint>& joints = skeleton.joints;
  StarterOptions opt;
  opt.deforming = skeleton.deforming; // a skin says which joints deform
  opt.nodes_per_ring = a.nodes_per_ring;
  opt.rings_per_bone = a.rings_per_bone;
  opt.middle_nodes = a.middle_nodes;
  opt.first_angle_deg = a.first_angle;
  opt.coverage = parse_coverage(a.coverage);
  opt.weights = {a.weight_rule == "segment" ? WeightRule::Segment : WeightRule::BlendZone, a.blend};
  // The mesh's own skin weights the nodes where it has one (docs/starter.md).
  std::optional<SkinnedMesh> skin;
  if ((a.weight_rule == "auto" || a.weight_rule == "skin") && is_skinned_file(a.mesh))
    skin = load_skinned_mesh(a.mesh);
  if (a.weight_rule == "skin" && !skin)
    throw InputError(a.mesh, "", "has no skin to take node weights from (--weight-rule skin)");
  if (skin)
    opt.skin = &*skin;
  opt.message = [](const std::string& m) { std::cout << "note: " << m << "\n"; };
  const StarterResult r = make_starter(mesh, joints, opt);
  write_rig(r.rig, a.out);
  print_starter(std::cout, a.mesh, mesh, joints.size(), r, opt);
  std::cout << "rig: " << a.out << "\n";
  return 0;
}

} // namespace curvenet::cli
