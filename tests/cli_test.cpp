// End-to-end: the curvenet command on real data and on bad input.

#include "curvenet/io.hpp"
#include "curvenet/skin.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>

namespace fs = std::filesystem;
using namespace curvenet;

namespace {

struct CliRun {
  int code;
  std::string out, err;
};

/// Runs the CLI with `args`; `env` (NAME=VALUE ...) changes its environment.
CliRun run(const std::string& args, const fs::path& dir, const std::string& env = "") {
  const fs::path o = dir / "stdout.txt", e = dir / "stderr.txt";
  const std::string cmd = (env.empty() ? "" : "env " + env + " ") + std::string(CURVENET_CLI) + " " + args + " >" +
                          o.string() + " 2>" + e.string();
  const int status = std::system(cmd.c_str());
  auto slurp = [](const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  };
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(o), slurp(e)};
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const char* kRig =
    R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0.5,0]},{"id":"b","position":[1,0.5,0]}],
  "profiles":[{"id":"p","from":"a","to":"b","points":[[0,0.5,0],[1,0.5,0]]}]})";
const char* kQuad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

} // namespace

TEST(Cli, HelpOnEveryCommand) {
  const auto dir = test::temp_dir("help");
  EXPECT_EQ(run("--help", dir).code, 0);
  EXPECT_EQ(run("embed --help", dir).code, 0);
  EXPECT_NE(run("embed --help", dir).out.find("--cut-mesh"), std::string::npos);
  EXPECT_EQ(run("demo --help", dir).code, 0);
  EXPECT_NE(run("subdivide --help", dir).out.find("--levels"), std::string::npos);
  EXPECT_EQ(run("", dir).code, 2);
}

TEST(Cli, EmbedsTheHandAndWritesEveryOutput) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("hand");
  const CliRun r =
      run("embed " + test::data("xr_tools_hand/hand_l.gltf") + " " +
              test::data("xr_tools_hand/example/hand_l.cnrig.json") + " --report " + (dir / "r.json").string() +
              " --regions " + (dir / "r.ply").string() + " --cut-mesh " + (dir / "cut.obj").string(),
          dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("SUCCESS"), std::string::npos);
  EXPECT_NE(r.out.find("regions: 47\n"), std::string::npos);
  std::ifstream in(dir / "r.json");
  const auto j = nlohmann::json::parse(in);
  for (const char* key : {"ok", "coverage", "logical_nodes", "profiles", "components", "regions", "expected_regions",
                          "mapped_faces", "unmapped_faces", "physical_nodes", "cut_mesh", "timings_ms"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["regions"], 47);
  EXPECT_EQ(j["expected_regions"], 47);
  EXPECT_EQ(j["logical_nodes"], 64);
  EXPECT_EQ(j["physical_nodes"], 64);
  EXPECT_TRUE(j["timings_ms"].contains("trace"));
  EXPECT_TRUE(j["cut_mesh"].contains("faces"));
  std::ifstream ply(dir / "r.ply");
  std::string first;
  std::getline(ply, first);
  EXPECT_EQ(first, "ply");
  EXPECT_TRUE(fs::exists(dir / "cut.obj"));
}

TEST(Cli, BadInputFailsCleanlyWithNoOutput) {
  const auto dir = test::temp_dir("bad");
  write(dir / "quad.obj", kQuad);
  write(dir / "ok.cnrig.json", kRig);
  write(dir / "fin.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n");
  write(dir / "nan.obj", "v 0 0 0\nv 1 0 0\nv 1e999 1 0\nf 1 2 3\n");
  write(dir / "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
  write(
      dir / "dup.cnrig.json",
      R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]},{"id":"a","position":[1,0,0]}],"profiles":[]})");
  write(
      dir / "missing.cnrig.json",
      R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]}],"profiles":[{"id":"p","from":"a","to":"q","points":[[0,0,0],[1,0,0]]}]})");
  write(dir / "unknown.cnrig.json", R"({"format":"curvenet-rig","version":1,"nodes":[],"profiles":[],"extra":1})");
  write(dir / "matrix.cnrig.json",
        R"({"format":"curvenet-rig","version":1,"frame":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,2],"nodes":[],"profiles":[]})");
  write(dir / "broken.cnrig.json", R"({"format":"curvenet-rig",)");
  struct Case {
    std::string mesh, rig, file, element;
  };
  const Case cases[] = {
      {"fin.obj", "ok.cnrig.json", "fin.obj", "edge 0-1"},
      {"nan.obj", "ok.cnrig.json", "nan.obj", "line 3"},
      {"flat.obj", "ok.cnrig.json", "flat.obj", "face 0"},
      {"nothere.obj", "ok.cnrig.json", "nothere.obj", "no such file"},
      {"quad.obj", "dup.cnrig.json", "dup.cnrig.json", "/nodes/1/id"},
      {"quad.obj", "missing.cnrig.json", "missing.cnrig.json", "/profiles/0/to"},
      {"quad.obj", "unknown.cnrig.json", "unknown.cnrig.json", "/extra"},
      {"quad.obj", "matrix.cnrig.json", "matrix.cnrig.json", "/frame"},
      {"quad.obj", "broken.cnrig.json", "broken.cnrig.json", "malformed JSON"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.mesh + " " + c.rig);
    const fs::path report = dir / "report.json";
    fs::remove(report);
    fs::remove(dir / "regions.ply");
    const CliRun r = run("embed " + (dir / c.mesh).string() + " " + (dir / c.rig).string() + " --report " +
                             report.string() + " --regions " + (dir / "regions.ply").string(),
                         dir);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find(c.file), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(c.element), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(report));
    EXPECT_FALSE(fs::exists(dir / "regions.ply"));
    for (const auto& entry : fs::directory_iterator(dir))
      EXPECT_EQ(entry.path().string().find(".tmp-"), std::string::npos);
  }
  // The good pair works.
  EXPECT_EQ(run("embed " + (dir / "quad.obj").string() + " " + (dir / "ok.cnrig.json").string(), dir).code, 0);
}

