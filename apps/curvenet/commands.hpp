#pragma once
// The CLI's commands: one function each, over the library.

#include "curvenet/jobs.hpp"

#include <optional>
#include <string>
#include <vector>

namespace curvenet::cli {

struct EmbedArgs {
  std::string mesh, rig, report, regions, cut_mesh, coverage;
  double density = 5.0;
  long long max_samples = 4'000'000;
  std::optional<bool> progress;
};
int run_embed(const EmbedArgs& args);

struct StarterArgs {
  std::string mesh, skeleton, out, coverage = "auto", weight_rule = "auto";
  int nodes_per_ring = 4;
  int rings_per_bone = 1;
  bool middle_nodes = true;
  double first_angle = 0;
  double blend = 0.3;
};
int run_starter(const StarterArgs& args);

struct DeformArgs {
  std::string mesh, rig, skeleton, laplacian = "intrinsic", rigid = "per-vertex", binding_cache;
  std::string method = "dq", rotation = "polar", interior = "bone-heat";
  bool curve_frames = false;
  // pose and animate: the net as a layer (layer.hpp)
  bool over_skin = false;
  std::string skinning = "linear", mask;
  double envelope = 1;
};

struct BindArgs : DeformArgs {
  std::string out;
};
int run_bind(const BindArgs& args);

struct PoseArgs : DeformArgs {
  std::string pose, out, cut_mesh;
};
int run_pose(const PoseArgs& args);

struct AnimateArgs : DeformArgs {
  std::string clip_file, clip, frames, out, obj_sequence, cut_mesh_sequence, node_keys;
  double fps = 24;
  long long max_frames = 100000;
};
int run_animate(const AnimateArgs& args);
/// The library's animate job for these arguments.
AnimateJob animate_job(const AnimateArgs& args);

struct FarmSubmitArgs : AnimateArgs {
  std::string folder;
  int shard_frames = 100;
  bool dry_run = false;
  std::vector<std::string> sbatch_options;
  double lock_timeout = 1800;
};
int run_farm_submit(const FarmSubmitArgs& args);
int run_farm_task(const std::string& folder, int index);
int run_farm_merge(const std::string& folder);
int run_farm_status(const std::string& folder);

struct BakeArgs : DeformArgs {
  std::string out, weights_csv, clip_file, fit, up = "y", weights = "harmonic";
  std::vector<std::string> clip_names;
  int max_influences = 4;
  int helpers = 0;
  double fps = 24;
  long long max_frames = 100000;
};
int run_bake(const BakeArgs& args);

struct TransferArgs {
  std::string rig, from, to, out, report, source_frame, target_frame;
  std::string align = "auto";     ///< frames, skeletons or auto (Alignment)
  int from_cage = 0, to_cage = 0; ///< Catmull-Clark levels when a mesh is a control cage
  long long max_faces = 4'000'000;
};
int run_transfer(const TransferArgs& args);

struct CompareArgs {
  std::string a, b;
  bool json = false;
};
int run_compare(const CompareArgs& args);

struct SubdivideArgs {
  std::string cage, out;
  int levels = 2;
  long long max_faces = 4'000'000;
};
int run_subdivide(const SubdivideArgs& args);

struct DemoArgs {
  std::string out = "out/demo";
};
int run_demo(const DemoArgs& args);

} // namespace curvenet::cli
