// The C++ -> C adapter of plugin.h, driven through the C ABI exactly as the
// host does: metadata, parameter checks, creation, runs, and every kind of
// exception turned into a status with its message.
#include "locforge/plugin.h"

#include <gtest/gtest.h>

#include <cstddef>

#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>

#include "locforge/fs.h"
#include "testing.h"

namespace locforge {
namespace {

struct EchoOptions {
  std::string behaviour = "ok";  // What Run does: ok or one of the failures.
  int repeat = 2;                // Times the text is written.
  double scale = 1.5;            // Unused; a bounded double.
  std::string text;              // Required.
  static void Declare(ParamSchema<EchoOptions>& s) {
    s.Add("behaviour", &EchoOptions::behaviour, "What Run does")
        .Choices({"ok", "input_error", "param_error", "error", "std", "int", "cancel", "long",
                  "bad_alloc"});
    s.Add("repeat", &EchoOptions::repeat, "Times the text is written").Range(1, 10);
    s.Add("scale", &EchoOptions::scale, "A bounded double").Min(0).NoCacheKey();
    s.Add("text", &EchoOptions::text, "Text to write").Required();
  }
  bool Check(std::string* why) const {
    if (text == "forbidden") {
      *why = "text must not be 'forbidden'";
      return false;
    }
    return true;
  }
};

class Echo : public Stage<EchoOptions> {
 public:
  static StageMeta Meta() {
    return {"test",
            "echo",
            "Writes its text to echo.txt",
            {{"in", "kapture.dataset", "optional input", LF_PORT_OPTIONAL}},
            {{"out", "report", "the written text"}},
            LF_STAGE_NONDETERMINISTIC};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override {
    const std::string& b = options().behaviour;
    if (b == "input_error") throw InputError("records_camera.txt", 12, "model", "unknown model");
    if (b == "param_error") throw ParamError("parameter 'x' is wrong");
    if (b == "error") throw Error("plain failure");
    if (b == "std") throw std::runtime_error("std failure");
    if (b == "int") throw 42;
    if (b == "cancel") throw Cancelled();
    if (b == "long") throw Error(std::string(5000, 'x'));
    if (b == "bad_alloc") throw std::bad_alloc();
    ctx.Info("echoing " + options().text);
    std::string out;
    for (int i = 0; i < options().repeat; ++i) out += options().text + "\n";
    if (ctx.HasInput("in")) out += "input=" + ctx.Input("in").string() + "\n";
    WriteFileAtomic(ctx.output_dir() / "echo.txt", out);
  }
};

struct LinesOptions {
  static void Declare(ParamSchema<LinesOptions>&) {}
};

class Lines : public PerItemStage<LinesOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"test", "lines", "One file per item", {}, {{"out", "report", ""}},
            LF_STAGE_SERIAL_ITEMS};
    meta.version = "2.0.1";  // its own, not the plugin's 1.2.3
    return meta;
  }
  using PerItemStage::PerItemStage;
  std::vector<std::string> ListItems(RunContext&) override { return {"a", "b", "bad"}; }
  void ProcessItem(RunContext& ctx, const std::string& item) override {
    if (item == "bad") throw InputError("items.txt", 3, "", "bad item");
    WriteFileAtomic(ctx.output_dir() / (item + ".txt"), item);
  }
  void Finalize(RunContext& ctx) override {
    WriteFileAtomic(ctx.output_dir() / "done.txt", "done");
  }
};

int32_t Align(void*, const LfPointCloudView*, const LfPointCloudView*, const double*, int32_t,
              LfRegistrationResult* result, LfError*) {
  result->converged = 1;
  return LF_OK;
}

class Aligner : public Component<NoOptions> {
 public:
  static constexpr const char* kInterface = LF_REGISTRATION_INTERFACE;
  static StageMeta Meta() { return {"registration", "fake", "A fake aligner", {}, {}}; }
  using Component::Component;
  const void* Table() const {
    static const LfRegistrationInterface table{sizeof(LfRegistrationInterface), &Align};
    return &table;
  }
};

}  // namespace
}  // namespace locforge

LOCFORGE_PLUGIN("test_plugin", "1.2.3", "Stages for the adapter tests", locforge::Echo,
                locforge::Lines, locforge::Aligner)

