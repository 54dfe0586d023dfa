#include "locforge/plugin.h"

#include <algorithm>
#include <cstring>

namespace locforge {
namespace internal {

void WriteError(LfError* err, const std::string& message) noexcept {
  const size_t n = std::min(message.size(), sizeof(err->message) - 1);
  std::memcpy(err->message, message.data(), n);
  err->message[n] = '\0';
}

PluginBuilder::PluginBuilder(const char* name, const char* version, const char* description) {
  info_.abi_version = LF_ABI_VERSION;
  info_.struct_size = sizeof(LfPluginInfo);
  info_.name = Keep(name);
  info_.version = Keep(version);
  info_.description = Keep(description);
  info_.sdk_version = Keep(LOCFORGE_VERSION_STRING);
}

const char* PluginBuilder::Keep(const std::string& s) {
  strings_.push_back(s);
  return strings_.back().c_str();
}

void PluginBuilder::AddStageInfo(LfStageInfo info, const StageMeta& meta,
                                 const std::vector<ParamDecl>& params, uint32_t flags,
                                 const char* iface) {
  info.kind = Keep(meta.kind);
  info.name = Keep(meta.name);
  info.doc = Keep(meta.doc);
  info.flags = flags | meta.flags;
  info.component_interface = iface ? Keep(iface) : nullptr;
  info.version = meta.version.empty() ? nullptr : Keep(meta.version);

  auto& specs = param_specs_.emplace_back();
  for (const auto& d : params) {
    LfParamSpec s{};
    s.struct_size = sizeof(LfParamSpec);
    s.name = Keep(d.name);
    s.type = d.type;
    s.flags = d.flags;
    s.default_value = d.required() ? nullptr : Keep(d.default_value);
    s.doc = Keep(d.doc);
    s.has_min = d.has_min;
    s.has_max = d.has_max;
    s.min_value = d.min_value;
    s.max_value = d.max_value;
    std::string choices;
    for (const auto& c : d.choices) choices += (choices.empty() ? "" : "|") + c;
    s.choices = d.choices.empty() ? nullptr : Keep(choices);
    s.component_interface = d.component_interface.empty() ? nullptr : Keep(d.component_interface);
    specs.push_back(s);
  }
  info.params = specs.data();
  info.num_params = static_cast<uint32_t>(specs.size());

  auto ports = [&](const std::vector<PortMeta>& in, const LfPortSpec** out, uint32_t* n) {
    auto& v = port_specs_.emplace_back();
    for (const auto& p : in) {
      LfPortSpec s{};
      s.struct_size = sizeof(LfPortSpec);
      s.name = Keep(p.name);
      s.artifact_type = Keep(p.artifact_type);
      s.flags = p.flags;
      s.doc = Keep(p.doc);
      v.push_back(s);
    }
    *out = v.data();
    *n = static_cast<uint32_t>(v.size());
  };
  ports(meta.inputs, &info.inputs, &info.num_inputs);
  ports(meta.outputs, &info.outputs, &info.num_outputs);
  stages_.push_back(info);
}

const LfPluginInfo* PluginBuilder::Finish() {
  info_.stages = stages_.data();
  info_.num_stages = static_cast<uint32_t>(stages_.size());
  return &info_;
}

}  // namespace internal
}  // namespace locforge
