// One declaration per stage drives its YAML keys, defaults, validation and
// `locforge plugins describe` output.
//
//   struct SiftOptions {
//     int max_keypoints = 8000;   // Keypoints kept per image, best first.
//     bool root_sift = true;      // Hellinger-normalise descriptors.
//     static void Declare(locforge::ParamSchema<SiftOptions>& s) {
//       s.Add("max_keypoints", &SiftOptions::max_keypoints, "Keypoints kept per image").Min(1);
//       s.Add("root_sift", &SiftOptions::root_sift, "Hellinger-normalise descriptors");
//     }
//     bool Check(std::string* why) const;  // optional cross-field validation
//   };
//
// Defaults are read off a default-constructed Options, so the in-class
// initialisers are the single source of truth. A stage over a library holds
// the library's options struct and declares its members in place (nested
// members; angles in degrees in the graph for members in radians):
//
//   struct BAStageOptions {
//     int rounds = 6;
//     sfm::SplineBAOptions ba;  // the library's defaults are the stage's
//     static void Declare(locforge::ParamSchema<BAStageOptions>& s) {
//       s.Add("rounds", &BAStageOptions::rounds, "Outer rounds").Min(1);
//       s.Add("knot_spacing_s", &BAStageOptions::ba, &sfm::SplineBAOptions::knot_spacing_s, "...");
//       s.AddDegrees("prior_sigma_rotation_deg", &BAStageOptions::ba,
//                    &sfm::SplineBAOptions::prior_sigma_rotation_rad, "...").Min(1e-6);
//     }
//     bool Check(std::string* why) const;  // calls the library's own check
//   };
//
// A component (another stage used in-process, e.g. a registration back-end)
// chosen and parameterised in the graph is a ComponentSpec member:
//
//   locforge::ComponentSpec registration{"registration/gicp"};
//   s.Add("registration", &O::registration, "Registration back-end")
//       .Implements(LF_REGISTRATION_INTERFACE);
#ifndef LOCFORGE_PARAMS_H_
#define LOCFORGE_PARAMS_H_

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "locforge/abi.h"
#include "locforge/error.h"

namespace locforge {

// The C++ form of one LfParamSpec.
struct ParamDecl {
  std::string name;
  LfParamType type = LF_PARAM_STRING;
  uint32_t flags = 0;
  std::string default_value;  // canonical; empty + LF_PARAM_REQUIRED when required
  std::string doc;
  bool has_min = false, has_max = false;
  double min_value = 0, max_value = 0;
  std::vector<std::string> choices;
  std::string component_interface;  // LF_PARAM_COMPONENT: interface required ("" : any)

  bool required() const { return (flags & LF_PARAM_REQUIRED) != 0; }
  // The default is "": the stage derives the value (a preset's) unless one is given.
  bool derived() const { return (flags & LF_PARAM_DERIVED) != 0; }
};

// A component chosen in the graph: the stage id of an in-process component
// and the parameters given to it (canonical values, sorted by name; the
// component's defaults hold for the others). YAML:
//   registration: registration/gicp
//   registration: {stage: registration/gicp, params: {max_correspondence_distance: 1.0}}
struct ComponentSpec {
  ComponentSpec() = default;
  ComponentSpec(std::string stage_id) : stage(std::move(stage_id)) {}  // NOLINT: implicit on purpose
  std::string stage;
  std::vector<std::pair<std::string, std::string>> params;

