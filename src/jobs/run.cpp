// The file-to-file jobs: bind, pose, animate and bake, each read, computed
// and written all or nothing.

#include "jobs/run.hpp"
#include "core/convex_least_squares.hpp"
#include "core/numbers.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/layer.hpp"
#include "curvenet/pose.hpp"
#include "io/file_bytes.hpp"
#include "io/frames_part.hpp"
#include "io/json_text.hpp"
#include "skeleton/skeleton_fit.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

namespace curvenet {
namespace {

/// Whether two paths name one file (by name when either cannot be resolved).
bool same_file(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty())
    return a == b;
  std::error_code ea, eb;
  const auto ca = std::filesystem::weakly_canonical(a, ea), cb = std::filesystem::weakly_canonical(b, eb);
  return ea || eb ? a == b : ca == cb;
}

/// Why a clip file's skeleton is not the rig's, or nothing: the rest
/// transforms of the joints both have, each relative to its parent (a
/// similarity put round the whole skeleton, as a transfer does, changes
/// none of them but the roots', which are left out). A bone whose rest
/// length differs by more than 5 %, or whose rest frame turns by more than
/// 10 degrees, against the rig's: pose entries of such a clip mean other
/// motions on the rig (a file exported in other units, or with other bone
/// axes).
std::string skeletons_differ(const std::vector<Joint>& rig, const std::vector<Joint>& clip) {
  std::map<std::string, const Joint*> in_clip, in_rig;
  for (const Joint& j : clip)
    in_clip[j.name] = &j;
  for (const Joint& j : rig)
    in_rig[j.name] = &j;
  auto local = [](const std::map<std::string, const Joint*>& all, const Joint& j) -> std::optional<Mat4> {
    if (!j.parent)
      return std::nullopt;
    const auto p = all.find(*j.parent);
    if (p == all.end())
      return std::nullopt;
    return Mat4(p->second->bind.inverse() * j.bind);
  };
  double extent = 0;
  for (const Joint& j : rig)
    for (const Joint& k : rig)
      extent = std::max(extent, (j.bind.col(3) - k.bind.col(3)).norm());
  for (const Joint& j : rig) {
    const auto c = in_clip.find(j.name);
    if (c == in_clip.end())
      continue;
    const auto a = local(in_rig, j), b = local(in_clip, *c->second);
    if (!a || !b || !a->allFinite() || !b->allFinite())
      continue;
    const double la = a->block<3, 1>(0, 3).norm(), lb = b->block<3, 1>(0, 3).norm();
    if (la > 1e-3 * extent && !(lb > 0.95 * la && lb < 1.05 * la)) {
      std::ostringstream why;
      why << "joint '" << j.name << "' rests " << lb / la << " times as far from its parent";
      return why.str();
    }
    const Eigen::Quaterniond qa(Eigen::Matrix3d(a->block<3, 3>(0, 0).colwise().normalized()));
    const Eigen::Quaterniond qb(Eigen::Matrix3d(b->block<3, 3>(0, 0).colwise().normalized()));
    if (const double turn = qa.angularDistance(qb) * 180 / 3.14159265358979323846; turn > 10) {
      std::ostringstream why;
      why << "joint '" << j.name << "' rests turned " << std::lround(turn) << " degrees against the rig's";
      return why.str();
    }
  }
  return "";
}

/// Where a clip file puts its skeleton under an armature that scales it (its
/// root keys carry that scale), and the rig's skeleton is the file's scaled
/// as a whole (a transfer to a mesh exported with the armature applied, as
/// Blender re-exports a glTF): the keys then scale the rig's mesh a second
/// time. Says so, with both scales; empty otherwise.
std::string armature_twice(const std::vector<Joint>& rig, const SkinnedMesh& clips) {
  if (placed_by_armature(rig, clips)) // its keys are taken against the armature's rest: applied once
    return "";
  // The keys carry the scale where the file's skin at rest is scaled: the
  // armature is outside its inverse bind matrices (a re-export that puts it
  // in them rests at its vertices' size, and its keys scale nothing).
  double armature = 1;
  const std::vector<Mat4> rest = clips.skinning_matrices(-1, 0);
  for (size_t j = 0; j < clips.joints.size() && j < rest.size(); ++j)
    if (!clips.joints[j].parent) {
      armature = std::cbrt(std::abs(rest[j].topLeftCorner<3, 3>().determinant()));
      break;
    }
  if (!(armature > 1.05 || armature < 1 / 1.05))
    return "";
  const auto fitted = detail::skeleton_similarity(rig, clips);
  if (!fitted)
    return "";
  const Mat4& g = *fitted;
  const double scale = std::cbrt(std::abs(g.topLeftCorner<3, 3>().determinant()));
  if (!std::isfinite(scale) || (scale < 1.05 && scale > 1 / 1.05))
    return "";
  std::ostringstream why;
  why << std::setprecision(3) << "its armature scales its skeleton by " << armature
      << ", and its root keys carry that scale; the rig's skeleton is this file's scaled by " << scale
      << " as a whole, so the keys may scale the rig's mesh a second time";
  return why.str();
}

JobSummary summary_of(const BoundScene& s) {
  JobSummary j;
  j.bind = s.binding.report();
  j.notes = s.notes;
  j.vertices = s.binding.num_input_vertices();
  return j;
}

/// The net as a layer over its own deformation, for the posed cut mesh
/// (CurveLayer::deform_cut): the scene's binding, or a new one when it came
/// from a cache without its embedding; an embedding failure names the rig file.
CurveLayer cut_layer(const BoundScene& s, const BindOptions& options) {
  try {
    LayerOptions lo;
    lo.bind = options;
    return bind_layer(s.mesh, s.rig, nullptr, lo, &s.binding);
  } catch (const EmbedError& e) {
    throw EmbedError(s.files.rig + ": " + e.what());
  }
}

/// Whether a bake carries clip `c`: every clip when no names are given, else
/// the clips the names find as find_clip finds them ("Walk" for
/// "AnimalArmature|Walk", or an index), as skinned_glb writes them.
bool carries(const SkinnedMesh& clips, const std::vector<std::string>& names, int c) {
  return names.empty() ||
         std::any_of(names.begin(), names.end(), [&](const std::string& n) { return clips.find_clip(n) == c; });
}


/// A mask file's `text`: one number from 0 to 1 per vertex of the mesh
/// file, one a line (blank lines and `#` comments skipped).
std::vector<double> read_mask(const std::string& path, const std::string& text, int vertices) {
  std::istringstream in(text);
  std::vector<double> mask;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    const auto a = line.find_first_not_of(" \t\r"), b = line.find_last_not_of(" \t\r");
    if (a == std::string::npos || line[a] == '#')
      continue;
    double x = 0;
    if (!detail::parse_finite(std::string_view(line).substr(a, b - a + 1), x) || x < 0 || x > 1)
      throw InputError(path, "line " + std::to_string(n), "expected a number from 0 to 1");
    mask.push_back(x);
  }
  if (static_cast<int>(mask.size()) != vertices)
    throw InputError(path, "",
                     std::to_string(mask.size()) + " values for a mesh of " + std::to_string(vertices) +
                         " vertices: give one per vertex of the mesh file, in its order");
  return mask;
}

