#pragma once
/// \file jobs.hpp
/// The work a front end asks for, done once in the library. Frames of a
/// clip are a checked range, deformed in parallel blocks of bounded memory
/// and streamed, in order, to any number of sinks (a PC2 cache, an OBJ
/// sequence, a caller's own). The CLI's `animate`, the Python module and
/// the Blender add-on all compute frames through Binding::deform_frames,
/// block by block, so they agree bit for bit. The commands that read files
/// and write files (bind, pose, animate, bake) are jobs: a struct of inputs
/// and outputs, run() to do all of it, all or nothing, and a summary to
/// print. The CLI and the farm tasks (farm.hpp) run the same jobs.

#include "curvenet/bake.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/scene.hpp"
#include "curvenet/skin.hpp"

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace curvenet {

/// Frames first..last (inclusive) of a clip, sampled at fps.
struct FrameRange {
  int first = 0, last = -1;
  double fps = 24;
  [[nodiscard]] int count() const { return last - first + 1; }
  /// The clip time of frame `frame`.
  [[nodiscard]] double time(int frame) const { return frame / fps; }
};

/// The frames of clip `clip`, or those `frames` names ("A:B", two whole
/// numbers; empty for the clip's own range).
/// \throw InputError naming `--frames` for a malformed or reversed range,
///   or one of more than `max_frames` frames.
FrameRange frame_range(const SkinnedMesh& clips, int clip, double fps, const std::string& frames = "",
                       long long max_frames = 100000);

/// Where frames go: write() is called once per frame, in frame order, with
/// one position per vertex of the binding's input.
class FrameSink {
public:
  virtual ~FrameSink() = default;
  virtual void write(int frame, std::span<const Vec3> positions) = 0;
};

/// A PC2 point cache, streamed into `files` (written when they are
/// committed). A position past single precision is refused naming `blame`
/// (the clip file, say; the path by default).
class Pc2Sink : public FrameSink {
public:
  Pc2Sink(OutputFiles& files, const std::string& path, int vertices, const FrameRange& range, std::string blame = "");
  void write(int frame, std::span<const Vec3> positions) override;

private:
  std::ostream* out_;
  std::string blame_;
  std::vector<float> buffer_;
};

/// One OBJ per frame, `DIR/PREFIX_NNNN.obj`, on the input's own topology.
class ObjSequenceSink : public FrameSink {
public:
  ObjSequenceSink(OutputFiles& files, std::string dir, const InputTopology& topology, std::string prefix = "frame");
  void write(int frame, std::span<const Vec3> positions) override;

private:
  OutputFiles& files_;
  std::string dir_, prefix_;
  const InputTopology& topology_;
};

/// A sink of the caller's: a function of the frame and its positions.
class FunctionSink : public FrameSink {
public:
  explicit FunctionSink(std::function<void(int, std::span<const Vec3>)> f) : f_(std::move(f)) {}
  void write(int frame, std::span<const Vec3> positions) override { f_(frame, positions); }

private:
  std::function<void(int, std::span<const Vec3>)> f_;
};

/// The name of frame `frame` in a sequence: PREFIX_NNNN.obj.
std::string sequence_name(const std::string& prefix, int frame);

/// Deforms every frame of `range` of clip `clip` through `binding` and
/// hands each to every sink, in frame order. Frames are computed in blocks
/// (about 64 MB of positions at a time) by Binding::deform_frames, in
/// parallel within a block, so memory does not grow with the frame count
/// and the result does not depend on the thread count.
/// \throw InputError naming the clip file, the frame and the vertex when a
///   position is not finite.
void animate(const Binding& binding, const SkinnedMesh& clips, int clip, const FrameRange& range,
             std::span<FrameSink* const> sinks);

/// The same through any deformer: `deform_frames(first, M, out)` as
/// Binding::deform_frames for the block of frames from `first` (frames x
/// joints matrices in, frames x `vertices` positions out).
void animate(int vertices, const std::function<void(int, std::span<const Mat4>, std::span<Vec3>)>& deform_frames,
             const std::function<std::vector<Mat4>(int frame)>& pose, const FrameRange& range,
             std::span<FrameSink* const> sinks, const std::string& source);

/// The same for frames whose skinning matrices `pose` gives (one per joint
/// of the binding); a non-finite position is refused naming `source`.
void animate(const Binding& binding, const std::function<std::vector<Mat4>(int frame)>& pose, const FrameRange& range,
             std::span<FrameSink* const> sinks, const std::string& source);

class CurveLayer;
/// A layer's frame: its skinning matrices (one per joint of the layer), its
/// envelope (0 to 1) and its nodes' offsets.
struct LayerFrame {
  std::vector<Mat4> skinning;
  double envelope = 1;
  NodeOffsets offsets;
};
/// The same through a layer (layer.hpp), `pose` giving each frame's
/// matrices, envelope and node offsets (a tool's keyed envelope and pulled
/// nodes: the Blender add-on's bake of a layer). Each frame is exactly what
/// CurveLayer::deform gives for it.
/// \throw InputError naming `source` and the frame for an envelope
///   outside [0, 1], or for a position that is not finite.
void animate(const CurveLayer& layer, const std::function<LayerFrame(int frame)>& pose, const FrameRange& range,
             std::span<FrameSink* const> sinks, const std::string& source);

/// Node offsets keyed over frames (docs/rig-format.md): per node, keys of
/// (frame, offset), interpolated linearly and held past the first and last.
struct NodeKeys {
  std::map<std::string, std::vector<std::pair<double, Vec3>>> nodes;
  /// Every node's offset at `frame`.
  [[nodiscard]] NodeOffsets at(double frame) const;
};
/// \throw InputError with the JSON path of the fault.
NodeKeys read_node_keys(const std::string& path);
NodeKeys parse_node_keys(const std::string& text, const std::string& source);

/// What a job's summary says of the binding it made.
struct JobSummary {
  BindReport bind;
  std::vector<std::string> notes; ///< repairs made on loading the mesh (load_notes)
  int vertices = 0;               ///< the mesh file's vertices
};

/// The net as a layer (layer.hpp): over the mesh file's own skin, and with a
/// pose's node offsets. A pose with node offsets is always layered (over
/// the net's own deformation when not over the skin).
struct LayerSpec {
  bool over_skin = false; ///< the mesh file's own skin (glTF, GLB, FBX) is the base
  Skinning skinning = Skinning::Linear;
  double envelope = 1;
  /// Optional: a text file of one number from 0 to 1 per vertex of the mesh
  /// file, or a JSON file {"regions": {region key: 0 to 1}, "others": 0 to 1}
  /// (CurveLayer::region_mask).
  std::string mask;
};

/// Binds a rig to a mesh and writes the rig with its nodes' weights filled in.
struct BindJob {
  SceneFiles scene;
  BindOptions options;
  std::string out; ///< the rig file written
};
JobSummary run(const BindJob& job);

/// Poses a mesh: one OBJ on the mesh file's own topology, and the posed cut mesh.
struct PoseJob {
  SceneFiles scene;
  BindOptions options;
  std::string pose;     ///< a pose file (pose.hpp); version 2 may give node offsets
  std::string out;      ///< the posed mesh, OBJ
  std::string cut_mesh; ///< optional: the posed cut mesh, OBJ with its curves
  LayerSpec layer;
};
JobSummary run(const PoseJob& job);

/// Deforms a clip's frames to a PC2 cache, an OBJ sequence, a farm part
/// file, and the cut mesh's OBJ sequence: any of them, all or nothing.
struct AnimateJob {
  SceneFiles scene;
  BindOptions options;
  std::string clip_file; ///< a glTF/GLB or FBX with clips for the rig's skeleton
  std::string clip;      ///< a clip's name or index; empty for the first
  std::string frames;    ///< "A:B"; empty for the clip's own range
  double fps = 24;
  long long max_frames = 100000;
  std::string pc2, obj_sequence, cut_mesh_sequence;
  LayerSpec layer;
  std::string node_keys; ///< optional: node offsets keyed over the frames (read_node_keys); layered
  /// A farm task's part file (farm.hpp): the frames checksummed, marked
  /// with `part_key` (the farm job's), in single precision (what a PC2
  /// cache keeps) or double (what an OBJ sequence prints).
  std::string frames_part;
  std::uint64_t part_key = 0;
  bool part_single_precision = false;
};
struct AnimateSummary : JobSummary {
  int clip = 0;
  std::string clip_name;
  FrameRange range;
};
/// \throw InputError before anything is written: no clips, an unknown clip,
///   a bad range, a clip for another skeleton, no output named.
AnimateSummary run(const AnimateJob& job);

/// Bakes the binding to an ordinary skin: a skinned GLB with the clips
/// retargeted, and the weights as CSV.
struct BakeJob {
  SceneFiles scene;
  BindOptions options;
  std::string glb, weights_csv;
  std::string clip_file;               ///< optional: clips to carry into the GLB
  std::vector<std::string> clip_names; ///< of those, these; empty for all
  std::string fit;                     ///< optional: fit the weights to the deformation over this file's clips too
  /// Fitted: weights fitted to the rig over training poses of the skeleton
  /// (training_poses) and the `fit` clips; harmonic: the top-k harmonic
  /// weights (or, with `fit`, fitted over its clips alone).
  enum class Weights { Fitted, Harmonic } weights = Weights::Harmonic;
  int max_influences = 4;
  /// Up to this many helper joints, each keyed half way between two joints
  /// (fit_weights, SkinWeights::helpers); the weights must be fitted.
  int helpers = 0;
  double fps = 24;
  /// Refuse clips (of `clip_file`, and of `fit`) that come to more frames
  /// than this at `fps`, before anything is bound.
  long long max_frames = 100000;
  GltfBakeOptions::Up up = GltfBakeOptions::Up::Y;
  /// With `fit`: fit the weights to the layered result (over the mesh's own
  /// skin), not to the net alone.
  LayerSpec layer;
};
/// How closely the baked skin plays one clip like the rig: over the clip's
/// frames at the job's fps, the distance of each vertex under LBS with the
/// baked weights from the rig's own deformation, as fractions of the mesh's
/// bounding-box diagonal.
struct BakeClipFidelity {
  std::string clip; ///< its name in the clip file (may be empty)
  int index = 0;    ///< its index there
  int frames = 0;
  double mean = 0; ///< over the frames, of the mean over the vertices
  double max = 0;  ///< the worst vertex of the worst frame
  int worst_vertex = -1;
  Vec3 worst_rest = Vec3::Zero(); ///< where that vertex is at rest (mesh space)
  std::string worst_joint;        ///< its heaviest baked joint
  double worst_time = 0;          ///< seconds into the clip
  /// At that vertex and frame, the closest any linear skin of the joints
  /// that move the vertex in the rig (`worst_joints` of them) can come to
  /// the rig, whatever its weights: the distance from the rig's position to
  /// the convex hull of where those joints carry the vertex. Where it is
  /// near `max`, no weights do better; a skin would need other joints.
  double worst_floor = 0;
  int worst_joints = 0;
};
struct BakeSummary : JobSummary {
  int joints = 0, influences = 0;
  int helpers = 0;                       ///< helper joints written (counted in `joints`)
  std::vector<std::string> helper_joints; ///< their names, `a~b`, best ranked first
  double mean_joints = 0; ///< joints of non-zero weight per vertex
  int most_joints = 0;
  int clips = 0;          ///< clips carried into the GLB
  int training_poses = 0; ///< poses of the skeleton the weights were fitted over
  /// Per clip carried into the GLB, the skin against the rig, worst first.
  std::vector<BakeClipFidelity> fidelity;
};
BakeSummary run(const BakeJob& job);

/// What a run says of a clip file against the rig's skeleton, one line each
/// (`animate` and `bake` print them as notes, Python's `animate` warns): the
/// rig's joints it lacks (matched by name; they stay at rest), and a
/// skeleton that is not the rig's: a bone both have whose rest length
/// differs by more than 5 % or whose rest frame turns by more than 10
/// degrees, relative to its parent (a similarity of the whole skeleton, as
/// a transfer makes, changes none of them). The file's keys, taken against
/// its own rest pose, would then move the rig's joints by other amounts or
/// about other axes. Empty when the file fits.
std::vector<std::string> clip_notes(const std::vector<Joint>& rig, const SkinnedMesh& clips);

/// Skinning matrices of every frame of every clip of `clips`, for `joints`,
/// sampled at fps: the poses a weight fit runs over.
/// \throw InputError naming the clip file past `max_frames` frames.
std::vector<std::vector<Mat4>> clip_poses(const std::vector<Joint>& joints, const SkinnedMesh& clips, double fps,
                                          long long max_frames = 100000);

} // namespace curvenet