  // The value of parameter `name`, or nullptr when not given.
  const std::string* Find(const std::string& name) const;
  // A copy with parameter `name` set to `canonical` (replaced when given).
  ComponentSpec With(const std::string& name, const std::string& canonical) const;
  bool operator==(const ComponentSpec& o) const { return stage == o.stage && params == o.params; }
};

// Canonical string of a component value (abi.h, LF_PARAM_COMPONENT).
std::string FormatComponent(const ComponentSpec& spec);
// Reads a canonical component value; false with the reason when malformed
// (no "kind/name", an entry without '=', a name given twice).
bool ParseComponent(const std::string& canonical, ComponentSpec* out, std::string* why = nullptr);

// Angles declared in degrees for members held in radians: the conversion of
// every such parameter, and the shortest degree string that reads back to
// exactly `radians` (the declared default).
inline double DegreesToRadians(double degrees) { return degrees * M_PI / 180.0; }
std::string FormatDegrees(double radians);

const char* ParamTypeName(LfParamType type);

// Canonical string forms (the ABI's wire format, also used for cache keys).
std::string FormatBool(bool v);
std::string FormatInt(int64_t v);
std::string FormatDouble(double v);
std::string JoinList(const std::vector<std::string>& items);
std::vector<std::string> SplitList(const std::string& canonical);

// Strict parsers: the whole string must be consumed. Return false on error.
bool ParseBool(const std::string& s, bool* v);
bool ParseInt(const std::string& s, int64_t* v);
bool ParseDouble(const std::string& s, double* v);

// Checks a canonical value against its declaration (type, range, choices).
// Returns an empty string when valid, else the reason.
std::string ValidateParamValue(const ParamDecl& decl, const std::string& canonical);

// Resolves given values against declarations: unknown names are refused (with
// a "did you mean" hint), missing ones take their default, each is validated.
// Throws ParamError naming the parameter.
std::map<std::string, std::string> ResolveParams(
    const std::vector<ParamDecl>& decls,
    const std::vector<std::pair<std::string, std::string>>& given);

// Closest candidate by edit distance, or "" when none is close.
std::string DidYouMean(const std::string& word, const std::vector<std::string>& candidates);

namespace internal {
template <typename T> struct ParamTraits;
template <> struct ParamTraits<bool> {
  static constexpr LfParamType kType = LF_PARAM_BOOL;
  static std::string Format(bool v) { return FormatBool(v); }
  static bool Parse(const std::string& s, bool* v) { return ParseBool(s, v); }
};
template <> struct ParamTraits<double> {
  static constexpr LfParamType kType = LF_PARAM_DOUBLE;
  static std::string Format(double v) { return FormatDouble(v); }
  static bool Parse(const std::string& s, double* v) { return ParseDouble(s, v); }
};
template <> struct ParamTraits<float> {
  static constexpr LfParamType kType = LF_PARAM_DOUBLE;
  static std::string Format(float v) { return FormatDouble(v); }
  static bool Parse(const std::string& s, float* v) {
    double d;
    if (!ParseDouble(s, &d)) return false;
    *v = static_cast<float>(d);
    return true;
  }
};
template <> struct ParamTraits<std::string> {
  static constexpr LfParamType kType = LF_PARAM_STRING;
  static std::string Format(const std::string& v) { return v; }
  static bool Parse(const std::string& s, std::string* v) { *v = s; return true; }
};
template <typename I>
struct IntParamTraits {
  static constexpr LfParamType kType = LF_PARAM_INT;
  static std::string Format(I v) { return FormatInt(static_cast<int64_t>(v)); }
  static bool Parse(const std::string& s, I* v) {
    int64_t x;
    if (!ParseInt(s, &x)) return false;
    // Compare as signed first: a negative x cast to uint64_t would look huge.
    if (x < static_cast<int64_t>(std::numeric_limits<I>::min()) ||
        (x > 0 && static_cast<uint64_t>(x) > static_cast<uint64_t>(std::numeric_limits<I>::max())))
      return false;
    *v = static_cast<I>(x);
    return true;
  }
};
template <> struct ParamTraits<int> : IntParamTraits<int> {};
template <> struct ParamTraits<int64_t> : IntParamTraits<int64_t> {};
template <> struct ParamTraits<uint32_t> : IntParamTraits<uint32_t> {};
template <> struct ParamTraits<uint64_t> : IntParamTraits<uint64_t> {};
template <> struct ParamTraits<ComponentSpec> {
  static constexpr LfParamType kType = LF_PARAM_COMPONENT;
  static std::string Format(const ComponentSpec& v) { return FormatComponent(v); }
  static bool Parse(const std::string& s, ComponentSpec* v) { return ParseComponent(s, v); }
};
// A double in radians read and written in degrees (ParamSchema::AddDegrees).
struct DegreeTraits {
  static constexpr LfParamType kType = LF_PARAM_DOUBLE;
  static std::string Format(double radians) { return FormatDegrees(radians); }
  static bool Parse(const std::string& s, double* radians) {
    double degrees;
    if (!ParseDouble(s, &degrees)) return false;
    *radians = DegreesToRadians(degrees);
    return true;
  }
};
template <typename E>
struct ParamTraits<std::vector<E>> {
  static constexpr LfParamType kType =
      ParamTraits<E>::kType == LF_PARAM_INT      ? LF_PARAM_INT_LIST
      : ParamTraits<E>::kType == LF_PARAM_DOUBLE ? LF_PARAM_DOUBLE_LIST
                                                 : LF_PARAM_STRING_LIST;
  static std::string Format(const std::vector<E>& v) {
    std::vector<std::string> items;
    for (const auto& e : v) items.push_back(ParamTraits<E>::Format(e));
    return JoinList(items);
  }
  static bool Parse(const std::string& s, std::vector<E>* v) {
    v->clear();
    for (const auto& item : SplitList(s)) {
      E e{};
      if (!ParamTraits<E>::Parse(item, &e)) return false;
      v->push_back(e);
    }
    return true;
  }
};

template <typename O, typename = void>
struct HasCheck : std::false_type {};
template <typename O>
struct HasCheck<O, std::void_t<decltype(std::declval<const O&>().Check(
                       static_cast<std::string*>(nullptr)))>> : std::true_type {};
}  // namespace internal

// Fluent handle on the declaration being added.
class ParamBuilder {
 public:
  explicit ParamBuilder(ParamDecl* decl) : decl_(decl) {}
  ParamBuilder& Min(double v) { decl_->has_min = true; decl_->min_value = v; return *this; }
  ParamBuilder& Max(double v) { decl_->has_max = true; decl_->max_value = v; return *this; }
  ParamBuilder& Range(double lo, double hi) { return Min(lo).Max(hi); }
  // The graph must give a value; the in-class default is ignored.
  ParamBuilder& Required() {
    decl_->flags |= LF_PARAM_REQUIRED;
    decl_->default_value.clear();
    return *this;
  }
  // A string naming a file or folder (its content stamp enters cache keys).
  // The graph checks that it exists. Unless Required(), it may be empty:
  // "none given" (an optional input file, e.g. a supplied vocabulary).
  ParamBuilder& Path() { decl_->type = LF_PARAM_PATH; return *this; }
  // A string restricted to these values.
  ParamBuilder& Choices(std::vector<std::string> choices) {
    decl_->type = LF_PARAM_ENUM;
    decl_->choices = std::move(choices);
    return *this;
  }
  // Not given, the value stays what the stage derived (the preset's, see
  // ParamSchema::AddPreset): the declared default is "" instead of the
  // in-class value, which a preset overlays.
  ParamBuilder& Derived() {
    decl_->flags |= LF_PARAM_DERIVED;
    decl_->default_value.clear();
    return *this;
  }
  // Does not change results (threads, verbosity): left out of cache keys.
  ParamBuilder& NoCacheKey() { decl_->flags |= LF_PARAM_NO_CACHE_KEY; return *this; }
  // A component parameter: the chosen stage must implement `interface`
  // (e.g. LF_REGISTRATION_INTERFACE).
  ParamBuilder& Implements(const char* interface) {
    decl_->component_interface = interface;
    return *this;
  }