TEST(Cli, CrossingProfilesAreRefusedNamingBoth) {
  const auto dir = test::temp_dir("cross");
  std::string grid;
  for (int j = 0; j <= 4; ++j)
    for (int i = 0; i <= 4; ++i)
      grid += "v " + std::to_string(i) + " " + std::to_string(j) + " 0\n";
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      const int a = j * 5 + i + 1;
      grid += "f " + std::to_string(a) + " " + std::to_string(a + 1) + " " + std::to_string(a + 6) + " " +
              std::to_string(a + 5) + "\n";
    }
  write(dir / "grid.obj", grid);
  write(dir / "x.cnrig.json", R"({"format":"curvenet-rig","version":1,
    "nodes":[{"id":"a","position":[0.3,0.4,0]},{"id":"b","position":[3.7,3.4,0]},{"id":"c","position":[0.2,3.3,0]},{"id":"d","position":[3.6,0.3,0]}],
    "profiles":[{"id":"diag1","from":"a","to":"b","points":[[0.3,0.4,0],[3.7,3.4,0]]},{"id":"diag2","from":"c","to":"d","points":[[0.2,3.3,0],[3.6,0.3,0]]}]})");
  const CliRun r = run("embed " + (dir / "grid.obj").string() + " " + (dir / "x.cnrig.json").string() + " --report " +
                           (dir / "r.json").string(),
                       dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("diag1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("diag2"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "r.json"));
}

TEST(Cli, StarterWritesARigThatEmbeds) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("starter");
  const fs::path rig = dir / "hand.cnrig.json";
  const CliRun r = run("starter " + test::data("xr_tools_hand/hand_l_quads.obj") + " --skeleton " +
                           test::data("xr_tools_hand/hand_l.gltf") + " -o " + rig.string(),
                       dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("Curvenet starter: SUCCESS"), std::string::npos);
  // Joints left without a ring are listed, each with its reason.
  EXPECT_NE(r.out.find("joints without a ring: 6\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  Palm_L: every section across its bone"), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(rig));
  EXPECT_EQ(run("embed " + test::data("xr_tools_hand/hand_l.gltf") + " " + rig.string(), dir).code, 0);
  // The skeleton can come from a rig file too.
  EXPECT_EQ(run("starter " + test::data("xr_tools_hand/hand_l_quads.obj") + " --skeleton " +
                    test::data("xr_tools_hand/example/hand_l.cnrig.json") + " -o " + (dir / "again.json").string(),
                dir)
                .code,
            0);
}

