// Graph parsing, substitution, matrix expansion and validation, with exact
// line:column positions, against fake stages (test_stages.h).
#include "graph.h"

#include <gtest/gtest.h>

#include <fstream>

#include "locforge/fs.h"

#include "test_stages.h"
#include "workspace.h"
#include "testing.h"

namespace locforge::host {
namespace {

using testing::FakeStages;

struct Parsed {
  bool ok = false;
  Graph graph;
  Diagnostics errors;
  std::string Text() const {
    std::string s;
    for (const auto& e : errors) s += e.ToString() + "\n";
    return s;
  }
};

Parsed Parse(const std::string& text, const std::vector<Override>& sets = {},
             const fs::path& file = "/graphs/g.yaml", const fs::path& cwd = "/cwd") {
  Parsed p;
  p.ok = ParseGraph(text, file, sets, cwd, &p.graph, &p.errors);
  return p;
}

// Parses and validates every variant; returns all diagnostics as text.
std::string Check(const std::string& text, const std::vector<Override>& sets = {},
                  std::vector<ResolvedGraph>* out = nullptr,
                  const fs::path& file = "/graphs/g.yaml", const fs::path& cwd = "/cwd") {
  static FakeStages stages;
  Parsed p = Parse(text, sets, file, cwd);
  for (const auto& v : p.graph.variants) {
    ResolvedGraph r;
    if (ResolveVariant(v, stages.lookup(), &r, &p.errors) && out) out->push_back(r);
  }
  p.errors = Deduplicate(p.errors);
  return p.Text();
}

const NodeSpec& NodeOf(const Graph& g, const std::string& name, size_t variant = 0) {
  for (const auto& n : g.variants.at(variant).nodes)
    if (n.name == name) return n;
  throw std::runtime_error("no node " + name);
}

TEST(GraphParse, SubstitutesVarsInsideScalarsAndWholeLists) {
  const Parsed p = Parse(R"(locforge: 1
vars:
  n: 8
  name: run
  scales: [1, 2.5]
nodes:
  a:
    stage: source/images
    params: {count: "${n}", tag: "${name}-${n}", scales: "${scales}"}
)");
  ASSERT_TRUE(p.ok) << p.Text();
  const NodeSpec& a = NodeOf(p.graph, "a");
  EXPECT_EQ(a.params.at("count").value.scalar(), "8");
  EXPECT_EQ(a.params.at("tag").value.scalar(), "run-8");
  EXPECT_TRUE(a.params.at("scales").value.is_list);
  EXPECT_EQ(a.params.at("scales").value.items, (std::vector<std::string>{"1", "2.5"}));
  EXPECT_EQ(a.params.at("count").value_where.ToString(), "/graphs/g.yaml:9:21");
}

TEST(GraphParse, UnquotedVariablesInFlowMappings) {
  // `{count: ${count}}` is not valid YAML as such; the graph format accepts it.
  const Parsed p = Parse(
      "locforge: 1\nvars: {n: 8, s: [1, 2]}\nnodes:\n"
      "  a: {stage: source/images, params: {count: ${n}, scales: ${s}, tag: x${n}y}}\n"
      "  b: {stage: source/images, params: {count: ${nn}}}\n");
  EXPECT_FALSE(p.ok);
  const NodeSpec& a = NodeOf(p.graph, "a");
  EXPECT_EQ(a.params.at("count").value.scalar(), "8");
  EXPECT_EQ(a.params.at("scales").value.items, (std::vector<std::string>{"1", "2"}));
  EXPECT_EQ(a.params.at("tag").value.scalar(), "x8y");
  EXPECT_EQ(p.Text(),
            "/graphs/g.yaml:5:45: error: unknown variable 'nn' (did you mean 'n'?); "
            "expected one of: n, s\n");
}

TEST(GraphParse, SetOverridesVarsAndNodeParams) {
  const Parsed p = Parse(R"(locforge: 1
vars: {n: 8}
nodes:
  a: {stage: source/images, params: {count: "${n}", mode: fast}}
)",
                         {{"n", "3"}, {"a.mode", "slow"}, {"a.scales", "[4, 5]"}});
  ASSERT_TRUE(p.ok) << p.Text();
  const NodeSpec& a = NodeOf(p.graph, "a");
  EXPECT_EQ(a.params.at("count").value.scalar(), "3");
  EXPECT_EQ(a.params.at("count").base_dir, fs::path("/cwd"));  // came from --set
  EXPECT_EQ(a.params.at("mode").value.scalar(), "slow");
  EXPECT_EQ(a.params.at("mode").value_where.ToString(), "--set a.mode=slow");
  EXPECT_EQ(a.params.at("scales").value.items, (std::vector<std::string>{"4", "5"}));
}

TEST(GraphParse, MatrixExpandsToCartesianProduct) {
  const Parsed p = Parse(R"(locforge: 1
matrix:
  local: [sift, r2d2]
  global: [netvlad, apgem, densevlad]
nodes:
  a: {stage: "features/${local}", params: {g: "${global}"}}
)");
  ASSERT_TRUE(p.ok) << p.Text();
  ASSERT_EQ(p.graph.variants.size(), 6u);
  EXPECT_EQ(p.graph.variants[0].name, "local=sift,global=netvlad");
  EXPECT_EQ(p.graph.variants[5].name, "local=r2d2,global=densevlad");
  EXPECT_EQ(NodeOf(p.graph, "a", 4).stage, "features/r2d2");
  EXPECT_EQ(NodeOf(p.graph, "a", 4).params.at("g").value.scalar(), "apgem");
}

TEST(GraphParse, SetPinsAMatrixKey) {
  const Parsed p = Parse(R"(locforge: 1
matrix: {local: [sift, r2d2], global: [a, b]}
nodes:
  n: {stage: "features/${local}"}
)",
                         {{"local", "r2d2"}});
  ASSERT_TRUE(p.ok) << p.Text();
  ASSERT_EQ(p.graph.variants.size(), 2u);
  EXPECT_EQ(p.graph.variants[0].name, "local=r2d2,global=a");
}

