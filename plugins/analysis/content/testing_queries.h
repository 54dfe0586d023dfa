// A query error for the analysis tests.
#ifndef LOCFORGE_PLUGINS_ANALYSIS_CONTENT_TESTING_QUERIES_H_
#define LOCFORGE_PLUGINS_ANALYSIS_CONTENT_TESTING_QUERIES_H_

#include <string>

#include "evaluation.h"

namespace locforge::analysis::testing {

inline evaluation::QueryError Q(const std::string& image, bool localized, double position_m, double rotation_deg) {
  evaluation::QueryError e;
  e.image = image;
  e.localized = localized;
  e.position_m = position_m;
  e.rotation_deg = rotation_deg;
  return e;
}

}  // namespace locforge::analysis::testing

#endif  // LOCFORGE_PLUGINS_ANALYSIS_CONTENT_TESTING_QUERIES_H_
