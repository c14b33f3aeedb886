// `animate` sharded over a Slurm array: the job folder, the tasks, the
// merge and the status (docs/farm.md).

#include "curvenet/farm.hpp"

#include "core/fnv1a.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/pose.hpp"
#include "io/file_bytes.hpp"
#include "io/frames_part.hpp"
#include "jobs/run.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

namespace curvenet {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kFormat = "curvenet-farm 1";

std::string absolute(const std::string& path) {
  return path.empty() ? path : fs::weakly_canonical(fs::absolute(path)).string();
}

std::string hex(std::uint64_t v) {
  std::ostringstream s;
  s << std::hex << std::setw(16) << std::setfill('0') << v;
  return s.str();
}

/// A file's size and checksum, as the manifest keeps them.
json fingerprint(const std::string& path) {
  const std::string bytes = detail::file_bytes(path);
  return {{"path", path}, {"bytes", bytes.size()}, {"fnv1a64", hex(detail::fnv1a(bytes))}};
}

std::string shell_quote(const std::string& s) {
  std::string q(1, '\'');
  for (char c : s)
    if (c == '\'')
      q.append("'\\''");
    else
      q.push_back(c);
  q.push_back('\'');
  return q;
}

/// Runs a command line through the shell; its standard output and error,
/// and whether it exited with 0.
std::pair<std::string, bool> run_command(const std::string& line) {
  std::string out;
  FILE* p = ::popen((line + " 2>&1").c_str(), "r");
  if (!p)
    return {"cannot run: " + line, false};
  char buf[4096];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0)
    out.append(buf, n);
  const int status = ::pclose(p);
  return {out, status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0};
}

bool on_path(const std::string& program) {
  if (const char* path = std::getenv("PATH")) {
    std::istringstream dirs(path);
    std::string d;
    while (std::getline(dirs, d, ':'))
      if (!d.empty() && ::access((fs::path(d) / program).c_str(), X_OK) == 0)
        return true;
  }
  return false;
}

std::string find_executable(const std::string& given) {
  if (!given.empty())
    return absolute(given);
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec && self.filename() == "curvenet")
    return self.string();
  if (const char* path = std::getenv("PATH")) {
    std::istringstream dirs(path);
    std::string d;
    while (std::getline(dirs, d, ':'))
      if (!d.empty() && ::access((fs::path(d) / "curvenet").c_str(), X_OK) == 0)
        return absolute((fs::path(d) / "curvenet").string());
  }
  throw Error("farm: no curvenet program on PATH for the tasks to run: name it");
}

json bind_options_json(const BindOptions& o) {
  return {{"method", to_string(o.method)},
          {"laplacian", o.laplacian == LaplacianChoice::Uniform ? "uniform" : "intrinsic"},
          {"rigid", o.rigid == RigidMode::Horn ? "horn" : "per-vertex"},
          {"rotation", o.rotation_blend == BindOptions::RotationBlend::Quaternion ? "quaternion" : "polar"},
          {"curve_frames", o.curve_frames}};
}

BindOptions bind_options_from(const json& j) {
  BindOptions o;
  if (!parse_deform_method(j.at("method").get<std::string>(), o.method))
    throw std::runtime_error("unknown method");
  o.laplacian = j.at("laplacian") == "uniform" ? LaplacianChoice::Uniform : LaplacianChoice::IntrinsicDelaunay;
  o.rigid = j.at("rigid") == "horn" ? RigidMode::Horn : RigidMode::PerVertex;
  o.rotation_blend =
      j.at("rotation") == "quaternion" ? BindOptions::RotationBlend::Quaternion : BindOptions::RotationBlend::Polar;
  o.curve_frames = j.at("curve_frames").get<bool>();
  return o;
}

/// The manifest, read and checked.
struct Manifest {
  FarmPlan plan;
  AnimateJob job;
  std::uint64_t key = 0;
  std::string job_name, cache;
  double lock_timeout_s = 1800;
  json inputs;
};

std::string part_path(const FarmPlan& plan, int index) {
  std::ostringstream name;
  name << "part_" << std::setw(4) << std::setfill('0') << index << ".frames";
  return (fs::path(plan.folder) / "parts" / name.str()).string();
}