/// A mask by region: a JSON object {"regions": {region key: 0 to 1, ...},
/// "others": 0 to 1 (default 1), "falloff": a fraction of the diagonal
/// (default 0)}, the keys as the embed report lists them;
/// read_region_mask gives none for a text that is not a JSON object.
struct RegionMask {
  std::map<std::string, double> values;
  double others = 1;
  double falloff = 0;
};
std::optional<RegionMask> read_region_mask(const std::string& path, const std::string& text) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || text[first] != '{')
    return std::nullopt;
  const nlohmann::ordered_json j = detail::parse_json(text, path);
  RegionMask m;
  auto number = [&](const nlohmann::ordered_json& x, const std::string& where) {
    if (!x.is_number() || !(x.get<double>() >= 0 && x.get<double>() <= 1))
      throw InputError(path, where, "expected a number from 0 to 1");
    return x.get<double>();
  };
  for (const auto& [key, x] : j.items()) {
    if (key == "others") {
      m.others = number(x, "/others");
    } else if (key == "falloff") {
      m.falloff = number(x, "/falloff");
    } else if (key == "regions") {
      if (!x.is_object())
        throw InputError(path, "/regions", "expected an object of region keys and numbers from 0 to 1");
      for (const auto& [region, v] : x.items())
        m.values[region] = number(v, "region '" + region + "'");
    } else {
      throw InputError(path, "/" + key, "unknown member: a region mask has \"regions\", \"others\" and \"falloff\"");
    }
  }
  return m;
}

