// The farm job (farm.hpp), without a scheduler: the folder prepare_farm()
// writes, tasks run in this process, and merges that must be bit for bit
// one `animate`, or refuse naming the part to rerun. The real Slurm cluster
// runs in tests/farm/test_slurm.py.

#include "curvenet/farm.hpp"

#include "curvenet/errors.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "helpers.hpp"
#include "io/frames_part.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>

#include <sys/wait.h>
#include <unistd.h>

using namespace curvenet;
namespace fs = std::filesystem;

namespace {

/// CesiumMan's walk with a starter net, sampled at 200 fps from frame 8,
/// so that every frame differs.
AnimateJob walk(const fs::path& out_dir, int frames) {
  AnimateJob a;
  a.scene.mesh = a.clip_file = test::data("cesium_man/CesiumMan.glb");
  a.scene.rig = (out_dir / "cesium.cnrig.json").string();
  if (!fs::exists(a.scene.rig)) {
    const SkinnedMesh skin = load_skinned_mesh(a.scene.mesh);
    StarterOptions opt;
    opt.deforming = weighted_joints(skin);
    write_rig(make_starter(load_mesh(a.scene.mesh), skin.joints, opt).rig, a.scene.rig);
  }
  a.fps = 200;
  a.frames = "8:" + std::to_string(8 + frames - 1);
  a.pc2 = (out_dir / "merged.pc2").string();
  return a;
}

FarmJob farm_of(const AnimateJob& a, const fs::path& folder, int shard_frames) {
  FarmJob f;
  f.animate = a;
  f.shard_frames = shard_frames;
  f.folder = folder.string();
  f.executable = CURVENET_CLI;
  return f;
}

/// The single-process animate of the same job, as the reference.
std::string single_pc2(AnimateJob a, const fs::path& dir) {
  a.pc2 = (dir / "single.pc2").string();
  (void)run(a);
  return test::file_bytes(a.pc2);
}

void run_all(const FarmPlan& plan) {
  std::ostringstream log;
  for (const auto& s : plan.shards)
    run_farm_task(plan.folder, s.index, log);
}

std::string part(const FarmPlan& plan, int index) {
  char name[32];
  std::snprintf(name, sizeof name, "part_%04d.frames", index);
  return (fs::path(plan.folder) / "parts" / name).string();
}

std::string merge_error(const std::string& folder) {
  try {
    (void)merge_farm(folder);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

} // namespace

TEST(Farm, TheFolderHoldsAManifestWithChecksumsShardsAndAnArrayScript) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("farm_folder");
  const FarmPlan plan = prepare_farm(farm_of(walk(dir, 95), dir / "job", 20));
  ASSERT_EQ(plan.shards.size(), 5u); // 20, 20, 20, 20 and 15 frames
  EXPECT_EQ(plan.shards.back().first, 88);
  EXPECT_EQ(plan.shards.back().last, 102);
  EXPECT_EQ(plan.vertices, 3273);
  const auto m = nlohmann::json::parse(test::file_bytes(plan.manifest));
  EXPECT_EQ(m["format"], "curvenet-farm 1");
  for (const char* role : {"mesh", "rig", "clip_file"}) {
    EXPECT_EQ(m["inputs"][role]["fnv1a64"].get<std::string>().size(), 16u) << role;
    EXPECT_TRUE(fs::path(m["inputs"][role]["path"].get<std::string>()).is_absolute()) << role;
  }
  EXPECT_EQ(m["bind"]["method"], "dq");
  EXPECT_EQ(m["frames"], nlohmann::json::array({8, 102}));
  EXPECT_EQ(m["fps"], 200.0);
  const std::string script = test::file_bytes(plan.script);
  EXPECT_NE(script.find("#SBATCH --job-name=curvenet-"), std::string::npos);
  EXPECT_NE(script.find("farm task '" + plan.folder + "' \"$SLURM_ARRAY_TASK_ID\""), std::string::npos) << script;
  EXPECT_EQ(plan.sbatch_line(), "sbatch --parsable --array=0-4 '" + plan.script + "'");
  EXPECT_EQ(plan.sbatch_line("3"), "sbatch --parsable --array=3 '" + plan.script + "'");
  // A folder that holds a job already is refused; so is a bad clip, before
  // anything is written.
  EXPECT_THROW(prepare_farm(farm_of(walk(dir, 95), dir / "job", 20)), Error);
  AnimateJob bad = walk(dir, 95);
  bad.clip = "NoSuchClip";
  fs::remove_all(dir / "job2");
  EXPECT_THROW(prepare_farm(farm_of(bad, dir / "job2", 20)), InputError);
  EXPECT_FALSE(fs::exists(dir / "job2"));
  // A clip file without clips is refused as animate refuses it (the farm had
  // a check of its own, with other words): a glTF without animations, and a
  // skinned FBX, whose skeleton is read and its animation not.
  AnimateJob still = walk(dir, 95);
  auto refused_as_animate_refuses = [&](const std::string& clip_file, const std::string& job, const char* element,
                                        const char* words) {
    still.clip_file = clip_file;
    try {
      (void)prepare_farm(farm_of(still, dir / job, 20));
      ADD_FAILURE() << clip_file << " was planned";
    } catch (const InputError& e) {
      EXPECT_EQ(e.element(), element);
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      std::string animate_says;
      try {
        (void)run(still);
      } catch (const InputError& a) {
        animate_says = a.what();
      }
      EXPECT_EQ(e.what(), animate_says);
    }
    EXPECT_FALSE(fs::exists(dir / job));
  };
  refused_as_animate_refuses(test::data("xr_tools_hand/hand_l.gltf"), "job3", "/animations", "no animation clips");
  refused_as_animate_refuses(std::string(CURVENET_SOURCE_DIR) + "/tests/data/good/fbx_skinned.fbx", "job4", "animation",
                             "glTF or GLB files only");
}

TEST(Farm, MergedShardsAreBitForBitOneAnimateAsPc2AndAsObjSequence) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("farm_merge");
  const AnimateJob a = walk(dir, 70);
  const FarmPlan plan = prepare_farm(farm_of(a, dir / "job", 16));
  run_all(plan);
  EXPECT_TRUE(fs::exists(fs::path(plan.folder) / "binding.cache")); // bound once, then read by the others
  // A PC2 job's parts keep floats, what the cache keeps: half the bytes.
  EXPECT_EQ(fs::file_size(part(plan, 0)), 40u + 16u * 3273u * 12u + 8u);
  const FarmMerge m = merge_farm(plan.folder);
  EXPECT_EQ(m.frames, 70);
  EXPECT_EQ(m.parts, 5);
  EXPECT_EQ(test::file_bytes(a.pc2), single_pc2(a, dir));

