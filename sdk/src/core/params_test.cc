#include "locforge/params.h"

#include "locforge/param_cli.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>

namespace locforge {
namespace {

using Given = std::vector<std::pair<std::string, std::string>>;

// Runs `f`, expecting a ParamError whose message contains every fragment.
template <typename F>
void ExpectParamError(F&& f, const std::vector<std::string>& fragments) {
  try {
    f();
    ADD_FAILURE() << "no ParamError thrown";
  } catch (const ParamError& e) {
    EXPECT_EQ(e.code(), LF_BAD_PARAMS);
    for (const auto& fragment : fragments)
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
          << "'" << fragment << "' not in: " << e.what();
  }
}

// A library's options declared once, bound in place by a stage's.
struct GroupLibraryOptions {
  double reach_m = 1;
  double turn_rad = DegreesToRadians(10);
  template <typename Schema>
  static void Declare(Schema& s) {
    s.Add("reach_m", &GroupLibraryOptions::reach_m, "How far (m)").Min(0);
    s.AddDegrees("turn_deg", &GroupLibraryOptions::turn_rad, "How much it turns (deg)").Range(0, 180);
  }
};
struct GroupStageOptions {
  int rounds = 2;
  GroupLibraryOptions library;
  static void Declare(ParamSchema<GroupStageOptions>& s) {
    s.Add("rounds", &GroupStageOptions::rounds, "Rounds").Min(1);
    s.AddGroup(&GroupStageOptions::library);
  }
};

TEST(ParamSchema, GroupIsTheLibrarysOwnDeclarationBoundInPlace) {
  const auto stage = ParamSchema<GroupStageOptions>().Decls();
  const auto library = ParamSchema<GroupLibraryOptions>().Decls();
  ASSERT_EQ(stage.size(), 3u);
  EXPECT_EQ(stage[0].name, "rounds");
  for (size_t i = 0; i < library.size(); ++i) {
    EXPECT_EQ(stage[i + 1].name, library[i].name);
    EXPECT_EQ(stage[i + 1].default_value, library[i].default_value);
    EXPECT_EQ(stage[i + 1].doc, library[i].doc);
  }
  EXPECT_EQ(stage[2].default_value, "10");
  const GroupStageOptions o = ParamSchema<GroupStageOptions>().Parse({{"turn_deg", "90"}, {"reach_m", "3"}});
  EXPECT_EQ(o.rounds, 2);
  EXPECT_EQ(o.library.reach_m, 3);
  EXPECT_EQ(o.library.turn_rad, DegreesToRadians(90));
  EXPECT_EQ(ParamSchema<GroupStageOptions>().Parse({}).library.turn_rad, DegreesToRadians(10));
  ExpectParamError([] { ParamSchema<GroupStageOptions>().Parse({{"turn_deg", "200"}}); }, {"turn_deg", "180"});
}

// A library whose presets set some options: the stage binds the library's
// declaration in place and the preset is an overlay of values.
struct PresetLibraryOptions {
  struct Size {
    double width_m = 1;
  };
  int count = 1;         // a preset sets it
  Size size;             // a preset sets its width
  double speed = 0.5;    // no preset touches it
  template <typename Schema>
  static void Declare(Schema& s) {
    s.Add("count", &PresetLibraryOptions::count, "How many (default: the preset's)").Range(1, 100).Derived();
    s.Add("width_m", &PresetLibraryOptions::size, &Size::width_m, "How wide (default: the preset's)")
        .Min(0.1).Derived();
    s.Add("speed", &PresetLibraryOptions::speed, "How fast").Min(0);
  }
};
PresetLibraryOptions NamedPreset(const std::string& name) {
  PresetLibraryOptions o;
  if (name == "big") o.count = 40, o.size.width_m = 12;
  return o;
}
struct PresetStageOptions {
  std::string preset = "plain";
  PresetLibraryOptions library;
  static void Declare(ParamSchema<PresetStageOptions>& s) {
    s.AddGroup(&PresetStageOptions::library);  // declared before the preset: read after it all the same
    s.AddPreset("preset", &PresetStageOptions::preset, "Which preset",
                [](PresetStageOptions& o) { o.library = NamedPreset(o.preset); })
        .Choices({"plain", "big"});
  }
};

TEST(ParamSchema, PresetIsAnOverlayAndDerivedOptionsKeepItsValues) {
  const auto decls = ParamSchema<PresetStageOptions>().Decls();
  ASSERT_EQ(decls.size(), 4u);
  EXPECT_TRUE(decls[0].derived());
  EXPECT_EQ(decls[0].default_value, "");
  EXPECT_TRUE(decls[1].derived());
  EXPECT_FALSE(decls[2].derived());
  EXPECT_EQ(decls[2].default_value, "0.5");

  const ParamSchema<PresetStageOptions> schema;
  PresetStageOptions o = schema.Parse({{"preset", "big"}});
  EXPECT_EQ(o.library.count, 40);
  EXPECT_EQ(o.library.size.width_m, 12);
  o = schema.Parse({{"preset", "big"}, {"count", "3"}, {"speed", "2"}});
  EXPECT_EQ(o.library.count, 3);  // given: over the preset
  EXPECT_EQ(o.library.size.width_m, 12);
  EXPECT_EQ(o.library.speed, 2);
  o = schema.Parse({{"preset", "big"}, {"width_m", ""}});  // "": the preset's
  EXPECT_EQ(o.library.size.width_m, 12);
  o = schema.Parse({});
  EXPECT_EQ(o.library.count, 1);
  EXPECT_EQ(o.library.size.width_m, 1);
  // A given value is still checked against its declaration; "" only means "the preset's".
  ExpectParamError([&] { schema.Parse({{"count", "0"}}); }, {"count", "1"});
  ExpectParamError([&] { schema.Parse({{"speed", ""}}); }, {"speed"});
  EXPECT_EQ(ValidateParamValue(decls[0], ""), "");
  EXPECT_NE(ValidateParamValue(decls[2], ""), "");
}

TEST(ParseToolOptions, HelpBadOptionAndValues) {
  auto parse = [](std::vector<std::string> args, GroupStageOptions* o) {
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    return ParseToolOptions(static_cast<int>(argv.size()), argv.data(), "usage: tool\n", o);
  };
  GroupStageOptions o;
  EXPECT_EQ(parse({"tool", "--rounds", "5", "--turn-deg=45"}, &o), -1);
  EXPECT_EQ(o.rounds, 5);
  EXPECT_EQ(o.library.turn_rad, DegreesToRadians(45));
  EXPECT_EQ(parse({"tool", "--help"}, &o), 0);
  EXPECT_EQ(parse({"tool", "--rounds", "x"}, &o), 2);
  EXPECT_EQ(parse({"tool", "--round", "3"}, &o), 2);
  EXPECT_EQ(parse({"tool", "--rounds"}, &o), 2);
}

TEST(FormatDouble, ShortestRoundTrip) {
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(1.0), "1");
  EXPECT_EQ(FormatDouble(-2.5), "-2.5");
  EXPECT_EQ(FormatDouble(0.0), "0");
  EXPECT_EQ(FormatDouble(1e-7), "1e-07");
  EXPECT_EQ(FormatDouble(123456789.0), "123456789");
  EXPECT_EQ(FormatDouble(0.1 + 0.2), "0.30000000000000004");  // 17 digits needed
  EXPECT_EQ(FormatDouble(1.0 / 3.0), "0.3333333333333333");
  EXPECT_EQ(FormatDouble(std::numeric_limits<double>::infinity()), "inf");
  // Round numbers in full, not "1e+01".
  EXPECT_EQ(FormatDouble(10.0), "10");
  EXPECT_EQ(FormatDouble(-5000.0), "-5000");
  EXPECT_EQ(FormatDouble(1.5e10), "15000000000");
  EXPECT_EQ(FormatDouble(1e15), "1000000000000000");
  EXPECT_EQ(FormatDouble(1e16), "1e+16");
  EXPECT_EQ(FormatDouble(2.5e-5), "2.5e-05");