Manifest read_manifest(const std::string& folder) {
  const std::string path = (fs::path(folder) / "manifest.json").string();
  const std::string text = detail::file_bytes(path);
  Manifest m;
  try {
    const json j = json::parse(text);
    if (j.at("format") != kFormat)
      throw InputError(path, "/format", "not a curvenet farm manifest (expected '" + std::string(kFormat) + "')");
    m.key = detail::fnv1a(text);
    m.plan.folder = absolute(folder);
    m.plan.manifest = path;
    m.plan.script = (fs::path(m.plan.folder) / "task.sbatch").string();
    m.plan.vertices = j.at("vertices").get<int>();
    m.plan.sbatch_options = j.at("sbatch_options").get<std::vector<std::string>>();
    for (const auto& s : j.at("shards"))
      m.plan.shards.push_back({static_cast<int>(m.plan.shards.size()), s.at(0).get<int>(), s.at(1).get<int>()});
    m.inputs = j.at("inputs");
    AnimateJob& a = m.job;
    a.scene.mesh = m.inputs.at("mesh").at("path");
    a.scene.rig = m.inputs.at("rig").at("path");
    if (m.inputs.contains("skeleton"))
      a.scene.skeleton = m.inputs.at("skeleton").at("path");
    a.clip_file = m.inputs.at("clip_file").at("path");
    a.clip = std::to_string(j.at("clip_index").get<int>());
    a.fps = j.at("fps").get<double>();
    a.options = bind_options_from(j.at("bind"));
    a.pc2 = j.at("output").value("pc2", "");
    a.obj_sequence = j.at("output").value("obj_sequence", "");
    m.cache = j.value("binding_cache", "");
    m.job_name = j.at("job_name");
    m.lock_timeout_s = j.at("lock_timeout_s").get<double>();
  } catch (const json::exception& e) {
    throw InputError(path, "", std::string("a damaged farm manifest: ") + e.what());
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const InputError*>(&e))
      throw;
    throw InputError(path, "/bind", std::string("a damaged farm manifest: ") + e.what());
  }
  return m;
}

/// Every input still has the checksum it was submitted with.
void check_inputs(const Manifest& m) {
  for (const auto& [role, f] : m.inputs.items()) {
    const std::string path = f.at("path");
    if (fingerprint(path).at("fnv1a64") != f.at("fnv1a64"))
      throw InputError(path, role,
                       "changed since the farm job was submitted (its checksum differs): submit the job again");
  }
}

/// The lock file's owner, "HOST PID".
std::string lock_owner() {
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  return std::string(host) + " " + std::to_string(::getpid());
}

