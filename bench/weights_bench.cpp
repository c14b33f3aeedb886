// Automatic weight rules against an asset's own skin. Every vertex of the
// mesh is skinned twice with the same joint matrices of every clip: once
// with the file's skin weights, once with the rule's weights. Prints the
// mean and the worst distance between the two, as % of the bounding-box
// diagonal, over all clips.
//
//   build/bin/weights_bench [file.glb]   (default: the shared hand's poses)

#include "curvenet/io.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/weights.hpp"

#include <algorithm>
#include <cstdio>
#include <string>

using namespace curvenet;

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : std::string(CURVENET_DATA_DIR) + "/xr_tools_hand/hand_l_poses.glb";
  const SkinnedMesh skin = load_skinned_mesh(path);
  const RawMesh raw = read_raw_mesh(path);
  Eigen::Vector3d lo = raw.positions[0], hi = lo;
  for (const auto& p : raw.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double diag = (hi - lo).norm();
  std::vector<std::vector<Mat4>> clips;
  for (int c = 0; c < skin.num_clips(); ++c)
    clips.push_back(skin.skinning_matrices(c, skin.clip_range(c).second));
  std::printf("%s: %zu vertices, %zu joints, %d clips (last frame of each)\n", path.c_str(), raw.positions.size(),
              skin.joints.size(), skin.num_clips());
  std::printf("%-12s %6s %12s %12s\n", "rule", "blend", "mean_%diag", "max_%diag");
  struct Case {
    WeightRule rule;
    double blend;
  };
  for (const Case& c : {Case{WeightRule::Segment, 0}, Case{WeightRule::BlendZone, 0.1}, Case{WeightRule::BlendZone, 0.2},
                        Case{WeightRule::BlendZone, 0.3}, Case{WeightRule::BlendZone, 0.5}}) {
    AutoWeightOptions opt;
    opt.rule = c.rule;
    opt.blend = c.blend;
    const SkinComparison r = compare_with_skin(skin, raw.positions, clips, opt);
    std::printf("%-12s %6.2f %12.3f %12.3f\n", to_string(c.rule), c.blend, 100 * r.mean / diag, 100 * r.max / diag);
  }
  return 0;
}