namespace locforge {
namespace {

const LfPluginInfo* Plugin() { return locforge_plugin_entry(LF_ABI_VERSION); }

const LfStageInfo& StageNamed(const std::string& name) {
  const LfPluginInfo* p = Plugin();
  for (uint32_t i = 0; i < p->num_stages; ++i)
    if (name == p->stages[i].name) return p->stages[i];
  throw std::runtime_error("no stage " + name);
}

std::vector<LfParam> ToParams(const std::vector<std::pair<std::string, std::string>>& given) {
  std::vector<LfParam> out;
  for (const auto& [k, v] : given) out.push_back({k.c_str(), v.c_str()});
  return out;
}

TEST(PluginAdapter, EntryPointChecksAbi) {
  EXPECT_NE(locforge_plugin_entry(LF_ABI_VERSION), nullptr);
  EXPECT_EQ(locforge_plugin_entry(LF_ABI_VERSION + 1), nullptr);
  EXPECT_EQ(locforge_plugin_entry(0), nullptr);
  // Built once: the same static data every call.
  EXPECT_EQ(locforge_plugin_entry(LF_ABI_VERSION), locforge_plugin_entry(LF_ABI_VERSION));
}

TEST(PluginAdapter, PluginMetadata) {
  const LfPluginInfo* p = Plugin();
  EXPECT_EQ(p->abi_version, LF_ABI_VERSION);
  EXPECT_EQ(p->struct_size, sizeof(LfPluginInfo));
  EXPECT_STREQ(p->name, "test_plugin");
  EXPECT_STREQ(p->version, "1.2.3");
  EXPECT_STREQ(p->description, "Stages for the adapter tests");
  EXPECT_STREQ(p->sdk_version, LOCFORGE_VERSION_STRING);
  ASSERT_EQ(p->num_stages, 3u);
  EXPECT_STREQ(p->stages[0].kind, "test");
  EXPECT_STREQ(p->stages[0].name, "echo");
  EXPECT_STREQ(p->stages[1].name, "lines");
  EXPECT_STREQ(p->stages[2].kind, "registration");
  for (uint32_t i = 0; i < p->num_stages; ++i) {
    EXPECT_EQ(p->stages[i].struct_size, sizeof(LfStageInfo));
    EXPECT_NE(p->stages[i].check_params, nullptr);
    EXPECT_NE(p->stages[i].create, nullptr);
    EXPECT_NE(p->stages[i].destroy, nullptr);
  }
}

TEST(PluginAdapter, WholeStageMetadata) {
  const LfStageInfo& s = StageNamed("echo");
  EXPECT_STREQ(s.doc, "Writes its text to echo.txt");
  EXPECT_EQ(s.flags, LF_STAGE_RUNNABLE | LF_STAGE_NONDETERMINISTIC);
  EXPECT_NE(s.run, nullptr);
  EXPECT_EQ(s.list_items, nullptr);
  EXPECT_EQ(s.process_item, nullptr);
  EXPECT_EQ(s.component_interface, nullptr);
  EXPECT_EQ(s.component, nullptr);

  ASSERT_EQ(s.num_inputs, 1u);
  EXPECT_EQ(s.inputs[0].struct_size, sizeof(LfPortSpec));
  EXPECT_STREQ(s.inputs[0].name, "in");
  EXPECT_STREQ(s.inputs[0].artifact_type, "kapture.dataset");
  EXPECT_STREQ(s.inputs[0].doc, "optional input");
  EXPECT_EQ(s.inputs[0].flags, LF_PORT_OPTIONAL);
  ASSERT_EQ(s.num_outputs, 1u);
  EXPECT_STREQ(s.outputs[0].name, "out");
  EXPECT_STREQ(s.outputs[0].artifact_type, "report");

  ASSERT_EQ(s.num_params, 4u);
  std::map<std::string, const LfParamSpec*> by_name;
  for (uint32_t i = 0; i < s.num_params; ++i) {
    EXPECT_EQ(s.params[i].struct_size, sizeof(LfParamSpec));
    by_name[s.params[i].name] = &s.params[i];
  }
  const LfParamSpec* behaviour = by_name.at("behaviour");
  EXPECT_EQ(behaviour->type, LF_PARAM_ENUM);
  EXPECT_STREQ(behaviour->default_value, "ok");
  ASSERT_NE(behaviour->choices, nullptr);
  EXPECT_EQ(std::string(behaviour->choices).rfind("ok|input_error|param_error|", 0), 0u);
  const LfParamSpec* repeat = by_name.at("repeat");
  EXPECT_EQ(repeat->type, LF_PARAM_INT);
  EXPECT_STREQ(repeat->default_value, "2");
  EXPECT_STREQ(repeat->doc, "Times the text is written");
  EXPECT_TRUE(repeat->has_min);
  EXPECT_TRUE(repeat->has_max);
  EXPECT_EQ(repeat->min_value, 1);
  EXPECT_EQ(repeat->max_value, 10);
  EXPECT_EQ(repeat->choices, nullptr);
  const LfParamSpec* scale = by_name.at("scale");
  EXPECT_EQ(scale->type, LF_PARAM_DOUBLE);
  EXPECT_STREQ(scale->default_value, "1.5");
  EXPECT_EQ(scale->flags, LF_PARAM_NO_CACHE_KEY);
  EXPECT_FALSE(scale->has_max);
  const LfParamSpec* text = by_name.at("text");
  EXPECT_EQ(text->flags & LF_PARAM_REQUIRED, LF_PARAM_REQUIRED);
  EXPECT_EQ(text->default_value, nullptr);
}

TEST(PluginAdapter, StageVersions) {
  // A stage's own version (StageMeta::version); NULL for a stage without one.
  EXPECT_STREQ(StageNamed("lines").version, "2.0.1");
  EXPECT_EQ(StageNamed("echo").version, nullptr);
  EXPECT_GE(StageNamed("echo").struct_size, offsetof(LfStageInfo, version) + sizeof(const char*));
}

TEST(PluginAdapter, PerItemAndComponentMetadata) {
  const LfStageInfo& lines = StageNamed("lines");
  EXPECT_EQ(lines.flags, LF_STAGE_RUNNABLE | LF_STAGE_PER_ITEM | LF_STAGE_SERIAL_ITEMS);
  EXPECT_EQ(lines.run, nullptr);
  EXPECT_NE(lines.list_items, nullptr);
  EXPECT_NE(lines.process_item, nullptr);
  EXPECT_NE(lines.finalize, nullptr);
  EXPECT_EQ(lines.num_params, 0u);
  EXPECT_EQ(lines.num_inputs, 0u);

  const LfStageInfo& fake = StageNamed("fake");
  EXPECT_EQ(fake.flags & LF_STAGE_RUNNABLE, 0u);  // a component is not a graph node
  EXPECT_STREQ(fake.component_interface, LF_REGISTRATION_INTERFACE);
  ASSERT_NE(fake.component, nullptr);
  LfError err{sizeof(LfError), {}};
  void* instance = fake.create(nullptr, 0, &err);
  ASSERT_NE(instance, nullptr) << err.message;
  const auto* table = static_cast<const LfRegistrationInterface*>(fake.component(instance));
  ASSERT_NE(table, nullptr);
  EXPECT_EQ(table->struct_size, sizeof(LfRegistrationInterface));
  LfRegistrationResult result{};
  EXPECT_EQ(table->align(instance, nullptr, nullptr, nullptr, 1, &result, &err), LF_OK);
  EXPECT_EQ(result.converged, 1);
  fake.destroy(instance);
}

// check_params and create refuse bad parameters with LF_BAD_PARAMS and a message.
TEST(PluginAdapter, CheckParams) {
  const LfStageInfo& s = StageNamed("echo");
  struct Case {
    std::vector<std::pair<std::string, std::string>> given;
    int32_t status;
    std::string message_part;
  };
  const std::vector<Case> cases = {
      {{{"text", "hi"}}, LF_OK, ""},
      {{{"text", "hi"}, {"repeat", "10"}, {"scale", "0"}}, LF_OK, ""},
      {{}, LF_BAD_PARAMS, "'text' is required"},
      {{{"text", "hi"}, {"repaet", "3"}}, LF_BAD_PARAMS, "did you mean 'repeat'"},
      {{{"text", "hi"}, {"repeat", "11"}}, LF_BAD_PARAMS, "out of range [1, 10]"},
      {{{"text", "hi"}, {"repeat", "x"}}, LF_BAD_PARAMS, "expected an integer"},
      {{{"text", "hi"}, {"behaviour", "crash"}}, LF_BAD_PARAMS, "'crash' is not one of"},
      {{{"text", "forbidden"}}, LF_BAD_PARAMS, "text must not be 'forbidden'"},
  };
  for (const auto& c : cases) {
    const auto params = ToParams(c.given);
    LfError err{sizeof(LfError), {}};
    EXPECT_EQ(s.check_params(params.data(), static_cast<uint32_t>(params.size()), &err),
              c.status)
        << err.message;
    EXPECT_NE(std::string(err.message).find(c.message_part), std::string::npos)
        << "'" << c.message_part << "' not in: " << err.message;
    LfError create_err{sizeof(LfError), {}};
    void* instance = s.create(params.data(), static_cast<uint32_t>(params.size()), &create_err);
    EXPECT_EQ(instance != nullptr, c.status == LF_OK) << create_err.message;
    if (c.status != LF_OK) {
      EXPECT_STREQ(create_err.message, err.message);
    }
    if (instance) s.destroy(instance);
  }
  // A NULL value reads as an empty string, refused for an int.
  const LfParam null_value[] = {{"text", "t"}, {"repeat", nullptr}};
  LfError err{sizeof(LfError), {}};
  EXPECT_EQ(s.check_params(null_value, 2, &err), LF_BAD_PARAMS);
}

struct Host {
  std::mutex mutex;
  std::vector<std::string> logs;
  static void Log(void* host, int32_t level, const char* message) {
    auto* h = static_cast<Host*>(host);
    std::lock_guard<std::mutex> lock(h->mutex);
    h->logs.push_back(std::to_string(level) + ":" + message);
  }
  static int32_t NotCancelled(void*) { return 0; }
};

class PluginRun : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = locforge::testing::MakeTempDir("locforge-plugin-test");
    out_ = (dir_ / "out").string();
    fs::create_directories(out_);
    ctx_.struct_size = sizeof(LfRunContext);
    ctx_.workspace = ws_.c_str();
    ctx_.output_dir = out_.c_str();
    ctx_.threads = 1;
    ctx_.shard_count = 1;
    ctx_.host = &host_;
    ctx_.log = &Host::Log;
    ctx_.cancelled = &Host::NotCancelled;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  // Creates echo with `behaviour`, runs it, returns the status; fills err_.
  int32_t RunEcho(const std::string& behaviour) {
    const LfStageInfo& s = StageNamed("echo");
    const auto params = ToParams({{"text", "hello"}, {"behaviour", behaviour}});
    void* instance = s.create(params.data(), static_cast<uint32_t>(params.size()), &err_);
    EXPECT_NE(instance, nullptr) << err_.message;
    if (!instance) return -1;
    std::memset(err_.message, 0, sizeof(err_.message));
    const int32_t rc = s.run(instance, &ctx_, &err_);
    s.destroy(instance);
    return rc;
  }
  fs::path dir_;
  std::string ws_ = "/tmp";
  std::string out_;
  Host host_;
  LfRunContext ctx_{};
  LfError err_{sizeof(LfError), {}};
};

TEST_F(PluginRun, WholeStageRuns) {
  const std::string input = "/data/in";
  const LfArtifact inputs[] = {{"in", "kapture.dataset", input.c_str()}};
  ctx_.inputs = inputs;
  ctx_.num_inputs = 1;
  ASSERT_EQ(RunEcho("ok"), LF_OK) << err_.message;
  EXPECT_EQ(ReadFile(fs::path(out_) / "echo.txt"), "hello\nhello\ninput=/data/in\n");
  ASSERT_EQ(host_.logs.size(), 1u);
  EXPECT_EQ(host_.logs[0], std::to_string(LF_LOG_INFO) + ":echoing hello");
}

TEST_F(PluginRun, ExceptionsBecomeStatuses) {
  struct Case {
    std::string behaviour;
    int32_t status;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"input_error", LF_BAD_INPUT, "records_camera.txt:12: field 'model': unknown model"},
      {"param_error", LF_BAD_PARAMS, "parameter 'x' is wrong"},
      {"error", LF_ERROR, "plain failure"},
      {"std", LF_ERROR, "std failure"},
      {"bad_alloc", LF_ERROR, "std::bad_alloc"},
      {"int", LF_ERROR, "unknown exception in plugin"},
      {"cancel", LF_CANCELLED, "cancelled"},
  };
  for (const auto& c : cases) {
    EXPECT_EQ(RunEcho(c.behaviour), c.status) << c.behaviour;
    EXPECT_EQ(std::string(err_.message), c.message) << c.behaviour;
  }
  EXPECT_FALSE(fs::exists(fs::path(out_) / "echo.txt"));
}

