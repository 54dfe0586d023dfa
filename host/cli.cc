#include "cli.h"

#include <iostream>
#include <set>
#include <stdexcept>

#include "locforge/params.h"
#include "locforge/version.h"

namespace locforge::host {

namespace {

const char kMainHelp[] = R"(locforge - visual-localization ground truth and benchmarks

Usage: locforge COMMAND [ARGS...]

Commands:
  plugins list                  Stages of the loaded plugins, and refused libraries
  plugins describe KIND/NAME    A stage's parameters, inputs, outputs
  validate GRAPH.yaml           Checks a graph without running anything
  run GRAPH.yaml --workspace D  Runs a graph, cached and resumable
  kapture ...                   Kapture dataset tools
  colmap ...                    COLMAP model tools
  collect W NODE/FILE           One table of a node's result over a matrix run's variants
  status W [--verify]           Per-node state and cost (a Slurm submission's jobs);
                                --verify hashes every cached output file
  report W [-o FILE]            One HTML report of a workspace's last run
  help [COMMAND]                This help, or a command's

Options:
  --version                     Prints the version
  --help, -h                    Prints help (also after any command)

Plugins are searched in the build's plugin folder, <prefix>/lib/locforge/plugins,
the folders of $LOCFORGE_PLUGIN_PATH (':'-separated), and the graph's plugin_paths.

Exit codes: 0 ok, 1 a stage failed, 2 bad usage, configuration or graph.
)";

const char kPluginsHelp[] = R"(Usage: locforge plugins list [--plugin-path DIR]...
       locforge plugins describe KIND/NAME [--plugin-path DIR]...

list      Every stage as KIND/NAME with its plugin, version and file. Libraries
          that were refused (not loadable, wrong ABI, bad metadata) are shown as
          warnings with the reason. Exits 1 when two libraries provide the same
          stage, naming both files.
describe  The stage's documentation, whether it runs per item or whole, its
          parameters (type, default, range or choices, required, doc), inputs
          and outputs with artifact types, and its component interface.

Options:
  --plugin-path DIR   Also load the plugins of DIR (repeatable)
)";

const char kGraphHelp[] = R"(Graph file (YAML):
  locforge: 1                   # graph format version (required)
  description: ...
  plugin_paths: [./my_plugins]  # extra plugin folders, relative to the graph file
  vars:                         # graph variables, overridable with --set name=value
    count: 8
  matrix:                       # optional: one variant per combination
    bins: [8, 16]
  nodes:
    images:
      stage: source/synthetic_images
      params: {count: ${count}}
    stats:
      stage: example/image_stats
      inputs: {images: images.images}   # NODE.PORT; a list for multi-wire ports
      params: {bins: ${bins}}

${name} substitutes a variable or matrix key inside any value; a value that is
exactly ${name} takes the variable's value as is (a list stays a list). YAML
lists give list parameters.

--set name=value        overrides a graph variable (or pins a matrix key; [a, b] sets its list)
--set node.param=value  overrides one node's parameter; [a, b] gives a list
Relative PATH parameters are resolved against the graph file's folder when
written in the graph, and against the current directory when they come from
--set (directly or through a variable set with --set).
)";

const char kValidateHelp[] =
    R"(Usage: locforge validate GRAPH.yaml [--set KEY=VALUE]... [--plugin-path DIR]...

Checks the graph without running anything: YAML syntax and duplicate keys,
unknown variables, stages (did you mean), parameters (names, types, ranges,
choices, required ones, the stage's own checks, PATH parameters that must
exist), wires (nodes, ports, artifact types, required inputs, cycles), and the
plugin libraries the graph names. Every problem is printed as FILE:LINE:COLUMN
with what was expected. Exits 0 when valid, 2 otherwise.

)";

const char kRunHelp[] = R"(Usage: locforge run GRAPH.yaml --workspace DIR [options]

Runs the graph's nodes in topological order. Each node writes into
DIR/cache/<node>-<key16>/, where the key hashes the stage, plugin and SDK
versions, the parameters, PATH parameter stamps and the input nodes' keys: a
node whose folder is complete is not run again. DIR/nodes/<node> links to the
node's current folder (DIR/variants/<variant>/nodes/<node> with a matrix).
Per-item nodes journal finished items, so an interrupted run resumes.
The log of each run is DIR/logs/run-<UTC time>.log.

Options:
  --workspace DIR     Workspace folder (created if missing; required)
  --set KEY=VALUE     Override a variable or NODE.PARAM (repeatable)
  --threads N         Threads for stages (default: hardware concurrency)
  --force             Rerun every node even when cached
  --shard I/N         Process shard I of N of per-item nodes; downstream nodes
                      wait for the other shards (run without --shard to finish)
  --variant NAME      Run only this matrix variant (e.g. bins=8)
  --plugin-path DIR   Also load the plugins of DIR (repeatable)
  --node NODE         Run only NODE; its inputs must be complete (a job's run)
  --executor E        local (default): run here; slurm: submit one job per
                      node not complete (DIR must be on a shared file system)

With --executor slurm:
  --shards N          Array tasks of each per-item node (default 4); a job
                      runs `locforge run GRAPH --node NODE --shard array/N`
  --slurm-opt [SEL:]OPTION=VALUE
                      An sbatch long option for the jobs (repeatable), e.g.
                      partition=cpu, mem=16G, time=2:00:00, gt:cpus-per-task=8;
                      SEL (default: all jobs) is a stage kind, a stage id or a
                      node; over the graph's `slurm:` section and the defaults
  --wait              Follow the jobs to the end (Ctrl-C cancels them with
                      scancel); else see `locforge status DIR`
  --poll SECONDS      Interval between squeue calls with --wait (default 10)
Jobs wait for their inputs' jobs (afterok). Complete nodes are not submitted;
of a partly done per-item node only the shards that did not finish. Job
logs: DIR/logs/slurm/; submissions: DIR/slurm/.

Ctrl-C stops cleanly: finished items are kept and the next run resumes.
Exit codes: 0 ok (or this shard done, or submitted), 1 a stage or job failed,
2 bad usage or graph.

)";

}  // namespace