  std::mt19937_64 rng(7);
  for (int i = 0; i < 20000; ++i) {
    double x;
    const uint64_t bits = rng();
    std::memcpy(&x, &bits, sizeof(x));
    if (!std::isfinite(x)) continue;
    const std::string s = FormatDouble(x);
    double back = 0;
    ASSERT_TRUE(ParseDouble(s, &back)) << s;
    ASSERT_EQ(back, x) << s;
    // Shortest: one significant digit fewer does not read back.
    char shorter[64];
    int digits = 0;  // significant digits of the mantissa
    bool leading = true;
    for (char c : s.substr(0, s.find('e'))) {
      if (!std::isdigit(static_cast<unsigned char>(c))) continue;
      if (leading && c == '0') continue;
      leading = false;
      ++digits;
    }
    const bool whole = s.find_first_of(".e") == std::string::npos;  // trailing zeros count
    if (digits > 1 && digits <= 17 && !whole) {
      std::snprintf(shorter, sizeof(shorter), "%.*g", digits - 1, x);
      EXPECT_NE(std::strtod(shorter, nullptr), x) << s;
    }
  }
}

TEST(Lists, SplitJoinRoundTrip) {
  const std::vector<std::string> items = {"a", "", "b c", "d,e"};
  const std::string joined = JoinList(items);
  EXPECT_EQ(joined, std::string("a\x1f\x1f" "b c\x1f" "d,e"));
  EXPECT_EQ(SplitList(joined), items);
  EXPECT_TRUE(SplitList("").empty());
  EXPECT_EQ(JoinList({}), "");
  EXPECT_EQ(SplitList("x"), std::vector<std::string>{"x"});
  EXPECT_EQ(SplitList(std::string("x\x1f")), (std::vector<std::string>{"x", ""}));
}

TEST(Parse, StrictParsers) {
  int64_t i = 0;
  EXPECT_TRUE(ParseInt("-42", &i));
  EXPECT_EQ(i, -42);
  EXPECT_TRUE(ParseInt("9223372036854775807", &i));
  EXPECT_EQ(i, std::numeric_limits<int64_t>::max());
  EXPECT_FALSE(ParseInt("9223372036854775808", &i));  // overflow
  EXPECT_FALSE(ParseInt("12abc", &i));
  EXPECT_FALSE(ParseInt("1.5", &i));
  EXPECT_FALSE(ParseInt("", &i));
  EXPECT_FALSE(ParseInt(" 12", &i));
  EXPECT_FALSE(ParseInt("12 ", &i));

  double d = 0;
  EXPECT_TRUE(ParseDouble("2.5e3", &d));
  EXPECT_EQ(d, 2500);
  EXPECT_FALSE(ParseDouble("nan", &d));
  EXPECT_FALSE(ParseDouble("1e999", &d));
  EXPECT_FALSE(ParseDouble("1.0x", &d));
  EXPECT_FALSE(ParseDouble(" 1", &d));
  EXPECT_FALSE(ParseDouble("", &d));
  // A subnormal printed by FormatDouble reads back (strtod flags it ERANGE).
  const double tiny = std::numeric_limits<double>::denorm_min();
  EXPECT_TRUE(ParseDouble(FormatDouble(tiny), &d)) << FormatDouble(tiny);
  EXPECT_EQ(d, tiny);

  bool b = false;
  EXPECT_TRUE(ParseBool("true", &b));
  EXPECT_TRUE(b);
  EXPECT_TRUE(ParseBool("off", &b));
  EXPECT_FALSE(b);
  EXPECT_FALSE(ParseBool("maybe", &b));
}

std::vector<ParamDecl> SampleDecls() {
  ParamDecl threads;
  threads.name = "num_threads";
  threads.type = LF_PARAM_INT;
  threads.default_value = "4";
  threads.has_min = true;
  threads.min_value = 1;
  threads.has_max = true;
  threads.max_value = 64;
  ParamDecl ratio;
  ratio.name = "ratio";
  ratio.type = LF_PARAM_DOUBLE;
  ratio.default_value = "0.8";
  ratio.has_min = true;
  ratio.min_value = 0;
  ratio.has_max = true;
  ratio.max_value = 1;
  ParamDecl method;
  method.name = "method";
  method.type = LF_PARAM_ENUM;
  method.default_value = "gicp";
  method.choices = {"icp", "gicp", "ndt"};
  ParamDecl input;
  input.name = "input_path";
  input.type = LF_PARAM_PATH;
  input.flags = LF_PARAM_REQUIRED;
  input.doc = "the folder to read";
  ParamDecl sizes;
  sizes.name = "sizes";
  sizes.type = LF_PARAM_INT_LIST;
  sizes.default_value = JoinList({"1", "2"});
  sizes.has_min = true;
  sizes.min_value = 0;
  return {threads, ratio, method, input, sizes};
}

TEST(ResolveParams, DefaultsAndGivenValues) {
  const auto out = ResolveParams(SampleDecls(), {{"input_path", "/data"}, {"ratio", "0.5"}});
  EXPECT_EQ(out.at("num_threads"), "4");
  EXPECT_EQ(out.at("ratio"), "0.5");
  EXPECT_EQ(out.at("method"), "gicp");
  EXPECT_EQ(out.at("input_path"), "/data");
  EXPECT_EQ(out.at("sizes"), JoinList({"1", "2"}));
  EXPECT_EQ(out.size(), 5u);
}

TEST(ResolveParams, UnknownParameterWithHint) {
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"num_thread", "2"}}); },
                   {"unknown parameter 'num_thread'", "did you mean 'num_threads'"});
  // Nothing close: no hint.
  try {
    ResolveParams(SampleDecls(), {{"input_path", "x"}, {"completely_different", "2"}});
    FAIL();
  } catch (const ParamError& e) {
    EXPECT_EQ(std::string(e.what()).find("did you mean"), std::string::npos) << e.what();
  }
}

