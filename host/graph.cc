#include "graph.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <functional>
#include <set>
#include <sstream>

#include "locforge/fs.h"
#include "locforge/params.h"

namespace locforge::host {

std::string SourceLocation::ToString() const {
  if (line <= 0) return file;
  return file + ":" + std::to_string(line) + ":" + std::to_string(column);
}

std::string Hint(const std::string& word, const std::vector<std::string>& candidates) {
  const std::string best = DidYouMean(word, candidates);
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

bool ParseOverride(const std::string& text, Override* out) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0) return false;
  out->key = text.substr(0, eq);
  out->value = text.substr(eq + 1);
  return true;
}

namespace {

bool IsIdentifier(const std::string& s, bool allow_dash) {
  if (s.empty()) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || (allow_dash && c == '-')))
      return false;
  return true;
}

// `${name}` is not a valid plain scalar inside a YAML flow mapping
// (`{count: ${count}}`), so before parsing each one becomes `$<name>`, which
// is, with the same length (positions stay exact); scalars are read back
// through Unmask().
std::string Mask(const std::string& text) {
  std::string out = text;
  for (size_t pos = out.find("${"); pos != std::string::npos; pos = out.find("${", pos + 1)) {
    size_t end = pos + 2;
    while (end < out.size() &&
           (std::isalnum(static_cast<unsigned char>(out[end])) || out[end] == '_'))
      ++end;
    if (end == pos + 2 || end >= out.size() || out[end] != '}') continue;
    out[pos + 1] = '<';
    out[end] = '>';
  }
  return out;
}

std::string Unmask(const std::string& scalar) {
  std::string out = scalar;
  for (size_t pos = out.find("$<"); pos != std::string::npos; pos = out.find("$<", pos + 1)) {
    size_t end = pos + 2;
    while (end < out.size() &&
           (std::isalnum(static_cast<unsigned char>(out[end])) || out[end] == '_'))
      ++end;
    if (end == pos + 2 || end >= out.size() || out[end] != '>') continue;
    out[pos + 1] = '{';
    out[end] = '}';
  }
  return out;
}

// A YAML value as a Value: a scalar, a list of scalars, or a component
// {stage: KIND/NAME, params: {name: scalar or list or component, ...}}.
bool ReadYamlValue(const YAML::Node& node, const std::function<SourceLocation(const YAML::Mark&)>& at,
                   const std::string& what, Value* out, Diagnostics* errors) {
  auto fail = [&](const YAML::Node& n, const std::string& message) {
    errors->push_back({at(n.Mark()), what + ": " + message});
    return false;
  };
  *out = Value{};
  if (node.IsScalar()) {
    out->items.push_back(Unmask(node.Scalar()));
    return true;
  }
  if (node.IsSequence()) {
    out->is_list = true;
    for (const auto& item : node) {
      if (!item.IsScalar()) return fail(item, "expected a scalar list element");
      out->items.push_back(Unmask(item.Scalar()));
    }
    return true;
  }
  if (!node.IsMap())
    return fail(node, "expected a scalar, a list of scalars or a component {stage: KIND/NAME, params: {...}}");
  out->is_component = true;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string key = it->first.IsScalar() ? it->first.Scalar() : "";
    if (key != "stage" && key != "params")
      return fail(it->first, "unknown key '" + key + "' of a component; expected stage and params");
  }
  const YAML::Node stage = node["stage"];
  if (!stage || !stage.IsScalar()) return fail(node, "a component needs 'stage: KIND/NAME'");
  out->items.push_back(Unmask(stage.Scalar()));
  const YAML::Node params = node["params"];
  if (!params || params.IsNull()) return true;
  if (!params.IsMap()) return fail(params, "a component's 'params' must be a mapping");
  for (auto it = params.begin(); it != params.end(); ++it) {
    ComponentParam p;
    p.name = it->first.Scalar();
    p.key_where = at(it->first.Mark());
    p.value_where = at(it->second.Mark());
    if (!ReadYamlValue(it->second, at, what + ": parameter '" + p.name + "'", &p.value, errors))
      return false;
    out->params.push_back(std::move(p));
  }
  return true;
}

// A value as written, before substitution, with its provenance.
struct RawValue {
  Value value;
  SourceLocation where;
  // Where relative paths in it resolve: empty for a value written in this
  // graph file (its folder); the current directory for a --set value; the
  // includer's base for a value an including graph passed in.
  fs::path base_dir;
  // A variable declared `!required DOC`: it has no default, so the command
  // line (or the including graph) must give it.
  bool required = false;
  std::string doc;
};

// An `include:` entry: another graph's nodes added to this one, their names
// prefixed, some of its variables set and some of its inputs wired here.
struct IncludeSpec {
  std::string name;
  SourceLocation where;
  fs::path file;        // absolute
  std::string display;  // as diagnostics name it
  std::string prefix;
  std::vector<std::pair<std::string, RawValue>> vars;
  std::vector<std::pair<std::string, RawValue>> inputs;  // "NODE.PORT" of the included graph -> wires here
};