TEST(GraphParse, SetListReplacesAMatrixKeysValues) {
  const Parsed p = Parse(R"(locforge: 1
matrix: {seed: [0, 1, 2, 3], local: [sift]}
nodes:
  n: {stage: "features/${local}", params: {s: "${seed}"}}
)",
                         {{"seed", "[7, 2]"}});
  ASSERT_TRUE(p.ok) << p.Text();
  ASSERT_EQ(p.graph.variants.size(), 2u);
  EXPECT_EQ(p.graph.variants[0].name, "seed=7,local=sift");
  EXPECT_EQ(NodeOf(p.graph, "n", 1).params.at("s").value.scalar(), "2");
  EXPECT_FALSE(Parse("locforge: 1\nmatrix: {seed: [0]}\nnodes:\n  n: {stage: a/b}\n",
                     {{"seed", "[]"}})
                   .ok);
}

TEST(GraphParse, UnknownVariableIsLocated) {
  const Parsed p = Parse(R"(locforge: 1
vars: {count: 8}
nodes:
  a:
    stage: source/images
    params: {count: "${cout}"}
)");
  EXPECT_FALSE(p.ok);
  EXPECT_EQ(p.Text(),
            "/graphs/g.yaml:6:21: error: unknown variable 'cout' (did you mean 'count'?); "
            "expected one of: count\n");
}

TEST(GraphParse, UnknownSetVariable) {
  const Parsed p = Parse("locforge: 1\nvars: {count: 8}\nnodes:\n  a: {stage: source/images}\n",
                         {{"conut", "3"}});
  EXPECT_FALSE(p.ok);
  EXPECT_NE(p.Text().find("--set conut=3: error: unknown variable 'conut' (did you mean 'count'?)"),
            std::string::npos)
      << p.Text();
}

TEST(GraphParse, DuplicateKeysAreLocated) {
  const Parsed p = Parse(R"(locforge: 1
nodes:
  a:
    stage: source/images
    params: {count: 1, count: 2}
  a:
    stage: source/images
)");
  EXPECT_FALSE(p.ok);
  EXPECT_NE(p.Text().find("g.yaml:5:24: error: duplicate key 'count'"), std::string::npos)
      << p.Text();
  EXPECT_NE(p.Text().find("g.yaml:6:3: error: duplicate key 'a'"), std::string::npos) << p.Text();
}