TEST(Cli, StarterRefusesAMeshWithoutASkeleton) {
  const auto dir = test::temp_dir("starter_bad");
  write(dir / "quad.obj", kQuad);
  const fs::path out = dir / "out.cnrig.json";
  CliRun r = run("starter " + (dir / "quad.obj").string() + " -o " + out.string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("quad.obj"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--skeleton"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  // A skeleton far outside the mesh.
  write(dir / "far.cnrig.json", R"({"format":"curvenet-rig","version":1,"nodes":[],"profiles":[],"skeleton":{"joints":[
    {"name":"a","parent":null,"bind":[1,0,0,100, 0,1,0,100, 0,0,1,0, 0,0,0,1]},
    {"name":"b","parent":"a","bind":[1,0,0,101, 0,1,0,100, 0,0,1,0, 0,0,0,1]}]}})");
  r = run("starter " + (dir / "quad.obj").string() + " --skeleton " + (dir / "far.cnrig.json").string() + " -o " +
              out.string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("outside the mesh"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(run("starter --help", dir).code, 0);
}

TEST(Cli, PoseAndAnimateOnTheInputTopology) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("pose");
  const std::string hand = test::data("xr_tools_hand/example/hand_l_welded.obj");
  const std::string rig = test::data("xr_tools_hand/example/hand_l.cnrig.json");
  // A rigid pose reproduces the example's own linear-blend reference exactly.
  CliRun r = run("pose " + hand + " " + rig + " " + test::data("xr_tools_hand/example/wrist_rigid.pose.json") + " -o " +
                     (dir / "wrist.obj").string(),
                 dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const RawMesh posed = read_raw_mesh((dir / "wrist.obj").string());
  const RawMesh reference = read_raw_mesh(test::data("xr_tools_hand/example/wrist_rigid_lbs.obj"));
  ASSERT_EQ(posed.positions.size(), reference.positions.size());
  EXPECT_EQ(posed.face_vertices, reference.face_vertices);
  for (size_t i = 0; i < posed.positions.size(); ++i)
    EXPECT_LT((posed.positions[i] - reference.positions[i]).norm(), 1e-9) << i;
  // A glTF input keeps its own (unwelded) vertices and its UVs.
  r = run("pose " + test::data("xr_tools_hand/hand_l.gltf") + " " + rig + " " +
              test::data("xr_tools_hand/example/fist.pose.json") + " -o " + (dir / "fist.obj").string(),
          dir);
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream fist(dir / "fist.obj");
  std::string text((std::istreambuf_iterator<char>(fist)), std::istreambuf_iterator<char>());
  EXPECT_EQ(read_raw_mesh((dir / "fist.obj").string()).positions.size(), 1764u);
  EXPECT_NE(text.find("\nvt "), std::string::npos);
  EXPECT_NE(text.find("\nvn "), std::string::npos);
  // Bad input: a pose naming a joint the skeleton lacks.
  write(dir / "bad.pose.json",
        R"({"format":"curvenet-pose","version":1,"joints":{"NoSuchJoint":{"rotation":[1,0,0,0]}}})");
  r = run("pose " + hand + " " + rig + " " + (dir / "bad.pose.json").string() + " -o " + (dir / "bad.obj").string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("NoSuchJoint"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "bad.obj"));
  write(dir / "norm.pose.json",
        R"({"format":"curvenet-pose","version":1,"joints":{"Wrist_L":{"rotation":[1,0.1,0,0]}}})");
  r = run("pose " + hand + " " + rig + " " + (dir / "norm.pose.json").string() + " -o " + (dir / "bad.obj").string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/joints/Wrist_L/rotation"), std::string::npos) << r.err;
}

TEST(Cli, StarterTakesTheWeightRule) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // RiggedSimple's skin blends along its whole bone: the segment rule
  // stands in for it (docs/starter.md), and the rig's node weights follow.
  const auto dir = test::temp_dir("starter_rule");
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf");
  const fs::path seg = dir / "segment.cnrig.json", zone = dir / "zone.cnrig.json";
  CliRun r = run("starter " + gltf + " --weight-rule segment -o " + seg.string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("weights: segment\n"), std::string::npos) << r.out;
  r = run("starter " + gltf + " --weight-rule blend-zone --blend 0.2 -o " + zone.string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("weights: blend-zone 0.20\n"), std::string::npos) << r.out;
  const Rig a = read_rig(seg.string()), b = read_rig(zone.string());
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  EXPECT_NE(a.weights, b.weights);
  // By default a skinned file's own skin weights the nodes.
  const fs::path own = dir / "skin.cnrig.json";
  r = run("starter " + gltf + " -o " + own.string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("weights: skin (the mesh's own"), std::string::npos) << r.out;
  EXPECT_NE(read_rig(own.string()).weights, b.weights);
  // With the skin, each profile along the bone has a node at its middle,
  // which takes the skin's weights there; --no-middle-nodes leaves them out.
  const Rig with_skin = read_rig(own.string());
  const auto middles = std::count_if(with_skin.nodes.begin(), with_skin.nodes.end(),
                                     [](const Node& n) { return n.id.find("_mid") != std::string::npos; });
  EXPECT_GE(middles, 4) << "4 profiles along the one bone between the 2 rings, and the rings' arcs";
  EXPECT_EQ(with_skin.nodes.size(), a.nodes.size() + static_cast<size_t>(middles));
  const fs::path plain = dir / "plain.cnrig.json";
  r = run("starter " + gltf + " --no-middle-nodes -o " + plain.string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(read_rig(plain.string()).nodes.size(), a.nodes.size());
  // An OBJ has no skin to take them from: refused by name, with nothing written.
  const std::string obj = test::data("xr_tools_hand/example/hand_l_welded.obj");
  const fs::path none = dir / "none.cnrig.json";
  r = run("starter " + obj + " --skeleton " + test::data("xr_tools_hand/hand_l.gltf") + " --weight-rule skin -o " +
              none.string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("hand_l_welded.obj"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no skin"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(none));

  r = run("starter " + gltf + " --blend 0.7 -o " + (dir / "bad.cnrig.json").string(), dir);
  EXPECT_NE(r.code, 0);
  EXPECT_FALSE(fs::exists(dir / "bad.cnrig.json"));
}

TEST(Cli, AnimationDoesNotDependOnTheThreadCount) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("threads");
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf");
  ASSERT_EQ(run("starter " + gltf + " --rings-per-bone 2 -o " + (dir / "rs.cnrig.json").string(), dir).code, 0);
  const std::string args =
      "animate " + gltf + " " + (dir / "rs.cnrig.json").string() + " " + gltf + " --frames 0:40 -o ";
  ASSERT_EQ(run(args + (dir / "many.pc2").string(), dir).code, 0);
  // oneTBB follows the process's CPU affinity: one CPU, one worker.
  const std::string one =
      "taskset -c 0 " + std::string(CURVENET_CLI) + " " + args + (dir / "one.pc2").string() + " >/dev/null";
  ASSERT_EQ(std::system(one.c_str()), 0);
  std::ifstream a(dir / "many.pc2", std::ios::binary), b(dir / "one.pc2", std::ios::binary);
  const std::string sa((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
  const std::string sb((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
  EXPECT_GT(sa.size(), 32u);
  EXPECT_EQ(sa, sb);
}

TEST(Cli, BlenderReadsThePointCache) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  ASSERT_EQ(std::system("command -v blender >/dev/null"), 0)
      << "blender is missing: scripts/install-deps.sh installs it";
  const auto dir = test::temp_dir("blender");
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf");
  ASSERT_EQ(run("starter " + gltf + " --rings-per-bone 2 -o " + (dir / "rs.cnrig.json").string(), dir).code, 0);
  write(dir / "rest.pose.json", R"({"format":"curvenet-pose","version":1})");
  ASSERT_EQ(run("pose " + gltf + " " + (dir / "rs.cnrig.json").string() + " " + (dir / "rest.pose.json").string() +
                    " -o " + (dir / "rest.obj").string(),
                dir)
                .code,
            0);
  const std::string common = "animate " + (dir / "rest.obj").string() + " " + (dir / "rs.cnrig.json").string() + " " +
                             gltf + " --fps 24 --frames 10:14 ";
  ASSERT_EQ(run(common + "-o " + (dir / "anim.pc2").string(), dir).code, 0);
  ASSERT_EQ(run(common + "--obj-sequence " + (dir / "seq").string(), dir).code, 0);
  // The frames really differ, so the frame mapping is tested too.
  const RawMesh f10 = read_raw_mesh((dir / "seq" / "frame_0010.obj").string());
  const RawMesh f14 = read_raw_mesh((dir / "seq" / "frame_0014.obj").string());
  double moved = 0;
  for (size_t i = 0; i < f10.positions.size(); ++i)
    moved = std::max(moved, (f10.positions[i] - f14.positions[i]).norm());
  EXPECT_GT(moved, 1e-3);
  const std::string cmd = "blender -b --factory-startup --python " + std::string(CURVENET_SOURCE_DIR) +
                          "/tests/blender/check_mesh_cache.py -- " + (dir / "rest.obj").string() + " " +
                          (dir / "anim.pc2").string() + " " + (dir / "seq").string() + " 10 14 > " +
                          (dir / "blender.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream log(dir / "blender.txt");
  std::string line, result;
  while (std::getline(log, line))
    if (line.rfind("CURVENET_CHECK", 0) == 0)
      result = line;
  ASSERT_FALSE(result.empty()) << "the Blender script printed no result";
  std::istringstream fields(result);
  std::string tag, k1, k2, k3;
  double err = 1, scale = 0;
  int frames = 0;
  fields >> tag >> k1 >> err >> k2 >> scale >> k3 >> frames;
  std::printf("Blender Mesh Cache: largest difference %.3g (coordinates up to %.3g) over %d frames\n", err, scale,
              frames);
  EXPECT_EQ(frames, 5);
  EXPECT_LT(err, 1e-6 * scale);
}

TEST(Cli, TransferAndCompare) {
  const auto dir = test::temp_dir("transfer");
  ASSERT_EQ(run("demo --out " + (dir / "demo").string(), dir).code, 0);
  const fs::path quads = dir / "demo" / "tube_quads.obj", tris = dir / "demo" / "tube_tris.obj";
  const fs::path out = dir / "tris.cnrig.json", report = dir / "transfer.json";
  CliRun r = run("transfer " + (dir / "demo" / "tube.cnrig.json").string() + " --from " + quads.string() + " --to " +
                     tris.string() + " -o " + out.string() + " --report " + report.string(),
                 dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("Curvenet transfer: SUCCESS"), std::string::npos);
  EXPECT_NE(r.out.find("region agreement: "), std::string::npos);
  ASSERT_TRUE(fs::exists(out));
  std::ifstream in(report);
  const auto j = nlohmann::json::parse(in);
  EXPECT_TRUE(j["ok"].get<bool>());
  EXPECT_GT(j["agreement"].get<double>(), 0.99);
  EXPECT_EQ(j["target"]["regions"], 16);
  // The transferred rig embeds on the target as it is.
  EXPECT_EQ(run("embed " + tris.string() + " " + out.string(), dir).code, 0);
  // A frame that is not a matrix.
  r = run("transfer " + (dir / "demo" / "tube.cnrig.json").string() + " --from " + quads.string() + " --to " +
              tris.string() + " -o " + (dir / "bad.json").string() + " --target-frame 1,2,3",
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--target-frame"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "bad.json"));
  // Compare, as text and as JSON.
  r = run("compare " + quads.string() + " " + tris.string() + " --json", dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto c = nlohmann::json::parse(r.out);
  EXPECT_GT(c["max"].get<double>(), 0.0);
  EXPECT_LT(c["max_percent"].get<double>(), 2.0);
  EXPECT_TRUE(c.contains("a_to_b") && c.contains("b_to_a") && c.contains("rms"));
  r = run("compare " + quads.string() + " " + quads.string(), dir);
  EXPECT_NE(r.out.find("max: "), std::string::npos) << r.out;
  const double self = std::stod(r.out.substr(r.out.find("max: ") + 5));
  EXPECT_LT(self, 1e-12);
}

TEST(Cli, SubdivideACageThenTransferToItsRemesh) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("subdivide");
  const fs::path cage2 = dir / "fish_cc2.obj";
  CliRun r = run("subdivide " + test::data("blub/fish_control_mesh.obj") + " --levels 2 -o " + cage2.string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("112 faces -> 1776 quads"), std::string::npos) << r.out;
  EXPECT_EQ(load_mesh(cage2.string()).num_faces(), 1776);
  // Out of range: refused, nothing written.
  r = run("subdivide " + test::data("blub/fish_control_mesh.obj") + " --levels 9 -o " + (dir / "no.obj").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(dir / "no.obj"));
  // Six levels of the hand's 3,052 triangles would be 9.4 million quads
  // (past a minute and 3 GB): refused up front, naming both options.
  const std::string hand = test::data("xr_tools_hand/hand_l.gltf");
  for (const std::string& args : {"subdivide " + hand + " --levels 6 -o " + (dir / "no.obj").string(),
                                  "transfer " + test::data("xr_tools_hand/example/hand_l.cnrig.json") + " --from " +
                                      hand + " --to " + hand + " --to-cage 6 -o " + (dir / "no.json").string()}) {
    r = run(args, dir);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.err.find(args.rfind("subdivide", 0) == 0 ? "--levels 6: would make 9375744 faces"
                                                         : "--to-cage 6: would make 9375744 faces"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("(--max-faces); use fewer levels"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "no.obj"));
    EXPECT_FALSE(fs::exists(dir / "no.json"));
  }

  // A two-joint spine along the fish (z), a starter net on the refined cage,
  // and its transfer to the triangle remesh.
  write(dir / "spine.cnrig.json",
        R"({"format":"curvenet-rig","version":1,"nodes":[],"profiles":[],"skeleton":{"joints":[
    {"name":"root","parent":null,"bind":[1,0,0,0, 0,1,0,0.2, 0,0,1,-1.05, 0,0,0,1]},
    {"name":"bend","parent":"root","bind":[1,0,0,0, 0,1,0,0.2, 0,0,1,-0.07, 0,0,0,1]}]}})");
  const fs::path rig = dir / "fish.cnrig.json";
  r = run("starter " + cage2.string() + " --skeleton " + (dir / "spine.cnrig.json").string() +
              " --rings-per-bone 3 --first-angle 45 -o " + rig.string(),
          dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const fs::path out = dir / "low.cnrig.json", report = dir / "low.json";
  r = run("transfer " + rig.string() + " --from " + cage2.string() + " --to " +
              test::data("blub/fish_low_resolution.obj") + " -o " + out.string() + " --report " + report.string(),
          dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("surfaces apart before the transfer: "), std::string::npos) << r.out;
  std::ifstream in(report);
  const auto j = nlohmann::json::parse(in);
  EXPECT_TRUE(j["ok"].get<bool>());
  EXPECT_GT(j["agreement"].get<double>(), 0.95);
  EXPECT_LT(j["shape_distance"]["max_percent"].get<double>(), 2.0);

  // fish.obj is Blub in another pose: even moved onto the others, the
  // transfer is refused, saying how far apart the surfaces lie, and no rig
  // is written.
  r = run("transfer " + rig.string() + " --from " + cage2.string() + " --to " + test::data("blub/fish.obj") +
              " --target-frame 1,0,0,-3.3963165,0,1,0,0,0,0,1,0,0,0,0,1 -o " + (dir / "posed.cnrig.json").string(),
          dir);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("of the diagonal apart"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "posed.cnrig.json"));
}

TEST(Cli, TransferToAGameLODLinesUpByTheSkeletonsOfBothFiles) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // Blender's decimation of the horse is in Y up and a scale of 100: by
  // default (--align auto) the skins' skeletons line the meshes up.
  const auto dir = test::temp_dir("transfer_lod");
  const std::string horse = test::data("quaternius/Horse.glb"),
                    lod = std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Horse_decimated.glb";
  const fs::path rig = dir / "horse.cnrig.json", out = dir / "lod.cnrig.json", report = dir / "report.json";
  ASSERT_EQ(run("starter " + horse + " --skeleton " + horse + " -o " + rig.string(), dir).code, 0);
  CliRun r = run("transfer " + rig.string() + " --from " + horse + " --to " + lod + " -o " + out.string() +
                     " --report " + report.string(),
                 dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("lined up by: skeletons: 50 joints matched, scale 100"), std::string::npos) << r.out;
  std::ifstream in(report);
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["skeleton_fit"]["joints"], 50);
  EXPECT_EQ(j["skeleton_fit"]["source_to_target"].size(), 16u);
  // The frames alone (none) leave the LOD far off: refused, nothing written.
  r = run("transfer " + rig.string() + " --from " + horse + " --to " + lod + " --align frames -o " +
              (dir / "frames.cnrig.json").string(),
          dir);
  EXPECT_EQ(r.code, 2) << r.out << r.err; // bad input
  EXPECT_NE(r.err.find("the frames do not line the meshes up"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "frames.cnrig.json"));
  // Asked for skeletons where the source (an OBJ) has none: one line, naming it.
  ASSERT_EQ(run("demo --out " + (dir / "demo").string(), dir).code, 0);
  const fs::path obj = dir / "demo" / "tube_quads.obj";
  r = run("transfer " + rig.string() + " --from " + obj.string() + " --to " + lod + " --align skeletons -o " +
              (dir / "none.cnrig.json").string(),
          dir);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("has no skeleton"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "none.cnrig.json"));
}

TEST(Cli, TransferToACageThroughItsLimitSurface) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("to_cage");
  write(dir / "spine.cnrig.json",
        R"({"format":"curvenet-rig","version":1,"nodes":[],"profiles":[],"skeleton":{"joints":[
    {"name":"root","parent":null,"bind":[1,0,0,0.03, 0,1,0,-0.86, 0,0,1,-0.09, 0,0,0,1]},
    {"name":"bend","parent":"root","bind":[1,0,0,0.03, 0,1,0,0.16, 0,0,1,-0.09, 0,0,0,1]}]}})");
  const fs::path rig = dir / "penguin.cnrig.json";
  CliRun r = run("starter " + test::data("penguin/penguin.obj") + " --skeleton " + (dir / "spine.cnrig.json").string() +
                     " --rings-per-bone 3 --first-angle 45 -o " + rig.string(),
                 dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const fs::path out = dir / "cage.cnrig.json", report = dir / "cage.json";
  r = run("transfer " + rig.string() + " --from " + test::data("penguin/penguin.obj") + " --to " +
              test::data("penguin/penguin_control_mesh.obj") + " --to-cage 2 -o " + out.string() + " --report " +
              report.string(),
          dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  std::ifstream in(report);
  const auto j = nlohmann::json::parse(in);
  EXPECT_TRUE(j["ok"].get<bool>());
  EXPECT_GT(j["agreement"].get<double>(), 0.99);
  // Measured against the cage's limit surface, not the cage.
  EXPECT_LT(j["shape_distance"]["max_percent"].get<double>(), 1.0);
  // The rig written for the cage embeds on the cage as it is.
  EXPECT_EQ(run("embed " + test::data("penguin/penguin_control_mesh.obj") + " " + out.string(), dir).code, 0);
  // Levels out of range are refused before anything is read.
  r = run("transfer " + rig.string() + " --from " + test::data("penguin/penguin.obj") + " --to " +
              test::data("penguin/penguin_control_mesh.obj") + " --to-cage 9 -o " + (dir / "no.json").string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(dir / "no.json"));
}

TEST(Cli, DemoRunsOnGeneratedData) {
  const auto dir = test::temp_dir("demo");
  const CliRun r = run("demo --out " + (dir / "out").string(), dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("tube_quads: SUCCESS"), std::string::npos);
  EXPECT_NE(r.out.find("tube_tris: SUCCESS"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "out" / "tube_quads.regions.ply"));
  EXPECT_NE(r.out.find("embeds on 2/2 tessellations"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir / "out" / "tube_starter.cnrig.json"));
  EXPECT_TRUE(fs::exists(dir / "out" / "tube_tris.bend.pc2"));
  EXPECT_NE(r.out.find("transfer tube_quads -> tube_tris: SUCCESS"), std::string::npos) << r.out;
  EXPECT_EQ(fs::file_size(dir / "out" / "tube_tris.bend.pc2"),
            32u + 24u * 3u * sizeof(float) * read_raw_mesh((dir / "out" / "tube_tris.obj").string()).positions.size());
}

TEST(Cli, EveryFileOfTheDamagedCorpusIsRefusedInOneLine) {
  // tests/data/bad holds one fault per file. Each is refused with exit code
  // 2 and one line on stderr that names the file, and nothing is written.
  // Under the sanitizer build this replays the corpus under ASan and UBSan.
  const auto dir = test::temp_dir("corpus");
  write(dir / "quad.obj", kQuad);
  std::string skinned = kRig;
  skinned.insert(skinned.rfind('}'),
                 R"(,"skeleton":{"joints":[{"name":"j","parent":null,"bind":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}]})");
  write(dir / "ok.cnrig.json", skinned);
  int files = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(CURVENET_SOURCE_DIR) / "tests" / "data" / "bad")) {
    const std::string path = entry.path().string(), name = entry.path().filename().string();
    std::string args;
    const std::string quad = (dir / "quad.obj").string(), rig = (dir / "ok.cnrig.json").string();
    if (name.starts_with("gltf_clip_")) // a clip's fault: refused by bake and animate before any work
      args = name.ends_with("1e7_s.gltf")
                 ? "bake " + quad + " " + rig + " --clip " + path + " -o " + (dir / "out.glb").string()
                 : "animate " + quad + " " + rig + " " + path + " -o " + (dir / "out.obj").string();
    else if (name.ends_with(".cnrig.json"))
      args = "embed " + (dir / "quad.obj").string() + " " + path + " --report " + (dir / "out.json").string();
    else if (name.ends_with(".pose.json"))
      args = "pose " + (dir / "quad.obj").string() + " " + (dir / "ok.cnrig.json").string() + " " + path + " -o " +
             (dir / "out.obj").string();
    else
      args = "compare " + path + " " + path;
    SCOPED_TRACE(name);
    const CliRun r = run(args, dir);
    ++files;
    EXPECT_EQ(r.code, 2) << r.out << r.err;
    EXPECT_EQ(r.err.rfind("curvenet: error: " + path + ": ", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / "out.json"));
    EXPECT_FALSE(fs::exists(dir / "out.obj"));
    EXPECT_FALSE(fs::exists(dir / "out.glb"));
  }
  EXPECT_GE(files, 15);
}