constexpr int kMaxIncludeDepth = 8;

class GraphParser {
 public:
  // `file` is absolute (it anchors relative paths); `display` names it in diagnostics.
  GraphParser(const fs::path& file, const std::string& display, const fs::path& cwd,
              Diagnostics* errors)
      : file_(file), display_(display), dir_(file.parent_path()), cwd_(cwd), errors_(errors) {}

  bool Parse(const std::string& text, const std::vector<Override>& sets, Graph* graph);

 private:
  // The graph as an include of another: `values` set its variables (already
  // substituted in the includer), `includer` names the include entry in
  // messages. Its nodes go into `nodes`, unprefixed.
  void ParseIncluded(const std::string& text, const std::map<std::string, RawValue>& values,
                     const IncludeSpec& includer, std::vector<NodeSpec>* nodes, Graph* graph);
  void ReadIncludes(const YAML::Node& node);
  void ExpandInclude(const IncludeSpec& include, GraphVariant* variant, Graph* graph);
  void CheckRequiredVars(const IncludeSpec* includer);
  InputSpec WiresOf(const Value& value, const SourceLocation& where) const;
  SourceLocation At(const YAML::Node& n) const { return At(n.Mark()); }
  SourceLocation At(const YAML::Mark& m) const { return {display_, m.line + 1, m.column + 1}; }
  void Fail(const SourceLocation& where, const std::string& message) {
    errors_->push_back({where, message});
  }

  void CheckDuplicateKeys(const YAML::Node& node);
  bool ReadRaw(const YAML::Node& node, const std::string& what, RawValue* out);
  void ReadVars(const YAML::Node& node);
  void ReadMatrix(const YAML::Node& node);
  void ReadSlurm(const YAML::Node& node, std::vector<SchedulerSetting>* out);
  void ApplyVarOverrides(const std::vector<Override>& sets);
  std::vector<GraphVariant> ExpandMatrix();
  void ReadNodes(const YAML::Node& nodes, GraphVariant* variant);
  void ReadNodeStage(const YAML::Node& stage, NodeSpec* node);
  void ReadNodeParams(const YAML::Node& params, NodeSpec* node);
  void ReadNodeInputs(const YAML::Node& inputs, NodeSpec* node);
  void ApplyNodeOverrides(GraphVariant* variant);

  // Substitution for the current variant. `base` is set to the base folder
  // of a substituted variable that was not written in this file (a --set or
  // an includer's value), so its relative paths resolve where they were
  // written; left as is otherwise.
  Value Substitute(const Value& raw, const SourceLocation& where, fs::path* base);
  bool SubstituteScalar(const std::string& s, const SourceLocation& where, Value* out,
                        fs::path* base);
  bool LookupVar(const std::string& name, const SourceLocation& where, Value* out, fs::path* base);
  // The folder relative paths of a value resolve against: `base` when a
  // foreign variable went in, else this file's folder.
  fs::path BaseDir(const fs::path& base) const { return base.empty() ? dir_ : base; }
  std::vector<std::string> KnownNames() const;

  fs::path file_;
  std::string display_;
  fs::path dir_, cwd_;
  Diagnostics* errors_;
  std::map<std::string, RawValue> vars_;
  std::vector<std::pair<std::string, std::vector<std::string>>> matrix_;
  std::map<std::string, SourceLocation> matrix_where_;
  std::vector<Override> node_overrides_;
  // Per-variant state.
  std::map<std::string, std::string> matrix_env_;
  std::map<std::string, std::pair<Value, fs::path>> resolved_vars_;  // value, base_dir
  std::set<std::string> resolving_;
  std::vector<IncludeSpec> includes_;
  int depth_ = 0;  // include nesting
};

void GraphParser::CheckDuplicateKeys(const YAML::Node& node) {
  if (node.IsMap()) {
    std::set<std::string> seen;
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string key = it->first.IsScalar() ? it->first.Scalar() : "";
      if (!seen.insert(key).second)
        Fail(At(it->first), "duplicate key '" + key + "' (expected each key once per mapping)");
      CheckDuplicateKeys(it->second);
    }
  } else if (node.IsSequence()) {
    for (const auto& child : node) CheckDuplicateKeys(child);
  }
}

bool GraphParser::ReadRaw(const YAML::Node& node, const std::string& what, RawValue* out) {
  out->where = At(node);
  out->value = Value{};
  return ReadYamlValue(node, [this](const YAML::Mark& m) { return At(m); }, what, &out->value,
                       errors_);
}

