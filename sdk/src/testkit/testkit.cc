#include "locforge/testkit.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "locforge/error.h"

namespace locforge::testkit {

namespace {

bool IsArtifactType(const std::string& t) {
  if (t.empty() || t.front() == '.' || t.back() == '.') return false;
  for (const char c : t)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '.')) return false;
  return true;
}

struct CheckResult {
  int32_t code = LF_OK;
  std::string message;
};

// Calls the plugin's own check_params; an escaping exception is a failure too.
CheckResult CallCheck(const runtime::StageEntry& stage,
                      const std::map<std::string, std::string>& values) {
  std::vector<LfParam> params;
  for (const auto& [name, value] : values) params.push_back({name.c_str(), value.c_str()});
  LfError err{};
  err.struct_size = sizeof(LfError);
  CheckResult r;
  try {
    r.code = stage.info->check_params(params.data(), static_cast<uint32_t>(params.size()), &err);
  } catch (...) {
    r.code = -1;
    r.message = "check_params threw an exception through the ABI";
    return r;
  }
  err.message[sizeof(err.message) - 1] = '\0';
  r.message = err.message;
  return r;
}

std::string Describe(const std::map<std::string, std::string>& values) {
  std::string out;
  for (const auto& [k, v] : values) {
    std::string shown = v;
    std::replace(shown.begin(), shown.end(), LF_LIST_SEPARATOR, ',');
    out += (out.empty() ? "" : ", ") + k + "=" + shown;
  }
  return "{" + out + "}";
}

// A value valid for `d`: its default, or one made up for a required parameter.
std::string ValidValue(const ParamDecl& d) {
  if (!d.required()) return d.default_value;
  auto clamp = [&](double x) {
    if (d.has_min) x = std::max(x, d.min_value);
    if (d.has_max) x = std::min(x, d.max_value);
    return x;
  };
  switch (d.type) {
    case LF_PARAM_BOOL: return "false";
    case LF_PARAM_INT: return FormatInt(static_cast<int64_t>(std::ceil(clamp(0))));
    case LF_PARAM_DOUBLE: return FormatDouble(clamp(0));
    case LF_PARAM_STRING: return "x";
    case LF_PARAM_PATH: return ".";
    case LF_PARAM_ENUM: return d.choices.empty() ? "" : d.choices.front();
    case LF_PARAM_COMPONENT: return "kind/name";
    default: return "";  // an empty list
  }
}

// Values `d` must refuse, each with why it is wrong.
std::vector<std::pair<std::string, std::string>> InvalidValues(const ParamDecl& d) {
  std::vector<std::pair<std::string, std::string>> out;
  const double step_min = std::max(1.0, std::fabs(d.min_value) * 0.5);
  const double step_max = std::max(1.0, std::fabs(d.max_value) * 0.5);
  switch (d.type) {
    case LF_PARAM_BOOL: out.push_back({"maybe", "not a bool"}); break;
    case LF_PARAM_INT:
      out.push_back({"not_a_number", "not an integer"});
      out.push_back({"1.5", "not an integer"});
      if (d.has_min && d.min_value > -9e18)
        out.push_back({FormatInt(static_cast<int64_t>(std::ceil(d.min_value)) - 1), "below the minimum"});
      if (d.has_max && d.max_value < 9e18)
        out.push_back({FormatInt(static_cast<int64_t>(std::floor(d.max_value)) + 1), "above the maximum"});
      break;
    case LF_PARAM_DOUBLE:
      out.push_back({"not_a_number", "not a number"});
      if (d.has_min) out.push_back({FormatDouble(d.min_value - step_min), "below the minimum"});
      if (d.has_max) out.push_back({FormatDouble(d.max_value + step_max), "above the maximum"});
      break;
    case LF_PARAM_ENUM: out.push_back({"__not_a_choice__", "not one of the choices"}); break;
    case LF_PARAM_PATH:
      if (d.required()) out.push_back({"", "an empty path"});  // optional paths may be empty
      break;
    case LF_PARAM_INT_LIST:
    case LF_PARAM_DOUBLE_LIST:
      out.push_back({"not_a_number", "a list with a non-numeric element"});
      if (d.has_min) out.push_back({FormatDouble(std::floor(d.min_value - step_min)), "a list element below the minimum"});
      if (d.has_max) out.push_back({FormatDouble(std::ceil(d.max_value + step_max)), "a list element above the maximum"});
      break;
    case LF_PARAM_COMPONENT:
      out.push_back({"no_stage_id", "not a KIND/NAME component"});
      out.push_back({d.default_value + LF_COMPONENT_SEPARATOR + "no_equals_sign",
                     "a component parameter that is not name=value"});
      break;
    default: break;  // any string is a valid string
  }
  return out;
}

