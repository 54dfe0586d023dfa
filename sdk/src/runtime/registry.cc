// Loading plugin libraries and checking what they declare before anything
// else touches it: a broken or foreign library is refused with a one-line
// reason and skipped, never allowed to crash or confuse the host.
#include "locforge/runtime/registry.h"

#include <dlfcn.h>
#include <elf.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include "locforge/error.h"

namespace locforge::runtime {

namespace {

// A refusal of one library; caught in LoadFile and turned into a PluginProblem.
struct Refused {
  std::string reason;
};

bool IsIdentifier(const char* s) {
  if (s == nullptr || *s == '\0') return false;
  for (const char* c = s; *c; ++c)
    if (!((*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') || *c == '_')) return false;
  return true;
}

std::string Quote(const char* s) { return s ? "'" + std::string(s) + "'" : "NULL"; }

// Elements of a plugin's array, stepping by the struct size the plugin was
// built with (fields are only ever appended, so a newer plugin's elements may
// be larger than ours).
template <typename T>
const T* Element(const T* first, uint32_t stride, uint32_t i) {
  const T* element = reinterpret_cast<const T*>(reinterpret_cast<const char*>(first) +
                                                static_cast<size_t>(stride) * i);
  if (element->struct_size != stride)
    throw Refused{"element #" + std::to_string(i) + " of an array has struct_size " +
                  std::to_string(element->struct_size) + ", the first has " +
                  std::to_string(stride) + "; all elements of an array must have the same size"};
  return element;
}

// The stride of a plugin array: its first element's struct_size, which must
// cover every field this host reads.
template <typename T>
uint32_t StrideOf(const T* first, uint32_t count, size_t needed, const std::string& what) {
  if (count == 0) return static_cast<uint32_t>(needed);
  if (first == nullptr) throw Refused{what + " array is NULL but its count is " +
                                      std::to_string(count)};
  if (first->struct_size < needed)
    throw Refused{what + " struct_size " + std::to_string(first->struct_size) +
                  " is smaller than this host's " + std::to_string(needed) +
                  "; rebuild the plugin against this locforge SDK"};
  return first->struct_size;
}

std::vector<std::string> SplitChoices(const char* choices) {
  std::vector<std::string> out;
  if (choices == nullptr) return out;
  std::string s = choices;
  size_t start = 0;
  while (true) {
    const size_t bar = s.find('|', start);
    out.push_back(s.substr(start, bar - start));
    if (bar == std::string::npos) break;
    start = bar + 1;
  }
  return out;
}

// Sizes of the structs as ABI 1 first defined them: fields appended since are
// read only when the plugin's struct_size covers them.
constexpr size_t kParamSpecBaseSize = offsetof(LfParamSpec, component_interface);
constexpr size_t kStageInfoBaseSize = offsetof(LfStageInfo, version);

// True when a struct of `stride` bytes holds the field at `offset` of `size` bytes.
bool Covers(uint32_t stride, size_t offset, size_t size) { return stride >= offset + size; }

ParamDecl ReadParam(const LfParamSpec& p, uint32_t stride, const std::string& where) {
  if (!IsIdentifier(p.name))
    throw Refused{where + ": parameter name " + Quote(p.name) +
                  " must be non-empty lower-case [a-z0-9_]"};
  const std::string at = where + ": parameter '" + p.name + "'";
  if (p.type > LF_PARAM_COMPONENT)
    throw Refused{at + ": unknown type " + std::to_string(p.type) +
                  " (a newer SDK's; update this host)"};
  ParamDecl d;
  d.name = p.name;
  d.type = static_cast<LfParamType>(p.type);
  d.flags = p.flags;
  d.doc = p.doc ? p.doc : "";
  d.has_min = p.has_min != 0;
  d.has_max = p.has_max != 0;
  d.min_value = p.min_value;
  d.max_value = p.max_value;
  if (d.has_min && d.has_max && d.min_value > d.max_value)
    throw Refused{at + ": minimum is greater than maximum"};
  if (d.type == LF_PARAM_ENUM) {
    d.choices = SplitChoices(p.choices);
    for (const auto& c : d.choices)
      if (c.empty()) throw Refused{at + ": enum without choices (or an empty choice)"};
  }
  if (d.type == LF_PARAM_COMPONENT &&
      Covers(stride, offsetof(LfParamSpec, component_interface), sizeof(p.component_interface)) &&
      p.component_interface != nullptr)
    d.component_interface = p.component_interface;
  if (d.derived() && (d.required() || (p.default_value != nullptr && *p.default_value != '\0')))
    throw Refused{at + ": LF_PARAM_DERIVED needs the default \"\" and no LF_PARAM_REQUIRED (the stage "
                       "derives the value when none is given)"};
  if (!d.required()) {
    if (p.default_value == nullptr)
      throw Refused{at + ": no default value and not marked LF_PARAM_REQUIRED"};
    d.default_value = p.default_value;
    const std::string why = ValidateParamValue(d, d.default_value);
    if (!why.empty()) throw Refused{at + ": invalid default value: " + why};
  }
  return d;
}

PortDecl ReadPort(const LfPortSpec& p, const std::string& where) {
  if (!IsIdentifier(p.name))
    throw Refused{where + ": port name " + Quote(p.name) +
                  " must be non-empty lower-case [a-z0-9_]"};
  if (p.artifact_type == nullptr || *p.artifact_type == '\0')
    throw Refused{where + ": port '" + p.name + "' has no artifact type"};
  return PortDecl{p.name, p.artifact_type, p.flags, p.doc ? p.doc : ""};
}

std::vector<PortDecl> ReadPorts(const LfPortSpec* ports, uint32_t n, const std::string& where,
                                const char* direction) {
  const uint32_t stride = StrideOf(ports, n, sizeof(LfPortSpec), where + ": " + direction + " port");
  std::vector<PortDecl> out;
  std::set<std::string> seen;
  for (uint32_t i = 0; i < n; ++i) {
    out.push_back(ReadPort(*Element(ports, stride, i), where));
    if (!seen.insert(out.back().name).second)
      throw Refused{where + ": " + direction + " port '" + out.back().name + "' declared twice"};
  }
  return out;
}

void CheckFunctions(const LfStageInfo& s, const std::string& where) {
  auto need = [&](bool present, const char* what) {
    if (!present) throw Refused{where + ": required function '" + std::string(what) + "' is NULL"};
  };
  need(s.check_params != nullptr, "check_params");
  need(s.create != nullptr, "create");
  need(s.destroy != nullptr, "destroy");
  if (s.flags & LF_STAGE_PER_ITEM) {
    need(s.list_items != nullptr, "list_items");
    need(s.process_item != nullptr, "process_item");
    need(s.finalize != nullptr, "finalize");
  } else if (s.flags & LF_STAGE_RUNNABLE) {
    need(s.run != nullptr, "run");
  }
  if (s.component_interface != nullptr) need(s.component != nullptr, "component");
  if (!(s.flags & LF_STAGE_RUNNABLE) && s.component_interface == nullptr)
    throw Refused{where + ": neither runnable (LF_STAGE_RUNNABLE) nor a component"};
}

std::unique_ptr<StageEntry> ReadStage(const LfStageInfo& s, uint32_t stage_stride,
                                      const LoadedPlugin* plugin, uint32_t index) {
  const std::string at = "stage #" + std::to_string(index);
  if (!IsIdentifier(s.kind))
    throw Refused{at + ": kind " + Quote(s.kind) + " must be non-empty lower-case [a-z0-9_]"};
  if (!IsIdentifier(s.name))
    throw Refused{at + ": name " + Quote(s.name) + " must be non-empty lower-case [a-z0-9_]"};
  auto entry = std::make_unique<StageEntry>();
  entry->id = std::string(s.kind) + "/" + s.name;
  entry->info = &s;
  entry->plugin = plugin;
  const std::string where = "stage '" + entry->id + "'";
  CheckFunctions(s, where);
  entry->version = plugin->info->version;
  if (Covers(stage_stride, offsetof(LfStageInfo, version), sizeof(s.version)) &&
      s.version != nullptr) {
    if (*s.version == '\0') throw Refused{where + ": version is empty (NULL: the plugin's)"};
    entry->version = s.version;
    entry->own_version = true;
  }

  const uint32_t stride = StrideOf(s.params, s.num_params, kParamSpecBaseSize, where + ": parameter");
  std::set<std::string> names;
  for (uint32_t i = 0; i < s.num_params; ++i) {
    entry->params.push_back(ReadParam(*Element(s.params, stride, i), stride, where));
    if (!names.insert(entry->params.back().name).second)
      throw Refused{where + ": parameter '" + entry->params.back().name + "' declared twice"};
  }
  entry->inputs = ReadPorts(s.inputs, s.num_inputs, where, "input");
  entry->outputs = ReadPorts(s.outputs, s.num_outputs, where, "output");
  return entry;
}

// Calls the entry point; a plugin that throws through it is refused, not fatal.
const LfPluginInfo* CallEntry(LfPluginEntryFn entry) {
  try {
    return entry(LF_ABI_VERSION);
  } catch (const std::exception& e) {
    throw Refused{"entry point " LF_ENTRY_SYMBOL " threw a C++ exception (" +
                  std::string(e.what()) + "); it must not throw"};
  } catch (...) {
    throw Refused{"entry point " LF_ENTRY_SYMBOL " threw an exception; it must not throw"};
  }
}

// Checks that `file` is a whole ELF shared object before dlopen maps it: a
// truncated library can pass dlopen and then crash (SIGBUS) when a page past
// the end of the file is touched. Returns "" when fine, else the reason.
std::string CheckElfFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return "cannot open file";
  in.seekg(0, std::ios::end);
  const uint64_t size = static_cast<uint64_t>(in.tellg());
  in.seekg(0);
  Elf64_Ehdr header{};
  if (!in.read(reinterpret_cast<char*>(&header), sizeof(header)))
    return "not an ELF shared library (file too short, " + std::to_string(size) + " bytes)";
  if (std::memcmp(header.e_ident, ELFMAG, SELFMAG) != 0) return "not an ELF shared library";
  if (header.e_ident[EI_CLASS] != ELFCLASS64) return "not a 64-bit ELF library";
  if (header.e_type != ET_DYN) return "ELF file is not a shared library";
  const auto truncated = [&](uint64_t end, const char* what) {
    return "truncated file: " + std::string(what) + " ends at byte " + std::to_string(end) +
           " but the file has " + std::to_string(size) + " bytes";
  };
  const uint64_t ph_end = header.e_phoff + uint64_t{header.e_phnum} * header.e_phentsize;
  if (ph_end > size) return truncated(ph_end, "program header table");
  const uint64_t sh_end = header.e_shoff + uint64_t{header.e_shnum} * header.e_shentsize;
  if (header.e_shoff != 0 && sh_end > size) return truncated(sh_end, "section header table");
  if (header.e_phentsize != sizeof(Elf64_Phdr)) return "";  // let dlopen judge
  in.seekg(static_cast<std::streamoff>(header.e_phoff));
  for (int i = 0; i < header.e_phnum; ++i) {
    Elf64_Phdr ph{};
    if (!in.read(reinterpret_cast<char*>(&ph), sizeof(ph))) return "cannot read program headers";
    if (ph.p_type == PT_LOAD && ph.p_offset + ph.p_filesz > size)
      return truncated(ph.p_offset + ph.p_filesz, "a loadable segment");
  }
  return "";
}

fs::path ExecutableDir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe.parent_path();
}

}  // namespace

Registry::Registry() = default;
Registry::~Registry() = default;

std::vector<fs::path> Registry::DefaultSearchPath() {
  std::vector<fs::path> candidates;
  const char* no_default = std::getenv("LOCFORGE_NO_DEFAULT_PLUGINS");
  if (!(no_default && std::string(no_default) == "1")) {
    // <exe>/../lib/locforge/plugins is the build tree's plugin folder; an
    // install may use a multiarch libdir (lib/x86_64-linux-gnu on Debian).
    const fs::path exe_dir = ExecutableDir();
    if (!exe_dir.empty()) {
      candidates.push_back(exe_dir / ".." / "lib" / "locforge" / "plugins");
      candidates.push_back(exe_dir / ".." / LOCFORGE_INSTALL_LIBDIR / "locforge" / "plugins");
    }
  }
  if (const char* env = std::getenv("LOCFORGE_PLUGIN_PATH"); env && *env) {
    std::string s = env;
    size_t start = 0;
    while (true) {
      const size_t colon = s.find(':', start);
      const std::string part = s.substr(start, colon - start);
      if (!part.empty()) candidates.emplace_back(part);
      if (colon == std::string::npos) break;
      start = colon + 1;
    }
  }
  std::vector<fs::path> out;
  std::set<fs::path> seen;
  for (const auto& c : candidates) {
    std::error_code ec;
    if (!fs::is_directory(c, ec)) continue;
    const fs::path canonical = fs::canonical(c, ec);
    if (ec) continue;
    if (seen.insert(canonical).second) out.push_back(canonical);
  }
  return out;
}

void Registry::LoadFolders(const std::vector<fs::path>& folders) {
  for (const auto& f : folders) LoadFolder(f);
}

void Registry::LoadFolder(const fs::path& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return;
  std::vector<fs::path> files;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() != ".so") continue;
    std::error_code type_ec;
    if (!it->is_regular_file(type_ec)) continue;  // follows symlinks
    files.push_back(p);
  }
  if (ec) {
    problems_.push_back({folder, folder.string() + ": cannot list plugin folder: " + ec.message()});
    return;
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) LoadFile(f);
}