bool layered(const LayerSpec& l, bool offsets) {
  // Without a skin under it or node offsets, the layer corrects nothing:
  // an envelope or a mask would be silently ignored.
  if (!l.over_skin && !offsets && (!l.mask.empty() || l.envelope != 1))
    throw InputError(l.mask.empty() ? "--envelope" : "--mask", l.mask.empty() ? std::to_string(l.envelope) : l.mask,
                     "scales the layer's correction, and there is none to scale: give --over-skin, or node offsets "
                     "(a version 2 pose, or --node-keys)");
  return l.over_skin || offsets;
}

/// The scene's net as a layer; an embedding failure names the rig file.
CurveLayer layer_of(const Scene& s, const LayerSpec& spec, const BindOptions& options) {
  if (!s.files.binding_cache.empty())
    throw InputError("--binding-cache", s.files.binding_cache, "a layer is bound without a binding cache");
  if (!(spec.envelope >= 0 && spec.envelope <= 1))
    throw InputError("--envelope", std::to_string(spec.envelope), "expected a number from 0 to 1");
  std::optional<SkinnedMesh> skin;
  if (spec.over_skin) {
    if (!is_skinned_file(s.files.mesh))
      throw InputError(s.files.mesh, "", "has no skin to layer over: --over-skin needs a skinned glTF, GLB or FBX");
    skin = load_skinned_mesh(s.files.mesh);
  }
  LayerOptions opt;
  opt.bind = options;
  opt.skinning = spec.skinning;
  std::optional<RegionMask> by_region;
  if (!spec.mask.empty()) {
    const std::string text = detail::file_bytes(spec.mask);
    by_region = read_region_mask(spec.mask, text);
    if (!by_region)
      opt.mask = read_mask(spec.mask, text, static_cast<int>(s.mesh.input_to_welded.size()));
  }
  std::optional<CurveLayer> layer;
  try {
    layer.emplace(bind_layer(s.mesh, s.rig, skin ? &*skin : nullptr, opt));
  } catch (const EmbedError& e) {
    throw EmbedError(s.files.rig + ": " + e.what());
  }
  if (by_region) {
    try {
      return layer->with_mask(layer->region_mask(by_region->values, by_region->others, by_region->falloff));
    } catch (const InputError& e) { // the mask file, and the region it names
      throw InputError(spec.mask, e.element(), e.reason());
    }
  }
  return *layer;
}

JobSummary summary_of(const Scene& s, const CurveLayer& layer) {
  JobSummary j;
  j.bind = layer.binding().report();
  j.notes = s.notes;
  j.vertices = layer.num_input_vertices();
  return j;
}

} // namespace

namespace detail {

/// Refuses a clip file with no clips: an FBX's animation is not read (its
/// skeleton is), so it says so.
void need_clips(const SkinnedMesh& clips, const std::string& file, const std::string& why) {
  if (clips.num_clips() > 0)
    return;
  if (detail::lower_extension(file) == ".fbx")
    throw InputError(file, "animation", "clips are read from glTF or GLB files only (an FBX gives its skeleton): "
                                        "export the clips as glTF, e.g. from Blender");
  throw InputError(file, "/animations", "the file has no animation clips" + why);
}

/// The clip file's clip `name` (a name or an index; the first when empty).
int find_clip(const SkinnedMesh& clips, const std::string& file, const std::string& name) {
  need_clips(clips, file);
  const int clip = name.empty() ? 0 : clips.find_clip(name);
  if (clip < 0)
    throw InputError(file, "clip '" + name + "'", "no clip has this name or index");
  return clip;
}

} // namespace detail