std::map<std::string, std::vector<char>> ListFiles(const fs::path& root, Report* report,
                                                    const std::string& label) {
  std::map<std::string, std::vector<char>> files;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file()) continue;
    const std::string rel = it->path().lexically_relative(root).generic_string();
    const std::string name = it->path().filename().string();
    if (name.rfind(".items-done.", 0) == 0) continue;
    if (name.find(".tmp-") != std::string::npos)
      report->Fail(label + ": leftover temp file " + rel + " (an output not written atomically?)");
    std::ifstream in(it->path(), std::ios::binary);
    files[rel].assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  if (ec) report->Fail(label + ": cannot list " + root.string() + ": " + ec.message());
  return files;
}

fs::path FreshTempDir() {
  static std::atomic<int> counter{0};
  const fs::path dir = fs::temp_directory_path() /
                       ("locforge-testkit-" + std::to_string(::getpid()) + "-" +
                        std::to_string(counter.fetch_add(1)) + "-" +
                        std::to_string(std::hash<std::string>{}(fs::current_path().string()) % 100000));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

}  // namespace

void Report::Merge(const Report& other) {
  failures.insert(failures.end(), other.failures.begin(), other.failures.end());
  notes.insert(notes.end(), other.notes.begin(), other.notes.end());
}

std::string Report::ToString() const {
  std::string out;
  for (const auto& f : failures) out += "FAIL: " + f + "\n";
  for (const auto& n : notes) out += "note: " + n + "\n";
  return out.empty() ? "all checks passed\n" : out;
}

Report CheckLoads(runtime::Registry& registry, const fs::path& plugin_file) {
  Report report;
  const size_t problems_before = registry.problems().size();
  const size_t duplicates_before = registry.duplicates().size();
  if (!registry.LoadFile(plugin_file)) {
    for (size_t i = problems_before; i < registry.problems().size(); ++i)
      report.Fail("refused: " + registry.problems()[i].message);
    if (report.ok()) report.Fail(plugin_file.string() + ": not loaded");
    return report;
  }
  for (size_t i = duplicates_before; i < registry.duplicates().size(); ++i)
    report.Fail(registry.duplicates()[i]);
  return report;
}

Report CheckMetadata(const runtime::StageEntry& stage) {
  Report r;
  const std::string at = stage.id;
  const LfPluginInfo* plugin = stage.plugin->info;
  const std::string file = stage.plugin->file.filename().string();
  if (!plugin->version || !*plugin->version) r.Fail(file + ": plugin version is empty");
  if (!plugin->description || !*plugin->description) r.Fail(file + ": plugin description is empty");
  if (!stage.info->doc || !*stage.info->doc) r.Fail(at + ": stage doc is empty");
  for (const auto& p : stage.params) {
    if (p.doc.empty()) r.Fail(at + ": parameter '" + p.name + "' has no doc");
    if (!p.required()) {
      const std::string why = ValidateParamValue(p, p.default_value);
      if (!why.empty()) r.Fail(at + ": parameter '" + p.name + "' default is invalid: " + why);
    }
  }
  auto ports = [&](const std::vector<runtime::PortDecl>& list, const char* direction) {
    for (const auto& p : list) {
      if (!IsArtifactType(p.artifact_type))
        r.Fail(at + ": " + direction + " port '" + p.name + "' artifact type '" + p.artifact_type +
               "' is not a dotted lower-case name");
      if (p.doc.empty()) r.Fail(at + ": " + direction + " port '" + p.name + "' has no doc");
    }
  };
  ports(stage.inputs, "input");
  ports(stage.outputs, "output");
  if (stage.runnable() && stage.outputs.empty())
    r.Fail(at + ": runnable stage declares no output port");
  return r;
}

Report CheckParamValidation(const runtime::StageEntry& stage) {
  Report r;
  const std::string at = stage.id;
  std::map<std::string, std::string> baseline;
  bool has_required = false;
  for (const auto& p : stage.params) {
    baseline[p.name] = ValidValue(p);
    has_required |= p.required();
  }
  if (!has_required) {
    const CheckResult none = CallCheck(stage, {});
    if (none.code != LF_OK)
      r.Fail(at + ": check_params refuses its defaults (no values given): " + none.message);
  }
  const CheckResult base = CallCheck(stage, baseline);
  if (base.code != LF_OK) {
    if (has_required) {
      r.Note(at + ": made-up values for required parameters were refused (" + base.message +
             "); refusal checks skipped");
      return r;
    }
    r.Fail(at + ": check_params refuses its own defaults " + Describe(baseline) + ": " +
           base.message);
    return r;
  }
  auto expect_refused = [&](const std::map<std::string, std::string>& values,
                            const std::string& param, const std::string& why) {
    const CheckResult c = CallCheck(stage, values);
    const std::string shown = Describe({{param, values.at(param)}});
    if (c.code != LF_BAD_PARAMS)
      r.Fail(at + ": " + shown + " (" + why + ") returned status " + std::to_string(c.code) +
             ", expected LF_BAD_PARAMS (" + std::to_string(LF_BAD_PARAMS) + ")" +
             (c.message.empty() ? "" : ": " + c.message));
    else if (c.message.find(param) == std::string::npos)
      r.Fail(at + ": refusal of " + shown + " does not name the parameter: '" + c.message + "'");
  };
  {
    auto values = baseline;
    values["locforge_testkit_unknown"] = "1";
    expect_refused(values, "locforge_testkit_unknown", "an unknown parameter");
  }
  for (const auto& p : stage.params) {
    for (const auto& [value, why] : InvalidValues(p)) {
      auto values = baseline;
      values[p.name] = value;
      expect_refused(values, p.name, why);
    }
  }
  return r;
}