namespace {

// Opens a plugin library and finds its entry point: null (and why) when it
// is no loadable locforge plugin. RTLD_NOW: an unresolved symbol is reported
// now, not as a crash mid-run. RTLD_LOCAL: plugins cannot see (or clash
// with) each other's symbols. Once opened, the library's static
// constructors have run: its handle is kept (never dlclose'd) so no code of
// it can be unmapped under our feet.
void* EntrySymbol(const fs::path& path, void** handle, std::string* why) {
  if (const std::string elf = CheckElfFile(path); !elf.empty()) {
    *why = "cannot load shared library: " + elf;
    return nullptr;
  }
  dlerror();
  *handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (*handle == nullptr) {
    const char* e = dlerror();
    *why = std::string("cannot load shared library: ") + (e ? e : "unknown dlopen error");
    return nullptr;
  }
  dlerror();
  void* symbol = dlsym(*handle, LF_ENTRY_SYMBOL);
  if (symbol == nullptr)
    *why = "no " LF_ENTRY_SYMBOL
           " symbol; not a locforge plugin (build it with locforge_add_plugin and "
           "LOCFORGE_PLUGIN)";
  return symbol;
}

// The plugin's info from its entry point, its ABI checked (Refused when it
// does not match: only the two fields checked first may be read before).
const LfPluginInfo* CheckedInfo(void* symbol) {
  LfPluginEntryFn entry = nullptr;
  static_assert(sizeof(entry) == sizeof(symbol), "function and data pointers differ");
  std::memcpy(&entry, &symbol, sizeof(entry));
  const LfPluginInfo* info = CallEntry(entry);
  if (info == nullptr)
    throw Refused{"entry point returned NULL (the plugin does not serve host ABI version " +
                  std::to_string(LF_ABI_VERSION) + "); rebuild it against this locforge SDK"};
  if (info->abi_version != LF_ABI_VERSION)
    throw Refused{"plugin ABI version " + std::to_string(info->abi_version) + ", host supports " +
                  std::to_string(LF_ABI_VERSION) + "; rebuild the plugin against this locforge SDK"};
  if (info->struct_size < sizeof(LfPluginInfo))
    throw Refused{"LfPluginInfo struct_size " + std::to_string(info->struct_size) +
                  " is smaller than this host's " + std::to_string(sizeof(LfPluginInfo)) +
                  " for ABI version " + std::to_string(LF_ABI_VERSION) +
                  "; rebuild the plugin against this locforge SDK"};
  if (!info->name || !*info->name) throw Refused{"plugin name is NULL or empty"};
  if (!info->version) throw Refused{"plugin version is NULL"};
  return info;
}

// The plugin's stages, each id once.
std::vector<std::unique_ptr<StageEntry>> ReadStages(const LfPluginInfo* info, LoadedPlugin* plugin) {
  std::vector<std::unique_ptr<StageEntry>> stages;
  const uint32_t stride = StrideOf(info->stages, info->num_stages, kStageInfoBaseSize, "LfStageInfo");
  std::set<std::string> ids;
  for (uint32_t i = 0; i < info->num_stages; ++i) {
    stages.push_back(ReadStage(*Element(info->stages, stride, i), stride, plugin, i));
    if (!ids.insert(stages.back()->id).second) throw Refused{"stage '" + stages.back()->id + "' declared twice"};
  }
  return stages;
}

}  // namespace

