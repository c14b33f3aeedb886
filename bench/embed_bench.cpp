// Embedding time against face count: the tube net (28 profiles) on refined
// capped tubes, from about 1k to 1M faces. Prints a table of medians.
//
//   build/bin/embed_bench [max_faces]

#include "curvenet/embed.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <vector>

using namespace curvenet;

int main(int argc, char** argv) {
  const long max_faces = argc > 1 ? std::atol(argv[1]) : 1100000;
  const Rig rig = make_tube_net();
  std::printf("%10s %10s %10s %12s %12s %8s\n", "faces", "crossings", "regions", "median_ms", "ms/kface", "ok");
  for (int around = 24;; around *= 2) {
    TubeSpec spec;
    spec.around = around;
    spec.along = around / 2;
    spec.cap_rings = std::max(2, around / 8);
    spec.triangulate = true;
    const SurfaceMesh mesh = make_surface_mesh(make_capped_tube(spec), "tube");
    if (mesh.num_faces() > max_faces) break;
    std::vector<double> ms;
    EmbedReport last;
    try {
      for (int rep = 0; rep < 5; ++rep) {
        const auto t0 = std::chrono::steady_clock::now();
        const Embedding e = embed(mesh, rig);
        ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        last = e.report();
      }
    } catch (const std::exception& err) {
      std::printf("%10d  embedding failed: %s\n", mesh.num_faces(), err.what());
      continue;
    }
    std::sort(ms.begin(), ms.end());
    std::printf("%10d %10d %10d %12.2f %12.4f %8s\n", mesh.num_faces(), last.crossings, last.regions, ms[2],
                ms[2] / (mesh.num_faces() / 1000.0), last.ok ? "yes" : "NO");
    std::fflush(stdout);
  }
  return 0;
}