std::vector<std::string> clip_notes(const std::vector<Joint>& rig, const SkinnedMesh& clips) {
  std::vector<std::string> notes;
  std::set<std::string> in_clips;
  for (const Joint& j : clips.joints)
    in_clips.insert(j.name);
  const auto matched =
      std::count_if(rig.begin(), rig.end(), [&](const Joint& j) { return in_clips.count(j.name) > 0; });
  if (matched < static_cast<long>(rig.size()))
    notes.push_back(clips.source + ": its skeleton has " + std::to_string(matched) + " of the rig's " +
                    std::to_string(rig.size()) + " joints (by name); the others stay at their rest pose");
  if (const std::string why = armature_twice(rig, clips); !why.empty())
    notes.push_back(clips.source + ": " + why +
                    ": a rig transferred to another file's mesh takes that file's skeleton with --skeleton FILE, "
                    "and its clips with it");
  if (const std::string why = skeletons_differ(rig, clips.joints); !why.empty())
    notes.push_back(clips.source + ": its skeleton is not the rig's (" + why +
                    "): its keys, taken against its own rest pose, move the rig's joints by other amounts "
                    "or about other axes; a rig transferred to this file's mesh takes its skeleton with "
                    "--skeleton " +
                    clips.source);
  return notes;
}

JobSummary run(const BindJob& job) {
  OutputFiles files;
  const BoundScene s = bind_scene(job.scene, job.options, files);
  Rig out = s.rig;
  out.weights = s.binding.node_weights();
  validate_rig(out, job.out);
  files.add(job.out, rig_to_json(out));
  files.commit(); // the rig and a new cache together
  return summary_of(s);
}

JobSummary run(const PoseJob& job) {
  const PoseFile pose = read_pose_file(job.pose);
  OutputFiles files; // the mesh, the cut mesh and the binding cache, all or nothing
  Scene scene = read_scene(job.scene);
  const InputTopology topology = read_input_topology(job.scene.mesh); // the parse load_mesh made
  auto check = [&](const std::vector<Vec3>& out) {
    for (size_t v = 0; v < out.size(); ++v)
      if (!out[v].allFinite())
        throw InputError(job.pose, "vertex " + std::to_string(v),
                         "the pose moves it out of range (not a finite number); nothing was written");
  };
  for (const auto& [id, o] : pose.nodes)
    if (scene.rig.node_index(id) < 0)
      throw InputError(job.pose, "/nodes/" + id, "the rig has no node of this id");
  if (layered(job.layer, !pose.nodes.empty())) {
    const CurveLayer layer = layer_of(scene, job.layer, job.options);
    const auto M = skinning_matrices(layer.joints(), pose.joints, job.pose);
    std::vector<Vec3> out(layer.num_input_vertices());
    layer.deform(M, out, job.layer.envelope, &pose.nodes);
    check(out);
    files.add(job.out, posed_obj(topology, out));
    if (!job.cut_mesh.empty()) {
      std::vector<Vec3> cut;
      layer.deform_cut(M, cut, job.layer.envelope, &pose.nodes);
      check(cut);
      files.add(job.cut_mesh, layer.binding().embedding().cut_mesh_obj(cut));
    }
    files.commit();
    return summary_of(scene, layer);
  }
  const BoundScene s = bind_scene(std::move(scene), job.options, files);
  const auto M = skinning_matrices(s.binding.joints(), pose.joints, job.pose);
  std::vector<Vec3> out(s.binding.num_input_vertices());
  s.binding.deform(M, out);
  check(out);
  files.add(job.out, posed_obj(topology, out)); // deform() gives the file's own vertex order
  if (!job.cut_mesh.empty()) {
    const CurveLayer layer = cut_layer(s, job.options);
    std::vector<Vec3> cut;
    layer.deform_cut(M, cut);
    check(cut);
    files.add(job.cut_mesh, layer.binding().embedding().cut_mesh_obj(cut));
  }
  files.commit();
  return summary_of(s);
}