TEST(Cli, NumbersInOptionsAreWholeFiniteAndInRange) {
  const auto dir = test::temp_dir("numbers");
  write(dir / "quad.obj", kQuad);
  write(dir / "ok.cnrig.json", kRig);
  const std::string mesh = (dir / "quad.obj").string(), rig = (dir / "ok.cnrig.json").string();
  struct Case {
    std::string args, says;
  };
  const Case cases[] = {
      {"embed " + mesh + " " + rig + " --density nan", "--density: 'nan' is not a finite number"},
      {"embed " + mesh + " " + rig + " --density 1e6", "--density: '1e6' is outside (0, 1000]"},
      {"starter " + mesh + " -o x.json --first-angle inf", "--first-angle: 'inf' is not a finite number"},
      {"animate " + mesh + " " + rig + " c.glb --fps nan -o x.pc2", "--fps: 'nan' is not a finite number"},
      {"transfer " + rig + " --from " + mesh + " --to " + mesh +
           " -o x.json --source-frame 1,0,0,0,0,0,0,0,0,0,1,0,0,0,0,1",
       "--source-frame: 1,0,0,0,0,0,0,0,0,0,1,0,0,0,0,1: the matrix is singular"},
      {"transfer " + rig + " --from " + mesh + " --to " + mesh +
           " -o x.json --target-frame 1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,nan",
       "'nan' is not a finite number"},
      {"embed " + mesh, "RIG is required"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.args);
    const CliRun r = run(c.args, dir);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err.rfind("curvenet: error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

TEST(Cli, FramesAreTwoWholeNumbersAroundOneColon) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("frames");
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf");
  ASSERT_EQ(run("starter " + gltf + " -o " + (dir / "rs.cnrig.json").string(), dir).code, 0);
  for (const std::string frames : {"1.5:3y", "1:2:3", "0:1e3", "3:", ":4", "a:b", "5:2"}) {
    SCOPED_TRACE(frames);
    const CliRun r = run("animate " + gltf + " " + (dir / "rs.cnrig.json").string() + " " + gltf + " --frames " +
                             frames + " -o " + (dir / "x.pc2").string(),
                         dir);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err.rfind("curvenet: error: --frames: " + frames + ": ", 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.pc2"));
  }
}

TEST(Cli, APoseThatWouldWriteNonFiniteNumbersIsRefused) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("huge_pose");
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf");
  ASSERT_EQ(run("starter " + gltf + " -o " + (dir / "rs.cnrig.json").string(), dir).code, 0);
  const Rig rig = read_rig((dir / "rs.cnrig.json").string());
  // Each joint scaled by 1e200: the child's world scale is 1e400, past a double.
  std::string joints;
  for (const auto& j : rig.joints)
    joints += (joints.empty() ? "\"" : ",\"") + j.name + R"(":{"scale":[1e200,1e200,1e200]})";
  write(dir / "huge.pose.json", R"({"format":"curvenet-pose","version":1,"joints":{)" + joints + "}}");
  const CliRun r = run("pose " + gltf + " " + (dir / "rs.cnrig.json").string() + " " +
                           (dir / "huge.pose.json").string() + " -o " + (dir / "out.obj").string(),
                       dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.rfind("curvenet: error: " + (dir / "huge.pose.json").string() + ": vertex ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find("not a finite number"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out.obj"));
  // The root alone scaled by 1e200: the positions are finite, and so must
  // be the normals (products of the coordinates overflowed to nan).
  write(dir / "big.pose.json", R"({"format":"curvenet-pose","version":1,"joints":{")" + rig.joints[0].name +
                                   R"(":{"scale":[1e200,1e200,1e200]}}})");
  const CliRun big = run("pose " + gltf + " " + (dir / "rs.cnrig.json").string() + " " +
                             (dir / "big.pose.json").string() + " -o " + (dir / "big.obj").string(),
                         dir);
  ASSERT_EQ(big.code, 0) << big.err;
  std::ifstream in(dir / "big.obj");
  int normals = 0;
  for (std::string line; std::getline(in, line);) {
    EXPECT_EQ(line.find("nan"), std::string::npos) << line;
    EXPECT_EQ(line.find("inf"), std::string::npos) << line;
    normals += line.rfind("vn ", 0) == 0;
  }
  EXPECT_GT(normals, 0);
}

