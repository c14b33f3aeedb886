#include "commands.hpp"

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
  for (const auto& n : m.notes)
    if (n.rfind("left out", 0) == 0 || n.rfind("repaired", 0) == 0)
      notes << "note: " << std::filesystem::path(path).filename().string() << ": " << n << "\n";
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

void print_summary(std::ostream& out, const std::string& mesh_name, const EmbedReport& r) {
  out << "Curvenet embedding: " << (r.ok ? "SUCCESS" : "FAILED") << "\n";
  out << "mesh: " << mesh_name << " (" << r.input_vertices << " vertices, " << r.input_faces << " faces)\n";
  out << "coverage: " << to_string(r.coverage) << "\n";
  out << "logical nodes: " << r.logical_nodes << "\n";
  out << "physical nodes: " << r.physical_nodes << "\n";
  out << "profiles: " << r.profiles << "\n";
  out << "components: " << r.components << "\n";
  out << "regions: " << r.regions << "\n";
  out << "expected regions: " << (r.expected_regions ? std::to_string(*r.expected_regions) : "not determined") << "\n";
  out << "mapped faces: " << r.mapped_faces << "\n";
  out << "unmapped faces: " << r.unmapped_faces << "\n";
  if (r.outside_faces)
    out << "outside faces: " << r.outside_faces << "\n";
  out << "cut mesh: " << r.cut_vertices << " vertices, " << r.cut_faces << " faces\n";
  {
    // The profile that strays most from its curve, and by how much.
    std::string worst;
    for (const auto& [id, d] : r.fidelity)
      if (d == r.fidelity_max)
        worst = id;
    const double diag = r.diagonal > 0 ? r.diagonal : 1.0;
    out << "chain fidelity: " << std::setprecision(3) << r.fidelity_max << " (" << r.fidelity_max / diag
        << " of the diagonal" << (worst.empty() ? "" : ", profile '" + worst + "'") << "), tolerance "
        << r.fidelity_tolerance << (r.fidelity_enforced ? "" : " (a cage: not enforced)") << "\n"
        << std::setprecision(6);
  }
  double total = 0;
  for (const auto& [s, ms] : r.timings_ms)
    total += ms;
  out << "time: " << std::fixed << std::setprecision(1) << total << " ms\n" << std::defaultfloat;
  for (const auto& p : r.problems)
    out << "problem: " << p << "\n";
  for (const auto& n : r.notes)
    out << "note: " << n << "\n";
}

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
    const std::string what = e.what(), prefix = e.file() + ": " + e.element() + ": ";
    throw InputError(e.file(), option + " " + e.element().substr(7),
                     what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what);
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
  print_summary(std::cout, std::filesystem::path(a.mesh).filename().string(), rep);
  return rep.ok ? 0 : 1;
}