namespace {

/// animate through a layer: the same sinks, the frames through CurveLayer.
AnimateSummary animate_layered(const AnimateJob& job, const Scene& scene, const SkinnedMesh& clips, int clip,
                               const FrameRange& range, OutputFiles& files) {
  if (!job.frames_part.empty())
    throw InputError("farm", "", "a farm job does not layer yet");
  const CurveLayer layer = layer_of(scene, job.layer, job.options);
  const int nv = layer.num_input_vertices();
  std::optional<InputTopology> topology;
  std::vector<std::unique_ptr<FrameSink>> sinks;
  if (!job.pc2.empty())
    sinks.push_back(std::make_unique<Pc2Sink>(
        files, job.pc2, nv, range, job.node_keys.empty() ? job.clip_file : job.clip_file + " with " + job.node_keys));
  if (!job.obj_sequence.empty()) {
    topology = read_input_topology(job.scene.mesh);
    sinks.push_back(std::make_unique<ObjSequenceSink>(files, job.obj_sequence, *topology));
  }
  std::vector<FrameSink*> all;
  for (const auto& k : sinks)
    all.push_back(k.get());
  const ClipPoser poser(layer.joints(), clips);
  auto pose = [&](int frame) { return poser(clip, range.time(frame)); };
  const double envelope = job.layer.envelope;
  std::optional<NodeKeys> keys;
  if (!job.node_keys.empty()) {
    keys = read_node_keys(job.node_keys);
    for (const auto& [id, k] : keys->nodes)
      if (scene.rig.node_index(id) < 0)
        throw InputError(job.node_keys, "/nodes/" + id, "the rig has no node of this id");
  }
  const size_t nj = layer.joints().size();
  auto frames = [&](int first, std::span<const Mat4> M, std::span<Vec3> out) {
    if (!keys)
      return layer.deform_frames(M, out, envelope);
    tbb::parallel_for(size_t{0}, M.size() / nj, [&](size_t f) {
      const NodeOffsets offsets = keys->at(first + static_cast<int>(f));
      layer.deform(M.subspan(f * nj, nj), out.subspan(f * nv, nv), envelope, &offsets);
    });
  };
  if (!all.empty()) // a frame out of range: the clip's pose, or the node keys' offsets on it
    animate(nv, frames, pose, range, all, keys ? clips.source + " with " + job.node_keys : clips.source);
  if (!job.cut_mesh_sequence.empty()) {
    std::vector<Vec3> cut;
    for (int f = range.first; f <= range.last; ++f) {
      const NodeOffsets offsets = keys ? keys->at(f) : NodeOffsets{};
      layer.deform_cut(pose(f), cut, envelope, &offsets);
      files.add((std::filesystem::path(job.cut_mesh_sequence) / sequence_name("cut_frame", f)).string(),
                layer.binding().embedding().cut_mesh_obj(cut));
    }
  }
  files.commit();
  AnimateSummary out;
  static_cast<JobSummary&>(out) = summary_of(scene, layer);
  out.clip = clip;
  out.clip_name = clips.clip_names[clip];
  out.range = range;
  return out;
}

} // namespace

AnimateSummary run(const AnimateJob& job) {
  return detail::run_animate(
      job, [&](Scene scene, OutputFiles& files) { return bind_scene(std::move(scene), job.options, files); });
}

AnimateSummary detail::run_animate(const AnimateJob& job, const Binder& binder) {
  if (job.pc2.empty() && job.obj_sequence.empty() && job.frames_part.empty() && job.cut_mesh_sequence.empty())
    throw InputError(job.clip_file, "", "no output named for the frames");
  const SkinnedMesh clips = load_skinned_mesh(job.clip_file);
  const int clip = detail::find_clip(clips, job.clip_file, job.clip);
  const FrameRange range = frame_range(clips, clip, job.fps, job.frames, job.max_frames);
  // All or nothing: the frames go to temporary files, moved into place at
  // the end (a folder this run made goes with them on a failure).
  Scene scene = read_scene(job.scene);
  (void)clip_skinning_matrices(scene.rig.joints, clips, clip, range.time(range.first)); // a clip for this skeleton
  for (auto& note : clip_notes(scene.rig.joints, clips))
    scene.notes.push_back(std::move(note));
  OutputFiles files;
  if (layered(job.layer, !job.node_keys.empty()))
    return animate_layered(job, scene, clips, clip, range, files);
  const BoundScene s = binder(std::move(scene), files);
  std::optional<InputTopology> topology;
  std::vector<std::unique_ptr<FrameSink>> sinks;
  detail::FramesPartSink* part = nullptr;
  if (!job.pc2.empty())
    sinks.push_back(std::make_unique<Pc2Sink>(files, job.pc2, s.binding.num_input_vertices(), range, job.clip_file));
  if (!job.obj_sequence.empty()) {
    topology = read_input_topology(job.scene.mesh);
    sinks.push_back(std::make_unique<ObjSequenceSink>(files, job.obj_sequence, *topology));
  }
  if (!job.frames_part.empty()) {
    auto p = std::make_unique<detail::FramesPartSink>(files, job.frames_part, s.binding.num_input_vertices(), range,
                                                      job.part_key, job.part_single_precision ? 4 : 8, job.clip_file);
    part = p.get();
    sinks.push_back(std::move(p));
  }
  std::vector<FrameSink*> all;
  for (const auto& k : sinks)
    all.push_back(k.get());
  if (!all.empty())
    animate(s.binding, clips, clip, range, all);
  if (part)
    part->finish();
  if (!job.cut_mesh_sequence.empty()) {
    const CurveLayer layer = cut_layer(s, job.options);
    std::vector<Vec3> cut;
    const ClipPoser poser(layer.joints(), clips);
    for (int f = range.first; f <= range.last; ++f) {
      layer.deform_cut(poser(clip, range.time(f)), cut);
      for (size_t v = 0; v < cut.size(); ++v)
        if (!cut[v].allFinite())
          throw InputError(clips.source, "frame " + std::to_string(f),
                           "the pose moves cut-mesh vertex " + std::to_string(v) +
                               " out of range (not a finite number); nothing was written");
      files.add((std::filesystem::path(job.cut_mesh_sequence) / sequence_name("cut_frame", f)).string(),
                layer.binding().embedding().cut_mesh_obj(cut));
    }
  }
  files.commit();
  AnimateSummary out;
  static_cast<JobSummary&>(out) = summary_of(s);
  out.clip = clip;
  out.clip_name = clips.clip_names[clip];
  out.range = range;
  return out;
}

