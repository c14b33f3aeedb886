// Which Laplacian and which rigid mode deform better? The shared hand's
// example rig is bound to two tessellations of the same hand with the same
// vertices (hand_l.gltf's triangles and hand_l_quads.obj's quads) and posed
// by all 35 clips of hand_l_poses.glb. For each choice the table gives the
// mean distance from the file's own linear blend skinning, and the mean
// distance between the two tessellations' results at the shared vertices
// (topology independence), both as % of the bounding-box diagonal.
//
//   build/bin/deform_modes

#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"

#include <chrono>
#include <cstdio>
#include <string>

using namespace curvenet;

int main() {
  const std::string dir = std::string(CURVENET_DATA_DIR) + "/xr_tools_hand/";
  const SkinnedMesh clips = load_skinned_mesh(dir + "hand_l_poses.glb");
  const RawMesh skinned = read_raw_mesh(dir + "hand_l_poses.glb");
  const SurfaceMesh tris = load_mesh(dir + "hand_l.gltf");
  const SurfaceMesh quads = load_mesh(dir + "hand_l_quads.obj");
  const Rig rig = read_rig(dir + "example/hand_l.cnrig.json");
  const double diag = tris.bbox_diagonal();
  // The quad mesh's vertex nearest to each welded vertex of the triangle mesh.
  std::vector<int> match(tris.num_vertices());
  for (int v = 0; v < tris.num_vertices(); ++v) {
    int best = 0;
    for (int u = 1; u < quads.num_vertices(); ++u)
      if ((quads.positions[u] - tris.positions[v]).squaredNorm() < (quads.positions[best] - tris.positions[v]).squaredNorm())
        best = u;
    match[v] = best;
  }
  // One glTF vertex of the skinned file per welded vertex (by position).
  std::vector<int> skin_vertex(tris.num_vertices(), -1);
  for (size_t i = 0; i < skinned.positions.size(); ++i)
    for (int v = 0; v < tris.num_vertices(); ++v)
      if (skin_vertex[v] < 0 && (skinned.positions[i] - tris.positions[v]).norm() < 1e-9) {
        skin_vertex[v] = static_cast<int>(i);
        break;
      }
  std::printf("%-10s %-11s %10s %14s %14s %12s\n", "laplacian", "rigid", "bind_ms", "vs_skin_%diag", "tess_%diag", "max_tess_%");
  for (const auto lap : {LaplacianChoice::IntrinsicDelaunay, LaplacianChoice::Uniform})
    for (const auto mode : {RigidMode::PerVertex, RigidMode::Horn}) {
      BindOptions opt;
      opt.laplacian = lap;
      opt.rigid = mode;
      const auto t0 = std::chrono::steady_clock::now();
      const Binding bt = bind(tris, rig, opt);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      const Binding bq = bind(quads, rig, opt);
      double vs_skin = 0, tess = 0, tess_max = 0;
      long n = 0;
      for (int c = 0; c < clips.num_clips(); ++c) {
        const double t = clips.clip_range(c).second;
        const Pose pose = pose_from_clip(clips, c, t);
        std::vector<Vec3> ot(bt.num_input_vertices()), oq(bq.num_input_vertices());
        bt.deform(skinning_matrices(bt.joints(), pose), ot);
        bq.deform(skinning_matrices(bq.joints(), pose), oq);
        const auto lbs = skin_positions(clips, skinned.positions, clips.skinning_matrices(c, t));
        // Welded positions of the triangle mesh's result.
        std::vector<Vec3> wt(tris.num_vertices()), wq(quads.num_vertices());
        for (size_t i = 0; i < ot.size(); ++i)
          wt[tris.input_to_welded[i]] = ot[i];
        for (size_t i = 0; i < oq.size(); ++i)
          wq[quads.input_to_welded[i]] = oq[i];
        for (int v = 0; v < tris.num_vertices(); ++v) {
          vs_skin += (wt[v] - lbs[skin_vertex[v]]).norm();
          const double d = (wt[v] - wq[match[v]]).norm();
          tess += d;
          tess_max = std::max(tess_max, d);
          ++n;
        }
      }
      std::printf("%-10s %-11s %10.1f %14.3f %14.4f %12.4f\n", lap == LaplacianChoice::Uniform ? "uniform" : "intrinsic",
                  mode == RigidMode::Horn ? "horn" : "per-vertex", ms, 100 * vs_skin / n / diag, 100 * tess / n / diag,
                  100 * tess_max / diag);
    }
  return 0;
}