void GraphParser::ReadVars(const YAML::Node& node) {
  if (!node.IsMap()) return Fail(At(node), "'vars' must be a mapping of name: value");
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string name = it->first.Scalar();
    if (!IsIdentifier(name, false)) {
      Fail(At(it->first), "variable name '" + name + "' must be letters, digits and '_'");
      continue;
    }
    if (it->second.Tag() == "!required") {
      RawValue raw;
      raw.where = At(it->second);
      raw.required = true;
      raw.doc = it->second.IsScalar() ? Unmask(it->second.Scalar()) : "";
      vars_[name] = raw;
      continue;
    }
    RawValue raw;
    if (ReadRaw(it->second, "variable '" + name + "'", &raw)) vars_[name] = raw;
  }
}

// "DIR" of "DIR: a kapture recording": the value's name in the message.
std::string Placeholder(const std::string& doc) {
  size_t n = 0;
  while (n < doc.size() && (std::isupper(static_cast<unsigned char>(doc[n])) || doc[n] == '_')) ++n;
  return n > 0 && (n == doc.size() || !std::isalnum(static_cast<unsigned char>(doc[n]))) ? doc.substr(0, n)
                                                                                         : "VALUE";
}

void GraphParser::CheckRequiredVars(const IncludeSpec* includer) {
  for (const auto& [name, raw] : vars_) {
    if (!raw.required) continue;
    const std::string doc = raw.doc.empty() ? "" : " (" + raw.doc + ")";
    if (includer)
      Fail(includer->where, "include '" + includer->name + "': variable '" + name + "' of " +
                                includer->display + " is required" + doc + "; set it under the include's vars");
    else
      Fail(raw.where, "variable '" + name + "' is required" + doc + ": give it with --set " + name + "=" +
                          Placeholder(raw.doc));
  }
}

void GraphParser::ReadMatrix(const YAML::Node& node) {
  if (!node.IsMap()) return Fail(At(node), "'matrix' must be a mapping of name: [values]");
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string name = it->first.Scalar();
    if (!IsIdentifier(name, false)) {
      Fail(At(it->first), "matrix key '" + name + "' must be letters, digits and '_'");
      continue;
    }
    if (vars_.count(name)) {
      Fail(At(it->first), "matrix key '" + name + "' is also a variable (expected distinct names)");
      continue;
    }
    RawValue raw;
    if (!ReadRaw(it->second, "matrix key '" + name + "'", &raw)) continue;
    if (!raw.value.is_list || raw.value.items.empty()) {
      Fail(raw.where, "matrix key '" + name + "': expected a non-empty list of values");
      continue;
    }
    matrix_.emplace_back(name, raw.value.items);
    matrix_where_[name] = At(it->first);
  }
}

void GraphParser::ReadSlurm(const YAML::Node& node, std::vector<SchedulerSetting>* out) {
  const std::string shape =
      "'slurm' must be a mapping of SELECTOR: {SBATCH_OPTION: value} (SELECTOR: default, a "
      "stage kind, a stage id or a node)";
  if (!node.IsMap()) return Fail(At(node), shape);
  for (auto it = node.begin(); it != node.end(); ++it) {
    if (!it->first.IsScalar() || !it->second.IsMap()) {
      Fail(At(it->first), shape);
      continue;
    }
    for (auto kv = it->second.begin(); kv != it->second.end(); ++kv) {
      if (!kv->first.IsScalar() || !kv->second.IsScalar()) {
        Fail(At(kv->first), "slurm." + it->first.Scalar() + ": expected option: scalar value");
        continue;
      }
      out->push_back({it->first.Scalar(), kv->first.Scalar(), kv->second.Scalar(), At(kv->first)});
    }
  }
}

// A --set value: a YAML list `[a, b]` or component `{stage: ..., params: {...}}`
// when it starts so, else the text itself.
Value ParseCommandLineValue(const std::string& text, const SourceLocation& where,
                            Diagnostics* errors) {
  Value v;
  if (!text.empty() && (text.front() == '[' || text.front() == '{')) {
    try {
      const YAML::Node node = YAML::Load(text);
      if (node.IsSequence()) {
        v.is_list = true;
        for (const auto& item : node) v.items.push_back(item.IsScalar() ? item.Scalar() : "");
        return v;
      }
      if (node.IsMap()) {
        ReadYamlValue(node, [&where](const YAML::Mark&) { return where; }, "value", &v, errors);
        return v;
      }
    } catch (const YAML::Exception&) {
    }
  }
  v.items.push_back(text);
  return v;
}