std::vector<std::vector<Mat4>> clip_poses(const std::vector<Joint>& joints, const SkinnedMesh& clips, double fps,
                                          long long max_frames) {
  std::vector<std::vector<Mat4>> poses;
  const ClipPoser poser(joints, clips);
  for (int c = 0; c < clips.num_clips(); ++c) {
    const auto [first, last] = clip_frames(clips, c, fps);
    for (int f = first; f <= last; ++f) {
      if (static_cast<long long>(poses.size()) >= max_frames)
        throw InputError(clips.source, "clip '" + clips.clip_names[c] + "'",
                         "more than " + std::to_string(max_frames) + " frames to fit over");
      poses.push_back(poser(c, f / fps));
    }
  }
  return poses;
}

namespace {

/// The baked skin against the rig's deformation (`deform`, one frame) over
/// each carried clip's frames: BakeClipFidelity, worst clip first.
std::vector<BakeClipFidelity>
bake_fidelity(const Binding& b, const SkinWeights& w, const SkinnedMesh& clips, const std::vector<std::string>& names,
              double fps, const std::function<void(std::span<const Mat4>, std::span<Vec3>)>& deform,
              const std::function<void(int, std::vector<std::pair<int, double>>&)>& joints_of) {
  const size_t n = static_cast<size_t>(b.num_input_vertices());
  std::vector<Vec3> rest(n), rig(n);
  deform(std::vector<Mat4>(b.joints().size(), Mat4::Identity()), rest);
  Eigen::AlignedBox3d box;
  for (const auto& p : rest)
    box.extend(p);
  const double diag = std::max(box.diagonal().norm(), 1e-300);
  std::vector<BakeClipFidelity> out;
  const ClipPoser poser(b.joints(), clips);
  for (int c = 0; c < clips.num_clips(); ++c) {
    if (!carries(clips, names, c))
      continue;
    BakeClipFidelity f;
    f.clip = clips.clip_names[static_cast<size_t>(c)];
    f.index = c;
    const auto [first, last] = clip_frames(clips, c, fps);
    const double t0 = clips.clip_range(c).first;
    Vec3 worst_rig = Vec3::Zero();
    double worst_scale = 1, worst_t = t0;
    for (int frame = first; frame <= last; ++frame) {
      const double t = std::max(t0, frame / fps);
      const std::vector<Mat4> M = poser(c, t);
      deform(M, rig);
      const std::vector<Vec3> skin = skin_positions(w, rest, M);
      // A file's armature may scale the whole skeleton (Blender's exports by
      // 100): distances are measured against the diagonal at the pose's own
      // scale, the median over the joints of each one's volume scale.
      std::vector<double> scales;
      for (const Mat4& m : M)
        scales.push_back(std::cbrt(std::abs(m.block<3, 3>(0, 0).determinant())));
      std::nth_element(scales.begin(), scales.begin() + static_cast<std::ptrdiff_t>(scales.size() / 2), scales.end());
      const double scale = scales.empty() || !(scales[scales.size() / 2] > 0) ? 1.0 : scales[scales.size() / 2];
      double sum = 0;
      for (size_t v = 0; v < n; ++v) {
        const double d = (skin[v] - rig[v]).norm() / (diag * scale);
        sum += d;
        if (d > f.max) {
          f.max = d;
          f.worst_vertex = static_cast<int>(v);
          f.worst_time = t - t0;
          worst_rig = rig[v];
          worst_scale = scale;
          worst_t = t;
        }
      }
      f.mean += n ? sum / static_cast<double>(n) : 0.0;
      ++f.frames;
    }
    if (f.frames)
      f.mean /= f.frames;
    if (f.worst_vertex >= 0) {
      const size_t v = static_cast<size_t>(f.worst_vertex);
      f.worst_rest = rest[v];
      const int j = w.joint[v * static_cast<size_t>(w.influences)]; // the largest weight comes first
      f.worst_joint = j >= 0 ? w.joints[static_cast<size_t>(j)] : "";
      // The floor there: where the joints that move it in the rig carry it.
      std::vector<std::pair<int, double>> inf;
      joints_of(f.worst_vertex, inf);
      const std::vector<Mat4> M = poser(c, worst_t); // that very frame
      std::vector<Vec3> carried;
      for (const auto& [k, x] : inf)
        carried.push_back((M[static_cast<size_t>(k)] * rest[v].homogeneous()).head<3>());
      f.worst_joints = static_cast<int>(carried.size());
      if (!carried.empty())
        f.worst_floor = detail::nearest_in_hull(carried, worst_rig).distance / (diag * worst_scale);
    }
    out.push_back(std::move(f));
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.max > b.max; });
  return out;
}

} // namespace

