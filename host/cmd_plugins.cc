// `locforge plugins list | describe KIND/NAME`
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "cli.h"
#include "locforge/params.h"

namespace locforge::host {

namespace {

// A canonical value as a person writes it: lists with commas, components as
// `kind/name {name: value, ...}`.
std::string Shown(const std::string& canonical, LfParamType type) {
  if (type == LF_PARAM_COMPONENT) {
    ComponentSpec spec;
    if (!ParseComponent(canonical, &spec)) return canonical;
    std::string out = spec.stage;
    for (size_t i = 0; i < spec.params.size(); ++i)
      out += (i ? ", " : " {") + spec.params[i].first + ": " +
             Shown(spec.params[i].second, LF_PARAM_STRING_LIST);
    return spec.params.empty() ? out : out + "}";
  }
  std::string out = canonical;
  for (char& c : out)
    if (c == LF_LIST_SEPARATOR) c = ',';
  return out;
}

std::string VersionText(const runtime::StageEntry& s) {
  return s.version + (s.own_version ? " (stage)" : " (plugin)");
}

std::string PortFlags(uint32_t flags) {
  std::string out;
  if (flags & LF_PORT_OPTIONAL) out += "optional";
  if (flags & LF_PORT_MULTIPLE) out += std::string(out.empty() ? "" : ", ") + "multiple";
  return out.empty() ? "required" : out;
}

std::string DescribeParam(const ParamDecl& d) {
  std::ostringstream s;
  s << "    " << d.name << "  (" << ParamTypeName(d.type) << ")";
  if (d.required())
    s << "  required";
  else if (d.derived())
    s << "  default: derived by the stage (see below)";
  else
    s << "  default: " << (d.default_value.empty() ? "\"\"" : Shown(d.default_value, d.type));
  if (d.has_min || d.has_max) {
    s << "  range: [" << (d.has_min ? FormatDouble(d.min_value) : "-inf") << ", "
      << (d.has_max ? FormatDouble(d.max_value) : "+inf") << "]";
  }
  if (!d.choices.empty()) {
    s << "  choices: ";
    for (size_t i = 0; i < d.choices.size(); ++i) s << (i ? "|" : "") << d.choices[i];
  }
  if (d.type == LF_PARAM_COMPONENT)
    s << "  implements: " << (d.component_interface.empty() ? "any" : d.component_interface);
  if (d.flags & LF_PARAM_NO_CACHE_KEY) s << "  (not in cache key)";
  s << "\n        " << d.doc << "\n";
  return s.str();
}

void DescribePorts(const char* title, const std::vector<runtime::PortDecl>& ports, bool inputs,
                   std::ostream& out) {
  out << title << ":\n";
  if (ports.empty()) out << "    (none)\n";
  for (const auto& p : ports)
    out << "    " << p.name << ": " << p.artifact_type
        << (inputs ? "  (" + PortFlags(p.flags) + ")" : "") << (p.doc.empty() ? "" : "  " + p.doc)
        << "\n";
}

int Describe(const runtime::Registry& registry, const std::string& id) {
  const runtime::StageEntry* stage = registry.Find(id);
  if (!stage) {
    const std::string hint = DidYouMean(id, registry.StageIds());
    std::cerr << "locforge plugins describe: unknown stage '" << id << "'"
              << (hint.empty() ? "" : " (did you mean '" + hint + "'?)")
              << "; see 'locforge plugins list'\n";
    return 2;
  }
  const LfStageInfo& info = *stage->info;
  const LfPluginInfo& plugin = *stage->plugin->info;
  std::ostream& out = std::cout;
  out << stage->id << "\n    " << (info.doc ? info.doc : "") << "\n";
  out << "plugin: " << (plugin.name ? plugin.name : "?") << " "
      << (plugin.version ? plugin.version : "?") << " (" << stage->plugin->file.string() << ")\n";
  out << "version: " << stage->version
      << (stage->own_version ? " (the stage's own; keys its cached results)"
                             : " (the plugin's; keys its cached results)")
      << "\n";
  std::string mode = !stage->runnable()  ? "component only (not a graph node)"
                     : stage->per_item() ? "per-item (threaded, sharded, resumable)"
                                         : "whole (runs once per node)";
  if (info.flags & LF_STAGE_SERIAL_ITEMS) mode += ", items run serially";
  if (info.flags & LF_STAGE_NONDETERMINISTIC) mode += ", nondeterministic";
  out << "runs: " << mode << "\n";
  out << "params:\n";
  if (stage->params.empty()) out << "    (none)\n";
  for (const auto& d : stage->params) out << DescribeParam(d);
  DescribePorts("inputs", stage->inputs, true, out);
  DescribePorts("outputs", stage->outputs, false, out);
  out << "component interface: " << (info.component_interface ? info.component_interface : "none")
      << "\n";
  if (info.component_interface) {
    // Where it can be chosen: the component parameters of other stages.
    std::vector<std::string> users;
    for (const auto* s : registry.Stages())
      for (const auto& d : s->params)
        if (d.type == LF_PARAM_COMPONENT &&
            (d.component_interface.empty() || d.component_interface == info.component_interface))
          users.push_back(s->id + "." + d.name);
    if (!users.empty()) {
      out << "chosen by:";
      for (const auto& u : users) out << " " << u;
      out << "\n";
    }
  }
  return 0;
}

int List(const runtime::Registry& registry) {
  size_t width = 0, version_width = 0, plugin_width = 0;
  for (const auto* s : registry.Stages()) {
    width = std::max(width, s->id.size());
    version_width = std::max(version_width, VersionText(*s).size());
    const LfPluginInfo& plugin = *s->plugin->info;
    plugin_width = std::max(plugin_width, std::string(plugin.name ? plugin.name : "?").size() + 1 +
                                              std::string(plugin.version ? plugin.version : "?").size());
  }
  for (const auto* s : registry.Stages()) {
    const LfPluginInfo& plugin = *s->plugin->info;
    const std::string version = VersionText(*s);
    const std::string plugin_text = std::string(plugin.name ? plugin.name : "?") + " " +
                                    (plugin.version ? plugin.version : "?");
    std::cout << s->id << std::string(width - s->id.size() + 2, ' ') << version
              << std::string(version_width - version.size() + 2, ' ') << plugin_text
              << std::string(plugin_width - plugin_text.size() + 2, ' ') << s->plugin->file.string()
              << "\n";
  }
  if (registry.Stages().empty()) std::cout << "(no stages: no plugin found in the search path)\n";
  for (const auto& d : registry.duplicates()) std::cerr << "error: duplicate stage: " << d << "\n";
  return registry.duplicates().empty() ? 0 : 1;
}

}  // namespace

int PluginsCommand(const Args& args) {
  if (WantsHelp(args)) {
    std::cout << HelpText("plugins");
    return 0;
  }
  std::vector<std::string> positional;
  std::vector<fs::path> extra;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      std::string value;
      if (TakeOption(args, &i, "--plugin-path", &value))
        extra.emplace_back(value);
      else if (args[i].rfind("--", 0) == 0)
        return UsageError("plugins", "unknown option '" + args[i] + "'");
      else
        positional.push_back(args[i]);
    }
  } catch (const std::invalid_argument& e) {
    return UsageError("plugins", e.what());
  }
  if (positional.empty()) return UsageError("plugins", "expected 'list' or 'describe KIND/NAME'");
  const std::string& sub = positional.front();
  runtime::Registry registry;
  // Folders named with --plugin-path are reported like the default ones here.
  for (const auto& p : LoadPlugins(&registry, extra))
    std::cerr << "warning: plugin " << p.file.string() << " refused and skipped: " << p.message
              << "\n";
  if (sub == "list") {
    if (positional.size() != 1) return UsageError("plugins", "'list' takes no argument");
    return List(registry);
  }
  if (sub == "describe") {
    if (positional.size() != 2) return UsageError("plugins", "expected 'describe KIND/NAME'");
    return Describe(registry, positional[1]);
  }
  const std::string hint = DidYouMean(sub, {"list", "describe"});
  return UsageError("plugins", "unknown subcommand '" + sub + "'" +
                                   (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
}

}  // namespace locforge::host