void GraphParser::ApplyVarOverrides(const std::vector<Override>& sets) {
  for (const auto& set : sets) {
    const SourceLocation where{"--set " + set.key + "=" + set.value};
    if (set.key.find('.') != std::string::npos) {
      node_overrides_.push_back(set);
      continue;
    }
    if (vars_.count(set.key)) {
      vars_[set.key] = RawValue{ParseCommandLineValue(set.value, where, errors_), where, cwd_, false, ""};
      continue;
    }
    auto m = std::find_if(matrix_.begin(), matrix_.end(),
                          [&](const auto& kv) { return kv.first == set.key; });
    if (m != matrix_.end()) {
      // A value pins the matrix to it; a list ([0, 1, 2]) replaces its values.
      const auto value = ParseCommandLineValue(set.value, where, errors_);
      if (value.is_list && value.items.empty()) {
        Fail(where, "matrix key '" + set.key + "': expected a value or a non-empty list");
        continue;
      }
      m->second = value.is_list ? value.items : std::vector<std::string>{set.value};
      continue;
    }
    Fail(where, "unknown variable '" + set.key + "'" + Hint(set.key, KnownNames()) +
                    "; expected one of: " + JoinNames(KnownNames()) +
                    " (or node.param to set one node's parameter)");
  }
}

std::vector<std::string> GraphParser::KnownNames() const {
  std::vector<std::string> names;
  for (const auto& [name, raw] : vars_) names.push_back(name);
  for (const auto& [name, values] : matrix_) names.push_back(name);
  return names;
}

