// Plugin conformance checks, for any plugin (ours or a third party's) to run
// from its own tests. No test framework is assumed: each check returns a
// Report whose `failures` lists what is wrong, one line each.
//
//   TEST(MyPlugin, Conforms) {
//     const auto report = locforge::testkit::CheckPlugin("/path/to/libmy_plugin.so");
//     EXPECT_TRUE(report.ok()) << report.ToString();
//   }
//
// What is checked:
//  - CheckPlugin: the library loads with no problem (ABI version, struct
//    sizes, metadata) and defines at least one stage; then CheckMetadata and
//    CheckParamValidation for each of its stages.
//  - CheckMetadata: plugin name/version/description, stage doc, every
//    parameter documented with a valid default, every port documented and
//    typed with a dotted artifact type (e.g. "kapture.dataset"), runnable
//    stages have an output.
//  - CheckParamValidation: the plugin's own check_params accepts its defaults
//    (also with no values given), and refuses with LF_BAD_PARAMS and a message
//    naming the parameter: an unknown parameter, a mistyped value for each
//    bool/int/double/enum/list parameter, and a value just outside each
//    numeric bound.
//  - CheckDeterminism: runs a stage twice with the same parameters and inputs
//    into two fresh output folders (first with `threads`, then with one
//    thread) and compares every file byte for byte; also flags leftover temp
//    files (non-atomic writes). Skipped for LF_STAGE_NONDETERMINISTIC stages.
#ifndef LOCFORGE_TESTKIT_H_
#define LOCFORGE_TESTKIT_H_

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "locforge/runtime/registry.h"

namespace locforge::testkit {

namespace fs = std::filesystem;

struct Report {
  std::vector<std::string> failures;  // one line each; empty when all checks passed
  std::vector<std::string> notes;     // checks skipped, and why

  bool ok() const { return failures.empty(); }
  void Fail(const std::string& what) { failures.push_back(what); }
  void Note(const std::string& what) { notes.push_back(what); }
  void Merge(const Report& other);
  // Failures then notes, one per line.
  std::string ToString() const;
};

// Loads `plugin_file` into `registry` and reports its problems (a registry
// already holding other plugins is fine; their problems are not reported).
Report CheckLoads(runtime::Registry& registry, const fs::path& plugin_file);

Report CheckMetadata(const runtime::StageEntry& stage);
Report CheckParamValidation(const runtime::StageEntry& stage);

// CheckLoads + CheckMetadata + CheckParamValidation for every stage of the file.
Report CheckPlugin(const fs::path& plugin_file);

struct DeterminismCase {
  std::string stage_id;
  std::vector<std::pair<std::string, std::string>> params;
  std::vector<runtime::InputArtifact> inputs;
  int threads = 4;         // first run; the second run uses 1 thread
  fs::path scratch;        // where the two outputs go; default: a fresh temp folder
  bool keep_outputs = false;  // keep the scratch folder even when the check passes
};
Report CheckDeterminism(const runtime::Registry& registry, const DeterminismCase& c);

// Runs one stage of `registry` (its parameters checked as the host checks
// them) into `output_dir`, its workspace the parent folder; throws Error with
// the stage's message when it fails. For tests that run stages in process.
runtime::RunResult RunStage(const runtime::Registry& registry, const std::string& stage_id,
                            const std::vector<std::pair<std::string, std::string>>& params,
                            const std::vector<runtime::InputArtifact>& inputs, const fs::path& output_dir,
                            int threads = 2);

// Compares two folders recursively, byte for byte. Journal files of per-item
// runs (`.items-done.*`) are ignored: their line order follows thread timing.
Report CompareFolders(const fs::path& a, const fs::path& b);

}  // namespace locforge::testkit

#endif  // LOCFORGE_TESTKIT_H_