  AnimateJob seq = walk(dir, 12);
  seq.pc2.clear();
  seq.obj_sequence = (dir / "frames").string();
  const FarmPlan seq_plan = prepare_farm(farm_of(seq, dir / "seq_job", 5));
  run_all(seq_plan);
  EXPECT_EQ(fs::file_size(part(seq_plan, 0)), 40u + 5u * 3273u * 24u + 8u); // an OBJ sequence's keep doubles
  (void)merge_farm(seq_plan.folder);
  AnimateJob one = seq;
  one.obj_sequence = (dir / "frames_single").string();
  (void)run(one);
  for (int f = 8; f < 20; ++f) {
    const std::string name = sequence_name("frame", f);
    EXPECT_EQ(test::file_bytes(dir / "frames" / name), test::file_bytes(dir / "frames_single" / name)) << name;
  }
}

TEST(Farm, AMissingTruncatedOrForeignPartIsNamedWithTheSbatchLineForItAlone) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("farm_faults");
  const AnimateJob a = walk(dir, 40);
  const FarmPlan plan = prepare_farm(farm_of(a, dir / "job", 10));
  run_all(plan);
  const std::string good = test::file_bytes(part(plan, 2));

  fs::remove(part(plan, 1)); // a task that never ran, or was cancelled
  {
    std::ofstream cut(part(plan, 2), std::ios::binary); // truncated by hand
    cut.write(good.data(), static_cast<std::streamsize>(good.size() / 2));
  }
  const std::string e = merge_error(plan.folder);
  EXPECT_NE(e.find("2 of 4 parts"), std::string::npos) << e;
  EXPECT_NE(e.find("part_0001.frames: missing"), std::string::npos) << e;
  EXPECT_NE(e.find("part_0002.frames"), std::string::npos) << e;
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  EXPECT_NE(e.find("sbatch --parsable --array=1,2 '" + plan.script + "'"), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << "one line";
  EXPECT_FALSE(fs::exists(a.pc2)) << "nothing is written";
  const FarmStatus st = farm_status(plan.folder);
  EXPECT_EQ(st.done, 2);
  EXPECT_EQ(st.shards[1].state, "missing");
  EXPECT_EQ(st.shards[2].state, "damaged");

  // A flipped byte inside a frame keeps the size: the checksum finds it.
  std::string flipped = good;
  flipped[flipped.size() / 2] ^= 0x10;
  std::ofstream(part(plan, 2), std::ios::binary) << flipped;
  std::ostringstream log;
  run_farm_task(plan.folder, 1, log);
  EXPECT_NE(merge_error(plan.folder).find("part 2 (frames 28:37): " + part(plan, 2) + ": the checksum"),
            std::string::npos)
      << merge_error(plan.folder);

  // Rerunning only that part fixes it.
  run_farm_task(plan.folder, 2, log);
  EXPECT_EQ(merge_error(plan.folder), "");
  EXPECT_EQ(test::file_bytes(a.pc2), single_pc2(a, dir));

  // A part of another job (its manifest differs) is not taken.
  const FarmPlan other = prepare_farm(farm_of(walk(dir, 40), dir / "other", 10));
  run_farm_task(other.folder, 0, log);
  fs::copy_file(part(other, 0), part(plan, 0), fs::copy_options::overwrite_existing);
  EXPECT_NE(merge_error(plan.folder).find("written for another job"), std::string::npos);
}