TEST_F(PluginRun, LongMessagesAreTruncatedAndTerminated) {
  EXPECT_EQ(RunEcho("long"), LF_ERROR);
  EXPECT_EQ(std::strlen(err_.message), sizeof(err_.message) - 1);
  EXPECT_EQ(err_.message[0], 'x');
}

TEST_F(PluginRun, PerItemStage) {
  const LfStageInfo& s = StageNamed("lines");
  void* instance = s.create(nullptr, 0, &err_);
  ASSERT_NE(instance, nullptr) << err_.message;
  std::vector<std::string> items;
  auto emit = [](void* user, const char* item) {
    static_cast<std::vector<std::string>*>(user)->push_back(item);
  };
  ASSERT_EQ(s.list_items(instance, &ctx_, emit, &items, &err_), LF_OK) << err_.message;
  EXPECT_EQ(items, (std::vector<std::string>{"a", "b", "bad"}));
  EXPECT_EQ(s.process_item(instance, &ctx_, "a", &err_), LF_OK) << err_.message;
  EXPECT_EQ(s.process_item(instance, &ctx_, "b", &err_), LF_OK) << err_.message;
  EXPECT_EQ(s.process_item(instance, &ctx_, "bad", &err_), LF_BAD_INPUT);
  EXPECT_STREQ(err_.message, "items.txt:3: bad item");
  EXPECT_EQ(s.finalize(instance, &ctx_, &err_), LF_OK) << err_.message;
  EXPECT_EQ(ReadFile(fs::path(out_) / "a.txt"), "a");
  EXPECT_EQ(ReadFile(fs::path(out_) / "b.txt"), "b");
  EXPECT_EQ(ReadFile(fs::path(out_) / "done.txt"), "done");
  s.destroy(instance);
}

