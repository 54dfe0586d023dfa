#include "workspace.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <type_traits>
#include <ctime>
#include <vector>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/version.h"
#include "locforge/sha256.h"

namespace locforge::host {

namespace {

std::string FileStamp(const fs::path& p) {
  std::error_code ec;
  const auto size = fs::file_size(p, ec);
  const auto mtime = fs::last_write_time(p, ec);
  return std::to_string(ec ? 0 : size) + "@" + std::to_string(mtime.time_since_epoch().count());
}

}  // namespace

namespace {

// Bounds of a folder stamp: enough for a floor's 40k images and hours of
// LiDAR (one file per scan), small enough that stamping stays a stat walk.
constexpr size_t kMaxStampEntries = 2000000;
constexpr int kMaxStampDepth = 16;  // also ends symlink cycles

// Feeds "relative/path size@mtime" (or "relative/path/ dir") of every entry
// under `dir` into `hash`, children sorted by name at every level so the
// stamp never depends on readdir order (and the entry cap cuts the same
// entries each time). Follows symlinks, as the stages reading the folder do.
void StampTree(const fs::path& dir, const std::string& rel, int depth, Sha256* hash,
               size_t* count) {
  std::error_code ec;
  std::vector<fs::path> children;
  for (auto it = fs::directory_iterator(dir, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::directory_iterator(); it.increment(ec))
    children.push_back(it->path());
  std::sort(children.begin(), children.end());
  for (const fs::path& child : children) {
    if (*count >= kMaxStampEntries) return;
    ++*count;
    const std::string name = rel + child.filename().string();
    if (fs::is_directory(child, ec)) {
      hash->Update(name + "/ dir\n");
      if (depth < kMaxStampDepth) StampTree(child, name + "/", depth + 1, hash, count);
    } else {
      hash->Update(name + " " + FileStamp(child) + "\n");
    }
  }
}

}  // namespace

std::string PathStamp(const fs::path& path) {
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec).lexically_normal();
  std::string out = abs.string();
  if (fs::is_regular_file(abs, ec)) return out + " file " + FileStamp(abs);
  if (!fs::is_directory(abs, ec)) return out + " missing";
  // Every entry at any depth (bounded), by size and mtime: a change deep in a
  // dataset (e.g. validation/sensors/trajectories.txt) invalidates the nodes reading it.
  Sha256 hash;
  size_t count = 0;
  StampTree(abs, "", 1, &hash, &count);
  out += " dir " + std::to_string(count) + " entries";
  if (count >= kMaxStampEntries) out += " (stamp capped)";
  return out + " sha256:" + hash.HexDigest();
}

std::string CacheKeyText(const ResolvedNode& node,
                         const std::map<std::string, std::string>& input_keys) {
  const LfPluginInfo* plugin = node.stage->plugin->info;
  std::string text = "locforge-cache-key 1\n";
  text += "stage " + node.stage->id + "\n";
  // A stage's own version keys its results; without one, its plugin's does.
  if (node.stage->own_version)
    text += "stage_version " + node.stage->version + "\n";
  else
    text += "plugin_version " + std::string(plugin->version ? plugin->version : "") + "\n";
  text += "sdk_version " + std::string(plugin->sdk_version ? plugin->sdk_version : "") + "\n";
  for (const auto& decl : node.stage->params) {
    if (decl.flags & LF_PARAM_NO_CACHE_KEY) continue;
    auto it = node.params.find(decl.name);
    const std::string value = it == node.params.end() ? decl.default_value : it->second;
    text += "param " + decl.name + "=" + value + "\n";
    if (decl.type == LF_PARAM_PATH && !value.empty())
      text += "stamp " + decl.name + "=" + PathStamp(value) + "\n";
  }
  for (const auto& [param, component] : node.components)
    text += "component " + param + "=" + component + "\n";
  for (const auto& in : node.inputs) {
    auto key = input_keys.find(in.node);
    text += "input " + in.port + "=" + (key == input_keys.end() ? "?" : key->second) + "\n";
  }
  return text;
}

std::string CacheKey(const ResolvedNode& node,
                     const std::map<std::string, std::string>& input_keys) {
  return Sha256Hex(CacheKeyText(node, input_keys));
}

Workspace::Workspace(const fs::path& root) : root_(fs::absolute(root).lexically_normal()) {
  for (const char* sub : {"cache", "nodes", "logs"}) fs::create_directories(root_ / sub);
}

fs::path Workspace::NodeDir(const std::string& node, const std::string& key) const {
  return root_ / "cache" / (node + "-" + key.substr(0, 16));
}

bool Workspace::IsComplete(const fs::path& node_dir) {
  std::error_code ec;
  return fs::is_regular_file(node_dir / kCompleteMarker, ec);
}

fs::path Workspace::LinkPath(const std::string& variant, const std::string& node) const {
  if (variant.empty()) return root_ / "nodes" / node;
  return root_ / "variants" / variant / "nodes" / node;
}

void Workspace::Link(const std::string& variant, const std::string& node,
                     const fs::path& node_dir) const {
  const fs::path link = LinkPath(variant, node);
  fs::create_directories(link.parent_path());
  const fs::path target = node_dir.lexically_relative(link.parent_path());
  std::error_code ec;
  if (fs::is_symlink(link, ec) && fs::read_symlink(link, ec) == target) return;
  const fs::path temp = TempSibling(link);
  fs::create_directory_symlink(target, temp);
  fs::rename(temp, link);  // atomic replacement of the old link
}

fs::path Workspace::NewLogFile() const {
  const std::string stamp = UtcNow(true);
  fs::path file = root_ / "logs" / ("run-" + stamp + ".log");
  for (int i = 1; fs::exists(file); ++i)
    file = root_ / "logs" / ("run-" + stamp + "-" + std::to_string(i) + ".log");
  return file;
}

fs::path Workspace::PartialDir(const fs::path& node_dir, bool per_item) {
  fs::path p = node_dir;
  p += per_item ? std::string(".partial") : ".partial-" + std::to_string(::getpid());
  return p;
}

void Workspace::RemoveStalePartials(const fs::path& node_dir) {
  const std::string prefix = node_dir.filename().string() + ".partial-";
  std::error_code ec;
  for (fs::directory_iterator it(node_dir.parent_path(), ec), end; !ec && it != end; it.increment(ec))
    if (it->path().filename().string().rfind(prefix, 0) == 0) fs::remove_all(it->path(), ec);
}

fs::path Workspace::LockFile(const fs::path& node_dir, const std::string& suffix) const {
  const fs::path locks = root_ / "locks";
  fs::create_directories(locks);
  return locks / (node_dir.filename().string() + suffix);
}

std::string FormatManifest(const Manifest& m) {
  std::string j = "{\n";
  j += "  \"stage\": " + JsonString(m.stage) + ",\n";
  j += "  \"plugin\": " + JsonString(m.plugin) + ",\n";
  j += "  \"plugin_version\": " + JsonString(m.plugin_version) + ",\n";
  j += "  \"stage_version\": " + JsonString(m.stage_version) + ",\n";
  j += "  \"plugin_file\": " + JsonString(m.plugin_file) + ",\n";
  j += "  \"key\": " + JsonString(m.key) + ",\n";
  j += "  \"params\": {";
  bool first = true;
  for (const auto& [name, value] : m.params) {
    j += std::string(first ? "\n" : ",\n") + "    " + JsonString(name) + ": " + JsonString(value);
    first = false;
  }
  j += "\n  },\n  \"inputs\": [";
  first = true;
  for (const auto& in : m.inputs) {
    j += std::string(first ? "\n" : ",\n") + "    {\"port\": " + JsonString(in.port) +
         ", \"type\": " + JsonString(in.type) + ", \"path\": " + JsonString(in.path) + "}";
    first = false;
  }
  char secs[32], cpu[32];
  std::snprintf(secs, sizeof(secs), "%.3f", m.seconds);
  std::snprintf(cpu, sizeof(cpu), "%.3f", m.cpu_seconds);
  j += "\n  ],\n  \"started\": " + JsonString(m.started) + ",\n  \"finished\": " +
       JsonString(m.finished) + ",\n  \"items\": " + std::to_string(m.items) +
       ",\n  \"seconds\": " + secs + ",\n  \"cpu_seconds\": " + cpu +
       ",\n  \"peak_rss_bytes\": " + std::to_string(m.peak_rss_bytes) +
       ",\n  \"output_bytes\": " + std::to_string(m.output_bytes) +
       ",\n  \"shards\": " + std::to_string(m.shards) +
       ",\n  \"file_count\": " + std::to_string(m.file_count) +
       ",\n  \"files_sha256\": " + JsonString(m.files_sha256) + "\n}\n";
  return j;
}

Manifest ReadManifest(const fs::path& node_dir) {
  const fs::path file = node_dir / kCompleteMarker;
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());  // JSON is YAML
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.line + 1, "manifest", "not JSON: " + e.msg);
  }
  if (!root.IsMap()) throw InputError(file.string(), 1, "manifest", "expected a JSON object");
  Manifest m;
  auto text = [&](const char* field) -> std::string {
    const YAML::Node n = root[field];
    if (!n) return "";
    if (!n.IsScalar())
      throw InputError(file.string(), n.Mark().line + 1, field, "expected a string");
    return n.Scalar();
  };
  m.stage = text("stage");
  m.plugin = text("plugin");
  m.plugin_version = text("plugin_version");
  m.stage_version = text("stage_version");
  m.plugin_file = text("plugin_file");
  m.key = text("key");
  m.finished = text("finished");
  m.started = text("started");
  m.files_sha256 = text("files_sha256");
  auto number = [&](const char* field, auto* out) {
    const YAML::Node n = root[field];
    if (!n) return;
    try {
      *out = n.as<std::remove_reference_t<decltype(*out)>>();
    } catch (const YAML::Exception& e) {
      throw InputError(file.string(), n.Mark().line + 1, field, "expected a number: " + e.msg);
    }
  };
  number("items", &m.items);
  number("seconds", &m.seconds);
  number("cpu_seconds", &m.cpu_seconds);
  number("peak_rss_bytes", &m.peak_rss_bytes);
  number("output_bytes", &m.output_bytes);
  number("shards", &m.shards);
  number("file_count", &m.file_count);
  if (const YAML::Node params = root["params"]; params && params.IsMap())
    for (auto it = params.begin(); it != params.end(); ++it)
      m.params[it->first.Scalar()] = it->second.IsScalar() ? it->second.Scalar() : "";
  if (const YAML::Node inputs = root["inputs"]; inputs && inputs.IsSequence())
    for (const auto& in : inputs)
      m.inputs.push_back({in["port"] ? in["port"].Scalar() : "", in["type"] ? in["type"].Scalar() : "",
                          in["path"] ? in["path"].Scalar() : ""});
  return m;
}

