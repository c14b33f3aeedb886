#pragma once
/// \file farm.hpp
/// `animate` on a render farm, through Slurm (docs/farm.md). A job folder
/// holds a manifest (the inputs' checksums, the binding options, the frame
/// ranges, the output) and a Slurm array script; each array task binds once
/// through the folder's binding cache (the first builds it behind a lock)
/// and writes its frames to its own part file, atomically; the merge checks
/// every part against the manifest and writes the final PC2 cache or OBJ
/// sequence, all or nothing, bit for bit what one `animate` writes.

#include "curvenet/jobs.hpp"

#include <string>
#include <vector>

namespace curvenet {

struct FarmJob {
  /// The inputs, the clip and its frames, the binding options, and the
  /// output: `pc2` or `obj_sequence` (one of them).
  AnimateJob animate;
  int shard_frames = 100;                  ///< frames per array task
  std::string folder;                      ///< the job folder, made by prepare_farm(); new or empty
  std::string executable;                  ///< the curvenet program the tasks run (found on PATH when empty)
  std::vector<std::string> sbatch_options; ///< more options for every sbatch line (`--partition=anim`)
  double lock_timeout_s = 1800;            ///< a binding-cache lock older than this counts as its owner's death
};

/// One array task's frames.
struct FarmShard {
  int index = 0, first = 0, last = 0;
};

/// What prepare_farm() wrote.
struct FarmPlan {
  std::string folder, manifest, script;
  std::vector<FarmShard> shards;
  int vertices = 0;
  /// The sbatch command line for every task (or `indices`, "3,5").
  [[nodiscard]] std::string sbatch_line(const std::string& indices = "") const;
  std::vector<std::string> sbatch_options;
};

/// Checks the inputs as `animate` would (the clip, the range, the skeleton)
/// and writes the job folder: `manifest.json`, `task.sbatch`, `parts/`,
/// `logs/`. Nothing is bound here: the tasks bind.
/// \throw InputError naming the file at fault, before anything is written;
///   Error when the folder holds anything already.
FarmPlan prepare_farm(const FarmJob& job);

/// prepare_farm(), then the array submitted with `sbatch --parsable`; the
/// Slurm job id is kept in the folder (`slurm_job_ids`).
/// \return the Slurm job id.
/// \throw Error with sbatch's own message when it refuses.
std::string submit_farm(const FarmPlan& plan, const std::string& indices = "");

/// The plan of an existing job folder, read from its manifest.
/// \throw InputError naming the manifest when it is missing or damaged.
FarmPlan read_farm_plan(const std::string& folder);

/// One array task: checks the inputs against the manifest's checksums,
/// binds through the folder's cache (the first task builds it behind a
/// lock; a lock whose owner died is taken over), and writes the shard's
/// part file atomically. Lines on what it did go to `log`.
/// \throw InputError when an input changed since the submission.
void run_farm_task(const std::string& folder, int index, std::ostream& log);

struct FarmMerge {
  std::string output;
  int frames = 0, vertices = 0, parts = 0;
};

/// Checks every part (present, complete, the manifest's frames and vertex
/// count, its checksum, finite numbers) and writes the job's output.
/// \throw InputError naming every missing or damaged part, with the sbatch
///   line that reruns only those; nothing is written then.
FarmMerge merge_farm(const std::string& folder);

struct FarmShardState {
  FarmShard shard;
  std::string state;  ///< PENDING, RUNNING, ... from squeue or sacct; done, damaged or missing from the part files
  std::string detail; ///< why a part is damaged, say
};
struct FarmStatus {
  std::vector<FarmShardState> shards;
  std::vector<std::string> sources; ///< what was asked: squeue, sacct, the part files
  int done = 0;
};

/// Each task's state, from squeue and sacct where they answer, and from the
/// part files otherwise.
FarmStatus farm_status(const std::string& folder);

} // namespace curvenet