TEST(GraphParse, SyntaxErrorAndMissingVersion) {
  Parsed p = Parse("locforge: 1\nnodes:\n  a: {stage: [x\n");
  EXPECT_FALSE(p.ok);
  EXPECT_NE(p.Text().find("g.yaml:4:1: error: YAML syntax: end of sequence flow not found"),
            std::string::npos)
      << p.Text();
  EXPECT_NE(p.Text().find("YAML syntax"), std::string::npos) << p.Text();
  p = Parse("nodes:\n  a: {stage: source/images}\n");
  EXPECT_EQ(p.Text(),
            "/graphs/g.yaml:1:1: error: missing 'locforge: 1' (the graph format version)\n");
  p = Parse("locforge: 2\nnodes:\n  a: {stage: source/images}\n");
  EXPECT_EQ(
      p.Text(),
      "/graphs/g.yaml:1:11: error: unsupported graph format version; expected 'locforge: 1'\n");
  p = Parse("locforge: 1\nnode:\n  a: {stage: source/images}\n");
  EXPECT_NE(
      p.Text().find("g.yaml:2:1: error: unknown top-level key 'node' (did you mean 'nodes'?)"),
      std::string::npos)
      << p.Text();
}

TEST(GraphCheck, ValidGraphIsOrderedTopologically) {
  std::vector<ResolvedGraph> out;
  const std::string errors = Check(R"(locforge: 1
nodes:
  match: {stage: match/pairs, inputs: {features: feats.features}}
  feats: {stage: features/sift, inputs: {images: imgs}, params: {count: 5, scales: [1, 2.0]}}
  imgs: {stage: source/images, params: {count: "0010", verbose: yes}}
)",
                                   {}, &out);
  ASSERT_EQ(errors, "");
  ASSERT_EQ(out.size(), 1u);
  const auto& nodes = out[0].nodes;
  ASSERT_EQ(nodes.size(), 3u);
  EXPECT_EQ(nodes[0].name, "imgs");
  EXPECT_EQ(nodes[1].name, "feats");
  EXPECT_EQ(nodes[2].name, "match");
  EXPECT_EQ(out[0].sinks, std::vector<std::string>{"match"});
  // Canonical values, defaults filled.
  EXPECT_EQ(nodes[0].params.at("count"), "10");
  EXPECT_EQ(nodes[0].params.at("verbose"), "true");
  EXPECT_EQ(nodes[0].params.at("mode"), "fast");
  EXPECT_EQ(nodes[1].params.at("scales"), std::string("1") + LF_LIST_SEPARATOR + "2");
  ASSERT_EQ(nodes[1].inputs.size(), 1u);
  EXPECT_EQ(nodes[1].inputs[0].node, "imgs");
  EXPECT_EQ(nodes[1].inputs[0].out_port, "images");  // the only output, implied
}

TEST(GraphCheck, UnknownStageWithHint) {
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  a: {stage: source/imags}\n"),
            "/graphs/g.yaml:3:14: error: node 'a': unknown stage 'source/imags' (did you mean "
            "'source/images'?); expected a KIND/NAME listed by `locforge plugins list`\n");
}

TEST(GraphCheck, UnknownParamWithHint) {
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  a:\n    stage: source/images\n    params: {cuont: 3}\n"),
            "/graphs/g.yaml:5:14: error: node 'a': stage 'source/images' has no parameter 'cuont' "
            "(did you mean 'count'?); expected one of: count, verbose, mode\n");
}

TEST(GraphCheck, MistypedOutOfRangeAndBadChoice) {
  const std::string e = Check(R"(locforge: 1
nodes:
  a: {stage: source/images, params: {count: many}}
  b: {stage: source/images, params: {count: 0}}
  c: {stage: source/images, params: {mode: fsat}}
  d: {stage: source/images, params: {count: [1, 2]}}
)");
  EXPECT_NE(
      e.find(
          "g.yaml:3:45: error: node 'a': parameter 'count' (int): expected an integer, got 'many'"),
      std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:4:45: error: node 'b': parameter 'count' (int): value 0 is out of range "
                   "[1, +inf]"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:5:44: error: node 'c': parameter 'mode' (enum): 'fsat' is not one of "
                   "{fast, bad, slow} (did you mean 'fast'?)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:6:45: error: node 'd': parameter 'count' (int): expected a single "
                   "value, got a list"),
            std::string::npos)
      << e;
}