TEST(ResolveParams, OutOfRange) {
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"num_threads", "0"}}); },
                   {"num_threads", "out of range [1, 64]"});
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"ratio", "1.5"}}); },
                   {"ratio", "1.5", "[0, 1]"});
  ExpectParamError(
      [] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"sizes", JoinList({"3", "-1"})}}); },
      {"sizes", "element 1"});
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"num_threads", "two"}}); },
                   {"num_threads", "expected an integer, got 'two'"});
  // Bounds are inclusive.
  EXPECT_NO_THROW(ResolveParams(SampleDecls(), {{"input_path", "x"}, {"num_threads", "64"}}));
}

TEST(ResolveParams, Required) {
  ExpectParamError([] { ResolveParams(SampleDecls(), {}); },
                   {"'input_path' is required", "the folder to read"});
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", ""}}); },
                   {"input_path", "empty"});
}

TEST(ResolveParams, OptionalPathMayBeEmpty) {
  std::vector<ParamDecl> decls = SampleDecls();
  ParamDecl vocabulary;
  vocabulary.name = "vocabulary";
  vocabulary.type = LF_PARAM_PATH;  // optional: empty = train one instead
  decls.push_back(vocabulary);
  const auto out = ResolveParams(decls, {{"input_path", "/data"}});
  EXPECT_EQ(out.at("vocabulary"), "");
  EXPECT_EQ(ResolveParams(decls, {{"input_path", "/data"}, {"vocabulary", "/v.bin"}}).at("vocabulary"),
            "/v.bin");
}