std::string SafeVariantPart(const std::string& s) {
  std::string out;
  for (char c : s)
    out +=
        (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.') ? c : '_';
  return out;
}

std::vector<GraphVariant> GraphParser::ExpandMatrix() {
  std::vector<GraphVariant> variants(1);
  for (const auto& [key, values] : matrix_) {
    std::vector<GraphVariant> next;
    for (const auto& v : variants)
      for (const auto& value : values) {
        GraphVariant g = v;
        g.matrix_values.emplace_back(key, value);
        g.name += (g.name.empty() ? "" : ",") + key + "=" + SafeVariantPart(value);
        next.push_back(std::move(g));
      }
    variants = std::move(next);
  }
  return variants;
}

bool GraphParser::LookupVar(const std::string& name, const SourceLocation& where, Value* out,
                            fs::path* base) {
  if (auto m = matrix_env_.find(name); m != matrix_env_.end()) {
    *out = Value{{m->second}, false};
    return true;
  }
  if (auto r = resolved_vars_.find(name); r != resolved_vars_.end()) {
    *out = r->second.first;
    if (!r->second.second.empty()) *base = r->second.second;
    return true;
  }
  auto v = vars_.find(name);
  if (v == vars_.end()) {
    Fail(where, "unknown variable '" + name + "'" + Hint(name, KnownNames()) +
                    "; expected one of: " + JoinNames(KnownNames()));
    return false;
  }
  if (!resolving_.insert(name).second) {
    Fail(v->second.where,
         "variable '" + name +
             "' is defined in terms of itself (expected no cycle of ${...} references)");
    return false;
  }
  fs::path var_base = v->second.base_dir;
  const size_t before = errors_->size();
  Value value = Substitute(v->second.value, v->second.where, &var_base);
  resolving_.erase(name);
  if (errors_->size() != before) return false;
  resolved_vars_[name] = {value, var_base};
  *out = value;
  if (!var_base.empty()) *base = var_base;
  return true;
}

bool GraphParser::SubstituteScalar(const std::string& s, const SourceLocation& where, Value* out,
                                   fs::path* base) {
  // A scalar that is exactly ${x} takes x's value as is (a list stays a list).
  if (s.size() > 3 && s.compare(0, 2, "${") == 0 && s.back() == '}' && s.find('}') == s.size() - 1)
    return LookupVar(s.substr(2, s.size() - 3), where, out, base);
  std::string result;
  size_t pos = 0;
  while (true) {
    const size_t start = s.find("${", pos);
    if (start == std::string::npos) break;
    const size_t end = s.find('}', start);
    if (end == std::string::npos) {
      Fail(where, "unterminated '${' in '" + s + "' (expected ${name})");
      return false;
    }
    result += s.substr(pos, start - pos);
    Value v;
    if (!LookupVar(s.substr(start + 2, end - start - 2), where, &v, base)) return false;
    if (v.is_list || v.is_component) {
      Fail(where, "variable '" + s.substr(start + 2, end - start - 2) + "' is a " +
                      (v.is_list ? "list" : "component") + "; expected a scalar inside '" + s + "'");
      return false;
    }
    result += v.scalar();
    pos = end + 1;
  }
  result += s.substr(pos);
  *out = Value{{result}, false};
  return true;
}

Value GraphParser::Substitute(const Value& raw, const SourceLocation& where, fs::path* base) {
  if (raw.is_component) {
    Value out = raw;
    out.items.clear();
    Value stage;
    if (SubstituteScalar(raw.scalar(), where, &stage, base)) out.items.push_back(stage.scalar());
    for (auto& p : out.params) p.value = Substitute(p.value, p.value_where, base);
    return out;
  }
  Value out;
  out.is_list = raw.is_list;
  for (const auto& item : raw.items) {
    Value v;
    if (!SubstituteScalar(item, where, &v, base)) continue;
    if ((v.is_list || v.is_component) && !raw.is_list) return v;  // "${var}" as the whole value
    if (v.is_component) {
      Fail(where, "a component variable cannot be a list element");
      continue;
    }
    out.items.insert(out.items.end(), v.items.begin(), v.items.end());
  }
  return out;
}

void GraphParser::ReadNodes(const YAML::Node& nodes, GraphVariant* variant) {
  static const std::vector<std::string> kNodeKeys = {"stage", "params", "inputs"};
  for (auto it = nodes.begin(); it != nodes.end(); ++it) {
    NodeSpec node;
    node.name = it->first.Scalar();
    node.where = At(it->first);
    const YAML::Node body = it->second;
    if (!IsIdentifier(node.name, true)) {
      Fail(node.where, "node name '" + node.name + "' must be letters, digits, '_' and '-'");
      continue;
    }
    if (!body.IsMap()) {
      Fail(At(body),
           "node '" + node.name + "': expected a mapping with 'stage', 'params', 'inputs'");
      continue;
    }
    for (auto k = body.begin(); k != body.end(); ++k) {
      const std::string key = k->first.Scalar();
      if (std::find(kNodeKeys.begin(), kNodeKeys.end(), key) == kNodeKeys.end())
        Fail(At(k->first), "node '" + node.name + "': unknown key '" + key + "'" +
                               Hint(key, kNodeKeys) + "; expected stage, params or inputs");
    }
    ReadNodeStage(body["stage"], &node);
    ReadNodeParams(body["params"], &node);
    ReadNodeInputs(body["inputs"], &node);
    variant->nodes.push_back(std::move(node));
  }
}

void GraphParser::ReadNodeStage(const YAML::Node& stage, NodeSpec* node) {
  if (!stage || !stage.IsScalar()) {
    Fail(node->where, "node '" + node->name + "': 'stage: KIND/NAME' is required");
    return;
  }
  node->stage_where = At(stage);
  fs::path base;
  const Value chosen = Substitute(Value{{Unmask(stage.Scalar())}, false}, node->stage_where, &base);
  if (chosen.is_list) {
    Fail(node->stage_where, "node '" + node->name + "': 'stage' is a list; expected KIND/NAME or a " +
                                "{stage: KIND/NAME, params: {...}} variable");
    return;
  }
  node->stage = chosen.scalar();
  // A variable holding {stage: ID, params: {...}} chooses the stage and its
  // parameters; the node's own params (read after) override them.
  if (!chosen.is_component) return;
  for (const ComponentParam& p : chosen.params)
    node->params[p.name] = ParamValue{p.value, p.key_where, p.value_where, BaseDir(base), false};
}

void GraphParser::ReadNodeParams(const YAML::Node& params, NodeSpec* node) {
  if (!params || params.IsNull()) return;
  if (!params.IsMap()) {
    Fail(At(params), "node '" + node->name + "': 'params' must be a mapping");
    return;
  }
  for (auto p = params.begin(); p != params.end(); ++p) {
    RawValue raw;
    if (!ReadRaw(p->second, "parameter '" + p->first.Scalar() + "'", &raw)) continue;
    ParamValue pv;
    pv.key_where = At(p->first);
    pv.value_where = raw.where;
    fs::path base;
    const size_t before = errors_->size();
    pv.value = Substitute(raw.value, raw.where, &base);
    pv.broken = errors_->size() != before;
    pv.base_dir = BaseDir(base);
    node->params[p->first.Scalar()] = pv;
  }
}

void GraphParser::ReadNodeInputs(const YAML::Node& inputs, NodeSpec* node) {
  if (!inputs || inputs.IsNull()) return;
  if (!inputs.IsMap()) {
    Fail(At(inputs), "node '" + node->name + "': 'inputs' must be a mapping port: node.port");
    return;
  }
  for (auto in = inputs.begin(); in != inputs.end(); ++in) {
    RawValue raw;
    if (!ReadRaw(in->second, "input '" + in->first.Scalar() + "'", &raw)) continue;
    InputSpec spec;
    spec.where = At(in->first);
    if (raw.value.is_component) {
      Fail(raw.where, "input '" + in->first.Scalar() + "': expected NODE.PORT or a list of them");
      continue;
    }
    fs::path base;
    const size_t before = errors_->size();
    const Value v = Substitute(raw.value, raw.where, &base);
    const SourceLocation key_where = spec.where;
    spec = WiresOf(v, raw.where);
    spec.where = key_where;
    spec.broken = errors_->size() != before;
    node->inputs[in->first.Scalar()] = spec;
  }
}

InputSpec GraphParser::WiresOf(const Value& value, const SourceLocation& where) const {
  InputSpec spec;
  spec.where = where;
  spec.is_list = value.is_list;
  for (const auto& text : value.items) {
    Wire w;
    w.where = where;
    const size_t dot = text.find('.');
    w.node = text.substr(0, dot);
    if (dot != std::string::npos) w.port = text.substr(dot + 1);
    spec.wires.push_back(w);
  }
  return spec;
}

void GraphParser::ReadIncludes(const YAML::Node& node) {
  if (!node.IsMap())
    return Fail(At(node), "'include' must be a mapping of name: {graph: FILE, prefix: ..., vars: {...}, inputs: {...}}");
  static const std::vector<std::string> kKeys = {"graph", "prefix", "vars", "inputs"};
  for (auto it = node.begin(); it != node.end(); ++it) {
    IncludeSpec inc;
    inc.name = it->first.Scalar();
    inc.where = At(it->first);
    const YAML::Node body = it->second;
    if (!IsIdentifier(inc.name, true)) {
      Fail(inc.where, "include name '" + inc.name + "' must be letters, digits, '_' and '-'");
      continue;
    }
    if (!body.IsMap()) {
      Fail(At(body), "include '" + inc.name + "': expected a mapping with 'graph' (and prefix, vars, inputs)");
      continue;
    }
    bool ok = true;
    for (auto k = body.begin(); k != body.end(); ++k) {
      const std::string key = k->first.Scalar();
      if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end()) {
        Fail(At(k->first), "include '" + inc.name + "': unknown key '" + key + "'" + Hint(key, kKeys) +
                               "; expected graph, prefix, vars or inputs");
        ok = false;
      }
    }
    const YAML::Node graph = body["graph"];
    if (!graph || !graph.IsScalar() || graph.Scalar().empty()) {
      Fail(inc.where, "include '" + inc.name + "': 'graph: FILE' is required (relative to this file)");
      continue;
    }
    inc.file = (dir_ / graph.Scalar()).lexically_normal();
    inc.display = (fs::path(display_).parent_path() / graph.Scalar()).lexically_normal().string();
    std::error_code ec;
    if (!fs::is_regular_file(inc.file, ec)) {
      Fail(At(graph), "include '" + inc.name + "': graph file '" + inc.file.string() + "' not found");
      continue;
    }
    if (const YAML::Node prefix = body["prefix"]) {
      inc.prefix = prefix.IsScalar() ? prefix.Scalar() : "";
      if (!inc.prefix.empty() && !IsIdentifier(inc.prefix, true)) {
        Fail(At(prefix), "include '" + inc.name + "': prefix '" + inc.prefix + "' must be letters, digits, '_' and '-'");
        ok = false;
      }
    }
    for (const char* section : {"vars", "inputs"}) {
      const YAML::Node m = body[section];
      if (!m || m.IsNull()) continue;
      if (!m.IsMap()) {
        Fail(At(m), "include '" + inc.name + "': '" + section + "' must be a mapping");
        ok = false;
        continue;
      }
      for (auto k = m.begin(); k != m.end(); ++k) {
        RawValue raw;
        if (!ReadRaw(k->second, "include '" + inc.name + "': " + section + " '" + k->first.Scalar() + "'", &raw)) {
          ok = false;
          continue;
        }
        raw.where = At(k->first);
        (std::string(section) == "vars" ? inc.vars : inc.inputs).emplace_back(k->first.Scalar(), raw);
      }
    }
    if (ok) includes_.push_back(std::move(inc));
  }
}