TEST(GraphCheck, DerivedParamLeftEmptyStaysEmptyAndAGivenOneIsChecked) {
  std::vector<ResolvedGraph> out;
  const std::string graph = "locforge: 1\nvars: {w: \"\"}\nnodes:\n  a: {stage: source/preset, params: {width: \"${w}\"}}\n";
  EXPECT_EQ(Check(graph, {}, &out), "");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].nodes[0].params.at("width"), "");  // the stage derives it
  out.clear();
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  a: {stage: source/preset}\n", {}, &out), "");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].nodes[0].params.at("width"), "");
  out.clear();
  EXPECT_EQ(Check(graph, {{"w", "2.5"}}, &out), "");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].nodes[0].params.at("width"), FormatDouble(2.5));
  const std::string e = Check(graph, {{"w", "0.5"}});
  EXPECT_NE(e.find("parameter 'width' (double): value 0.5 is out of range [1, +inf]"), std::string::npos) << e;
}

TEST(GraphCheck, PluginCheckRefusal) {
  const std::string e =
      Check("locforge: 1\nnodes:\n  a: {stage: source/images, params: {mode: bad}}\n");
  EXPECT_EQ(e,
            "/graphs/g.yaml:3:14: error: node 'a': parameters refused by stage 'source/images': "
            "source/images: mode 'bad' is refused by Check()\n");
}

TEST(GraphCheck, RequiredParamAndMissingPath) {
  const fs::path dir = locforge::testing::MakeTempDir("lf-graph");
  fs::create_directories(dir / "data");
  const fs::path graph = dir / "g.yaml";
  std::vector<ResolvedGraph> out;
  // Written in the graph: relative to the graph file's folder.
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  a: {stage: source/folder, params: {root: data}}\n", {},
                  &out, graph, "/elsewhere"),
            "");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].nodes[0].params.at("root"), (dir / "data").string());
  // From --set: relative to the current directory.
  const std::string e =
      Check("locforge: 1\nnodes:\n  a: {stage: source/folder, params: {root: data}}\n",
            {{"a.root", "data"}}, nullptr, graph, "/elsewhere");
  EXPECT_EQ(e,
            "--set a.root=data: error: node 'a': parameter 'root' (path): '/elsewhere/data' does "
            "not exist (expected an existing file or folder)\n");
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  a: {stage: source/folder}\n"),
            "/graphs/g.yaml:3:3: error: node 'a': required parameter 'root' (path, input folder) "
            "is missing\n");
  fs::remove_all(dir);
}

TEST(GraphCheck, WiresUnknownNodeUnknownPortTypeMismatchUnwired) {
  const std::string e = Check(R"(locforge: 1
nodes:
  imgs: {stage: source/images}
  f1: {stage: features/sift, inputs: {images: imgz.images}}
  f2: {stage: features/sift, inputs: {images: imgs.imagez}}
  f3: {stage: features/sift, inputs: {imags: imgs.images}}
  m1: {stage: match/pairs, inputs: {features: imgs.images}}
  m2: {stage: match/pairs}
  m3: {stage: match/pairs, inputs: {features: [f2, f3]}}
)");
  EXPECT_NE(e.find("g.yaml:4:47: error: node 'f1': input 'images' reads unknown node 'imgz' (did "
                   "you mean 'imgs'?)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:5:47: error: node 'f2': node 'imgs' (source/images) has no output "
                   "'imagez' (did you mean 'images'?)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:6:39: error: node 'f3': stage 'features/sift' has no input 'imags' (did "
                   "you mean 'images'?)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:7:47: error: node 'm1': input 'features' expects artifact type "
                   "'kapture.features' but imgs.images gives 'kapture.dataset'"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:8:3: error: node 'm2': required input 'features' (kapture.features) is "
                   "not wired"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:9:37: error: node 'm3': input 'features' takes exactly one wire"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("g.yaml:6:3: error: node 'f3': required input 'images'"), std::string::npos)
      << e;
}

TEST(GraphCheck, MultipleWiresOnAMultiplePort) {
  std::vector<ResolvedGraph> out;
  EXPECT_EQ(Check(R"(locforge: 1
nodes:
  imgs: {stage: source/images}
  a: {stage: features/sift, inputs: {images: imgs}}
  b: {stage: features/sift, inputs: {images: imgs}, params: {count: 3}}
  all: {stage: filter/features, inputs: {features: [a.features, b.features]}}
)",
                  {}, &out),
            "");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].nodes.back().inputs.size(), 2u);
}

