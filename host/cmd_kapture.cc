// `locforge kapture info DIR` and `locforge kapture copy SRC DST`.
#include <algorithm>
#include <iostream>
#include <stdexcept>

#include "cli.h"
#include "locforge/error.h"
#include "locforge/kapture/kapture.h"

namespace locforge::host {

namespace {

const char kKaptureHelp[] =
    "Usage: locforge kapture info DIR [--strict] [--check-images]\n"
    "       locforge kapture copy SRC DST [--overwrite] [--no-records-data] [--unpack]\n"
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

}  // namespace

int KaptureCommand(const Args& args) {
  if (args.empty()) return UsageError("kapture", "missing subcommand (info or copy)");
  if (WantsHelp(args) || args[0] == "help") {
    std::cout << kKaptureHelp;
    return 0;
  }
  const std::string sub = args[0];
  const Args rest(args.begin() + 1, args.end());
  try {
    if (sub == "info") return Info(rest);
    if (sub == "copy") return Copy(rest);
    return UsageError("kapture", "unknown subcommand '" + sub + "' (info or copy)");
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
