// Runs a graph on a Slurm cluster over a shared workspace
// (`locforge run G --workspace W --executor slurm`): every node not complete
// becomes a job running `locforge run G --workspace W --node NODE`; a
// per-item node an array job of N shards (`--shard array/N`: the task id is
// the shard); jobs wait for their inputs' jobs (afterok). sbatch, squeue,
// sacct and scancel are run with argument vectors (host/process.h).
//
//   W/slurm/job.sh                      the batch script: `exec "$@"` (the job's
//                                       command is sbatch's argument vector)
//   W/slurm/submission-<UTC>.tsv        one line per node: job id (or - when
//                                       cached), variant, node, stage, key, shards,
//                                       array indices, log file, jobs waited for
//   W/slurm/latest                      the name of the last submission
//   W/logs/slurm/<node>-<job>[_<task>].log  each job's output
// A re-submission computes the keys again: complete nodes are not submitted,
// and of a partly done per-item node only the shards without a shard record
// (workspace.h), whose items resume from the journals.
#ifndef LOCFORGE_HOST_SLURM_H_
#define LOCFORGE_HOST_SLURM_H_

#include <atomic>
#include <map>
#include <string>
#include <vector>

#include "graph.h"
#include "progress.h"
#include "workspace.h"

namespace locforge::host {

struct SlurmOptions {
  int shards = 4;                           // array tasks of a per-item node
  std::vector<SchedulerSetting> settings;   // --slurm-opt, in command-line order
  fs::path graph;                           // absolute
  std::vector<std::string> forward;         // arguments each job repeats (--set, --plugin-path)
  fs::path locforge;                        // the executable the jobs run
  fs::path cwd;                             // the jobs' working directory
  bool Check(std::string* why) const;
};

// Parses a --slurm-opt value, `[SELECTOR:]KEY=VALUE` (SELECTOR default:
// `default`). Returns false when malformed.
bool ParseSchedulerSetting(const std::string& text, SchedulerSetting* out);

// Checks settings (the graph's and --slurm-opt's) against the variants:
// selectors that name no stage kind, stage or node, malformed option names,
// and options locforge sets itself (array, dependency, output, ...).
void CheckSchedulerSettings(const std::vector<SchedulerSetting>& settings,
                            const std::vector<ResolvedGraph>& variants, Diagnostics* errors);

// The sbatch options of a node's jobs: built-in defaults per stage kind,
// then the graph's settings, then --slurm-opt, each by specificity
// (default < kind < kind/name < node).
std::map<std::string, std::string> JobOptions(const ResolvedNode& node,
                                              const std::vector<SchedulerSetting>& graph,
                                              const std::vector<SchedulerSetting>& cli);

// One line of a submission record.
struct SlurmJob {
  std::string job_id;  // "-": complete at submission, nothing submitted
  std::string variant, node, stage, key16;
  int shards = 1;      // > 1: an array job of that many shards
  std::string array;   // the submitted indices ("0-2", "1"), "" for one job
  std::string log;     // log file (array: with %A and %a)
  std::string after;   // job ids waited for, ',' separated
};

struct Submission {
  fs::path file;
  std::vector<SlurmJob> jobs;  // topological order of each variant
};

// Computes the plan and submits it: one sbatch call per job, in order.
// Writes the record (also when an sbatch call fails: what was submitted is
// listed). Throws Error naming the node and sbatch's message.
Submission SubmitToSlurm(const Workspace& workspace, const std::vector<ResolvedGraph>& variants,
                         const std::vector<SchedulerSetting>& graph_settings,
                         const SlurmOptions& options, Reporter& reporter);

// The latest submission of the workspace; throws InputError when there is none.
Submission ReadLatestSubmission(const Workspace& workspace);
Submission ReadSubmission(const fs::path& file);

// The state of a submission's nodes, from the workspace (complete folders,
// shard records) and Slurm (squeue, then sacct when accounting is there).
struct NodeState {
  SlurmJob job;
  std::string state;    // done, cached, pending, running, failed, blocked, lost
  std::string detail;   // e.g. "2/3 shards done, 1 running", the pending reason
  bool terminal = false;
  std::vector<std::string> failures;  // "shard 1/3 (job 12_1) CANCELLED; log: ..."
  std::vector<std::string> active_ids;  // job (or job_task) ids still queued or running
  Manifest manifest;    // when done
  bool has_manifest = false;
};
std::vector<NodeState> QuerySlurmStatus(const Workspace& workspace, const Submission& submission);

// Per-node table: state, jobs, items, wall and CPU seconds, peak memory, output.
std::string FormatSlurmStatus(const std::vector<NodeState>& states);

// Follows the submission until no job is queued or running, printing state
// changes; on `cancel` runs scancel on the jobs still queued or running.
// Returns the final states.
std::vector<NodeState> WaitForSlurm(const Workspace& workspace, const Submission& submission,
                                    double poll_seconds, const std::atomic<bool>* cancel,
                                    Reporter& reporter, bool* cancelled);

// Cancels the given job ids (scancel). Returns scancel's error, "" when fine.
std::string CancelSlurmJobs(const std::vector<std::string>& ids);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_SLURM_H_