TEST(GraphCheck, CycleIsNamed) {
  EXPECT_EQ(Check(R"(locforge: 1
nodes:
  imgs: {stage: source/images}
  a: {stage: filter/features, inputs: {features: [c.features]}}
  b: {stage: filter/features, inputs: {features: [a.features]}}
  c: {stage: filter/features, inputs: {features: [b.features]}}
)"),
            "/graphs/g.yaml:4:3: error: cycle in the graph: a -> b -> c -> a (expected a graph "
            "without cycles)\n");
}

TEST(GraphCheck, ComponentIsNotANode) {
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  r: {stage: registration/icp}\n"),
            "/graphs/g.yaml:3:14: error: node 'r': stage 'registration/icp' is a component used "
            "inside other stages, not runnable as a graph node\n");
}

TEST(GraphCheck, SetOnUnknownNode) {
  EXPECT_NE(Check("locforge: 1\nnodes:\n  imgs: {stage: source/images}\n", {{"img.count", "3"}})
                .find("--set img.count=3: error: unknown node 'img' (did you mean 'imgs'?)"),
            std::string::npos);
}


TEST(GraphCheck, ComponentParamIsCheckedAgainstTheChosenStage) {
  std::vector<ResolvedGraph> out;
  EXPECT_EQ(Check(R"(locforge: 1
vars: {icp: {stage: registration/fake_icp, params: {iterations: 20}}}
nodes:
  a: {stage: slam/graph}
  b: {stage: slam/graph, params: {backend: {stage: registration/fake_icp, params: {iterations: 5, mode: slow}}}}
  c: {stage: slam/graph, params: {backend: "${icp}"}}
  d: {stage: slam/graph, params: {backend: registration/fake_icp}}
)",
                  {}, &out),
            "");
  ASSERT_EQ(out.size(), 1u);
  std::map<std::string, const ResolvedNode*> nodes;
  for (const auto& n : out[0].nodes) nodes[n.name] = &n;
  const std::string sep(1, LF_COMPONENT_SEPARATOR);
  EXPECT_EQ(nodes.at("a")->params.at("backend"), "registration/fake_icp");
  EXPECT_EQ(nodes.at("b")->params.at("backend"),
            "registration/fake_icp" + sep + "iterations=5" + sep + "mode=slow");
  EXPECT_EQ(nodes.at("c")->params.at("backend"), "registration/fake_icp" + sep + "iterations=20");
  EXPECT_EQ(nodes.at("d")->params.at("backend"), "registration/fake_icp");
  // The chosen stage, its version and all its parameter values, given or default, key the
  // node's results: a default changed without a version bump changes the key.
  EXPECT_EQ(nodes.at("a")->components.at("backend"),
            "registration/fake_icp 2.0.0 iterations=10 mode=fast");
  EXPECT_EQ(nodes.at("b")->components.at("backend"),
            "registration/fake_icp 2.0.0 iterations=5 mode=slow");
  EXPECT_NE(CacheKeyText(*nodes.at("a"), {})
                .find("component backend=registration/fake_icp 2.0.0 iterations=10 mode=fast"),
            std::string::npos);
  EXPECT_NE(CacheKey(*nodes.at("a"), {}), CacheKey(*nodes.at("b"), {}));
  EXPECT_EQ(CacheKey(*nodes.at("a"), {}), CacheKey(*nodes.at("d"), {}));
}