void GraphParser::ExpandInclude(const IncludeSpec& inc, GraphVariant* variant, Graph* graph) {
  if (depth_ >= kMaxIncludeDepth)
    return Fail(inc.where, "include '" + inc.name + "': includes nested more than " +
                               std::to_string(kMaxIncludeDepth) + " deep (does a graph include itself?)");
  std::string text;
  try {
    text = ReadFile(inc.file);
  } catch (const std::exception& e) {
    return Fail(inc.where, "include '" + inc.name + "': " + e.what());
  }
  // Values are substituted here, in the including graph's variables. Relative
  // paths among them resolve where each was written: this file's folder, or
  // the current directory for a --set value.
  std::map<std::string, RawValue> values;
  for (const auto& [name, raw] : inc.vars) {
    const size_t before = errors_->size();
    fs::path base;
    Value v = Substitute(raw.value, raw.where, &base);
    if (errors_->size() != before) continue;
    values[name] = RawValue{v, raw.where, BaseDir(base), false, ""};
  }
  GraphParser inner(inc.file, inc.display, cwd_, errors_);
  inner.depth_ = depth_ + 1;
  std::vector<NodeSpec> nodes;
  inner.ParseIncluded(text, values, inc, &nodes, graph);
  // Wires to the included graph's own nodes get the prefix; a wire to any
  // other name came in through a variable and names a node of this graph.
  std::set<std::string> names;
  for (const auto& n : nodes) names.insert(n.name);
  for (auto& n : nodes) {
    n.name = inc.prefix + n.name;
    for (auto& [port, spec] : n.inputs)
      for (auto& w : spec.wires)
        if (names.count(w.node)) w.node = inc.prefix + w.node;
  }
  for (const auto& [target, raw] : inc.inputs) {
    const size_t dot = target.find('.');
    const std::string node_name = target.substr(0, dot);
    auto node = std::find_if(nodes.begin(), nodes.end(),
                             [&](const NodeSpec& n) { return n.name == inc.prefix + node_name; });
    if (dot == std::string::npos || dot + 1 == target.size() || node == nodes.end()) {
      const std::vector<std::string> known(names.begin(), names.end());
      Fail(raw.where, "include '" + inc.name + "': inputs key '" + target + "' must be NODE.PORT of a node of " +
                          inc.display + Hint(node_name, known) + "; nodes: " + JoinNames(known));
      continue;
    }
    fs::path base;
    const size_t before = errors_->size();
    const Value v = Substitute(raw.value, raw.where, &base);
    if (v.is_component) {
      Fail(raw.where, "include '" + inc.name + "': input '" + target + "': expected NODE.PORT or a list of them");
      continue;
    }
    InputSpec spec = WiresOf(v, raw.where);
    spec.broken = errors_->size() != before;
    node->inputs[target.substr(dot + 1)] = spec;
  }
  for (auto& n : nodes) {
    if (std::any_of(variant->nodes.begin(), variant->nodes.end(),
                    [&](const NodeSpec& o) { return o.name == n.name; })) {
      Fail(inc.where, "include '" + inc.name + "': node '" + n.name + "' of " + inc.display +
                          " has the name of a node already in the graph (expected distinct names: set a prefix)");
      continue;
    }
    variant->nodes.push_back(std::move(n));
  }
}