TEST(Cli, MultipleOutputsAreAllOrNothingAndStaleTemporariesAreCleaned) {
  const auto dir = test::temp_dir("all_or_nothing");
  write(dir / "quad.obj", kQuad);
  write(dir / "ok.cnrig.json", kRig);
  const std::string mesh = (dir / "quad.obj").string(), rig = (dir / "ok.cnrig.json").string();
  const fs::path report = dir / "r.json", bad = dir / "quad.obj" / "cannot.ply"; // a file is not a folder
  // embed: the report is not left behind when the preview cannot be written.
  CliRun r = run("embed " + mesh + " " + rig + " --report " + report.string() + " --regions " + bad.string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(report));
  // transfer: neither is the report when the rig cannot be written.
  r = run("transfer " + rig + " --from " + mesh + " --to " + mesh + " --report " + report.string() + " -o " +
              bad.string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(report));
  for (const auto& entry : fs::directory_iterator(dir))
    EXPECT_EQ(entry.path().string().find(".tmp-"), std::string::npos) << entry.path();
  // A temporary file a killed run left beside a destination goes when the
  // destination is next written; one of a live process stays.
  const fs::path stale = report.string() + ".tmp-curvenet-2147483646", live = report.string() + ".tmp-curvenet-1";
  write(stale, "half a report");
  write(live, "another run's");
  EXPECT_EQ(run("embed " + mesh + " " + rig + " --report " + report.string(), dir).code, 0);
  EXPECT_TRUE(fs::exists(report));
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(live)); // pid 1 is alive
}