/// Whether the owner written in a lock file is gone: a process of this host
/// that no longer runs, or a lock older than the timeout.
bool lock_is_dead(const std::string& lock, const std::string& owner, double timeout_s) {
  std::istringstream in(owner);
  std::string host;
  long pid = 0;
  in >> host >> pid;
  char here[256] = {};
  ::gethostname(here, sizeof here - 1);
  if (host == here && pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
    return true;
  std::error_code ec;
  const auto written = fs::last_write_time(lock, ec);
  return !ec && std::chrono::duration<double>(fs::file_time_type::clock::now() - written).count() > timeout_s;
}

/// Binds through the job's shared cache: a cache already there is read; the
/// first task to find none builds it behind the lock; the others wait, and
/// bind themselves if the lock's owner died.
BoundScene bind_shared(Scene scene, const BindOptions& options, OutputFiles& files, const Manifest& m,
                       std::ostream& log) {
  if (m.cache.empty()) // the gradient mode keeps no cache
    return bind_scene(std::move(scene), options, files);
  const std::string lock = m.cache + ".lock";
  for (;;) {
    if (fs::exists(m.cache))
      return bind_scene(std::move(scene), options, files); // read, or rebuilt with the outputs if it does not fit
    const int fd = ::open(lock.c_str(), O_CREAT | O_EXCL | O_WRONLY, 0644);
    if (fd >= 0) {
      const std::string owner = lock_owner() + "\n";
      const bool wrote = ::write(fd, owner.data(), owner.size()) == static_cast<ssize_t>(owner.size());
      ::close(fd);
      log << "curvenet farm: building the binding cache " << m.cache << (wrote ? "" : " (lock owner not written)")
          << "\n";
      try {
        OutputFiles own; // the cache alone, committed before the lock goes
        BoundScene b = bind_scene(std::move(scene), options, own);
        own.commit();
        fs::remove(lock);
        return b;
      } catch (...) {
        std::error_code ec;
        fs::remove(lock, ec);
        throw;
      }
    }
    std::string owner;
    try {
      owner = detail::file_bytes(lock);
    } catch (const InputError&) {
      continue; // the lock went between the two calls
    }
    if (lock_is_dead(lock, owner, m.lock_timeout_s)) {
      owner.erase(owner.find_last_not_of('\n') + 1);
      log << "curvenet farm: the binding-cache lock " << lock << " is held by '" << owner
          << "', which is gone: binding here\n";
      std::error_code ec;
      std::string again;
      try {
        again = detail::file_bytes(lock);
      } catch (const InputError&) {
      }
      if (again.substr(0, owner.size()) == owner)
        fs::remove(lock, ec);
      return bind_scene(std::move(scene), options, files); // the cache joins this task's outputs
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

std::string indices_of(const std::vector<int>& bad) {
  std::string s;
  for (int i : bad)
    s += (s.empty() ? "" : ",") + std::to_string(i);
  return s;
}

} // namespace

std::string FarmPlan::sbatch_line(const std::string& indices) const {
  std::ostringstream line;
  line << "sbatch --parsable --array=";
  if (indices.empty())
    line << "0-" << static_cast<int>(shards.size()) - 1;
  else
    line << indices;
  for (const auto& o : sbatch_options)
    line << ' ' << shell_quote(o);
  line << ' ' << shell_quote(script);
  return line.str();
}

FarmPlan prepare_farm(const FarmJob& job) {
  const AnimateJob& a = job.animate;
  if (job.folder.empty())
    throw InputError("--folder", "", "name the job folder");
  if (job.shard_frames < 1)
    throw InputError("--shard-frames", std::to_string(job.shard_frames), "a shard holds at least one frame");
  if (a.pc2.empty() == a.obj_sequence.empty())
    throw InputError("--output", "", "name one output: a PC2 file or an OBJ-sequence folder");
  if (!(job.lock_timeout_s > 0))
    throw InputError("--lock-timeout", std::to_string(job.lock_timeout_s), "expected a positive number of seconds");
  // What animate checks before it binds: the files, the clip, the range and
  // the skeleton.
  const Scene scene = read_scene(a.scene);
  const SkinnedMesh clips = load_skinned_mesh(a.clip_file);
  const int clip = detail::find_clip(clips, a.clip_file, a.clip);
  const FrameRange range = frame_range(clips, clip, a.fps, a.frames, a.max_frames);
  (void)clip_skinning_matrices(scene.rig.joints, clips, clip, range.time(range.first));
  const std::string executable = find_executable(job.executable);

  FarmPlan plan;
  plan.folder = absolute(job.folder);
  plan.manifest = (fs::path(plan.folder) / "manifest.json").string();
  plan.script = (fs::path(plan.folder) / "task.sbatch").string();
  plan.vertices = static_cast<int>(scene.mesh.input_to_welded.size());
  plan.sbatch_options = job.sbatch_options;
  for (long long f = range.first; f <= range.last; f += job.shard_frames)
    plan.shards.push_back({static_cast<int>(plan.shards.size()), static_cast<int>(f),
                           static_cast<int>(std::min<long long>(range.last, f + job.shard_frames - 1))});
  if (plan.shards.size() > 100000)
    throw InputError("--shard-frames", std::to_string(job.shard_frames), "more than 100000 tasks: larger shards");
  if (fs::exists(plan.folder) && !fs::is_empty(plan.folder))
    throw Error(plan.folder + ": the job folder is not empty: give a new one");

  json inputs = {{"mesh", fingerprint(absolute(a.scene.mesh))},
                 {"rig", fingerprint(absolute(a.scene.rig))},
                 {"clip_file", fingerprint(absolute(a.clip_file))}};
  if (!a.scene.skeleton.empty())
    inputs["skeleton"] = fingerprint(absolute(a.scene.skeleton));
  json shards = json::array();
  for (const auto& s : plan.shards)
    shards.push_back({s.first, s.last});
  json output = a.pc2.empty() ? json{{"obj_sequence", absolute(a.obj_sequence)}} : json{{"pc2", absolute(a.pc2)}};
  const std::string job_name = "curvenet-" + hex(detail::fnv1a(plan.folder)).substr(0, 8);
  json manifest = {{"format", kFormat},
                   {"inputs", inputs},
                   {"bind", bind_options_json(a.options)},
                   {"binding_cache", a.options.method == DeformMethod::Gradient
                                         ? ""
                                         : (fs::path(plan.folder) / "binding.cache").string()},
                   {"lock_timeout_s", job.lock_timeout_s},
                   {"clip", clips.clip_names[clip]},
                   {"clip_index", clip},
                   {"fps", a.fps},
                   {"frames", {range.first, range.last}},
                   {"vertices", plan.vertices},
                   {"shards", shards},
                   {"output", output},
                   {"executable", executable},
                   {"job_name", job_name},
                   {"sbatch_options", job.sbatch_options}};
  std::ostringstream script;
  script << "#!/bin/sh\n"
         << "# curvenet farm: one shard of frames per array task (" << plan.shards.size() << " tasks of "
         << job.shard_frames << " frames, clip '" << clips.clip_names[clip] << "').\n"
         << "# Merge the parts with: curvenet farm merge " << shell_quote(plan.folder) << "\n"
         << "#SBATCH --job-name=" << job_name << "\n"
         << "#SBATCH --output=" << (fs::path(plan.folder) / "logs" / "task_%a.log").string() << "\n"
         << "exec " << shell_quote(executable) << " farm task " << shell_quote(plan.folder)
         << " \"$SLURM_ARRAY_TASK_ID\"\n";
  OutputFiles files; // the folder all or nothing
  files.add(plan.manifest, manifest.dump(2) + "\n");
  files.add(plan.script, script.str());
  files.add((fs::path(plan.folder) / "parts" / ".keep").string(), "");
  files.add((fs::path(plan.folder) / "logs" / ".keep").string(), "");
  files.commit();
  fs::permissions(plan.script, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                  fs::perm_options::add);
  return plan;
}

FarmPlan read_farm_plan(const std::string& folder) {
  return read_manifest(folder).plan;
}

std::string submit_farm(const FarmPlan& plan, const std::string& indices) {
  if (!on_path("sbatch"))
    throw Error("farm: sbatch is not on PATH (Slurm's client): the job folder " + plan.folder +
                " is ready; submit it with: " + plan.sbatch_line(indices));
  const auto [out, ok] = run_command(plan.sbatch_line(indices));
  const std::string first = out.substr(0, out.find('\n'));
  const std::string id = first.substr(0, first.find(';'));
  if (!ok || id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit))
    throw Error("farm: sbatch refused the job in " + plan.folder + ": " + first +
                " (the folder is ready; submit it with: " + plan.sbatch_line(indices) + ")");
  std::ofstream(fs::path(plan.folder) / "slurm_job_ids", std::ios::app) << id << "\n";
  return id;
}

void run_farm_task(const std::string& folder, int index, std::ostream& log) {
  const Manifest m = read_manifest(folder);
  if (index < 0 || index >= static_cast<int>(m.plan.shards.size()))
    throw InputError(m.plan.manifest, "task " + std::to_string(index),
                     "no such task: the job has " + std::to_string(m.plan.shards.size()));
  check_inputs(m);
  const FarmShard& s = m.plan.shards[index];
  AnimateJob job = m.job;
  job.pc2.clear();
  job.obj_sequence.clear();
  job.frames = std::to_string(s.first) + ":" + std::to_string(s.last);
  job.max_frames = s.last - s.first + 1;
  job.scene.binding_cache = m.cache;
  job.frames_part = part_path(m.plan, index);
  job.part_key = m.key;
  job.part_single_precision = !m.job.pc2.empty(); // a PC2 cache keeps floats: half the bytes to move
  const auto t0 = std::chrono::steady_clock::now();
  const AnimateSummary r = detail::run_animate(
      job, [&](Scene scene, OutputFiles& files) { return bind_shared(std::move(scene), job.options, files, m, log); });
  log << "curvenet farm: task " << index << ": frames " << s.first << ":" << s.last << " of clip '" << r.clip_name
      << "', " << r.vertices << " vertices, in " << std::fixed << std::setprecision(2)
      << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s -> " << job.frames_part
      << "\n";
}

FarmMerge merge_farm(const std::string& folder) {
  const Manifest m = read_manifest(folder);
  check_inputs(m);
  const FarmPlan& plan = m.plan;
  const int nv = plan.vertices;
  const FrameRange range{plan.shards.front().first, plan.shards.back().last, m.job.fps};
  OutputFiles files;
  std::optional<InputTopology> topology;
  std::unique_ptr<FrameSink> sink;
  if (!m.job.pc2.empty()) {
    sink = std::make_unique<Pc2Sink>(files, m.job.pc2, nv, range, m.job.clip_file);
  } else {
    topology = read_input_topology(m.job.scene.mesh);
    sink = std::make_unique<ObjSequenceSink>(files, m.job.obj_sequence, *topology);
  }
  std::vector<int> bad;
  std::vector<std::string> why;
  std::vector<Vec3> frame(static_cast<size_t>(nv));
  for (const FarmShard& s : plan.shards) {
    const std::string path = part_path(plan, s.index);
    try {
      detail::FramesPartReader part(path);
      const auto& h = part.header();
      if (h.key != m.key)
        throw InputError(path, "header", "written for another job or manifest");
      if (h.first != s.first || h.count != s.last - s.first + 1)
        throw InputError(path, "header",
                         "frames " + std::to_string(h.first) + ":" + std::to_string(h.first + h.count - 1) +
                             ", not the shard's " + std::to_string(s.first) + ":" + std::to_string(s.last));
      if (h.vertices != nv)
        throw InputError(path, "header",
                         std::to_string(h.vertices) + " vertices, not the mesh's " + std::to_string(nv));
      if (h.precision != (m.job.pc2.empty() ? 8 : 4))
        throw InputError(path, "header", "written for another output (its precision)");
      if (!part.complete())
        throw InputError(path, "", "the file's size is not what its header says (truncated or padded)");
      for (int f = s.first; part.next(frame); ++f) {
        for (int v = 0; v < nv; ++v)
          if (!frame[v].allFinite())
            throw InputError(path, "frame " + std::to_string(f) + " vertex " + std::to_string(v),
                             "not a finite number");
        if (bad.empty()) // past a bad part the output is not written: the others are only checked
          sink->write(f, frame);
      }
      if (!part.checksum_ok())
        throw InputError(path, "", "the checksum does not match (damaged)");
    } catch (const InputError& e) {
      bad.push_back(s.index);
      why.push_back("part " + std::to_string(s.index) + " (frames " + std::to_string(s.first) + ":" +
                    std::to_string(s.last) + "): " + e.what());
    }
  }
  if (!bad.empty()) {
    std::string list;
    for (const auto& w : why)
      list += (list.empty() ? "" : "; ") + w;
    throw InputError(plan.folder, std::to_string(bad.size()) + " of " + std::to_string(plan.shards.size()) + " parts",
                     list + "; nothing was written; rerun only " + (bad.size() == 1 ? "that part" : "those parts") +
                         " with: " + plan.sbatch_line(indices_of(bad)));
  }
  files.commit();
  return {m.job.pc2.empty() ? m.job.obj_sequence : m.job.pc2, range.count(), nv, static_cast<int>(plan.shards.size())};
}

FarmStatus farm_status(const std::string& folder) {
  const Manifest m = read_manifest(folder);
  FarmStatus st;
  // A task's latest state in the queue, split into those still under way
  // and those that ended (kept by squeue for MinJobAge, by sacct for good).
  std::map<int, std::string> active, ended;
  auto note = [&](int index, const std::string& state) {
    static const std::set<std::string> over = {"COMPLETED", "CANCELLED", "FAILED",   "TIMEOUT",      "NODE_FAIL",
                                               "PREEMPTED", "BOOT_FAIL", "DEADLINE", "OUT_OF_MEMORY"};
    (over.count(state) ? ended : active)[index] = state;
  };
  if (on_path("squeue")) {
    // Every array task of this job's name, reruns included.
    const auto [out, ok] = run_command("squeue -h -r -t all --name=" + m.job_name + " -o '%K %T'");
    if (ok) {
      st.sources.push_back("squeue");
      std::istringstream lines(out);
      std::string index, state;
      while (lines >> index >> state)
        if (!index.empty() && std::all_of(index.begin(), index.end(), ::isdigit))
          note(std::stoi(index), state);
    }
  }
  if (on_path("sacct")) {
    const auto [out, ok] = run_command("sacct -n -P -X --name=" + m.job_name + " -o JobID,State");
    if (ok) {
      st.sources.push_back("sacct");
      std::istringstream lines(out);
      std::string line;
      while (std::getline(lines, line)) {
        const auto us = line.find('_'), bar = line.find('|');
        if (us == std::string::npos || bar == std::string::npos || bar < us)
          continue;
        const std::string index = line.substr(us + 1, bar - us - 1);
        if (!index.empty() && index.size() < 9 && std::all_of(index.begin(), index.end(), ::isdigit))
          note(std::stoi(index), line.substr(bar + 1, line.find(' ', bar) - bar - 1));
      }
    }
  }
  st.sources.push_back("part files");
  for (const FarmShard& s : m.plan.shards) {
    FarmShardState one{s, "missing", ""};
    const std::string path = part_path(m.plan, s.index);
    if (active.count(s.index)) {
      one.state = active[s.index];
    } else if (fs::exists(path)) {
      try {
        detail::FramesPartReader part(path);
        const auto& h = part.header();
        if (h.key != m.key || h.first != s.first || h.count != s.last - s.first + 1 || h.vertices != m.plan.vertices)
          one = {s, "damaged", "written for another job or shard"};
        else if (!part.complete())
          one = {s, "damaged", "truncated"};
        else
          one.state = "done";
      } catch (const InputError& e) {
        one = {s, "damaged", e.what()};
      }
    } else if (ended.count(s.index)) {
      one = {s, ended[s.index], "no part file"};
    }
    st.done += one.state == "done";
    st.shards.push_back(one);
  }
  return st;
}

} // namespace curvenet
