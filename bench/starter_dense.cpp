// The starter on dense meshes, as a user runs it: `curvenet starter` on the
// shared animals and the hand refined by Catmull-Clark (`curvenet
// subdivide`, one to three levels: 8k to 140k quads), with the source file's
// skeleton. Prints the median wall time of each, the process included.
//
//   starter_dense [--against OTHER_CURVENET] [--reps N]
//
// With --against, another build of the CLI (an earlier commit's) runs on the
// same meshes in the same run, alternating with ours, and the table gives
// both and their ratio. Every run's rig is compared with ours: a change
// meant only to be faster must write the same rig.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace fs = std::filesystem;

namespace {

double run_ms(const std::string& command) {
  const auto t0 = std::chrono::steady_clock::now();
  if (std::system((command + " > /dev/null 2>&1").c_str()) != 0) {
    std::fprintf(stderr, "starter_dense: failed, so its time would mean nothing: %s\n", command.c_str());
    std::exit(1);
  }
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

long faces_of(const fs::path& obj) {
  std::ifstream in(obj);
  long n = 0;
  for (std::string line; std::getline(in, line);)
    n += line.rfind("f ", 0) == 0;
  return n;
}

} // namespace

int main(int argc, char** argv) {
  std::string against;
  int reps = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--against" && i + 1 < argc)
      against = argv[++i];
    else if (a == "--reps" && i + 1 < argc)
      reps = std::max(1, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: starter_dense [--against OTHER_CURVENET] [--reps N]\n");
      return 2;
    }
  }
  const std::string cli = CURVENET_CLI, data = CURVENET_DATA_DIR;
  const fs::path dir = fs::temp_directory_path() / ("curvenet_starter_dense_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<std::string> sources = {data + "/quaternius/Horse.glb", data + "/quaternius/Wolf.glb",
                                            data + "/quaternius/Trex.glb", data + "/quaternius/Apatosaurus.glb",
                                            data + "/xr_tools_hand/hand_l_poses.glb"};
  std::printf("curvenet starter on refined meshes: median of %d runs, the whole process\n\n", reps);
  if (against.empty()) {
    std::printf("| mesh | faces | starter |\n|---|---|---|\n");
  } else {
    std::printf("| mesh | faces | starter | %s | ratio |\n|---|---|---|---|---|\n", against.c_str());
  }
  bool differ = false;
  for (const std::string& src : sources) {
    const std::string name = fs::path(src).stem().string();
    for (int level = 1; level <= 3; ++level) {
      const fs::path mesh = dir / (name + "_L" + std::to_string(level) + ".obj");
      run_ms(cli + " subdivide '" + src + "' --levels " + std::to_string(level) + " -o '" + mesh.string() + "'");
      const fs::path ours = dir / "ours.cnrig.json", theirs = dir / "theirs.cnrig.json";
      auto command = [&](const std::string& exe, const fs::path& out) {
        return exe + " starter '" + mesh.string() + "' --skeleton '" + src + "' -o '" + out.string() + "'";
      };
      std::vector<double> a, b;
      for (int r = 0; r < reps; ++r) {
        a.push_back(run_ms(command(cli, ours)));
        if (!against.empty())
          b.push_back(run_ms(command(against, theirs)));
      }
      const long faces = faces_of(mesh);
      if (against.empty()) {
        std::printf("| %s, level %d | %ld | %.0f ms |\n", name.c_str(), level, faces, median(a));
      } else {
        const bool same = slurp(ours) == slurp(theirs);
        differ = differ || !same;
        std::printf("| %s, level %d | %ld | %.0f ms | %.0f ms%s | %.2f |\n", name.c_str(), level, faces, median(a),
                    median(b), same ? "" : " (another rig)", median(b) / median(a));
      }
      std::fflush(stdout);
      fs::remove(mesh);
    }
  }
  fs::remove_all(dir);
  if (differ)
    std::printf("\nSome rigs differ between the two builds (marked).\n");
  return 0;
}