Report CheckPlugin(const fs::path& plugin_file) {
  // Kept alive for the process: plugins are never unloaded.
  static std::vector<std::unique_ptr<runtime::Registry>>* registries =
      new std::vector<std::unique_ptr<runtime::Registry>>();
  registries->push_back(std::make_unique<runtime::Registry>());
  runtime::Registry& registry = *registries->back();
  Report report = CheckLoads(registry, plugin_file);
  if (!report.ok()) return report;
  if (registry.Stages().empty()) report.Fail(plugin_file.string() + ": defines no stage");
  for (const auto* stage : registry.Stages()) {
    report.Merge(CheckMetadata(*stage));
    report.Merge(CheckParamValidation(*stage));
  }
  return report;
}

Report CompareFolders(const fs::path& a, const fs::path& b) {
  Report r;
  const auto fa = ListFiles(a, &r, "first run");
  const auto fb = ListFiles(b, &r, "second run");
  if (fa.empty() && fb.empty()) r.Note("both folders are empty");
  for (const auto& [rel, bytes] : fa) {
    auto it = fb.find(rel);
    if (it == fb.end()) {
      r.Fail(rel + ": written by the first run only");
      continue;
    }
    if (it->second == bytes) continue;
    const auto diff = std::mismatch(bytes.begin(), bytes.end(), it->second.begin(), it->second.end());
    r.Fail(rel + ": contents differ (sizes " + std::to_string(bytes.size()) + " and " +
           std::to_string(it->second.size()) + ", first difference at byte " +
           std::to_string(diff.first - bytes.begin()) + ")");
  }
  for (const auto& [rel, bytes] : fb)
    if (!fa.count(rel)) r.Fail(rel + ": written by the second run only");
  return r;
}

Report CheckDeterminism(const runtime::Registry& registry, const DeterminismCase& c) {
  Report r;
  const runtime::StageEntry* stage = registry.Find(c.stage_id);
  if (stage == nullptr) {
    r.Fail("unknown stage '" + c.stage_id + "'");
    return r;
  }
  if (stage->info->flags & LF_STAGE_NONDETERMINISTIC) {
    r.Note(c.stage_id + ": declared nondeterministic; determinism check skipped");
    return r;
  }
  const fs::path scratch = c.scratch.empty() ? FreshTempDir() : c.scratch;
  const int threads[2] = {std::max(1, c.threads), 1};
  fs::path outputs[2];
  for (int run = 0; run < 2; ++run) {
    const std::string label = c.stage_id + " run " + std::to_string(run + 1) + " (" +
                              std::to_string(threads[run]) + " threads)";
    outputs[run] = scratch / ("output" + std::to_string(run + 1));
    std::error_code ec;
    fs::remove_all(outputs[run], ec);
    try {
      runtime::StageInstance instance(*stage, runtime::CheckStageParams(*stage, c.params));
      runtime::RunOptions o;
      o.workspace = scratch;
      o.output_dir = outputs[run];
      o.journal_dir = scratch / ("journal" + std::to_string(run + 1));
      fs::remove_all(o.journal_dir, ec);
      o.inputs = c.inputs;
      o.threads = threads[run];
      const runtime::RunResult result = instance.Run(o);
      if (!result.complete) r.Fail(label + ": run did not complete");
    } catch (const std::exception& e) {
      r.Fail(label + " failed: " + e.what());
      return r;
    }
  }
  Report diff = CompareFolders(outputs[0], outputs[1]);
  for (const auto& f : diff.failures) r.Fail(c.stage_id + ": not deterministic: " + f);
  for (const auto& n : diff.notes) r.Note(c.stage_id + ": " + n);
  if (r.ok() && c.scratch.empty() && !c.keep_outputs) {
    std::error_code ec;
    fs::remove_all(scratch, ec);
  } else if (!r.ok()) {
    r.Note("outputs kept in " + scratch.string());
  }
  return r;
}

runtime::RunResult RunStage(const runtime::Registry& registry, const std::string& stage_id,
                            const std::vector<std::pair<std::string, std::string>>& params,
                            const std::vector<runtime::InputArtifact>& inputs, const fs::path& output_dir,
                            int threads) {
  const runtime::StageEntry* stage = registry.Find(stage_id);
  if (!stage) throw Error("no stage " + stage_id + " in the registry");
  runtime::StageInstance instance(*stage, runtime::CheckStageParams(*stage, params));
  runtime::RunOptions run;
  run.workspace = output_dir.parent_path();
  run.output_dir = output_dir;
  run.inputs = inputs;
  run.threads = threads;
  return instance.Run(run);
}

}  // namespace locforge::testkit