bool IsProtocolFile(const std::string& name) {
  return name == kCompleteMarker || name == kFileList || name.rfind(kJournalPrefix, 0) == 0 ||
         name.rfind(kShardRecordPrefix, 0) == 0;
}

uint64_t OutputBytes(const fs::path& dir) {
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it.depth() == 0 && IsProtocolFile(it->path().filename().string())) continue;
    std::error_code fec;
    if (it->is_regular_file(fec) && !it->is_symlink(fec)) total += it->file_size(fec);
  }
  return total;
}

fs::path ShardRecordPath(const fs::path& dir, int index, int count) {
  return dir / (std::string(kShardRecordPrefix) + std::to_string(index) + "-of-" +
                std::to_string(count));
}

void WriteShardRecord(const fs::path& dir, const ShardRecord& r) {
  char secs[32], cpu[32];
  std::snprintf(secs, sizeof(secs), "%.3f", r.seconds);
  std::snprintf(cpu, sizeof(cpu), "%.3f", r.cpu_seconds);
  WriteFileAtomic(ShardRecordPath(dir, r.index, r.count),
                  "{\"index\": " + std::to_string(r.index) + ", \"count\": " +
                      std::to_string(r.count) + ", \"items\": " + std::to_string(r.items) +
                      ", \"seconds\": " + secs + ", \"cpu_seconds\": " + cpu +
                      ", \"peak_rss_bytes\": " + std::to_string(r.peak_rss_bytes) +
                      ", \"host\": " + JsonString(r.host) + ", \"started\": " +
                      JsonString(r.started) + ", \"finished\": " + JsonString(r.finished) +
                      "}\n");
}