namespace {

std::string lower_ext(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

/// The rig, with its skeleton replaced by --skeleton when given (joints matched by name).
Rig rig_for(const DeformArgs& a) {
  Rig rig = read_rig(a.rig);
  if (!a.skeleton.empty())
    rig = with_skeleton(std::move(rig), load_skeleton(a.skeleton), a.skeleton);
  if (!rig.has_skeleton)
    throw InputError(a.rig, "/skeleton", "the rig has no skeleton: give one in the rig or with --skeleton");
  return rig;
}

BindOptions bind_options(const DeformArgs& a);

/// A new binding cache joins `files`, the command's other outputs: written with them or not at all.
Binding bind_for(const SurfaceMesh& mesh, const Rig& rig, const DeformArgs& a, OutputFiles& files) {
  return naming_rig(a.rig, [&] {
    if (a.binding_cache.empty())
      return bind(mesh, rig, bind_options(a));
    return bind_cached(mesh, rig, bind_options(a), a.binding_cache, nullptr, &files);
  });
}

BindOptions bind_options(const DeformArgs& a) {
  BindOptions o;
  o.laplacian = a.laplacian == "uniform" ? LaplacianChoice::Uniform : LaplacianChoice::IntrinsicDelaunay;
  o.rigid = a.rigid == "horn" ? RigidMode::Horn : RigidMode::PerVertex;
  parse_deform_method(a.method, o.method); // the CLI checks the spelling
  o.rotation_blend =
      a.rotation == "quaternion" ? BindOptions::RotationBlend::Quaternion : BindOptions::RotationBlend::Polar;
  o.curve_frames = a.curve_frames;
  return o;
}

void print_bind(std::ostream& out, const Binding& b) {
  const BindReport& r = b.report();
  out << "binding: " << r.vertices << " mesh vertices; on the cut mesh, " << r.constrained << " on the curves, "
      << r.free << " solved for, " << r.rigid << " rigid\n";
  out << "influences per vertex: " << std::fixed << std::setprecision(2) << r.mean_influences << std::defaultfloat
      << std::setprecision(6) << "\n";
  out << "negative Laplacian weights: " << r.negative_weights_before << " before, " << r.negative_weights_after
      << " after " << r.flips << " intrinsic flips (" << r.negative_weights_solved
      << " at a vertex solved for; the others lie along the curves, outside the solve)\n";
  double total = 0;
  for (const auto& [s, ms] : r.timings_ms)
    total += ms;
  out << "bind time: " << std::fixed << std::setprecision(1) << total << " ms\n"
      << std::defaultfloat << std::setprecision(6);
  for (const auto& n : r.notes)
    out << "note: " << n << "\n";
}

} // namespace

int run_bind(const BindArgs& a) {
  const SurfaceMesh mesh = load_mesh_noting(a.mesh);
  const Rig rig = rig_for(a);
  OutputFiles files;
  const Binding b = bind_for(mesh, rig, a, files);
  Rig out = rig;
  out.weights = b.node_weights();
  write_rig(out, a.out);
  files.commit(); // the cache, after the rig
  std::cout << "Curvenet bind: SUCCESS\n";
  print_bind(std::cout, b);
  std::cout << "rig: " << a.out << "\n";
  return 0;
}

namespace {
/// Positions a pose or clip put out of range are refused, naming that file.
void check_posed(const std::vector<Vec3>& positions, const std::string& file, const std::string& what) {
  for (size_t v = 0; v < positions.size(); ++v)
    if (!positions[v].allFinite())
      throw InputError(file, what + "vertex " + std::to_string(v),
                       "the pose moves it out of range (not a finite number); nothing was written");
}
} // namespace

int run_pose(const PoseArgs& a) {
  const SurfaceMesh mesh = load_mesh_noting(a.mesh);
  const InputTopology topo = read_input_topology(a.mesh);
  const Rig rig = rig_for(a);
  const Pose pose = read_pose(a.pose);
  OutputFiles files; // the mesh and the binding cache, all or nothing
  const Binding b = bind_for(mesh, rig, a, files);
  const auto M = skinning_matrices(b.joints(), pose, a.pose);
  std::vector<Vec3> out(b.num_input_vertices());
  b.deform(M, out);
  check_posed(out, a.pose, "");
  files.add(a.out, posed_obj(topo, out)); // deform() returns the file's own vertex order
  if (!a.cut_mesh.empty()) {
    const CutMeshBinding cut = naming_rig(a.rig, [&] { return bind_cut_mesh(mesh, rig, bind_options(a), &b); });
    files.add(a.cut_mesh, cut.posed_obj(M));
  }
  files.commit();
  std::cout << "Curvenet pose: SUCCESS\n";
  print_bind(std::cout, b);
  std::cout << "output: " << a.out << " (" << out.size() << " vertices)\n";
  return 0;
}

int run_animate(const AnimateArgs& a) {
  const SurfaceMesh mesh = load_mesh_noting(a.mesh);
  const Rig rig = rig_for(a);
  const SkinnedMesh clips = load_skinned_mesh(a.clip_file);
  if (clips.num_clips() == 0)
    throw InputError(a.clip_file, "/animations", "the file has no animation clips");
  const int clip = a.clip.empty() ? 0 : clips.find_clip(a.clip);
  if (clip < 0)
    throw InputError(a.clip_file, "clip '" + a.clip + "'", "no clip has this name or index");
  const FrameRange range = frame_range(clips, clip, a.fps, a.frames, a.max_frames);
  (void)clip_skinning_matrices(rig.joints, clips, clip, range.time(range.first)); // a clip for this skeleton
  // All or nothing: the frames go to temporary files, moved into place at
  // the end (a folder this run made goes with them on a failure).
  OutputFiles files;
  const Binding b = bind_for(mesh, rig, a, files);
  std::optional<InputTopology> topo;
  std::unique_ptr<FrameSink> sink;
  if (!a.obj_sequence.empty()) {
    topo = read_input_topology(a.mesh);
    sink = std::make_unique<ObjSequenceSink>(files, a.obj_sequence, *topo);
  } else {
    sink = std::make_unique<Pc2Sink>(files, a.out, b.num_input_vertices(), range, a.clip_file);
  }
  FrameSink* sinks[] = {sink.get()};
  animate(b, clips, clip, range, sinks);
  if (!a.cut_mesh_sequence.empty()) {
    const CutMeshBinding cut = naming_rig(a.rig, [&] { return bind_cut_mesh(mesh, rig, bind_options(a), &b); });
    FunctionSink cut_frames([&](int frame, std::span<const Vec3> positions) {
      files.add((std::filesystem::path(a.cut_mesh_sequence) / sequence_name("cut_frame", frame)).string(),
                cut.embedding.cut_mesh_obj(positions));
    });
    FrameSink* cut_sinks[] = {&cut_frames};
    animate(cut.binding, clips, clip, range, cut_sinks);
  }
  files.commit();
  std::cout << "Curvenet animate: SUCCESS\n";
  print_bind(std::cout, b);
  std::cout << "clip: " << clips.clip_names[clip] << " (" << clip << "), frames " << range.first << ":" << range.last
            << " at " << a.fps << " fps\n";
  std::cout << "output: " << (a.obj_sequence.empty() ? a.out : a.obj_sequence) << " (" << range.count() << " frames, "
            << b.num_input_vertices() << " vertices)\n";
  return 0;
}

/// Skinning matrices of every frame of every clip of a file, for `joints`.
std::vector<std::vector<Mat4>> clip_poses(const std::vector<Joint>& joints, const SkinnedMesh& clips, double fps,
                                          long long max_frames) {
  std::vector<std::vector<Mat4>> poses;
  for (int c = 0; c < clips.num_clips(); ++c) {
    const auto [first, last] = clip_frames(clips, c, fps);
    for (int f = first; f <= last; ++f) {
      if (static_cast<long long>(poses.size()) >= max_frames)
        throw InputError(clips.source, "clip '" + clips.clip_names[c] + "'",
                         "more than " + std::to_string(max_frames) + " frames to fit over");
      poses.push_back(clip_skinning_matrices(joints, clips, c, f / fps));
    }
  }
  return poses;
}

int run_bake(const BakeArgs& a) {
  const SurfaceMesh mesh = load_mesh_noting(a.mesh);
  const Rig rig = rig_for(a);
  std::optional<SkinnedMesh> clips, fit;
  if (!a.clip_file.empty()) {
    clips = load_skinned_mesh(a.clip_file);
    for (const auto& name : a.clip_names)
      if (clips->find_clip(name) < 0)
        throw InputError(a.clip_file, "clip '" + name + "'", "no clip has this name");
  } else if (!a.clip_names.empty()) {
    throw InputError("--clip-name", a.clip_names.front(), "give the clip file with --clip");
  }
  if (!a.fit.empty()) {
    fit = load_skinned_mesh(a.fit);
    if (fit->num_clips() == 0)
      throw InputError(a.fit, "/animations", "the file has no animation clips to fit over");
    (void)clip_skinning_matrices(rig.joints, *fit, 0, fit->clip_range(0).first); // a clip for this skeleton
  }
  OutputFiles files; // all or nothing
  const Binding b = bind_for(mesh, rig, a, files);
  const SkinWeights w = fit ? fit_weights(b, clip_poses(b.joints(), *fit, a.fps, 100000), a.max_influences)
                            : bake_weights(b, a.max_influences);
  GltfBakeOptions opt;
  opt.up = a.up == "z" ? GltfBakeOptions::Up::Z : GltfBakeOptions::Up::Y;
  opt.fps = a.fps;
  opt.clips = a.clip_names;
  if (!a.out.empty())
    files.add(a.out, skinned_glb(a.mesh, b.joints(), w, clips ? &*clips : nullptr, opt));
  if (!a.weights_csv.empty())
    files.add(a.weights_csv, weights_csv(w));
  files.commit();
  int used = 0, most = 0;
  for (int v = 0; v < w.num_vertices(); ++v) {
    int n = 0;
    for (int i = 0; i < w.influences; ++i)
      n += w.joint[static_cast<size_t>(v) * w.influences + i] >= 0;
    used += n;
    most = std::max(most, n);
  }
  std::cout << "Curvenet bake: SUCCESS\n";
  print_bind(std::cout, b);
  std::cout << "weights: "
            << (fit ? "fitted to the deformation over " + a.fit
                    : std::string("harmonic, top ") + std::to_string(w.influences))
            << ", " << std::fixed << std::setprecision(2)
            << (w.num_vertices() ? static_cast<double>(used) / w.num_vertices() : 0.0) << std::defaultfloat
            << std::setprecision(6) << " joints per vertex on average, " << most << " at most, " << w.joints.size()
            << " joints\n";
  if (clips)
    std::cout << "clips: " << (a.clip_names.empty() ? clips->num_clips() : static_cast<int>(a.clip_names.size()))
              << " from " << a.clip_file << " at " << a.fps << " keys per second\n";
  if (!a.out.empty())
    std::cout << "glTF: " << a.out << " (" << w.num_vertices() << " vertices, Y-up"
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
  std::cout << "Curvenet transfer: " << (rep.ok ? "SUCCESS" : "FAILED") << "\n";
  std::cout << "source: " << std::filesystem::path(a.from).filename().string() << " (" << source.num_faces()
            << " faces), " << rep.source.regions << " regions\n";
  std::cout << "target: " << std::filesystem::path(a.to).filename().string() << " (" << target.num_faces()
            << " faces), " << rep.target.regions << " regions, expected "
            << (rep.target.expected_regions ? std::to_string(*rep.target.expected_regions) : "not determined") << "\n";
  std::cout << "logical nodes: " << rep.target.logical_nodes << "\nprofiles: " << rep.target.profiles << "\n";
  std::cout << "unmapped faces: " << rep.target.unmapped_faces << "\n";
  std::cout << std::fixed << std::setprecision(2) << "region agreement: " << 100 * rep.agreement << "% of the area\n";
  const RegionAgreement* worst = nullptr;
  for (const auto& g : rep.regions)
    if (!worst || g.agree < worst->agree)
      worst = &g;
  if (worst)
    std::cout << "least agreeing region: " << 100 * worst->agree << "% (" << worst->key << ")\n";
  std::cout << "surfaces apart before the transfer: " << rep.shape.percent(rep.shape.mean)
            << "% of the diagonal on average, " << rep.shape.percent(rep.shape.max) << "% at most\n";
  std::cout << "largest node move onto the target: " << rep.max_node_offset << "% of the diagonal\n"
            << std::defaultfloat << std::setprecision(6);
  for (const auto& p : rep.problems)
    std::cout << "problem: " << p << "\n";
  if (rep.ok)
    std::cout << "rig: " << a.out << "\n";
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
  std::vector<Joint> joints;
  StarterOptions opt;
  if (!a.skeleton.empty()) {
    joints = load_skeleton(a.skeleton);
    const std::string ext = lower_ext(a.skeleton);
    if (ext == ".gltf" || ext == ".glb" || ext == ".fbx") // a skin says which joints deform
      opt.deforming = weighted_joints(load_skinned_mesh(a.skeleton));
  } else {
    const std::string ext = lower_ext(a.mesh);
    if (ext != ".gltf" && ext != ".glb" && ext != ".fbx")
      throw InputError(
          a.mesh, "",
          "has no skin to take a skeleton from: give one with --skeleton (a rig file, or a skinned glTF or FBX)");
    const SkinnedMesh skin = load_skinned_mesh(a.mesh);
    joints = skin.joints;
    opt.deforming = weighted_joints(skin);
  }
  opt.nodes_per_ring = a.nodes_per_ring;
  opt.rings_per_bone = a.rings_per_bone;
  opt.first_angle_deg = a.first_angle;
  opt.coverage = a.coverage == "local" ? Coverage::Local : Coverage::Full;
  opt.weights = {a.weight_rule == "segment" ? WeightRule::Segment : WeightRule::BlendZone, a.blend};
  opt.message = [](const std::string& m) { std::cout << "note: " << m << "\n"; };
  const StarterResult r = make_starter(mesh, joints, opt);
  write_rig(r.rig, a.out);
  const int V = static_cast<int>(r.rig.nodes.size()), E = static_cast<int>(r.rig.profiles.size());
  std::cout << "Curvenet starter: SUCCESS\n";
  std::cout << "mesh: " << std::filesystem::path(a.mesh).filename().string() << " (" << mesh.num_vertices()
            << " vertices, " << mesh.num_faces() << " faces)\n";
  std::cout << "joints: " << joints.size() << "\n";
  std::cout << "rings: " << r.rings << "\n";
  std::cout << "nodes: " << V << "\n";
  std::cout << "profiles: " << E << "\n";
  std::cout << "components: " << r.net_components << "\n";
  std::cout << "joins: " << r.joins << "\n";
  std::cout << "unjoined chains: " << r.unjoined << "\n";
  std::cout << "weights: "
            << (opt.weights.rule == WeightRule::Segment
                    ? std::string("segment")
                    : "blend-zone " + std::to_string(opt.weights.blend).substr(0, 4))
            << "\n";
  std::cout << "joints without a ring: " << r.ringless.size() << "\n";
  for (const auto& [joint, why] : r.ringless)
    std::cout << "  " << joint << ": " << why << "\n";
  std::cout << "rig: " << a.out << "\n";
  return 0;
}

int run_demo(const DemoArgs& a) {
  namespace fs = std::filesystem;
  const fs::path out(a.out);
  fs::create_directories(out);
  std::cout << "curvenet demo: the thesis's tube net on two tessellations of a capped tube\n";
  const Rig rig = make_tube_net();
  write_rig(rig, (out / "tube.cnrig.json").string());
  struct Case {
    const char* name;
    TubeSpec spec;
  };
  TubeSpec quads;
  TubeSpec tris;
  tris.around = 24;
  tris.along = 20;
  tris.cap_rings = 6;
  tris.triangulate = true;
  const Case cases[] = {{"tube_quads", quads}, {"tube_tris", tris}};
  std::vector<std::string> lines;
  bool all_ok = true;
  for (const auto& c : cases) {
    const RawMesh raw = make_capped_tube(c.spec);
    const std::string mesh_path = (out / (std::string(c.name) + ".obj")).string();
    write_file_atomic(mesh_path, mesh_to_obj(raw.positions, raw.face_offsets, raw.face_vertices));
    const SurfaceMesh mesh = make_surface_mesh(raw, mesh_path);
    const Embedding emb = embed(mesh, rig);
    write_file_atomic((out / (std::string(c.name) + ".report.json")).string(), report_to_json(emb.report()));
    write_file_atomic((out / (std::string(c.name) + ".regions.ply")).string(), emb.regions_ply());
    write_file_atomic((out / (std::string(c.name) + ".cut.obj")).string(), emb.cut_mesh_obj());
    std::cout << "\n";
    print_summary(std::cout, fs::path(mesh_path).filename().string(), emb.report());
    const auto& r = emb.report();
    all_ok = all_ok && r.ok;
    std::ostringstream s;
    s << c.name << ": " << (r.ok ? "SUCCESS" : "FAILED") << ", " << r.input_faces << " faces, " << r.regions << "/"
      << (r.expected_regions ? std::to_string(*r.expected_regions) : "?") << " regions";
    lines.push_back(s.str());
  }
  // A starter net from a skeleton along the tube, made on the quad tube and
  // embedded on both.
  {
    StarterOptions so;
    const SurfaceMesh quad_mesh = make_surface_mesh(make_capped_tube(quads), "tube_quads");
    const StarterResult st = make_starter(quad_mesh, make_tube_skeleton({0.3, 1.2, 2.1, 3.0, 3.7}), so);
    write_rig(st.rig, (out / "tube_starter.cnrig.json").string());
    int ok = 0;
    for (const auto& c : cases) {
      const Embedding emb = embed(make_surface_mesh(make_capped_tube(c.spec), c.name), st.rig);
      ok += emb.report().ok;
      all_ok = all_ok && emb.report().ok;
    }
    std::ostringstream s;
    s << "starter: " << st.rings << " rings, " << st.rig.nodes.size() << " nodes, " << st.rig.profiles.size()
      << " profiles from a 5-joint skeleton; embeds on " << ok << "/2 tessellations";
    lines.push_back(s.str());
  }
  // Transfer the net from the quad tube to the triangle tube, by ids only.
  {
    const SurfaceMesh from = make_surface_mesh(make_capped_tube(quads), "tube_quads");
    const SurfaceMesh to = make_surface_mesh(make_capped_tube(tris), "tube_tris");
    const TransferResult tr = transfer(rig, from, to);
    write_rig(tr.rig, (out / "tube_tris.transferred.cnrig.json").string());
    write_file_atomic((out / "transfer.report.json").string(), transfer_report_json(tr.report));
    all_ok = all_ok && tr.report.ok;
    std::ostringstream s;
    s << "transfer tube_quads -> tube_tris: " << (tr.report.ok ? "SUCCESS" : "FAILED") << ", "
      << tr.report.target.regions << "/" << tr.report.source.regions << " regions, " << std::fixed
      << std::setprecision(2) << 100 * tr.report.agreement << "% of the area in the region of the same identity"
      << std::defaultfloat << std::setprecision(6);
    lines.push_back(s.str());
  }
  // Bend the tube's two joints over 24 frames, through the tube net, on both
  // tessellations: a PC2 cache each, and the last frame as OBJ.
  {
    for (const auto& c : cases) {
      const SurfaceMesh mesh = make_surface_mesh(make_capped_tube(c.spec), c.name);
      const Binding b = bind(mesh, rig);
      const int frames = 24, nv = b.num_input_vertices();
      std::vector<float> data;
      std::vector<Vec3> posed(nv);
      for (int f = 0; f < frames; ++f) {
        const double s = static_cast<double>(f) / (frames - 1);
        Pose pose;
        pose["mid"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.8 * s, Eigen::Vector3d::UnitZ()));
        pose["tip"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.6 * s, Eigen::Vector3d::UnitZ()));
        b.deform(skinning_matrices(b.joints(), pose), posed);
        for (const Vec3& p : posed)
          for (int k = 0; k < 3; ++k)
            data.push_back(static_cast<float>(p[k]));
      }
      const std::string base = (out / c.name).string();
      write_file_atomic(base + ".bend.pc2", pc2_cache(nv, frames, 0.0f, data));
      write_file_atomic(base + ".bent.obj", posed_obj(read_input_topology(base + ".obj"), posed));
      std::ostringstream line;
      line << "bend " << c.name << ": " << frames << " frames, " << std::fixed << std::setprecision(2)
           << b.report().mean_influences << " influences per vertex" << std::defaultfloat << std::setprecision(6);
      lines.push_back(line.str());
      // The same binding baked to an ordinary skin: a skinned glTF any engine
      // reads (the tube stands along Z: turned to glTF's Y-up).
      GltfBakeOptions bake;
      bake.up = GltfBakeOptions::Up::Z;
      const SkinWeights w = bake_weights(b, 4);
      write_file_atomic(base + ".baked.glb", skinned_glb(base + ".obj", b.joints(), w, nullptr, bake));
      lines.push_back(std::string("bake ") + c.name + ": " + c.name + ".baked.glb, a skin of " +
                      std::to_string(w.joints.size()) + " joints, 4 influences at most");
    }
  }
  std::cout << "\nsummary:\n";
  for (const auto& l : lines)
    std::cout << "  " << l << "\n";
  std::cout << "outputs in " << out.string()
            << "/ (meshes, rigs, reports, region previews, cut meshes, bend caches: Mesh Cache, forward +Y, up +Z, on "
               "the OBJ; baked skins as glTF)\n";
  return all_ok ? 0 : 1;
}

} // namespace curvenet::cli
