// Validation of a parsed graph variant against the registered stages, and its
// topological order.
#include <algorithm>
#include <functional>
#include <set>

#include "graph.h"
#include "locforge/error.h"
#include "locforge/params.h"

namespace locforge::host {

StageLookup LookupOf(const runtime::Registry& registry) {
  StageLookup out;
  for (const auto* stage : registry.Stages()) out[stage->id] = stage;
  return out;
}

namespace {

std::vector<std::string> PortNames(const std::vector<runtime::PortDecl>& ports) {
  std::vector<std::string> out;
  for (const auto& p : ports) out.push_back(p.name);
  return out;
}

// Turns one element into its canonical form for `type` (validated already).
std::string CanonicalItem(LfParamType type, const std::string& s) {
  // Empty stays empty: valid only where the declaration allows "" (an optional
  // path, a string, a value the stage derives), refused by validation elsewhere.
  if (s.empty()) return s;
  switch (type) {
    case LF_PARAM_BOOL: {
      bool b = false;
      ParseBool(s, &b);
      return FormatBool(b);
    }
    case LF_PARAM_INT:
    case LF_PARAM_INT_LIST: {
      int64_t i = 0;
      ParseInt(s, &i);
      return FormatInt(i);
    }
    case LF_PARAM_DOUBLE:
    case LF_PARAM_DOUBLE_LIST: {
      double d = 0;
      ParseDouble(s, &d);
      return FormatDouble(d);
    }
    default:
      return s;
  }
}

bool IsListType(LfParamType t) {
  return t == LF_PARAM_INT_LIST || t == LF_PARAM_DOUBLE_LIST || t == LF_PARAM_STRING_LIST;
}

// Checks one given value against its declaration (a component's against the
// chosen stage, by `check_component`); returns its canonical string, or
// false with a diagnostic.
using ComponentCheck = std::function<bool(const std::string& what, const ParamDecl& decl,
                                          const ParamValue& given, std::string* canonical)>;
bool CanonicalParam(const std::string& node, const ParamDecl& decl, const ParamValue& given,
                    const ComponentCheck& check_component, std::string* canonical,
                    Diagnostics* errors) {
  const std::string what =
      "node '" + node + "': parameter '" + decl.name + "' (" + ParamTypeName(decl.type) + ")";
  if (decl.type == LF_PARAM_COMPONENT) return check_component(what, decl, given, canonical);
  if (given.value.is_component) {
    errors->push_back({given.value_where, what + ": expected a " +
                                              (IsListType(decl.type) ? "list" : "single value") +
                                              ", got a component mapping"});
    return false;
  }
  if (given.value.is_list && !IsListType(decl.type)) {
    errors->push_back({given.value_where, what + ": expected a single value, got a list"});
    return false;
  }
  std::vector<std::string> items = given.value.items;
  if (items.empty() && !IsListType(decl.type)) items.push_back("");
  if (decl.type == LF_PARAM_PATH) {
    fs::path p = items.empty() ? fs::path() : fs::path(items.front());
    if (!p.empty() && p.is_relative()) p = given.base_dir / p;
    items = {p.empty() ? "" : p.lexically_normal().string()};
  }
  const std::string why =
      ValidateParamValue(decl, IsListType(decl.type) ? JoinList(items) : items.front());
  std::vector<std::string> canon;
  for (const auto& item : items) canon.push_back(CanonicalItem(decl.type, item));
  const std::string value = IsListType(decl.type) ? JoinList(canon) : canon.front();
  if (!why.empty()) {
    std::string shown = why;
    std::replace(shown.begin(), shown.end(), LF_LIST_SEPARATOR, ',');
    errors->push_back({given.value_where, what + ": " + shown});
    return false;
  }
  if (decl.type == LF_PARAM_PATH && !value.empty()) {
    std::error_code ec;
    if (!fs::exists(value, ec)) {
      errors->push_back({given.value_where, what + ": '" + value +
                                                "' does not exist (expected an existing file "
                                                "or folder)"});
      return false;
    }
  }
  *canonical = value;
  return true;
}

class VariantChecker {
 public:
  VariantChecker(const GraphVariant& variant, const StageLookup& stages, Diagnostics* errors)
      : variant_(variant), stages_(stages), errors_(errors) {
    for (const auto& n : variant.nodes) node_names_.push_back(n.name);
  }

  bool Check(ResolvedGraph* out);

