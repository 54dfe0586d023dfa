#include "output_files.h"

#include <algorithm>
#include <cctype>

#include "locforge/abi.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/sha256.h"

namespace locforge::host {

namespace {

constexpr const char* kListHeader = "# locforge output files 1: kind, size, sha256, path\n";

// Paths may hold any byte but '/'-separated names: tabs and line breaks are
// escaped so that each file stays one line of four fields.
std::string EscapePath(const std::string& path) {
  std::string out;
  for (char c : path) {
    switch (c) {
      case '\\': out += "\\\\"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      default: out += c;
    }
  }
  return out;
}

bool UnescapePath(const std::string& text, std::string* path) {
  path->clear();
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '\\') {
      *path += text[i];
      continue;
    }
    if (++i == text.size()) return false;
    const char c = text[i];
    if (c == '\\') *path += '\\';
    else if (c == 't') *path += '\t';
    else if (c == 'n') *path += '\n';
    else if (c == 'r') *path += '\r';
    else return false;
  }
  return !path->empty();
}

bool IsSha256Hex(const std::string& s) {
  return s.size() == 64 && std::all_of(s.begin(), s.end(), [](unsigned char c) {
           return std::isdigit(c) || (c >= 'a' && c <= 'f');
         });
}

// "" when `f` is as listed, else what differs.
std::string CheckFile(const fs::path& dir, const OutputFile& f, bool hash, uint64_t* hashed) {
  const fs::path p = dir / fs::path(f.path);
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(p, ec);
  if (ec || !fs::exists(st)) return "missing";
  if (f.link) {
    if (!fs::is_symlink(st)) return "no longer a symbolic link";
    const fs::path target = fs::read_symlink(p, ec);
    if (ec || Sha256Hex(target.string()) != f.sha256) return "symbolic link changed target";
    return "";
  }
  if (!fs::is_regular_file(st)) return "no longer a regular file";
  const uint64_t size = fs::file_size(p, ec);
  if (ec) return "unreadable: " + ec.message();
  if (size != f.size)
    return "size " + std::to_string(size) + " bytes, recorded " + std::to_string(f.size);
  if (!hash) return "";
  try {
    *hashed += size;
    if (Sha256FileHex(p) != f.sha256) return "content changed (SHA-256 differs from the recorded one)";
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

std::vector<OutputFile> ListOutputFiles(const fs::path& dir) {
  std::vector<OutputFile> out;
  for (fs::recursive_directory_iterator it(dir), end; it != end; ++it) {
    if (it.depth() == 0 && IsProtocolFile(it->path().filename().string())) continue;
    OutputFile f;
    f.path = it->path().lexically_relative(dir).generic_string();
    if (it->is_symlink()) {
      f.link = true;
      f.sha256 = Sha256Hex(fs::read_symlink(it->path()).string());
    } else if (it->is_regular_file()) {
      f.size = it->file_size();
      f.sha256 = Sha256FileHex(it->path());
    } else {
      continue;  // folders are implied by their files
    }
    out.push_back(std::move(f));
  }
  std::sort(out.begin(), out.end(),
            [](const OutputFile& a, const OutputFile& b) { return a.path < b.path; });
  return out;
}

std::string FormatFileList(const std::vector<OutputFile>& files) {
  std::string text = kListHeader;
  for (const OutputFile& f : files)
    text += std::string(f.link ? "l" : "f") + "\t" + std::to_string(f.size) + "\t" + f.sha256 +
            "\t" + EscapePath(f.path) + "\n";
  return text;
}

std::vector<OutputFile> ParseFileList(const std::string& text, const std::string& origin) {
  std::vector<OutputFile> out;
  size_t start = 0;
  for (int64_t line = 1; start < text.size(); ++line) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string row = text.substr(start, end - start);
    start = end + 1;
    if (row.empty() || row[0] == '#') continue;
    std::vector<std::string> cells;
    for (size_t from = 0;;) {
      const size_t tab = row.find('\t', from);
      cells.push_back(row.substr(from, tab == std::string::npos ? std::string::npos : tab - from));
      if (tab == std::string::npos) break;
      from = tab + 1;
    }
    if (cells.size() != 4) throw InputError(origin, line, "", "expected 4 tab-separated fields");
    OutputFile f;
    if (cells[0] != "f" && cells[0] != "l") throw InputError(origin, line, "kind", "expected f or l");
    f.link = cells[0] == "l";
    const auto digit = [](unsigned char c) { return std::isdigit(c) != 0; };
    if (cells[1].empty() || !std::all_of(cells[1].begin(), cells[1].end(), digit))
      throw InputError(origin, line, "size", "expected a byte count");
    f.size = std::stoull(cells[1]);
    if (!IsSha256Hex(cells[2])) throw InputError(origin, line, "sha256", "expected 64 hex digits");
    f.sha256 = cells[2];
    if (!UnescapePath(cells[3], &f.path)) throw InputError(origin, line, "path", "bad path");
    out.push_back(std::move(f));
  }
  return out;
}

void RecordOutputFiles(const fs::path& dir, Manifest* manifest) {
  const std::vector<OutputFile> files = ListOutputFiles(dir);
  const std::string text = FormatFileList(files);
  WriteFileAtomic(dir / kFileList, text);
  manifest->files_sha256 = Sha256Hex(text);
  manifest->file_count = files.size();
}

FolderCheck CheckNodeFolder(const fs::path& dir, bool hash_contents) {
  FolderCheck check;
  std::vector<OutputFile> files;
  try {
    const Manifest m = ReadManifest(dir);
    if (m.files_sha256.empty()) {
      check.verifiable = false;
      return check;
    }
    const std::string text = ReadFile(dir / kFileList);
    if (Sha256Hex(text) != m.files_sha256) {
      check.damage.push_back(std::string(kFileList) +
                             ": changed since the run (its SHA-256 differs from the manifest's)");
      return check;
    }
    files = ParseFileList(text, (dir / kFileList).string());
  } catch (const std::exception& e) {
    check.damage.push_back(e.what());
    return check;
  }
  for (const OutputFile& f : files) {
    ++check.files;
    const std::string problem = CheckFile(dir, f, hash_contents, &check.bytes_hashed);
    if (!problem.empty()) check.damage.push_back(f.path + ": " + problem);
  }
  return check;
}

bool ServableFromCache(const Workspace& workspace, const std::string& label, const fs::path& dir,
                       Reporter& reporter) {
  if (!Workspace::IsComplete(dir)) return false;
  const FolderCheck check = CheckNodeFolder(dir, false);
  if (!check.verifiable) {
    reporter.FileOnly(label + ": " + dir.string() +
                      " lists no output files (an older run's manifest): served unverified");
    return true;
  }
  if (check.ok()) return true;
  FileLock lock(workspace.LockFile(dir, ".lock"), FileLock::kExclusive);
  // Another process may have found it too and computed it again meanwhile.
  if (Workspace::IsComplete(dir) && CheckNodeFolder(dir, false).ok()) return true;
  reporter.Log(label, LF_LOG_WARNING,
               "cached folder " + dir.string() + " is damaged (" + DamageText(check) +
                   "); computing the node again");
  DiscardNodeFolder(dir);
  return false;
}

std::string DamageText(const FolderCheck& check) {
  constexpr size_t kShown = 5;
  std::string text;
  for (size_t i = 0; i < check.damage.size() && i < kShown; ++i)
    text += (i ? "; " : "") + check.damage[i];
  if (check.damage.size() > kShown)
    text += "; and " + std::to_string(check.damage.size() - kShown) + " more";
  return text;
}

}  // namespace locforge::host