TEST(GraphCheck, ComponentParamErrorsAreLocated) {
  const std::string errors = Check(R"(locforge: 1
nodes:
  a: {stage: slam/graph, params: {backend: registration/fake_ipc}}
  b: {stage: slam/graph, params: {backend: {stage: registration/fake_icp, params: {iteration: 5}}}}
  c: {stage: slam/graph, params: {backend: {stage: registration/fake_icp, params: {iterations: 500}}}}
  d: {stage: slam/graph, params: {backend: registration/other}}
  e: {stage: slam/graph, params: {backend: {stage: registration/fake_icp, params: {mode: bad}}}}
  f: {stage: slam/graph, params: {backend: source/images}}
  g: {stage: slam/graph, params: {backend: {stage: registration/fake_icp, extra: 1}}}
)");
  for (const char* expected :
       {"/graphs/g.yaml:3:44: error: node 'a': parameter 'backend' (component): unknown stage "
        "'registration/fake_ipc' (did you mean 'registration/fake_icp'?); expected a component "
        "implementing locforge.registration/1: registration/fake_icp",
        "error: node 'b': parameter 'backend' (component): component 'registration/fake_icp' has "
        "no parameter 'iteration' (did you mean 'iterations'?)",
        "/graphs/g.yaml:5:96: error: node 'c' component 'registration/fake_icp': parameter "
        "'iterations' (int): value 500 is out of range [1, 100]",
        "node 'd': parameter 'backend' (component): stage 'registration/other' implements "
        "locforge.other/1, not locforge.registration/1",
        "node 'e': parameter 'backend' (component): parameters refused by component "
        "'registration/fake_icp': ",
        "node 'f': parameter 'backend' (component): stage 'source/images' is not a component",
        "/graphs/g.yaml:9:75: error: parameter 'backend': unknown key 'extra' of a component; "
        "expected stage and params"})
    EXPECT_NE(errors.find(expected), std::string::npos) << expected << "\n---\n" << errors;
}

TEST(GraphParse, ComponentFromTheCommandLine) {
  std::vector<ResolvedGraph> out;
  EXPECT_EQ(Check("locforge: 1\nnodes:\n  a: {stage: slam/graph}\n",
                  {{"a.backend", "{stage: registration/fake_icp, params: {iterations: 7}}"}}, &out),
            "");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].nodes[0].params.at("backend"),
            "registration/fake_icp" + std::string(1, LF_COMPONENT_SEPARATOR) + "iterations=7");
}

TEST(GraphParse, NodeStageFromAComponentVariable) {
  // The variable chooses the stage and its parameters; the node's own
  // params override them; --set replaces the choice.
  const std::string graph = R"(locforge: 1
vars:
  features: {stage: source/images, params: {count: 5, mode: fast}}
nodes:
  a:
    stage: "${features}"
    params: {mode: slow}
)";
  const Parsed p = Parse(graph);
  ASSERT_TRUE(p.ok) << p.Text();
  const NodeSpec& a = NodeOf(p.graph, "a");
  EXPECT_EQ(a.stage, "source/images");
  EXPECT_EQ(a.params.at("count").value.scalar(), "5");
  EXPECT_EQ(a.params.at("mode").value.scalar(), "slow");
  EXPECT_EQ(a.params.at("count").value_where.ToString(), "/graphs/g.yaml:3:52");
  const Parsed q = Parse(graph, {{"features", "{stage: features/sift, params: {scales: [1, 2]}}"}});
  ASSERT_TRUE(q.ok) << q.Text();
  const NodeSpec& b = NodeOf(q.graph, "a");
  EXPECT_EQ(b.stage, "features/sift");
  EXPECT_EQ(b.params.at("scales").value.items, (std::vector<std::string>{"1", "2"}));
  EXPECT_EQ(b.params.count("count"), 0u);
}

TEST(GraphParse, NodeStageFromAListVariableIsRefused) {
  const Parsed p = Parse("locforge: 1\nvars:\n  s: [source/images, features/sift]\nnodes:\n  a: {stage: \"${s}\"}\n");
  EXPECT_FALSE(p.ok);
  EXPECT_NE(p.Text().find("/graphs/g.yaml:5:"), std::string::npos) << p.Text();
  EXPECT_NE(p.Text().find("'stage' is a list"), std::string::npos) << p.Text();
}