void GraphParser::ParseIncluded(const std::string& text, const std::map<std::string, RawValue>& values,
                                const IncludeSpec& includer, std::vector<NodeSpec>* nodes, Graph* graph) {
  YAML::Node root;
  try {
    root = YAML::Load(Mask(text));
  } catch (const YAML::Exception& e) {
    return Fail(At(e.mark), "YAML syntax: " + e.msg);
  }
  if (!root.IsMap()) return Fail({display_, 1, 1}, "expected a mapping with 'locforge: 1' and 'nodes:'");
  CheckDuplicateKeys(root);
  if (const YAML::Node matrix = root["matrix"])
    Fail(At(matrix), "an included graph has no matrix (include '" + includer.name +
                         "'); put the matrix in the including graph and pass its keys as vars");
  const YAML::Node version = root["locforge"];
  if (!version || !version.IsScalar() || version.Scalar() != "1")
    Fail(version ? At(version) : SourceLocation{display_, 1, 1}, "expected 'locforge: 1' (the graph format version)");
  if (const YAML::Node vars = root["vars"]) ReadVars(vars);
  for (const auto& [name, value] : values) {
    if (!vars_.count(name)) {
      Fail(value.where, "include '" + includer.name + "': " + includer.display + " has no variable '" + name + "'" +
                            Hint(name, KnownNames()) + "; expected one of: " + JoinNames(KnownNames()));
      continue;
    }
    vars_[name] = value;
  }
  CheckRequiredVars(&includer);
  if (const YAML::Node paths = root["plugin_paths"]) {
    RawValue raw;
    if (ReadRaw(paths, "plugin_paths", &raw)) {
      fs::path base;
      for (const auto& p : Substitute(raw.value, raw.where, &base).items) {
        const fs::path folder = (dir_ / p).lexically_normal();
        if (std::none_of(graph->plugin_paths.begin(), graph->plugin_paths.end(),
                         [&](const auto& known) { return known.first == folder; }))
          graph->plugin_paths.emplace_back(folder, raw.where);
      }
    }
  }
  GraphVariant variant;
  if (const YAML::Node n = root["nodes"]; n && n.IsMap()) ReadNodes(n, &variant);
  if (const YAML::Node inc = root["include"]) ReadIncludes(inc);
  for (const auto& sub : includes_) ExpandInclude(sub, &variant, graph);
  *nodes = std::move(variant.nodes);
}

void GraphParser::ApplyNodeOverrides(GraphVariant* variant) {
  for (const auto& set : node_overrides_) {
    const SourceLocation where{"--set " + set.key + "=" + set.value};
    const size_t dot = set.key.find('.');
    const std::string node_name = set.key.substr(0, dot);
    const std::string param = set.key.substr(dot + 1);
    auto node = std::find_if(variant->nodes.begin(), variant->nodes.end(),
                             [&](const NodeSpec& n) { return n.name == node_name; });
    if (node == variant->nodes.end()) {
      std::vector<std::string> names;
      for (const auto& n : variant->nodes) names.push_back(n.name);
      Fail(where, "unknown node '" + node_name + "'" + Hint(node_name, names) +
                      "; expected one of: " + JoinNames(names));
      continue;
    }
    ParamValue pv;
    pv.key_where = pv.value_where = where;
    fs::path base = cwd_;
    const size_t before = errors_->size();
    pv.value = Substitute(ParseCommandLineValue(set.value, where, errors_), where, &base);
    pv.broken = errors_->size() != before;
    pv.base_dir = cwd_;
    node->params[param] = pv;
  }
}