TEST(ResolveParams, EnumChoices) {
  EXPECT_EQ(ResolveParams(SampleDecls(), {{"input_path", "x"}, {"method", "ndt"}}).at("method"),
            "ndt");
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"method", "gicpp"}}); },
                   {"'gicpp' is not one of {icp, gicp, ndt}", "did you mean 'gicp'"});
  ExpectParamError([] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"method", "GICP"}}); },
                   {"'GICP' is not one of"});
}

TEST(ResolveParams, GivenTwice) {
  ExpectParamError(
      [] { ResolveParams(SampleDecls(), {{"input_path", "x"}, {"ratio", "0.1"}, {"ratio", "0.2"}}); },
      {"'ratio' given twice"});
}

TEST(DidYouMean, ClosestByEditDistance) {
  EXPECT_EQ(DidYouMean("max_keypoint", {"max_keypoints", "min_score"}), "max_keypoints");
  EXPECT_EQ(DidYouMean("rato", {"ratio", "radius"}), "ratio");
  // A swap of two neighbouring letters counts as one edit.
  EXPECT_EQ(DidYouMean("max_keypionts", {"min_keypoints", "max_keypoints"}), "max_keypoints");
  EXPECT_EQ(DidYouMean("voxle_size", {"voxel_size", "vox_scale"}), "voxel_size");
  EXPECT_EQ(DidYouMean("voxel_size", {"max_keypoints", "min_score"}), "");
  EXPECT_EQ(DidYouMean("x", {}), "");
}