TEST(PluginAdapter, RunContextView) {
  const LfArtifact inputs[] = {{"images", "kapture.dataset", "/a"},
                               {"images", "kapture.dataset", "/b"},
                               {"model", "colmap.model", "/m"}};
  LfRunContext raw{};
  raw.struct_size = sizeof(raw);
  raw.workspace = "/ws";
  raw.output_dir = "/ws/out";
  raw.inputs = inputs;
  raw.num_inputs = 3;
  raw.threads = 0;      // unset -> 1
  raw.shard_count = 0;  // unset -> 1
  RunContext ctx(&raw);
  EXPECT_EQ(ctx.workspace(), fs::path("/ws"));
  EXPECT_EQ(ctx.output_dir(), fs::path("/ws/out"));
  EXPECT_EQ(ctx.threads(), 1);
  EXPECT_EQ(ctx.shard_count(), 1);
  EXPECT_EQ(ctx.Inputs("images"), (std::vector<fs::path>{"/a", "/b"}));
  EXPECT_EQ(ctx.Input("model"), fs::path("/m"));
  EXPECT_FALSE(ctx.HasInput("query"));
  EXPECT_THROW(ctx.Input("query"), Error);
  // No callbacks: logging, progress and cancellation are no-ops.
  EXPECT_NO_THROW(ctx.Info("x"));
  EXPECT_NO_THROW(ctx.Progress(1, 2));
  EXPECT_FALSE(ctx.cancelled());
  EXPECT_NO_THROW(ctx.ThrowIfCancelled());
}

}  // namespace
}  // namespace locforge