std::string VersionText() {
  return std::string("locforge ") + LOCFORGE_VERSION_STRING + " (plugin ABI " +
         std::to_string(LF_ABI_VERSION) + ")";
}

std::string HelpText(const std::string& command) {
  if (command.empty()) return kMainHelp;
  if (command == "plugins") return kPluginsHelp;
  if (command == "validate") return std::string(kValidateHelp) + kGraphHelp;
  if (command == "run") return std::string(kRunHelp) + kGraphHelp;
  if (command == "help") return "Usage: locforge help [COMMAND]\n";
  return "";
}

bool WantsHelp(const Args& args) {
  for (const auto& a : args)
    if (a == "--help" || a == "-h") return true;
  return false;
}

int UsageError(const std::string& command, const std::string& message) {
  std::cerr << "locforge " << command << ": " << message << "\n"
            << "Run 'locforge " << command << " --help' for usage.\n";
  return 2;
}

bool TakeOption(const Args& args, size_t* i, const std::string& name, std::string* value) {
  const std::string& a = args[*i];
  if (a.rfind(name + "=", 0) == 0) {
    *value = a.substr(name.size() + 1);
    return true;
  }
  if (a != name) return false;
  if (*i + 1 >= args.size()) throw std::invalid_argument(name + " needs a value");
  *value = args[++*i];
  return true;
}

std::vector<runtime::PluginProblem> LoadPlugins(runtime::Registry* registry,
                                                const std::vector<fs::path>& extra) {
  std::set<fs::path> loaded;
  auto canonical = [](const fs::path& p) {
    std::error_code ec;
    const fs::path c = fs::canonical(p, ec);
    return ec ? p : c;
  };
  for (const auto& folder : runtime::Registry::DefaultSearchPath())
    if (loaded.insert(canonical(folder)).second) registry->LoadFolder(folder);
  const size_t default_problems = registry->problems().size();
  for (const auto& folder : extra) {
    std::error_code ec;
    if (!fs::is_directory(folder, ec))
      std::cerr << "warning: plugin folder " << folder.string() << " does not exist\n";
    else if (loaded.insert(canonical(folder)).second)
      registry->LoadFolder(folder);
  }
  const auto& problems = registry->problems();
  for (size_t i = 0; i < default_problems; ++i)
    std::cerr << "warning: plugin " << problems[i].file.string()
              << " refused and skipped: " << problems[i].message << "\n";
  return {problems.begin() + static_cast<long>(default_problems), problems.end()};
}

int Main(const Args& args) {
  if (args.empty()) {
    std::cerr << kMainHelp;
    return 2;
  }
  const std::string& command = args.front();
  const Args rest(args.begin() + 1, args.end());
  if (command == "--version" || command == "version") {
    std::cout << VersionText() << "\n";
    return 0;
  }
  if (command == "--help" || command == "-h") {
    std::cout << kMainHelp;
    return 0;
  }
  if (command == "help") {
    if (rest.empty() || rest.front() == "--help" || rest.front() == "-h") {
      std::cout << (rest.empty() ? kMainHelp : HelpText("help"));
      return 0;
    }
    if (rest.front() == "collect") return CollectCommand({"--help"});
    if (rest.front() == "status") return StatusCommand({"--help"});
    if (rest.front() == "report") return ReportCommand({"--help"});
    if (rest.front() == "kapture" || rest.front() == "colmap")
      return rest.front() == "kapture" ? KaptureCommand({"--help"}) : ColmapCommand({"--help"});
    const std::string text = HelpText(rest.front());
    if (text.empty()) {
      const std::string hint =
          DidYouMean(rest.front(), {"plugins", "validate", "run", "kapture", "colmap", "collect", "report"});
      return UsageError("help", "no such command '" + rest.front() + "'" +
                                    (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
    std::cout << text;
    return 0;
  }
  if (command == "plugins") return PluginsCommand(rest);
  if (command == "validate") return ValidateCommand(rest);
  if (command == "run") return RunCommand(rest);
  if (command == "kapture") return KaptureCommand(rest);
  if (command == "collect") return CollectCommand(rest);
  if (command == "status") return StatusCommand(rest);
  if (command == "report") return ReportCommand(rest);
  if (command == "colmap") return ColmapCommand(rest);
  const std::vector<std::string> commands = {"plugins", "validate", "run",    "kapture", "colmap",
                                             "collect", "status",   "report", "help"};
  const std::string hint = DidYouMean(command, commands);
  std::cerr << "locforge: unknown command '" << command << "'"
            << (hint.empty() ? "" : " (did you mean '" + hint + "'?)")
            << "\nRun 'locforge --help' for the list of commands.\n";
  return 2;
}

}  // namespace locforge::host