struct SampleOptions {
  int max_keypoints = 8000;          // Keypoints kept per image.
  double ratio = 0.8;                // Lowe ratio.
  bool root_sift = true;             // Hellinger-normalise.
  std::string mode = "fast";         // Speed/quality trade-off.
  std::string database;              // Required path.
  int offset = -3;                   // Negative default.
  uint32_t seed = 7;                 // Random seed.
  int64_t big = 5000000000;          // Beyond 32 bits.
  float scale = 0.25f;               // A float field.
  std::vector<double> weights = {0.5, 1.5};
  std::vector<std::string> tags = {"a", "b"};
  int min_size = 1;
  int max_size = 10;

  static void Declare(ParamSchema<SampleOptions>& s) {
    s.Add("max_keypoints", &SampleOptions::max_keypoints, "Keypoints kept per image").Min(1);
    s.Add("ratio", &SampleOptions::ratio, "Lowe ratio").Range(0, 1);
    s.Add("root_sift", &SampleOptions::root_sift, "Hellinger-normalise");
    s.Add("mode", &SampleOptions::mode, "Speed/quality trade-off").Choices({"fast", "exact"});
    s.Add("database", &SampleOptions::database, "Database file").Path().Required();
    s.Add("offset", &SampleOptions::offset, "Offset").Range(-10, 10);
    s.Add("seed", &SampleOptions::seed, "Random seed").NoCacheKey();
    s.Add("big", &SampleOptions::big, "Large count");
    s.Add("scale", &SampleOptions::scale, "Scale");
    s.Add("weights", &SampleOptions::weights, "Weights").Min(0);
    s.Add("tags", &SampleOptions::tags, "Tags");
    s.Add("min_size", &SampleOptions::min_size, "Smallest size");
    s.Add("max_size", &SampleOptions::max_size, "Largest size");
  }
  bool Check(std::string* why) const {
    if (min_size > max_size) {
      *why = "min_size (" + std::to_string(min_size) + ") must not exceed max_size (" +
             std::to_string(max_size) + ")";
      return false;
    }
    return true;
  }
};

TEST(ParamSchema, DeclsCarryInClassDefaults) {
  const ParamSchema<SampleOptions> schema;
  const auto decls = schema.Decls();
  ASSERT_EQ(decls.size(), 13u);
  std::map<std::string, ParamDecl> by_name;
  for (const auto& d : decls) by_name[d.name] = d;
  EXPECT_EQ(by_name["max_keypoints"].default_value, "8000");
  EXPECT_EQ(by_name["max_keypoints"].type, LF_PARAM_INT);
  EXPECT_TRUE(by_name["max_keypoints"].has_min);
  EXPECT_FALSE(by_name["max_keypoints"].has_max);
  EXPECT_EQ(by_name["ratio"].default_value, "0.8");
  EXPECT_EQ(by_name["ratio"].type, LF_PARAM_DOUBLE);
  EXPECT_EQ(by_name["ratio"].max_value, 1);
  EXPECT_EQ(by_name["root_sift"].default_value, "true");
  EXPECT_EQ(by_name["root_sift"].type, LF_PARAM_BOOL);
  EXPECT_EQ(by_name["mode"].type, LF_PARAM_ENUM);
  EXPECT_EQ(by_name["mode"].choices, (std::vector<std::string>{"fast", "exact"}));
  EXPECT_EQ(by_name["mode"].default_value, "fast");
  EXPECT_EQ(by_name["database"].type, LF_PARAM_PATH);
  EXPECT_TRUE(by_name["database"].required());
  EXPECT_EQ(by_name["database"].default_value, "");
  EXPECT_EQ(by_name["offset"].default_value, "-3");
  EXPECT_EQ(by_name["seed"].flags & LF_PARAM_NO_CACHE_KEY, LF_PARAM_NO_CACHE_KEY);
  EXPECT_EQ(by_name["big"].default_value, "5000000000");
  EXPECT_EQ(by_name["scale"].default_value, "0.25");
  EXPECT_EQ(by_name["weights"].type, LF_PARAM_DOUBLE_LIST);
  EXPECT_EQ(by_name["weights"].default_value, JoinList({"0.5", "1.5"}));
  EXPECT_EQ(by_name["tags"].type, LF_PARAM_STRING_LIST);
  EXPECT_EQ(by_name["max_keypoints"].doc, "Keypoints kept per image");
}