BakeSummary run(const BakeJob& job) {
  std::optional<SkinnedMesh> clips, fit;
  if (!job.clip_file.empty()) {
    clips = load_skinned_mesh(job.clip_file);
    detail::need_clips(*clips, job.clip_file, " to carry");
    for (const auto& name : job.clip_names)
      if (clips->find_clip(name) < 0)
        throw InputError(job.clip_file, "clip '" + name + "'", "no clip has this name");
  } else if (!job.clip_names.empty()) {
    throw InputError("--clip-name", job.clip_names.front(), "give the clip file with --clip");
  }
  if (job.helpers < 0)
    throw InputError("--helpers", std::to_string(job.helpers), "must be 0 or more");
  if (job.helpers > 0 && job.fit.empty() && job.weights == BakeJob::Weights::Harmonic)
    throw InputError("--helpers", std::to_string(job.helpers),
                     "helper joints are fitted: give --weights fitted, or the clips to fit over with --fit");
  Scene scene = read_scene(job.scene);
  if (!job.fit.empty()) {
    fit = load_skinned_mesh(job.fit);
    detail::need_clips(*fit, job.fit, " to fit over");
    (void)clip_skinning_matrices(scene.rig.joints, *fit, 0, fit->clip_range(0).first); // a clip for this skeleton
  }
  // The keys carried, measured and fitted over are taken against each
  // file's own rest pose: say when a file's skeleton is not the rig's.
  const SkinnedMesh* said[] = {clips ? &*clips : nullptr,
                               fit && !same_file(job.fit, job.clip_file) ? &*fit : nullptr}; // one file said once
  for (const SkinnedMesh* file : said)
    if (file)
      for (auto& note : clip_notes(scene.rig.joints, *file))
        scene.notes.push_back(std::move(note));
  // The frames the bake will sample (keys written, fidelity measured, poses
  // fitted over), counted before any work: a clip whose keys run for days
  // is refused by name instead of being sampled for hours.
  for (const auto* file : {clips ? &*clips : nullptr, fit ? &*fit : nullptr}) {
    if (!file)
      continue;
    long long frames = 0;
    for (int c = 0; c < file->num_clips(); ++c) {
      if (clips && file == &*clips && !carries(*clips, job.clip_names, c))
        continue;
      const auto [first, last] = clip_frames(*file, c, job.fps);
      frames += static_cast<long long>(last) - first + 1;
      if (frames > job.max_frames) {
        std::ostringstream why;
        why << "the clips come to " << frames << " frames or more at " << job.fps
            << " fps (--fps), more than --max-frames (" << job.max_frames << ")";
        throw InputError(file->source, "clip '" + file->clip_names[static_cast<size_t>(c)] + "'", why.str());
      }
    }
  }
  OutputFiles files; // all or nothing
  std::optional<CurveLayer> layer;
  std::optional<BoundScene> bound;
  if (layered(job.layer, false)) {
    if (!fit && job.weights == BakeJob::Weights::Harmonic)
      throw InputError("--over-skin", "", "a layered bake fits its weights: give the clips to fit over with --fit");
    layer.emplace(layer_of(scene, job.layer, job.options));
  } else {
    bound.emplace(bind_scene(std::move(scene), job.options, files));
  }
  const Binding& b = layer ? layer->binding() : bound->binding;
  // The poses to fit over: the skeleton's own training poses, and the clips given.
  std::vector<std::vector<Mat4>> poses;
  if (job.weights == BakeJob::Weights::Fitted)
    poses = training_poses(b.joints());
  const int skeleton_poses = static_cast<int>(poses.size());
  if (fit) {
    auto more = clip_poses(b.joints(), *fit, job.fps);
    poses.insert(poses.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
  }
  SkinWeights w;
  if (layer) {
    const double envelope = job.layer.envelope;
    w = fit_weights(
        b, poses, job.max_influences,
        [&](std::span<const Mat4> M, std::span<Vec3> out) { layer->deform_frames(M, out, envelope); },
        [&](int v, std::vector<std::pair<int, double>>& inf) {
          // The skin's joints join the net's, and the pull goes towards the skin's weights.
          std::vector<std::pair<int, double>> base;
          layer->base_weights(v, base);
          for (auto& [j, x] : inf)
            x = 0;
          for (const auto& [j, x] : base) {
            const auto it = std::find_if(inf.begin(), inf.end(), [j = j](const auto& q) { return q.first == j; });
            if (it == inf.end())
              inf.emplace_back(j, x);
            else
              it->second = x;
          }
        },
        job.helpers);
  } else {
    w = poses.empty() ? bake_weights(b, job.max_influences) : fit_weights(b, poses, job.max_influences, job.helpers);
  }
  GltfBakeOptions opt;
  opt.up = job.up;
  opt.fps = job.fps;
  opt.clips = job.clip_names;
  if (!job.glb.empty())
    files.add(job.glb, skinned_glb(job.scene.mesh, b.joints(), w, clips ? &*clips : nullptr, opt));
  if (!job.weights_csv.empty())
    files.add(job.weights_csv, weights_csv(w));
  files.commit();
  BakeSummary out;
  static_cast<JobSummary&>(out) =
      layer ? summary_of(scene, *layer) : summary_of(*bound); // scene moved only without a layer
  long long used = 0;
  for (int v = 0; v < w.num_vertices(); ++v) {
    int n = 0;
    for (int i = 0; i < w.influences; ++i)
      n += w.joint[static_cast<size_t>(v) * w.influences + i] >= 0;
    used += n;
    out.most_joints = std::max(out.most_joints, n);
  }
  out.mean_joints = w.num_vertices() ? static_cast<double>(used) / w.num_vertices() : 0.0;
  out.joints = static_cast<int>(w.joints.size());
  out.helpers = static_cast<int>(w.helpers.size());
  out.helper_joints.assign(w.joints.begin() + w.rig_joints(), w.joints.end());
  out.influences = w.influences;
  out.training_poses = skeleton_poses;
  out.clips = 0;
  for (int c = 0; clips && c < clips->num_clips(); ++c)
    out.clips += carries(*clips, job.clip_names, c) ? 1 : 0;
  if (clips) {
    const double envelope = job.layer.envelope;
    out.fidelity =
        bake_fidelity(b, w, *clips, job.clip_names, job.fps, [&](std::span<const Mat4> M, std::span<Vec3> x) {
          if (layer)
            layer->deform_frames(M, x, envelope);
          else
            b.deform(M, x);
        },
        [&](int v, std::vector<std::pair<int, double>>& inf) {
          // The net's joints there, and over a skin the skin's as well.
          b.harmonic_weights(v, inf);
          if (layer) {
            std::vector<std::pair<int, double>> base;
            layer->base_weights(v, base);
            for (const auto& [j, x] : base)
              if (std::none_of(inf.begin(), inf.end(), [j = j](const auto& q) { return q.first == j; }))
                inf.emplace_back(j, x);
          }
        });
  }
  return out;
}

} // namespace curvenet