 private:
  void Fail(const SourceLocation& where, const std::string& message) {
    errors_->push_back({where, message});
  }
  const runtime::StageEntry* CheckStage(const NodeSpec& node);
  void CheckParams(const NodeSpec& node, const runtime::StageEntry& stage, ResolvedNode* out);
  bool CheckComponent(const std::string& node, const std::string& what, const ParamDecl& decl,
                      const ParamValue& given, std::string* canonical);
  const runtime::StageEntry* FindComponent(const std::string& id, const ParamDecl& decl,
                                           const SourceLocation& where, const std::string& what);
  void CheckInputs(const NodeSpec& node, const runtime::StageEntry& stage, ResolvedNode* out);
  ComponentCheck Components(const std::string& node);
  const NodeSpec* FindNode(const std::string& name) const {
    for (const auto& n : variant_.nodes)
      if (n.name == name) return &n;
    return nullptr;
  }
  bool Order(std::vector<ResolvedNode> nodes, ResolvedGraph* out);

  const GraphVariant& variant_;
  const StageLookup& stages_;
  Diagnostics* errors_;
  std::vector<std::string> node_names_;
  std::map<std::string, const runtime::StageEntry*> node_stages_;
  std::map<std::string, std::set<std::string>> edges_;  // node -> the nodes it reads
};

const runtime::StageEntry* VariantChecker::CheckStage(const NodeSpec& node) {
  if (node.stage.empty()) return nullptr;
  auto it = stages_.find(node.stage);
  if (it == stages_.end()) {
    std::vector<std::string> ids;
    for (const auto& [id, stage] : stages_) ids.push_back(id);
    Fail(node.stage_where, "node '" + node.name + "': unknown stage '" + node.stage + "'" +
                               Hint(node.stage, ids) +
                               "; expected a KIND/NAME listed by `locforge plugins list`");
    return nullptr;
  }
  const runtime::StageEntry* stage = it->second;
  if (!stage->runnable()) {
    Fail(node.stage_where, "node '" + node.name + "': stage '" + node.stage +
                               "' is a component used inside other stages, not runnable as a "
                               "graph node");
    return nullptr;
  }
  return stage;
}

void VariantChecker::CheckParams(const NodeSpec& node, const runtime::StageEntry& stage,
                                 ResolvedNode* out) {
  const size_t before = errors_->size();
  std::vector<std::string> names;
  for (const auto& d : stage.params) names.push_back(d.name);
  std::vector<std::pair<std::string, std::string>> given;
  bool broken = false;
  for (const auto& [name, value] : node.params) {
    if (value.broken) {
      broken = true;
      continue;
    }
    auto decl = std::find_if(stage.params.begin(), stage.params.end(),
                             [&](const ParamDecl& d) { return d.name == name; });
    if (decl == stage.params.end()) {
      Fail(value.key_where, "node '" + node.name + "': stage '" + stage.id +
                                "' has no parameter '" + name + "'" + Hint(name, names) +
                                "; expected one of: " + JoinNames(names));
      continue;
    }
    std::string canonical;
    if (CanonicalParam(node.name, *decl, value, Components(node.name), &canonical, errors_))
      given.emplace_back(name, canonical);
  }
  for (const auto& d : stage.params)
    if (d.required() && !node.params.count(d.name))
      Fail(node.where, "node '" + node.name + "': required parameter '" + d.name + "' (" +
                           ParamTypeName(d.type) + ", " + d.doc + ") is missing");
  if (broken || errors_->size() != before) return;
  try {
    out->params = runtime::CheckStageParams(stage, given);
  } catch (const std::exception& e) {
    Fail(node.stage_where,
         "node '" + node.name + "': parameters refused by stage '" + stage.id + "': " + e.what());
    return;
  }
  // Every component parameter, given or default: its stage, version and every parameter
  // value, given or the component's default, key the results (a default changed without a
  // version bump must not reuse results computed with the old one).
  for (const auto& d : stage.params) {
    if (d.type != LF_PARAM_COMPONENT) continue;
    ComponentSpec spec;
    if (!ParseComponent(out->params[d.name], &spec)) continue;  // refused above
    auto given_value = node.params.find(d.name);
    const SourceLocation where =
        given_value != node.params.end() ? given_value->second.value_where : node.stage_where;
    const std::string what = "node '" + node.name + "': parameter '" + d.name + "' (component" +
                             (given_value == node.params.end() ? ", default" : "") + ")";
    if (const runtime::StageEntry* c = FindComponent(spec.stage, d, where, what)) {
      std::string text = c->id + " " + c->version;
      for (const auto& cd : c->params) {
        if (cd.flags & LF_PARAM_NO_CACHE_KEY) continue;
        const std::string* given_param = spec.Find(cd.name);
        text += " " + cd.name + "=" + (given_param ? *given_param : cd.default_value);
      }
      out->components[d.name] = text;
    }
  }
}

ComponentCheck VariantChecker::Components(const std::string& node) {
  return [this, node](const std::string& what, const ParamDecl& decl, const ParamValue& given,
                      std::string* canonical) {
    return CheckComponent(node, what, decl, given, canonical);
  };
}

const runtime::StageEntry* VariantChecker::FindComponent(const std::string& id,
                                                         const ParamDecl& decl,
                                                         const SourceLocation& where,
                                                         const std::string& what) {
  std::vector<std::string> candidates;  // stages implementing the interface
  for (const auto& [sid, s] : stages_)
    if (s->is_component() && (decl.component_interface.empty() ||
                              decl.component_interface == s->info->component_interface))
      candidates.push_back(sid);
  const std::string expected =
      "; expected a component" +
      (decl.component_interface.empty() ? "" : " implementing " + decl.component_interface) +
      ": " + JoinNames(candidates);
  auto it = stages_.find(id);
  if (it == stages_.end()) {
    Fail(where, what + ": unknown stage '" + id + "'" + Hint(id, candidates) + expected);
    return nullptr;
  }
  const runtime::StageEntry* c = it->second;
  if (!c->is_component()) {
    Fail(where, what + ": stage '" + id + "' is not a component" + expected);
    return nullptr;
  }
  if (!decl.component_interface.empty() && decl.component_interface != c->info->component_interface) {
    Fail(where, what + ": stage '" + id + "' implements " + c->info->component_interface +
                    ", not " + decl.component_interface + expected);
    return nullptr;
  }
  return c;
}

bool VariantChecker::CheckComponent(const std::string& node, const std::string& what,
                                    const ParamDecl& decl, const ParamValue& given,
                                    std::string* canonical) {
  if (given.value.is_list) {
    Fail(given.value_where, what + ": expected KIND/NAME or {stage: KIND/NAME, params: {...}}, "
                                   "got a list");
    return false;
  }
  const std::string id = given.value.scalar();
  const runtime::StageEntry* c = FindComponent(id, decl, given.value_where, what);
  if (!c) return false;
  // The component's parameters against its own declarations, then its own checks.
  const size_t before = errors_->size();
  std::vector<std::string> names;
  for (const auto& d : c->params) names.push_back(d.name);
  std::vector<std::pair<std::string, std::string>> params;
  for (const ComponentParam& p : given.value.params) {
    auto d = std::find_if(c->params.begin(), c->params.end(),
                          [&](const ParamDecl& x) { return x.name == p.name; });
    if (d == c->params.end()) {
      Fail(p.key_where, what + ": component '" + id + "' has no parameter '" + p.name + "'" +
                            Hint(p.name, names) + "; expected one of: " + JoinNames(names));
      continue;
    }
    ParamValue inner;
    inner.value = p.value;
    inner.key_where = p.key_where;
    inner.value_where = p.value_where;
    inner.base_dir = given.base_dir;
    std::string value;
    if (CanonicalParam(node + "' component '" + id, *d, inner, Components(node), &value, errors_))
      params.emplace_back(p.name, value);
  }
  if (errors_->size() != before) return false;
  try {
    (void)runtime::CheckStageParams(*c, params);
  } catch (const std::exception& e) {
    Fail(given.value_where, what + ": parameters refused by component '" + id + "': " + e.what());
    return false;
  }
  ComponentSpec spec(id);
  spec.params = params;
  *canonical = FormatComponent(spec);
  return true;
}

void VariantChecker::CheckInputs(const NodeSpec& node, const runtime::StageEntry& stage,
                                 ResolvedNode* out) {
  const auto& inputs = stage.inputs;
  for (const auto& [port_name, spec] : node.inputs) {
    for (const Wire& wire : spec.wires)
      if (FindNode(wire.node)) edges_[node.name].insert(wire.node);  // cycles, whatever the types
    if (spec.broken) continue;
    auto port = std::find_if(inputs.begin(), inputs.end(),
                             [&](const runtime::PortDecl& p) { return port_name == p.name; });
    if (port == inputs.end()) {
      Fail(spec.where, "node '" + node.name + "': stage '" + stage.id + "' has no input '" +
                           port_name + "'" + Hint(port_name, PortNames(inputs)) +
                           "; expected one of: " + JoinNames(PortNames(inputs)));
      continue;
    }
    if (spec.wires.size() != 1 && !(port->flags & LF_PORT_MULTIPLE)) {
      Fail(spec.where, "node '" + node.name + "': input '" + port_name +
                           "' takes exactly one wire (expected node.port, not a list)");
      continue;
    }
    for (const Wire& wire : spec.wires) {
      const NodeSpec* from = FindNode(wire.node);
      if (!from) {
        Fail(wire.where, "node '" + node.name + "': input '" + port_name +
                             "' reads unknown node '" + wire.node + "'" +
                             Hint(wire.node, node_names_) +
                             "; expected NODE.PORT with NODE one of: " + JoinNames(node_names_));
        continue;
      }
      auto st = node_stages_.find(wire.node);
      if (st == node_stages_.end() || !st->second) continue;  // its stage error is reported
      const auto& outputs = st->second->outputs;
      std::string out_port = wire.port;
      if (out_port.empty() && outputs.size() == 1) out_port = outputs.front().name;
      auto o = std::find_if(outputs.begin(), outputs.end(),
                            [&](const runtime::PortDecl& p) { return out_port == p.name; });
      if (o == outputs.end()) {
        Fail(wire.where, "node '" + node.name + "': node '" + wire.node + "' (" + st->second->id +
                             ") has no output '" + wire.port + "'" +
                             Hint(wire.port, PortNames(outputs)) +
                             "; expected one of: " + JoinNames(PortNames(outputs)));
        continue;
      }
      if (o->artifact_type != port->artifact_type) {
        Fail(wire.where, "node '" + node.name + "': input '" + port_name +
                             "' expects artifact type '" + port->artifact_type + "' but " +
                             wire.node + "." + out_port + " gives '" + o->artifact_type + "'");
        continue;
      }
      out->inputs.push_back({port_name, port->artifact_type, wire.node, out_port});
    }
  }
  for (const auto& port : inputs)
    if (!(port.flags & LF_PORT_OPTIONAL) && !node.inputs.count(port.name))
      Fail(node.where, "node '" + node.name + "': required input '" + port.name + "' (" +
                           port.artifact_type + ") is not wired; expected inputs: {" + port.name +
                           ": NODE.PORT}");
}

bool VariantChecker::Order(std::vector<ResolvedNode> nodes, ResolvedGraph* out) {
  std::map<std::string, std::set<std::string>>& upstream = edges_;
  std::set<std::string> read;
  for (const auto& [node, from] : edges_) read.insert(from.begin(), from.end());
  std::set<std::string> done;  // ordered, or without a stage (reported elsewhere)
  for (const auto& name : node_names_)
    if (std::none_of(nodes.begin(), nodes.end(),
                     [&](const ResolvedNode& n) { return n.name == name; }))
      done.insert(name);
  while (!nodes.empty()) {
    auto ready = std::find_if(nodes.begin(), nodes.end(), [&](const ResolvedNode& n) {
      for (const auto& u : upstream[n.name])
        if (!done.count(u)) return false;
      return true;
    });
    if (ready == nodes.end()) break;
    done.insert(ready->name);
    if (!read.count(ready->name)) out->sinks.push_back(ready->name);
    out->nodes.push_back(std::move(*ready));
    nodes.erase(ready);
  }
  if (nodes.empty()) return true;
  // A cycle remains: walk upstream from a blocked node until a node repeats.
  std::vector<std::string> path = {nodes.front().name};
  while (true) {
    std::string next;
    for (const auto& u : upstream[path.back()])
      if (!done.count(u)) {
        next = u;
        break;
      }
    if (next.empty()) return false;  // not reachable: a blocked node has a pending input
    auto seen = std::find(path.begin(), path.end(), next);
    if (seen != path.end()) {
      std::vector<std::string> cycle(seen, path.end());
      std::reverse(cycle.begin(), cycle.end());  // data-flow order
      // Start at the node written first in the file.
      auto first_written =
          std::min_element(cycle.begin(), cycle.end(), [&](const auto& a, const auto& b) {
            return std::find(node_names_.begin(), node_names_.end(), a) <
                   std::find(node_names_.begin(), node_names_.end(), b);
          });
      std::rotate(cycle.begin(), first_written, cycle.end());
      std::string text;
      for (const auto& n : cycle) text += n + " -> ";
      text += cycle.front();
      const NodeSpec* first = FindNode(cycle.front());
      Fail(first ? first->where : SourceLocation{},
           "cycle in the graph: " + text + " (expected a graph without cycles)");
      return false;
    }
    path.push_back(next);
  }
}

bool VariantChecker::Check(ResolvedGraph* out) {
  const size_t before = errors_->size();
  for (const auto& node : variant_.nodes) node_stages_[node.name] = CheckStage(node);
  std::vector<ResolvedNode> resolved;
  for (const auto& node : variant_.nodes) {
    const runtime::StageEntry* stage = node_stages_[node.name];
    if (!stage) continue;
    ResolvedNode r;
    r.name = node.name;
    r.stage = stage;
    CheckParams(node, *stage, &r);
    CheckInputs(node, *stage, &r);
    resolved.push_back(std::move(r));
  }
  out->variant = variant_.name;
  const bool ordered = Order(std::move(resolved), out);  // reports cycles even beside other errors
  return ordered && errors_->size() == before;
}

}  // namespace

bool ResolveVariant(const GraphVariant& variant, const StageLookup& stages, ResolvedGraph* out,
                    Diagnostics* errors) {
  *out = ResolvedGraph{};
  return VariantChecker(variant, stages, errors).Check(out);
}

}  // namespace locforge::host