TEST(ParamSchema, ParseFillsOptions) {
  const ParamSchema<SampleOptions> schema;
  const SampleOptions defaults = schema.Parse({{"database", "db.sqlite"}});
  EXPECT_EQ(defaults.max_keypoints, 8000);
  EXPECT_EQ(defaults.offset, -3);  // negative ints parse back
  EXPECT_EQ(defaults.big, 5000000000);
  EXPECT_EQ(defaults.database, "db.sqlite");
  EXPECT_EQ(defaults.weights, (std::vector<double>{0.5, 1.5}));

  const SampleOptions o = schema.Parse({{"database", "d"},
                                        {"max_keypoints", "100"},
                                        {"ratio", "0.75"},
                                        {"root_sift", "false"},
                                        {"mode", "exact"},
                                        {"offset", "-10"},
                                        {"seed", "4294967295"},
                                        {"scale", "2"},
                                        {"weights", JoinList({"0", "3.25"})},
                                        {"tags", JoinList({"x"})}});
  EXPECT_EQ(o.max_keypoints, 100);
  EXPECT_EQ(o.ratio, 0.75);
  EXPECT_FALSE(o.root_sift);
  EXPECT_EQ(o.mode, "exact");
  EXPECT_EQ(o.offset, -10);
  EXPECT_EQ(o.seed, 4294967295u);
  EXPECT_EQ(o.scale, 2.0f);
  EXPECT_EQ(o.weights, (std::vector<double>{0, 3.25}));
  EXPECT_EQ(o.tags, (std::vector<std::string>{"x"}));
}

// Format gives every parameter in the form Parse reads: parsing it back
// gives the same options, and formatting those the same values.
TEST(ParamSchema, FormatIsWhatParseReadsBack) {
  const ParamSchema<SampleOptions> schema;
  const SampleOptions o = schema.Parse({{"database", "d"}, {"ratio", "0.1"}, {"offset", "-10"},
                                        {"scale", "2.5"}, {"weights", JoinList({"0", "3.25"})},
                                        {"tags", JoinList({"x", "y z"})}, {"mode", "exact"}});
  const auto values = schema.Format(o);
  ASSERT_EQ(values.size(), schema.Decls().size());
  std::map<std::string, std::string> by_name(values.begin(), values.end());
  EXPECT_EQ(by_name["ratio"], "0.1");
  EXPECT_EQ(by_name["offset"], "-10");
  EXPECT_EQ(by_name["mode"], "exact");
  EXPECT_EQ(by_name["database"], "d");
  const SampleOptions back = schema.Parse(values);
  EXPECT_EQ(back.ratio, o.ratio);
  EXPECT_EQ(back.weights, o.weights);
  EXPECT_EQ(back.tags, o.tags);
  EXPECT_EQ(schema.Format(back), values);
  EXPECT_NE(schema.Format(schema.Parse({{"database", "d"}, {"ratio", "0.2"}})), values);
}

TEST(ParamSchema, ParseRefusesValuesTheFieldCannotHold) {
  const ParamSchema<SampleOptions> schema;
  ExpectParamError([&] { schema.Parse({{"database", "d"}, {"seed", "-1"}}); }, {"seed", "-1"});
  ExpectParamError([&] { schema.Parse({{"database", "d"}, {"seed", "4294967296"}}); },
                   {"seed"});
  ExpectParamError([&] { schema.Parse({{"database", "d"}, {"max_keypoints", "3000000000"}}); },
                   {"max_keypoints"});
  ExpectParamError([&] { schema.Parse({{"database", "d"}, {"weights", JoinList({"1", "-2"})}}); },
                   {"weights", "element 1"});
}