TEST(Farm, ALockWhoseOwnerDiedIsTakenOverAndTheCacheBuilt) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("farm_lock");
  const AnimateJob a = walk(dir, 20);
  const FarmPlan plan = prepare_farm(farm_of(a, dir / "job", 10));
  // A task that took the lock and died: its PID is of a process that has
  // exited and been reaped.
  const pid_t dead = ::fork();
  if (dead == 0)
    ::_exit(0);
  ::waitpid(dead, nullptr, 0);
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  const fs::path cache = fs::path(plan.folder) / "binding.cache";
  std::ofstream(cache.string() + ".lock") << host << " " << dead << "\n";
  std::ostringstream log;
  run_farm_task(plan.folder, 0, log); // does not wait for ever
  EXPECT_NE(log.str().find("which is gone: binding here"), std::string::npos) << log.str();
  EXPECT_FALSE(fs::exists(cache.string() + ".lock"));
  EXPECT_TRUE(fs::exists(cache));
  run_farm_task(plan.folder, 1, log);
  EXPECT_EQ(merge_error(plan.folder), "");
  EXPECT_EQ(test::file_bytes(a.pc2), single_pc2(a, dir));
}

TEST(Farm, ATaskRefusesInputsThatChangedSinceTheSubmission) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("farm_changed");
  AnimateJob a = walk(dir, 10);
  fs::copy_file(a.scene.rig, dir / "walk.cnrig.json", fs::copy_options::overwrite_existing);
  a.scene.rig = (dir / "walk.cnrig.json").string();
  const FarmPlan plan = prepare_farm(farm_of(a, dir / "job", 10));
  std::ofstream(a.scene.rig, std::ios::app) << "\n";
  std::ostringstream log;
  try {
    run_farm_task(plan.folder, 0, log);
    ADD_FAILURE() << "a changed rig was used";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("walk.cnrig.json: rig: changed since the farm job was submitted"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(run_farm_task(plan.folder, 1, log), InputError); // no such task
}