TEST(Cli, AnimateRefusesMoreFramesThanItsCap) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("max_frames");
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf");
  ASSERT_EQ(run("starter " + gltf + " -o " + (dir / "rs.cnrig.json").string(), dir).code, 0);
  const std::string base = "animate " + gltf + " " + (dir / "rs.cnrig.json").string() + " " + gltf + " -o " +
                           (dir / "x.pc2").string() + " --frames 0:200000000";
  CliRun r = run(base, dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "curvenet: error: --frames: 0:200000000: 200000001 frames is more than --max-frames (100000)\n");
  EXPECT_FALSE(fs::exists(dir / "x.pc2"));
}

TEST(Cli, BakeWritesASkinnedGlbAndTheWeightsOrNothing) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const fs::path dir = fs::path(::testing::TempDir()) / "cli_bake";
  fs::create_directories(dir);
  const std::string mesh = test::data("xr_tools_hand/hand_l.gltf"),
                    rig = test::data("xr_tools_hand/example/hand_l.cnrig.json");
  const std::string clips = test::data("xr_tools_hand/hand_l_poses.glb");
  const fs::path glb = dir / "hand.glb", csv = dir / "hand.csv";
  CliRun r = run("bake " + mesh + " " + rig + " -o " + glb.string() + " --weights-csv " + csv.string() + " --clip " +
                     clips + " --clip-name Grip --max-influences 8",
                 dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("Curvenet bake: SUCCESS"), std::string::npos);
  EXPECT_TRUE(fs::file_size(glb) > 1000 && fs::file_size(csv) > 1000);
  const SkinnedMesh back = load_skinned_mesh(glb.string());
  EXPECT_EQ(back.clip_names, std::vector<std::string>{"Grip"});
  // The skin against the rig, for the one clip carried: mean and worst vertex with its place.
  EXPECT_NE(r.out.find("fidelity: the skin against the rig, % of the diagonal: mean "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  clip 'Grip': 1 frames, mean "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(" s in; floor "), std::string::npos) << r.out; // and its floor
  EXPECT_NE(r.out.find(" rig joints there comes closer, whatever its weights)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("clip 'Pinky'"), std::string::npos) << "only the clips carried";
  // Fitted over the clips' frames.
  r = run("bake " + mesh + " " + rig + " --weights-csv " + (dir / "fit.csv").string() + " --fit " + clips, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("fitted"), std::string::npos);
  // With helper joints: said in the weights line, written to the GLB after
  // the rig's joints, and the floor said to be of the rig's joints alone.
  r = run("bake " + mesh + " " + rig + " -o " + (dir / "helpers.glb").string() + " --weights fitted --helpers 6" +
              " --clip " + clips + " --clip-name Grip",
          dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find(" joints (6 helpers of the 6 allowed, each keyed half way between two joints)"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find(" rig joints alone there comes closer"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\nhelpers: "), std::string::npos) << r.out; // named, each a~b
  EXPECT_NE(r.out.find(" (each node's extras name its two joints)\n"), std::string::npos) << r.out;
  EXPECT_EQ(load_skinned_mesh((dir / "helpers.glb").string()).joints.size(), back.joints.size() + 6);
  // Refusals: one line, exit 2, nothing written.
  for (const std::string& bad :
       {std::string(" -o ") + (dir / "x.glb").string() + " --clip " + clips + " --clip-name NoSuchClip",
        std::string(" -o ") + (dir / "x.glb").string() + " --max-influences 9",
        std::string(" -o ") + (dir / "x.glb").string() + " --helpers 4", // helpers are fitted
        std::string(" -o ") + (dir / "x.glb").string() + " --weights fitted --helpers -1",
        std::string(" --clip-name Grip -o ") + (dir / "x.glb").string(), std::string("")}) {
    r = run("bake " + mesh + " " + rig + bad, dir);
    EXPECT_EQ(r.code, 2) << bad;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.glb")) << bad;
  }
}

TEST(Cli, TheGradientModeIsAnOptionOfEveryDeformingCommand) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const fs::path dir = fs::path(::testing::TempDir()) / "cli_gradient";
  fs::create_directories(dir);
  const std::string mesh = test::data("xr_tools_hand/example/hand_l_welded.obj");
  const std::string rig = test::data("xr_tools_hand/example/hand_l.cnrig.json");
  const std::string pose = test::data("xr_tools_hand/example/fist.pose.json");
  for (const std::string rot : {"polar", "quaternion"}) {
    const CliRun r = run("pose " + mesh + " " + rig + " " + pose + " -o " + (dir / ("fist_" + rot + ".obj")).string() +
                             " --method gradient --rotation " + rot,
                         dir);
    EXPECT_EQ(r.code, 0) << r.err;
  }
  // The two modes give different fists; the gradient one keeps more volume (docs/deform.md).
  EXPECT_EQ(run("pose " + mesh + " " + rig + " " + pose + " -o " + (dir / "fist_h.obj").string(), dir).code, 0);
  const RawMesh a = read_raw_mesh((dir / "fist_polar.obj").string()), h = read_raw_mesh((dir / "fist_h.obj").string());
  double diff = 0;
  for (size_t i = 0; i < a.positions.size(); ++i)
    diff = std::max(diff, (a.positions[i] - h.positions[i]).norm());
  EXPECT_GT(diff, 1e-4);
  const CliRun bad = run("pose " + mesh + " " + rig + " " + pose + " -o " + (dir / "x.obj").string() +
                             " --method gradient --binding-cache " + (dir / "c.bin").string(),
                         dir);
  EXPECT_EQ(bad.code, 2);
  EXPECT_FALSE(fs::exists(dir / "x.obj"));
  EXPECT_EQ(
      run("pose " + mesh + " " + rig + " " + pose + " -o " + (dir / "x.obj").string() + " --method splines", dir).code,
      2);
}

TEST(Cli, EveryCommandWritesADeviceInPlaceAndABindingCacheOnlyWithItsOutput) {
  // `-o /dev/null` as root once renamed a temporary over the device. A
  // device node of the test's own stands for it (the null device's
  // numbers; making one needs root).
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("device_out");
  const fs::path null = dir / "null";
  const std::string gltf = test::data("rigged_simple/RiggedSimple.gltf"), rig = (dir / "rs.cnrig.json").string();
  ASSERT_EQ(run("starter " + gltf + " -o " + rig, dir).code, 0);
  write(dir / "bend.pose.json", R"({"format":"curvenet-pose","version":1,"joints":{}})");
  if (::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0)
    GTEST_SKIP() << "cannot make a device node here (not root)";
  const std::string n = null.string();
  for (const std::string& args : {"embed " + gltf + " " + rig + " --report " + n, "starter " + gltf + " -o " + n,
                                  "bind " + gltf + " " + rig + " -o " + n,
                                  "pose " + gltf + " " + rig + " " + (dir / "bend.pose.json").string() + " -o " + n,
                                  "animate " + gltf + " " + rig + " " + gltf + " -o " + n,
                                  "transfer " + rig + " --from " + gltf + " --to " + gltf + " -o " + n,
                                  "subdivide " + gltf + " --levels 1 -o " + n}) {
    SCOPED_TRACE(args);
    const CliRun r = run(args, dir);
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::is_character_file(null));
  }
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
  // The binding cache goes with the posed mesh: not written when the mesh cannot be.
  const fs::path cache = dir / "rs.cnbind", bad = dir / "rs.cnrig.json" / "out.obj"; // a file is not a folder
  CliRun r = run("pose " + gltf + " " + rig + " " + (dir / "bend.pose.json").string() + " --binding-cache " +
                     cache.string() + " -o " + bad.string(),
                 dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(cache));
  // A cache is read back before it is rewritten: a FIFO would block that
  // read for ever (a fuzzer's hang), and a device keeps nothing. Both are
  // refused by name, and left as they are.
  const fs::path fifo = dir / "cache.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0666), 0);
  for (const fs::path& c : {fifo, null}) {
    SCOPED_TRACE(c.string());
    r = run("bind " + gltf + " " + rig + " --binding-cache " + c.string() + " -o " + (dir / "bound.json").string(),
            dir);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err, "curvenet: error: " + c.string() +
                         ": a binding cache is read back and rewritten: give a regular file, not a device, a FIFO "
                         "or a folder\n");
    EXPECT_FALSE(fs::exists(dir / "bound.json"));
  }
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_character_file(null));
}

TEST(Cli, PoseAndAnimateWriteThePosedCutMeshOnRequest) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // A small skinned file, and a game character as shipped (its starter net
  // had failed to embed again on its own cut mesh).
  for (const char* file : {"rigged_simple/RiggedSimple.gltf", "quaternius/Horse.glb"}) {
    SCOPED_TRACE(file);
    const auto dir = test::temp_dir("cut_mesh_out");
    const std::string gltf = test::data(file), rig = (dir / "rs.cnrig.json").string();
    ASSERT_EQ(run("starter " + gltf + " -o " + rig, dir).code, 0);
    ASSERT_EQ(run("embed " + gltf + " " + rig + " --cut-mesh " + (dir / "rest_cut.obj").string(), dir).code, 0);
    const Rig r = read_rig(rig);
    write(dir / "bend.pose.json", R"({"format":"curvenet-pose","version":1,"joints":{")" + r.joints.back().name +
                                      R"(":{"rotation":[0.3826834,0,0,0.9238795]}}})");
    CliRun out = run("pose " + gltf + " " + rig + " " + (dir / "bend.pose.json").string() + " -o " +
                         (dir / "posed.obj").string() + " --cut-mesh " + (dir / "posed_cut.obj").string(),
                     dir);
    ASSERT_EQ(out.code, 0) << out.err;
    auto count = [](const fs::path& p, const char* prefix) {
      std::ifstream in(p);
      int n = 0;
      for (std::string line; std::getline(in, line);)
        n += line.rfind(prefix, 0) == 0;
      return n;
    };
    // The posed cut mesh has the rest cut mesh's vertices and curves, moved.
    EXPECT_EQ(count(dir / "posed_cut.obj", "v "), count(dir / "rest_cut.obj", "v "));
    EXPECT_EQ(count(dir / "posed_cut.obj", "l "), static_cast<int>(r.profiles.size()));
    EXPECT_NE(load_mesh((dir / "posed_cut.obj").string()).positions,
              load_mesh((dir / "rest_cut.obj").string()).positions);
    out = run("animate " + gltf + " " + rig + " " + gltf + " -o " + (dir / "a.pc2").string() + " --frames 0:2" +
                  " --cut-mesh-sequence " + (dir / "cut").string(),
              dir);
    ASSERT_EQ(out.code, 0) << out.err;
    for (const char* f : {"cut_frame_0000.obj", "cut_frame_0001.obj", "cut_frame_0002.obj"})
      EXPECT_EQ(count(dir / "cut" / f, "v "), count(dir / "rest_cut.obj", "v ")) << f;
  }
}

