// `curvenet farm`: submit, task, merge and status, over farm.hpp.

#include "commands.hpp"

#include "curvenet/farm.hpp"

#include <iostream>

namespace curvenet::cli {

int run_farm_submit(const FarmSubmitArgs& a) {
  FarmJob job;
  job.animate = animate_job(a);
  job.shard_frames = a.shard_frames;
  job.folder = a.folder;
  job.sbatch_options = a.sbatch_options;
  job.lock_timeout_s = a.lock_timeout;
  const FarmPlan plan = prepare_farm(job);
  std::cout << "Curvenet farm: " << (a.dry_run ? "job folder written" : "submitting") << "\n"
            << "folder: " << plan.folder << "\n"
            << "tasks: " << plan.shards.size() << " of at most " << a.shard_frames << " frames, frames "
            << plan.shards.front().first << ":" << plan.shards.back().last << ", " << plan.vertices << " vertices\n";
  if (a.dry_run) {
    std::cout << "submit with: " << plan.sbatch_line() << "\n";
    return 0;
  }
  const std::string id = submit_farm(plan);
  std::cout << "slurm job: " << id << "\n"
            << "then: curvenet farm status " << plan.folder << "; curvenet farm merge " << plan.folder << "\n";
  return 0;
}

int run_farm_task(const std::string& folder, int index) {
  curvenet::run_farm_task(folder, index, std::cerr);
  return 0;
}

int run_farm_merge(const std::string& folder) {
  const FarmMerge m = merge_farm(folder);
  std::cout << "Curvenet farm merge: SUCCESS\n"
            << "parts: " << m.parts << "\n"
            << "output: " << m.output << " (" << m.frames << " frames, " << m.vertices << " vertices)\n";
  return 0;
}

int run_farm_status(const std::string& folder) {
  const FarmStatus st = farm_status(folder);
  std::cout << "from:";
  for (const auto& s : st.sources)
    std::cout << " " << s;
  std::cout << "\n";
  for (const auto& s : st.shards)
    std::cout << "task " << s.shard.index << " (frames " << s.shard.first << ":" << s.shard.last << "): " << s.state
              << (s.detail.empty() ? "" : " (" + s.detail + ")") << "\n";
  std::cout << "done: " << st.done << " of " << st.shards.size() << "\n";
  return st.done == static_cast<int>(st.shards.size()) ? 0 : 1;
}

} // namespace curvenet::cli
