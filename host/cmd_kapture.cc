// `locforge kapture info DIR`, `locforge kapture copy SRC DST` and
// `locforge kapture export W OUT`.
#include <algorithm>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "cli.h"
#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "run_record.h"
#include "workspace.h"

namespace locforge::host {

namespace {

const char kKaptureHelp[] =
    "Usage: locforge kapture info DIR [--strict] [--check-images]\n"
    "       locforge kapture copy SRC DST [--overwrite] [--no-records-data] [--unpack]\n"
    "       locforge kapture export W OUT [--nodes A,B,...] [--trajectories NODE] [--copy]\n"
    "                                     [--force]\n"
    "\n"
    "Tools for kapture 1.1 datasets (sensors/, reconstruction/).\n"
    "\n"
    "  info DIR     Reads every file of the kapture at DIR (records are streamed) and\n"
    "               prints: sensors by type, rigs, trajectories (poses, devices, time\n"
    "               span), records per type (count, devices, time span), features\n"
    "               (type, dtype, dsize, file count), matches, reconstruction, and\n"
    "               the problems found (missing record files, records or trajectories\n"
    "               of unknown devices, rig sensors absent from sensors.txt, camera\n"
    "               records without a feature file).\n"
    "      --strict         exit 1 when problems are found\n"
    "      --check-images   also decode every camera record's image whole and list\n"
    "                       the damaged ones (truncated or corrupt JPEG, broken PNG)\n"
    "                       with the reason; exit 1 when there is one\n"
    "\n"
    "  copy SRC DST Reads everything under SRC and writes it to DST: text files\n"
    "               re-emitted in the kapture toolbox's format, feature and matches\n"
    "               files checked against their dtype/dsize and re-written byte for\n"
    "               byte, tar-packed feature and matches files (kapture 1.1's\n"
    "               <kind>.tar, matches.tar) checked and kept packed, byte for byte,\n"
    "               sensors/records_data copied, other files copied verbatim.\n"
    "               Refuses a DST that is SRC, inside SRC or contains it, and record\n"
    "               paths leaving SRC. Record files missing in SRC are listed.\n"
    "      --overwrite      allow a DST folder that exists and is not empty\n"
    "      --no-records-data  do not copy sensors/records_data (images, scans)\n"
    "      --unpack         write the files of tar-packed types loose instead\n"
    "\n"
    "  export W OUT One complete kapture 1.1 at OUT of finished nodes of workspace W,\n"
    "               as kapture-localization takes it: sensors, rigs, trajectories,\n"
    "               records, keypoints, descriptors, global features, matches,\n"
    "               points3d and observations in the toolbox's layout (tar-packed\n"
    "               types written loose). Sensors, rigs and trajectories are merged\n"
    "               by id; any other file held by two nodes must be the same, else\n"
    "               the export is refused naming the file and both nodes (as it is\n"
    "               when two nodes define one sensor differently). Record files are\n"
    "               symbolic links to the nodes' files. OUT is built beside itself\n"
    "               and renamed into place when complete; the result is inspected\n"
    "               as `info` does and its problems printed.\n"
    "               Default nodes, from the newest run: the map of the run's\n"
    "               mapper/* node (its map, features and matches inputs, the global\n"
    "               features computed on that map, and its reconstruction), e.g.\n"
    "               for configs/demo.yaml bench_map, bench_map_features,\n"
    "               bench_map_verified, bench_map_global, bench_triangulation;\n"
    "               without a mapper, the ground truth node `gt`.\n"
    "      --nodes A,B,...       export these nodes (W/nodes/A; VARIANT/A for\n"
    "                            W/variants/VARIANT/nodes/A of a matrix run)\n"
    "      --trajectories NODE   take trajectories.txt from NODE only (added to\n"
    "                            the nodes), e.g. a localizer's estimated poses\n"
    "      --copy                copy the record files instead of linking them\n"
    "      --force               replace an OUT that exists and is not empty\n"
    "\n"
    "Exit status: 0 done, 1 the work failed (or --strict and problems found),\n"
    "2 bad usage or bad input (the message names the file, line and field).\n";

bool LooksLikeKapture(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "sensors", ec) || fs::is_directory(dir / "reconstruction", ec);
}

int CheckKaptureDir(const std::string& sub, const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    return UsageError("kapture " + sub, "'" + dir.string() + "' is not a folder");
  if (!LooksLikeKapture(dir))
    return UsageError("kapture " + sub, "'" + dir.string() +
                                            "' is not a kapture (no sensors/ nor reconstruction/)");
  return 0;
}

// Checks the image of every camera record; prints the count and each damaged
// one (file and reason). Returns how many are damaged.
size_t CheckImages(const fs::path& dir) {
  const kapture::Kapture k(dir);
  int64_t checked = 0;
  const auto damaged = kapture::FindDamagedImages(k, &checked);
  std::cout << "images checked: " << checked << ", damaged: " << damaged.size() << "\n";
  for (const auto& d : damaged)
    std::cout << "  damaged image " << (dir / kapture::layout::kRecordsData / d.path).string() << ": "
              << d.reason << "\n";
  return damaged.size();
}

int Info(const Args& args) {
  std::vector<std::string> positional;
  bool strict = false, check_images = false;
  for (const std::string& a : args) {
    if (a == "--strict") {
      strict = true;
    } else if (a == "--check-images") {
      check_images = true;
    } else if (a.rfind("--", 0) == 0) {
      return UsageError("kapture", "unknown option '" + a + "' for info");
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 1) return UsageError("kapture", "info takes one folder");
  const fs::path dir = positional[0];
  if (int rc = CheckKaptureDir("info", dir)) return rc;
  const kapture::KaptureSummary summary = kapture::InspectKapture(dir);
  std::cout << kapture::FormatSummary(summary);
  const size_t damaged = check_images ? CheckImages(dir) : 0;
  return damaged > 0 || (strict && !summary.problems.empty()) ? 1 : 0;
}

int Copy(const Args& args) {
  std::vector<std::string> positional;
  kapture::CopyOptions options;
  for (const std::string& a : args) {
    if (a == "--overwrite") {
      options.overwrite = true;
    } else if (a == "--no-records-data") {
      options.copy_records_data = false;
    } else if (a == "--unpack") {
      options.unpack_archives = true;
    } else if (a.rfind("--", 0) == 0) {
      return UsageError("kapture", "unknown option '" + a + "' for copy");
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 2) return UsageError("kapture", "copy takes SRC and DST");
  const fs::path src = positional[0], dst = positional[1];
  if (int rc = CheckKaptureDir("copy", src)) return rc;
  const kapture::CopyReport report = kapture::CopyKapture(src, dst, options);
  std::cout << "copied " << src.string() << " -> " << dst.string() << ": " << report.text_files
            << " text files (" << report.records << " records), " << report.binary_files
            << " feature/matches files, " << report.data_files << " record data files, "
            << report.other_files << " other files\n";
  const size_t shown = std::min<size_t>(report.missing_data_files.size(), 10);
  for (size_t i = 0; i < shown; ++i)
    std::cout << "  missing in source: " << report.missing_data_files[i] << "\n";
  if (report.missing_data_files.size() > shown)
    std::cout << "  ... " << report.missing_data_files.size() - shown << " more listed\n";
  for (const std::string& n : report.notes) std::cout << "  note: " << n << "\n";
  return 0;
}


// W/nodes/NODE, or W/variants/VARIANT/nodes/NODE for "VARIANT/NODE".
fs::path NodeFolder(const fs::path& workspace, const std::string& name) {
  const size_t slash = name.find('/');
  if (slash == std::string::npos) return workspace / "nodes" / name;
  return workspace / "variants" / name.substr(0, slash) / "nodes" / name.substr(slash + 1);
}

std::vector<std::string> SplitList(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

// The map of the newest run's mapper/* node: its map, features and matches
// inputs, the global features computed on that map, and the mapper itself;
// without a mapper, the ground truth node `gt`. Throws InputError saying
// why none can be chosen.
std::vector<std::string> DefaultExportNodes(const fs::path& workspace) {
  const fs::path record = NewestRunRecord(workspace);
  if (record.empty())
    throw InputError((workspace / "logs").string(), 0, "",
                     "no run record (run-*.json): name the nodes with --nodes");
  const RunRecord run = ReadRunRecord(record);
  for (const auto& n : run.nodes)
    if (!n.variant.empty())
      throw InputError(record.string(), 0, "nodes",
                       "a matrix run: name the nodes with --nodes VARIANT/NODE,...");
  std::vector<const RunRecord::Node*> mappers;
  for (const auto& n : run.nodes)
    if (n.stage.rfind("mapper/", 0) == 0 && !n.folder.empty()) mappers.push_back(&n);
  if (mappers.size() > 1) {
    std::string names;
    for (const auto* m : mappers) names += (names.empty() ? "" : ", ") + m->name;
    throw InputError(record.string(), 0, "nodes",
                     "several mapper nodes (" + names + "): name the nodes with --nodes");
  }
  if (mappers.empty()) {
    for (const auto& n : run.nodes)
      if (n.name == "gt" && !n.folder.empty()) return {"gt"};
    throw InputError(record.string(), 0, "nodes",
                     "no mapper/* node nor a finished `gt` node: name the nodes with --nodes");
  }
  const RunRecord::Node& mapper = *mappers.front();
  std::vector<std::string> nodes;
  std::string map;
  for (const auto& in : mapper.inputs)
    if (in.port == "map") map = in.node;
  // The dataset first: it says what the others are of.
  if (!map.empty()) nodes.push_back(map);
  for (const auto& in : mapper.inputs)
    if (std::find(nodes.begin(), nodes.end(), in.node) == nodes.end()) nodes.push_back(in.node);
  for (const auto& n : run.nodes) {
    std::error_code ec;
    const bool global = fs::is_directory(NodeFolder(workspace, n.name) / "reconstruction/global_features", ec);
    for (const auto& in : n.inputs)
      if (global && !map.empty() && in.node == map &&
          std::find(nodes.begin(), nodes.end(), n.name) == nodes.end())
        nodes.push_back(n.name);
  }
  nodes.push_back(mapper.name);
  return nodes;
}

void PrintExportReport(const fs::path& out, const kapture::ExportReport& r) {
  std::cout << "exported " << out.string() << ": " << r.sensors << " sensors, " << r.rigs << " rigs, "
            << r.trajectory_poses << " poses";
  for (const auto& [type, n] : r.records) std::cout << ", " << n << " " << type << " records";
  std::cout << ", " << r.data_files << " record files";
  for (const auto& [type, n] : r.feature_files) std::cout << ", " << n << " " << type << " files";
  for (const auto& [type, n] : r.match_pairs) std::cout << ", " << n << " " << type << " match pairs";
  std::cout << ", " << r.points3d << " points3d, " << r.observation_entries << " observed points\n";
  for (const std::string& m : r.missing_data_files) std::cout << "  missing in its node: " << m << "\n";
  if (r.missing_data_count > static_cast<int64_t>(r.missing_data_files.size()))
    std::cout << "  ... " << r.missing_data_count - r.missing_data_files.size() << " more missing\n";
}

// The finished node folders of `names` as export sources.
std::vector<kapture::ExportSource> ExportSources(const fs::path& workspace,
                                                 const std::vector<std::string>& names) {
  std::vector<kapture::ExportSource> sources;
  for (const std::string& name : names) {
    const fs::path dir = NodeFolder(workspace, name);
    std::error_code ec;
    if (!fs::is_directory(dir, ec))
      throw InputError(dir.string(), 0, "", "no node '" + name + "' in this workspace");
    if (!Workspace::IsComplete(dir))
      throw InputError(dir.string(), 0, "", "node '" + name + "' has not finished (no " +
                                                std::string(kCompleteMarker) + "): run the graph first");
    sources.push_back({name, dir});
  }
  return sources;
}

int Export(const Args& args) {
  std::vector<std::string> positional, nodes;
  kapture::ExportOptions options;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      std::string value;
      if (TakeOption(args, &i, "--nodes", &value)) {
        nodes = SplitList(value);
      } else if (TakeOption(args, &i, "--trajectories", &value)) {
        options.trajectories_from = value;
      } else if (args[i] == "--copy") {
        options.link_records_data = false;
      } else if (args[i] == "--force") {
        options.overwrite = true;
      } else if (args[i].rfind("--", 0) == 0) {
        return UsageError("kapture", "unknown option '" + args[i] + "' for export");
      } else {
        positional.push_back(args[i]);
      }
    }
  } catch (const std::invalid_argument& e) {
    return UsageError("kapture", e.what());
  }
  if (positional.size() != 2) return UsageError("kapture", "export takes W and OUT");
  const fs::path workspace = positional[0], out = positional[1];
  std::error_code ec;
  if (!fs::is_directory(workspace / "nodes", ec) && !fs::is_directory(workspace / "variants", ec))
    return UsageError("kapture", "'" + workspace.string() + "' is not a workspace (no nodes/)");
  if (!options.overwrite && fs::is_directory(out, ec) && !fs::is_empty(out, ec))
    return UsageError("kapture", "'" + out.string() + "' exists and is not empty (--force replaces it)");
  if (nodes.empty()) {
    nodes = DefaultExportNodes(workspace);
    std::string list;
    for (const auto& n : nodes) list += (list.empty() ? "" : ",") + n;
    std::cout << "nodes (default): " << list << "\n";
  }
  if (!options.trajectories_from.empty() &&
      std::find(nodes.begin(), nodes.end(), options.trajectories_from) == nodes.end())
    nodes.push_back(options.trajectories_from);
  const kapture::ExportReport report =
      kapture::ExportKapture(ExportSources(workspace, nodes), out, options);
  PrintExportReport(out, report);
  const kapture::KaptureSummary summary = kapture::InspectKapture(out);
  for (const std::string& p : summary.problems) std::cout << "  problem: " << p << "\n";
  return 0;
}

}  // namespace

int KaptureCommand(const Args& args) {
  if (args.empty()) return UsageError("kapture", "missing subcommand (info, copy or export)");
  if (WantsHelp(args) || args[0] == "help") {
    std::cout << kKaptureHelp;
    return 0;
  }
  const std::string sub = args[0];
  const Args rest(args.begin() + 1, args.end());
  try {
    if (sub == "info") return Info(rest);
    if (sub == "copy") return Copy(rest);
    if (sub == "export") return Export(rest);
    return UsageError("kapture", "unknown subcommand '" + sub + "' (info, copy or export)");
  } catch (const InputError& e) {
    std::cerr << "locforge kapture " << sub << ": " << e.what() << "\n";
    return 2;
  } catch (const ParamError& e) {
    std::cerr << "locforge kapture " << sub << ": " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "locforge kapture " << sub << ": error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace locforge::host
