// Units shared by every stage: one definition of the degree and one
// declaration of the kapture timestamp unit, so a stage cannot spell them its
// own way (a different doc, range or default).
#ifndef LOCFORGE_UNITS_H_
#define LOCFORGE_UNITS_H_

#include "locforge/params.h"

namespace locforge {

// One degree in radians.
inline constexpr double kDeg = 3.14159265358979323846 / 180.0;

// kapture timestamps are integers; this is the duration of one (1e-6: the
// microseconds kapture's own importers write).
inline constexpr double kDefaultSecondsPerUnit = 1e-6;
inline constexpr const char* kSecondsPerUnitDoc =
    "Duration of one kapture timestamp unit (s; 1e-6: microseconds)";

// The `seconds_per_unit` option of a stage that reads kapture timestamps
// (Schema: a ParamSchema<Options>, or a ParamGroup whose members are Options').
template <typename Schema, typename Options>
ParamBuilder AddSecondsPerUnit(Schema& s, double Options::*field) {
  return s.Add("seconds_per_unit", field, kSecondsPerUnitDoc).Range(1e-12, 1);
}

}  // namespace locforge

#endif  // LOCFORGE_UNITS_H_