TEST(GraphParse, RequiredVariableSaysHowToGiveIt) {
  const std::string graph = R"(locforge: 1
vars:
  dataset: !required "DIR: a kapture recording"
  count: 8
nodes:
  a: {stage: source/folder, params: {root: "${dataset}"}}
)";
  const std::string errors = Check(graph);
  EXPECT_NE(errors.find("/graphs/g.yaml:3:"), std::string::npos) << errors;
  EXPECT_NE(errors.find("error: variable 'dataset' is required (DIR: a kapture recording): "
                        "give it with --set dataset=DIR"),
            std::string::npos)
      << errors;
  // Given on the command line, the graph is valid (the folder must exist).
  const fs::path dir = locforge::testing::MakeTempDir("graph_required");
  EXPECT_EQ(Check(graph, {{"dataset", dir.string()}}), "");
  // Without a capitalised name first, the message says VALUE.
  EXPECT_NE(Check("locforge: 1\nvars: {x: !required the x}\nnodes:\n  a: {stage: source/images}\n")
                .find("give it with --set x=VALUE"),
            std::string::npos);
  fs::remove_all(dir);
}

// A graph including two others: names prefixed, variables set from the
// including graph (its own variables and matrix keys substituted), inputs of
// included nodes wired to nodes of the includer, --set on included nodes.
TEST(GraphParse, IncludeAddsPrefixedNodesWiredToTheIncluder) {
  const fs::path dir = locforge::testing::MakeTempDir("graph_include");
  fs::create_directories(dir / "parts");
  WriteFileAtomic(dir / "parts/features.yaml", R"(locforge: 1
vars:
  count: 4
  images: !required the dataset node
nodes:
  sift:
    stage: features/sift
    params: {count: "${count}"}
    inputs: {images: "${images}"}
  merged:
    stage: filter/features
    inputs: {features: [sift]}
)");
  WriteFileAtomic(dir / "parts/match.yaml", R"(locforge: 1
nodes:
  pairs: {stage: match/pairs}
)");
  const std::string main = R"(locforge: 1
vars: {n: 6}
matrix: {m: [1, 2]}
include:
  a:
    graph: parts/features.yaml
    prefix: a_
    vars: {count: "${n}${m}", images: src}
  b:
    graph: parts/match.yaml
    inputs: {pairs.features: a_merged, pairs.extra: a_sift}
nodes:
  src: {stage: source/images}
)";
  WriteFileAtomic(dir / "main.yaml", main);
  Graph g;
  Diagnostics errors;
  ASSERT_TRUE(LoadGraph(dir / "main.yaml", {{"a_sift.scales", "[1, 2]"}}, &g, &errors))
      << (errors.empty() ? "" : errors[0].ToString());
  ASSERT_EQ(g.variants.size(), 2u);
  std::vector<std::string> names;
  for (const auto& n : g.variants[1].nodes) names.push_back(n.name);
  EXPECT_EQ(names, (std::vector<std::string>{"src", "a_sift", "a_merged", "pairs"}));
  const NodeSpec& sift = NodeOf(g, "a_sift", 1);
  EXPECT_EQ(sift.params.at("count").value.scalar(), "62");
  EXPECT_EQ(sift.params.at("scales").value.items, (std::vector<std::string>{"1", "2"}));
  EXPECT_EQ(sift.inputs.at("images").wires.at(0).node, "src");
  EXPECT_EQ(NodeOf(g, "a_merged", 1).inputs.at("features").wires.at(0).node, "a_sift");
  const NodeSpec& pairs = NodeOf(g, "pairs", 1);
  EXPECT_EQ(pairs.inputs.at("features").wires.at(0).node, "a_merged");
  EXPECT_EQ(pairs.inputs.at("extra").wires.at(0).node, "a_sift");
  // Positions inside an included graph name its file.
  EXPECT_EQ(sift.where.file, (dir / "parts/features.yaml").lexically_normal().string());
  EXPECT_EQ(sift.where.line, 6);
  static FakeStages stages;
  ResolvedGraph resolved;
  Diagnostics check;
  EXPECT_TRUE(ResolveVariant(g.variants[0], stages.lookup(), &resolved, &check))
      << (check.empty() ? "" : check[0].ToString());

  // Mistakes name the include and what was expected.
  WriteFileAtomic(dir / "bad.yaml", R"(locforge: 1
include:
  a:
    graph: parts/features.yaml
    vars: {cont: 3}
    inputs: {sfit.images: x}
  b: {graph: parts/missing.yaml}
  c: {graph: parts/match.yaml}
  d: {graph: parts/match.yaml}
)");
  Graph bad;
  Diagnostics e;
  EXPECT_FALSE(LoadGraph(dir / "bad.yaml", {}, &bad, &e));
  std::string text;
  for (const auto& d : e) text += d.ToString() + "\n";
  for (const char* expected :
       {"bad.yaml:5:12: error: include 'a': ", "has no variable 'cont' (did you mean 'count'?)",
        "bad.yaml:3:3: error: include 'a': variable 'images' of ",
        "is required (the dataset node); set it under the include's vars",
        "bad.yaml:6:14: error: include 'a': inputs key 'sfit.images' must be NODE.PORT of a node of ",
        "(did you mean 'sift'?)", "bad.yaml:7:14: error: include 'b': graph file ",
        "bad.yaml:9:3: error: include 'd': node 'pairs' of ",
        "has the name of a node already in the graph (expected distinct names: set a prefix)"})
    EXPECT_NE(text.find(expected), std::string::npos) << expected << "\n---\n" << text;
  // A graph including itself stops.
  WriteFileAtomic(dir / "self.yaml", "locforge: 1\ninclude:\n  me: {graph: self.yaml, prefix: x}\n");
  Graph self;
  Diagnostics se;
  EXPECT_FALSE(LoadGraph(dir / "self.yaml", {}, &self, &se));
  std::string st;
  for (const auto& d : se) st += d.ToString() + "\n";
  EXPECT_NE(st.find("includes nested more than 8 deep"), std::string::npos) << st;
  fs::remove_all(dir);
}