TEST(ParamSchema, CheckRefusal) {
  const ParamSchema<SampleOptions> schema;
  ExpectParamError(
      [&] { schema.Parse({{"database", "d"}, {"min_size", "20"}, {"max_size", "5"}}); },
      {"min_size (20) must not exceed max_size (5)"});
  EXPECT_NO_THROW(schema.Parse({{"database", "d"}, {"min_size", "5"}, {"max_size", "5"}}));
}

TEST(ParamSchema, NoOptions) {
  const ParamSchema<NoOptions> schema;
  EXPECT_TRUE(schema.Decls().empty());
  EXPECT_NO_THROW(schema.Parse({}));
  ExpectParamError([&] { schema.Parse({{"anything", "1"}}); }, {"unknown parameter 'anything'"});
}

// A library's options struct held by a stage's options and declared in place.
struct LibraryOptions {
  double spacing_s = 0.3;
  double sigma_rad = DegreesToRadians(0.115);
  bool align = true;
};
struct NestedOptions {
  int rounds = 6;
  LibraryOptions lib;
  double turn_rad = DegreesToRadians(3.0);
  static void Declare(ParamSchema<NestedOptions>& s) {
    s.Add("rounds", &NestedOptions::rounds, "rounds").Min(1);
    s.Add("spacing_s", &NestedOptions::lib, &LibraryOptions::spacing_s, "spacing").Range(1e-3, 100);
    s.AddDegrees("sigma_deg", &NestedOptions::lib, &LibraryOptions::sigma_rad, "sigma").Min(1e-6);
    s.Add("align", &NestedOptions::lib, &LibraryOptions::align, "align");
    s.AddDegrees("turn_deg", &NestedOptions::turn_rad, "turn").Range(0, 360);
  }
  bool Check(std::string* why) const {
    if (lib.align && lib.spacing_s > 10) return *why = "align needs spacing_s <= 10", false;
    return true;
  }
};

TEST(ParamSchema, NestedMembersAndDegreesHaveOneDefault) {
  const ParamSchema<NestedOptions> schema;
  const auto decls = schema.Decls();
  ASSERT_EQ(decls.size(), 5u);
  EXPECT_EQ(decls[1].name, "spacing_s");
  EXPECT_EQ(decls[1].default_value, "0.3");
  // Degrees shown as written, though the member holds radians.
  EXPECT_EQ(decls[2].name, "sigma_deg");
  EXPECT_EQ(decls[2].type, LF_PARAM_DOUBLE);
  EXPECT_EQ(decls[2].default_value, "0.115");
  EXPECT_EQ(decls[4].default_value, "3");
  // Parsing the defaults gives back exactly the in-class values.
  const NestedOptions d = schema.Parse({});
  EXPECT_EQ(d.lib.spacing_s, 0.3);
  EXPECT_EQ(d.lib.sigma_rad, DegreesToRadians(0.115));
  EXPECT_EQ(d.turn_rad, DegreesToRadians(3.0));
  const NestedOptions o = schema.Parse({{"spacing_s", "0.1"}, {"sigma_deg", "90"}, {"align", "false"}});
  EXPECT_EQ(o.lib.spacing_s, 0.1);
  EXPECT_NEAR(o.lib.sigma_rad, M_PI / 2, 1e-15);
  EXPECT_FALSE(o.lib.align);
  EXPECT_EQ(o.rounds, 6);
  // Ranges apply to the value as written (degrees); the struct's Check sees nested members.
  ExpectParamError([&] { schema.Parse({{"turn_deg", "361"}}); }, {"turn_deg", "out of range"});
  ExpectParamError([&] { schema.Parse({{"spacing_s", "20"}}); }, {"align needs spacing_s <= 10"});
  EXPECT_NO_THROW(schema.Parse({{"spacing_s", "20"}, {"align", "false"}}));
}