bool Registry::LoadFile(const fs::path& file) {
  std::error_code ec;
  const fs::path canonical = fs::weakly_canonical(file, ec);
  const fs::path path = ec ? file : canonical;
  const std::string name = path.filename().string();
  for (const auto& p : plugins_)
    if (p->file == path) return true;  // already loaded (folder listed twice)

  auto refuse = [&](const std::string& reason) {
    problems_.push_back({path, name + ": " + reason});
    return false;
  };
  void* handle = nullptr;
  std::string why;
  void* symbol = EntrySymbol(path, &handle, &why);
  if (symbol == nullptr) return refuse(why);

  auto plugin = std::make_unique<LoadedPlugin>();
  plugin->file = path;
  plugin->handle = handle;
  std::vector<std::unique_ptr<StageEntry>> stages;
  try {
    plugin->info = CheckedInfo(symbol);
    stages = ReadStages(plugin->info, plugin.get());
  } catch (const Refused& r) {
    return refuse(r.reason);
  } catch (const std::exception& e) {
    return refuse(std::string("unexpected error while reading its metadata: ") + e.what());
  }

  const LoadedPlugin* owner = plugin.get();
  plugins_.push_back(std::move(plugin));
  for (auto& s : stages) {
    auto it = stages_.find(s->id);
    if (it != stages_.end()) {
      duplicates_.push_back("stage '" + s->id + "' is provided by both " +
                            it->second->plugin->file.string() + " and " + owner->file.string() +
                            "; using the first");
      continue;
    }
    const std::string id = s->id;
    stages_.emplace(id, std::move(s));
  }
  return true;
}

const StageEntry* Registry::Find(const std::string& id) const {
  auto it = stages_.find(id);
  return it == stages_.end() ? nullptr : it->second.get();
}

std::vector<const StageEntry*> Registry::Stages() const {
  std::vector<const StageEntry*> out;
  for (const auto& [id, s] : stages_) out.push_back(s.get());
  return out;
}

std::vector<std::string> Registry::StageIds() const {
  std::vector<std::string> out;
  for (const auto& [id, s] : stages_) out.push_back(id);
  return out;
}

}  // namespace locforge::runtime