// Each value passed to an included graph keeps the base folder of where it was
// written: a --set of one variable must not move the others' relative paths
// (it did: every value of the include then resolved against the current directory).
TEST(GraphParse, IncludedValuesResolveRelativePathsWhereEachWasWritten) {
  const fs::path dir = locforge::testing::MakeTempDir("graph_include_paths");
  fs::create_directories(dir / "configs/parts");
  WriteFileAtomic(dir / "configs/parts/inner.yaml", R"(locforge: 1
vars: {root: data, count: 1, own: own_data}
nodes:
  a: {stage: source/folder, params: {root: "${root}"}}
  b: {stage: source/folder, params: {root: "${own}"}}
  c: {stage: source/images, params: {count: "${count}"}}
)");
  const std::string outer = R"(locforge: 1
vars: {root: ../data, count: 2}
include:
  x: {graph: parts/inner.yaml, vars: {root: "${root}", count: "${count}"}}
)";
  const fs::path file = dir / "configs/outer.yaml";
  for (const std::vector<Override>& sets :
       {std::vector<Override>{}, std::vector<Override>{{"count", "3"}}}) {
    Graph g;
    Diagnostics errors;
    ASSERT_TRUE(ParseGraph(outer, file, sets, "/cwd", &g, &errors))
        << (errors.empty() ? "" : errors[0].ToString());
    const NodeSpec& a = NodeOf(g, "a", 0);
    EXPECT_EQ(a.params.at("root").base_dir, dir / "configs") << sets.size() << " --set";
    EXPECT_EQ(NodeOf(g, "b", 0).params.at("root").base_dir, dir / "configs/parts");
    EXPECT_EQ(NodeOf(g, "c", 0).params.at("count").base_dir,
              sets.empty() ? dir / "configs" : fs::path("/cwd"));
  }
  Graph g;
  Diagnostics errors;
  ASSERT_TRUE(ParseGraph(outer, file, {{"root", "mine"}}, "/cwd", &g, &errors));
  EXPECT_EQ(NodeOf(g, "a", 0).params.at("root").base_dir, fs::path("/cwd"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::host