bool GraphParser::Parse(const std::string& text, const std::vector<Override>& sets, Graph* graph) {
  const size_t before = errors_->size();
  YAML::Node root;
  try {
    root = YAML::Load(Mask(text));
  } catch (const YAML::Exception& e) {
    Fail(At(e.mark), "YAML syntax: " + e.msg);
    return false;
  }
  if (!root.IsMap()) {
    Fail({display_, 1, 1}, "expected a mapping with 'locforge: 1' and 'nodes:'");
    return false;
  }
  CheckDuplicateKeys(root);
  static const std::vector<std::string> kTopKeys = {"locforge", "description", "plugin_paths", "vars",
                                                    "matrix",   "include",     "nodes",        "slurm"};
  for (auto it = root.begin(); it != root.end(); ++it) {
    const std::string key = it->first.Scalar();
    if (std::find(kTopKeys.begin(), kTopKeys.end(), key) == kTopKeys.end())
      Fail(At(it->first), "unknown top-level key '" + key + "'" + Hint(key, kTopKeys) +
                              "; expected one of: " + JoinNames(kTopKeys));
  }
  const YAML::Node version = root["locforge"];
  if (!version) {
    Fail({display_, 1, 1}, "missing 'locforge: 1' (the graph format version)");
  } else if (!version.IsScalar() || version.Scalar() != "1") {
    Fail(At(version), "unsupported graph format version; expected 'locforge: 1'");
  }
  graph->file = file_;
  if (const YAML::Node d = root["description"]; d && d.IsScalar()) graph->description = d.Scalar();
  if (const YAML::Node vars = root["vars"]) ReadVars(vars);
  if (const YAML::Node matrix = root["matrix"]) ReadMatrix(matrix);
  if (const YAML::Node slurm = root["slurm"]) ReadSlurm(slurm, &graph->slurm);
  ApplyVarOverrides(sets);
  CheckRequiredVars(nullptr);
  if (const YAML::Node inc = root["include"]) ReadIncludes(inc);
  if (const YAML::Node paths = root["plugin_paths"]) {
    RawValue raw;
    if (ReadRaw(paths, "plugin_paths", &raw)) {
      fs::path base;
      for (const auto& p : Substitute(raw.value, raw.where, &base).items)
        graph->plugin_paths.emplace_back((dir_ / p).lexically_normal(), raw.where);
    }
  }
  const YAML::Node nodes = root["nodes"];
  const bool has_nodes = nodes && nodes.IsMap() && nodes.size() > 0;
  if (!has_nodes && (includes_.empty() || (nodes && !nodes.IsMap() && !nodes.IsNull()))) {
    Fail(nodes ? At(nodes) : SourceLocation{display_, 1, 1},
         "expected 'nodes:' with at least one node (or 'include:')");
  } else {
    for (GraphVariant variant : ExpandMatrix()) {
      matrix_env_.clear();
      resolved_vars_.clear();
      for (const auto& [key, value] : variant.matrix_values) matrix_env_[key] = value;
      if (has_nodes) ReadNodes(nodes, &variant);
      for (const auto& inc : includes_) ExpandInclude(inc, &variant, graph);
      ApplyNodeOverrides(&variant);
      graph->variants.push_back(std::move(variant));
    }
  }
  *errors_ = Deduplicate(*errors_);
  return errors_->size() == before;
}

}  // namespace

bool ParseGraph(const std::string& text, const fs::path& file, const std::vector<Override>& sets,
                const fs::path& cwd, Graph* graph, Diagnostics* errors) {
  return GraphParser(fs::absolute(file).lexically_normal(), file.string(), cwd, errors)
      .Parse(text, sets, graph);
}

bool LoadGraph(const fs::path& file, const std::vector<Override>& sets, Graph* graph,
               Diagnostics* errors) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) {
    errors->push_back({{file.string()}, "graph file not found (expected a YAML file)"});
    return false;
  }
  std::string text;
  try {
    text = ReadFile(file);
  } catch (const std::exception& e) {
    errors->push_back({{file.string()}, e.what()});
    return false;
  }
  return ParseGraph(text, file, sets, fs::current_path(), graph, errors);
}

Diagnostics Deduplicate(const Diagnostics& errors) {
  Diagnostics out;
  std::set<std::string> seen;
  for (const auto& d : errors)
    if (seen.insert(d.ToString()).second) out.push_back(d);
  return out;
}

}  // namespace locforge::host
