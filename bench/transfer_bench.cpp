// Transfer time against the target's face count: the tube net authored on a
// capped quad tube, transferred to a triangulated tube of about 2.5 to 3.5
// times as many faces (placing, embedding on both, region agreement and the
// shape distance all included), against embedding the transferred rig on
// the target alone, the two alternated. Prints medians of 21 (of 5 from
// 50k target faces) from one run, and their ratio; CURVENET_RUNS sets
// another count.
//
//   build/bin/transfer_bench [max_target_faces]

#include "curvenet/embed.hpp"
#include "curvenet/transfer.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

using namespace curvenet;

namespace {
double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
SurfaceMesh tube(int around, int along, int caps, bool triangulate) {
  TubeSpec s;
  s.around = around;
  s.along = along;
  s.cap_rings = caps;
  s.triangulate = triangulate;
  return make_surface_mesh(make_capped_tube(s), "tube");
}
} // namespace

int main(int argc, char** argv) {
  const long max_faces = argc > 1 ? std::atol(argv[1]) : 300000;
  const Rig net = make_tube_net();
  std::printf("%12s %12s %10s %12s %14s %16s %10s %6s\n", "source", "target", "regions", "median_ms", "us/tgt face",
              "embed target ms", "ratio", "ok");
  for (int k : {1, 2, 4, 8}) {
    const SurfaceMesh from = tube(32 * k, 32 * k, 4 * k, false), to = tube(45 * k, 40 * k, 6 * k, true);
    if (to.num_faces() > max_faces)
      break;
    // Alternated, so that a busy moment of a shared machine falls on both.
    std::vector<double> ms, embed_ms;
    TransferResult r;
    const char* runs_env = std::getenv("CURVENET_RUNS");
    const int kRuns = runs_env ? std::max(1, std::atoi(runs_env)) : to.num_faces() < 50000 ? 21 : 5;
    for (int rep = 0; rep < kRuns; ++rep) {
      double t0 = now_ms();
      r = transfer(net, from, to);
      ms.push_back(now_ms() - t0);
      // The yardstick: embedding the transferred rig on the target alone.
      t0 = now_ms();
      const Embedding e = embed(to, r.rig);
      embed_ms.push_back(now_ms() - t0);
    }
    std::sort(ms.begin(), ms.end());
    std::sort(embed_ms.begin(), embed_ms.end());
    std::printf("%12d %12d %10d %12.1f %14.2f %16.1f %10.2f %6s\n", from.num_faces(), to.num_faces(),
                r.report.target.regions, ms[kRuns / 2], 1000 * ms[kRuns / 2] / to.num_faces(), embed_ms[kRuns / 2],
                ms[kRuns / 2] / embed_ms[kRuns / 2],
                r.report.ok ? "yes" : "NO");
  }
  return 0;
}