 private:
  ParamDecl* decl_;
};

template <typename Options, typename M>
class ParamGroup;

template <typename Options>
class ParamSchema {
 public:
  ParamSchema() { Options::Declare(*this); }

  // A member of Options.
  template <typename T>
  ParamBuilder Add(const char* name, T Options::*field, const char* doc) {
    return AddField<internal::ParamTraits<T>, T>(
        name, doc, [field](Options& o) -> T& { return o.*field; });
  }
  // A member of a member struct of Options (e.g. the options of the library
  // the stage wraps): one declaration, the library's default.
  template <typename T, typename M>
  ParamBuilder Add(const char* name, M Options::*outer, T M::*inner, const char* doc) {
    return AddField<internal::ParamTraits<T>, T>(
        name, doc, [outer, inner](Options& o) -> T& { return (o.*outer).*inner; });
  }
  // An angle given in degrees (name it *_deg) for a member in radians.
  ParamBuilder AddDegrees(const char* name, double Options::*field, const char* doc) {
    return AddField<internal::DegreeTraits, double>(
        name, doc, [field](Options& o) -> double& { return o.*field; });
  }
  template <typename M>
  ParamBuilder AddDegrees(const char* name, M Options::*outer, double M::*inner, const char* doc) {
    return AddField<internal::DegreeTraits, double>(
        name, doc, [outer, inner](Options& o) -> double& { return (o.*outer).*inner; });
  }

  // A preset: a named overlay of values. Its value is read before every other
  // parameter and `apply(options)` writes the preset's values; parameters
  // declared Derived() keep them unless the graph gives its own.
  template <typename T, typename Apply>
  ParamBuilder AddPreset(const char* name, T Options::*field, const char* doc, Apply apply) {
    ParamBuilder b = AddField<internal::ParamTraits<T>, T>(
        name, doc, [field](Options& o) -> T& { return o.*field; });
    Entry& e = *entries_.back();
    e.preset = true;
    e.parse = [apply, parse = e.parse](Options& o, const std::string& s) {
      if (!parse(o, s)) return false;
      apply(o);
      return true;
    };
    return b;
  }