TEST(FormatDegrees, ShortestDegreesThatReadBackExactly) {
  for (double deg : {0.115, 0.2, 3.0, 1.5, 0.005, 179.99, 1e-6}) {
    const double rad = DegreesToRadians(deg);
    const std::string s = FormatDegrees(rad);
    double back = 0;
    ASSERT_TRUE(ParseDouble(s, &back)) << s;
    EXPECT_EQ(DegreesToRadians(back), rad) << s;
    EXPECT_EQ(back, deg) << s;  // the value written in the code, not 0.11500000000000001
  }
  // A radian value no short decimal maps to: still reads back exactly.
  const std::string s = FormatDegrees(0.002);
  double back = 0;
  ASSERT_TRUE(ParseDouble(s, &back));
  EXPECT_EQ(DegreesToRadians(back), 0.002) << s;
}

struct ComponentOptions {
  ComponentSpec backend{"registration/gicp"};
  static void Declare(ParamSchema<ComponentOptions>& s) {
    s.Add("backend", &ComponentOptions::backend, "back-end").Implements(LF_REGISTRATION_INTERFACE);
  }
};

TEST(ParamSchema, ComponentValuesRoundTrip) {
  const ParamSchema<ComponentOptions> schema;
  const auto decls = schema.Decls();
  ASSERT_EQ(decls.size(), 1u);
  EXPECT_EQ(decls[0].type, LF_PARAM_COMPONENT);
  EXPECT_EQ(decls[0].default_value, "registration/gicp");
  EXPECT_EQ(decls[0].component_interface, LF_REGISTRATION_INTERFACE);
  const std::string sep(1, LF_COMPONENT_SEPARATOR);
  // Parameters come out sorted by name whatever the order given.
  ComponentSpec spec("registration/pcl_gicp");
  spec.params = {{"voxel_size", "0.2"}, {"max_iterations", "30"}};
  const std::string canonical = FormatComponent(spec);
  EXPECT_EQ(canonical, "registration/pcl_gicp" + sep + "max_iterations=30" + sep + "voxel_size=0.2");
  const ComponentOptions o = schema.Parse({{"backend", canonical}});
  EXPECT_EQ(o.backend.stage, "registration/pcl_gicp");
  ASSERT_EQ(o.backend.params.size(), 2u);
  EXPECT_EQ(*o.backend.Find("voxel_size"), "0.2");
  EXPECT_EQ(o.backend.Find("nope"), nullptr);
  // With(): one parameter replaced or added, the rest kept.
  const ComponentSpec refined = o.backend.With("max_correspondence_distance", "0.3").With("voxel_size", "0.1");
  EXPECT_EQ(FormatComponent(refined), "registration/pcl_gicp" + sep + "max_correspondence_distance=0.3" + sep +
                                          "max_iterations=30" + sep + "voxel_size=0.1");
  // A list value keeps its own separator inside a component value.
  ComponentSpec with_list("registration/gicp");
  with_list.params = {{"weights", JoinList({"1", "2"})}};
  ComponentSpec back;
  ASSERT_TRUE(ParseComponent(FormatComponent(with_list), &back));
  EXPECT_EQ(back, with_list);
  // The form is checked here; the parameters themselves by the host, against the component.
  ExpectParamError([&] { schema.Parse({{"backend", "gicp"}}); }, {"parameter 'backend'", "KIND/NAME"});
  ExpectParamError([&] { schema.Parse({{"backend", "registration/gicp" + sep + "voxel"}}); },
                   {"parameter 'backend'", "'voxel' is not name=value"});
  ExpectParamError([&] { schema.Parse({{"backend", "a/b" + sep + "x=1" + sep + "x=2"}}); }, {"given twice"});
  EXPECT_STREQ(ParamTypeName(LF_PARAM_COMPONENT), "component");
}

TEST(ParamTypeName, Names) {
  EXPECT_STREQ(ParamTypeName(LF_PARAM_DOUBLE_LIST), "double list");
  EXPECT_STREQ(ParamTypeName(LF_PARAM_PATH), "path");
}

}  // namespace
}  // namespace locforge