std::vector<ShardRecord> ReadShardRecords(const fs::path& dir, int count) {
  std::vector<ShardRecord> out;
  for (int i = 0; i < count; ++i) {
    const fs::path file = ShardRecordPath(dir, i, count);
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) continue;
    try {
      const YAML::Node n = YAML::LoadFile(file.string());
      ShardRecord r;
      r.index = i;
      r.count = count;
      r.items = n["items"].as<uint64_t>();
      r.seconds = n["seconds"].as<double>();
      r.cpu_seconds = n["cpu_seconds"].as<double>();
      r.peak_rss_bytes = n["peak_rss_bytes"].as<uint64_t>();
      r.host = n["host"].as<std::string>();
      r.started = n["started"].as<std::string>();
      r.finished = n["finished"].as<std::string>();
      out.push_back(r);
    } catch (const std::exception&) {
      // A torn or foreign file: the shard counts as not done.
    }
  }
  return out;
}

void DiscardNodeFolder(const fs::path& node_dir) {
  fs::path aside = node_dir;
  aside += ".damaged-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(aside, ec);
  fs::rename(node_dir, aside, ec);  // another process may have moved it first
  fs::remove_all(aside, ec);
}

void Publish(const fs::path& partial_dir, const fs::path& node_dir, const std::string& manifest) {
  WriteFileAtomic(partial_dir / kCompleteMarker, manifest);
  std::error_code ec;
  fs::path old;
  if (fs::exists(node_dir, ec)) {
    old = node_dir;
    old += ".old-" + std::to_string(::getpid());
    fs::remove_all(old, ec);
    fs::rename(node_dir, old);
  }
  fs::rename(partial_dir, node_dir);
  if (!old.empty()) fs::remove_all(old, ec);
}

FileLock::FileLock(const fs::path& file, Mode mode) {
  fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw Error("cannot open lock file " + file.string() + ": " + std::strerror(errno));
  int rc;
  do {
    rc = ::flock(fd_, mode == kShared ? LOCK_SH : LOCK_EX);
  } while (rc != 0 && errno == EINTR);
  if (rc != 0) {
    ::close(fd_);
    throw Error("cannot lock " + file.string() + ": " + std::strerror(errno));
  }
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the lock
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  return out + "\"";
}

std::string UtcNow(bool compact) {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), compact ? "%Y%m%dT%H%M%SZ" : "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace locforge::host