TEST(Cli, FarmCommandsRefuseBadInputInOneLineAndSbatchAbsentLeavesTheFolderReady) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("cli_farm");
  const std::string mesh = test::data("xr_tools_hand/hand_l.gltf"),
                    rig = test::data("xr_tools_hand/example/hand_l.cnrig.json"),
                    clips = test::data("xr_tools_hand/hand_l_poses.glb");
  const std::string base = "farm submit " + mesh + " " + rig + " " + clips + " --frames 0:29";
  CliRun r = run(base + " --clip Grip --folder " + (dir / "a").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "curvenet: error: farm submit: give -o OUT.pc2 or --obj-sequence DIR\n");
  r = run(base + " --clip Nope -o x.pc2 --folder " + (dir / "b").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("hand_l_poses.glb: clip 'Nope': no clip has this name or index"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "b"));
  // No sbatch on PATH: the folder is written and the line to submit it named.
  r = run("farm submit " + mesh + " " + rig + " " + clips + " --clip Grip --frames 0:29 --shard-frames 7 -o " +
              (dir / "m.pc2").string() + " --folder " + (dir / "c").string() + " --sbatch-option=--partition=anim",
          dir, "PATH=/nonexistent");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("sbatch is not on PATH"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("sbatch --parsable --array=0-4 '--partition=anim' '"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir / "c" / "manifest.json"));
  r = run("farm status " + (dir / "c").string(), dir, "PATH=/nonexistent");
  EXPECT_EQ(r.code, 1); // not done
  EXPECT_NE(r.out.find("task 4 (frames 28:29): missing"), std::string::npos) << r.out;
  r = run("farm merge " + (dir / "nowhere").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("nowhere/manifest.json: cannot open the file for reading"), std::string::npos) << r.err;
  write(dir / "c" / "manifest.json", "{\"format\": \"curvenet-farm 1\"}");
  r = run("farm merge " + (dir / "c").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("manifest.json: a damaged farm manifest"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
}

TEST(Cli, ALayerOverTheSkinRefusesWhatItCannotLayerInOneLine) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("cli_layer");
  const std::string gltf = test::data("xr_tools_hand/hand_l.gltf"),
                    obj = test::data("xr_tools_hand/example/hand_l_welded.obj"),
                    rig = test::data("xr_tools_hand/example/hand_l.cnrig.json"),
                    pose = test::data("xr_tools_hand/example/fist.pose.json");
  const std::string out = " -o " + (dir / "out.obj").string();
  CliRun r = run("pose " + obj + " " + rig + " " + pose + out + " --over-skin", dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("hand_l_welded.obj: has no skin to layer over"), std::string::npos) << r.err;
  // An envelope or a mask with nothing to scale (no skin under the net, no
  // node offsets) is refused, not ignored.
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --envelope 0.5", dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--envelope: 0.5"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("give --over-skin"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out.obj"));
  // A hand-typed quaternion of four digits is refused with what to do.
  write(dir / "typed.pose.json",
        R"({"format":"curvenet-pose","version":1,"joints":{"Wrist_L":{"rotation":[0.7071,0,0,0.7071]}}})");
  r = run("pose " + gltf + " " + rig + " " + (dir / "typed.pose.json").string() + out, dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("norm is 0.99999"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("divide the four numbers by their norm"), std::string::npos) << r.err;
  write(dir / "short.mask", "1\n0.5\n");
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --mask " + (dir / "short.mask").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("short.mask: 2 values for a mesh of 1764 vertices"), std::string::npos) << r.err;
  write(dir / "bad.mask", "1\n1.5\n");
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --mask " + (dir / "bad.mask").string(), dir);
  EXPECT_NE(r.err.find("bad.mask: line 2: expected a number from 0 to 1"), std::string::npos) << r.err;
  // A mask by region: a key no region has is named, with the mask file.
  write(dir / "regions.json", R"({"regions": {"nope:L": 0}})");
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --mask " + (dir / "regions.json").string(),
          dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("regions.json: region 'nope:L': no region of the net has this key"), std::string::npos) << r.err;
  write(dir / "regions.json", R"({"regions": {}, "others": 1.5})");
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --mask " + (dir / "regions.json").string(),
          dir);
  EXPECT_NE(r.err.find("regions.json: /others: expected a number from 0 to 1"), std::string::npos) << r.err;
  write(dir / "regions.json", R"({"regions": {}, "falloff": -1})");
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --mask " + (dir / "regions.json").string(),
          dir);
  EXPECT_NE(r.err.find("regions.json: /falloff: expected a number from 0 to 1"), std::string::npos) << r.err;
  // A falloff with every region at 0 changes nothing: there is no curve between two values.
  write(dir / "regions.json", R"({"regions": {}, "others": 0, "falloff": 0.05})");
  r = run("pose " + gltf + " " + rig + " " + pose + " -o " + (dir / "soft.obj").string() + " --over-skin --mask " +
              (dir / "regions.json").string(),
          dir);
  EXPECT_EQ(r.code, 0) << r.err;
  // Every region at 0 is the skin: the same file as the envelope at 0.
  write(dir / "regions.json", R"({"regions": {}, "others": 0})");
  r = run("pose " + gltf + " " + rig + " " + pose + " -o " + (dir / "none.obj").string() + " --over-skin --mask " +
              (dir / "regions.json").string(),
          dir);
  EXPECT_EQ(r.code, 0) << r.err;
  r = run("pose " + gltf + " " + rig + " " + pose + " -o " + (dir / "skin.obj").string() + " --over-skin --envelope 0",
          dir);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(read(dir / "none.obj").empty());
  EXPECT_EQ(read(dir / "none.obj"), read(dir / "skin.obj"));
  EXPECT_EQ(read(dir / "soft.obj"), read(dir / "skin.obj"));
  fs::remove(dir / "soft.obj");
  fs::remove(dir / "none.obj");
  fs::remove(dir / "skin.obj");
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --binding-cache " + (dir / "c").string(), dir);
  EXPECT_NE(r.err.find("a layer is bound without a binding cache"), std::string::npos) << r.err;
  write(dir / "nope.pose.json",
        R"({"format": "curvenet-pose", "version": 2, "nodes": {"nope": {"offset": [0, 0, 0]}}})");
  r = run("pose " + gltf + " " + rig + " " + (dir / "nope.pose.json").string() + out, dir);
  EXPECT_NE(r.err.find("nope.pose.json: /nodes/nope: the rig has no node of this id"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out.obj"));
  // A mask of all ones, and a layered animation of the hand's Grip.
  std::string ones;
  for (int i = 0; i < 1764; ++i)
    ones += "1\n";
  write(dir / "ones.mask", ones);
  r = run("pose " + gltf + " " + rig + " " + pose + out + " --over-skin --skinning dq --mask " +
              (dir / "ones.mask").string() + " --cut-mesh " + (dir / "cut.obj").string(),
          dir);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "cut.obj"));
  r = run("animate " + gltf + " " + rig + " " + test::data("xr_tools_hand/hand_l_poses.glb") +
              " --clip Grip --over-skin --envelope 0.5 -o " + (dir / "grip.pc2").string(),
          dir);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(fs::file_size(dir / "grip.pc2"), 32u + 1764u * 12u);
}