  // Every option of a member struct M, declared once by M's own
  // `template <typename Schema> static void Declare(Schema&)` (which also
  // serves ParamSchema<M>): a library's options bound in place.
  template <typename M>
  void AddGroup(M Options::*outer);

  std::vector<ParamDecl> Decls() const {
    std::vector<ParamDecl> out;
    for (const auto& e : entries_) out.push_back(e->decl);
    return out;
  }

  // Every parameter's value in `o`, in declaration order, in the canonical
  // form Parse reads (e.g. to record the options a result was made with).
  std::vector<std::pair<std::string, std::string>> Format(const Options& o) const {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& e : entries_) out.emplace_back(e->decl.name, e->format(o));
    return out;
  }

  // Resolves, validates and parses the given values into Options, then runs
  // Options::Check() when it exists. Throws ParamError with the reason.
  Options Parse(const std::vector<std::pair<std::string, std::string>>& given) const {
    const auto resolved = ResolveParams(Decls(), given);
    Options o{};
    for (const bool presets : {true, false}) {  // a preset's values first, then the rest over them
      for (const auto& e : entries_) {
        if (e->preset != presets) continue;
        const std::string& value = resolved.at(e->decl.name);
        if (value.empty() && e->decl.derived()) continue;
        if (!e->parse(o, value))
          throw ParamError("parameter '" + e->decl.name + "': cannot parse '" + value + "' as " +
                           ParamTypeName(e->decl.type));
      }
    }
    if constexpr (internal::HasCheck<Options>::value) {
      std::string why;
      if (!o.Check(&why)) throw ParamError(why.empty() ? "invalid parameters" : why);
    }
    return o;
  }

 private:
  template <typename, typename>
  friend class ParamGroup;
  struct Entry {
    ParamDecl decl;
    std::function<bool(Options&, const std::string&)> parse;
    std::function<std::string(const Options&)> format;
    bool preset = false;  // read before the others (AddPreset)
  };
  template <typename Traits, typename T, typename Access>
  ParamBuilder AddField(const char* name, const char* doc, Access access) {
    auto entry = std::make_unique<Entry>();
    entry->decl.name = name;
    entry->decl.type = Traits::kType;
    entry->decl.doc = doc;
    Options defaults{};
    entry->decl.default_value = Traits::Format(access(defaults));
    entry->parse = [access](Options& o, const std::string& s) {
      return Traits::Parse(s, &access(o));
    };
    // access() only selects the member; Format reads it.
    entry->format = [access](const Options& o) { return Traits::Format(access(const_cast<Options&>(o))); };
    entries_.push_back(std::move(entry));
    return ParamBuilder(&entries_.back()->decl);
  }
  std::vector<std::unique_ptr<Entry>> entries_;
};

// The view of a ParamSchema<Options> that M::Declare writes through: its
// Add / AddDegrees name members of M, bound as members of Options' `outer`.
template <typename Options, typename M>
class ParamGroup {
 public:
  ParamGroup(ParamSchema<Options>* schema, M Options::*outer) : schema_(schema), outer_(outer) {}
  template <typename T>
  ParamBuilder Add(const char* name, T M::*field, const char* doc) {
    return schema_->Add(name, outer_, field, doc);
  }
  ParamBuilder AddDegrees(const char* name, double M::*field, const char* doc) {
    return schema_->AddDegrees(name, outer_, field, doc);
  }
  // A member of a member struct of M (e.g. the image scale of a library's rig options).
  template <typename T, typename N>
  ParamBuilder Add(const char* name, N M::*middle, T N::*inner, const char* doc) {
    return schema_->template AddField<internal::ParamTraits<T>, T>(
        name, doc, [outer = outer_, middle, inner](Options& o) -> T& { return ((o.*outer).*middle).*inner; });
  }

 private:
  ParamSchema<Options>* schema_;
  M Options::*outer_;
};

template <typename Options>
template <typename M>
void ParamSchema<Options>::AddGroup(M Options::*outer) {
  ParamGroup<Options, M> group(this, outer);
  M::Declare(group);
}

// Options of a stage without parameters.
struct NoOptions {
  static void Declare(ParamSchema<NoOptions>&) {}
};

}  // namespace locforge

#endif  // LOCFORGE_PARAMS_H_
