// Errors of the SDK. Code inside a plugin throws these; the plugin adapter
// (plugin.h) turns them into an LfError status so nothing crosses the ABI.
#ifndef LOCFORGE_ERROR_H_
#define LOCFORGE_ERROR_H_

#include <cstdint>
#include <stdexcept>
#include <string>

#include "locforge/abi.h"

namespace locforge {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message, int32_t code = LF_ERROR)
      : std::runtime_error(message), code_(code) {}
  int32_t code() const { return code_; }

 private:
  int32_t code_;
};

// Bad data in a file: the message names the file, the line (1-based, 0 when
// not applicable) and the field.
class InputError : public Error {
 public:
  explicit InputError(const std::string& message) : Error(message, LF_BAD_INPUT) {}
  InputError(const std::string& file, int64_t line, const std::string& field,
             const std::string& what)
      : Error(Format(file, line, field, what), LF_BAD_INPUT) {}

  static std::string Format(const std::string& file, int64_t line, const std::string& field,
                            const std::string& what) {
    std::string s = file;
    if (line > 0) s += ":" + std::to_string(line);
    if (!field.empty()) s += ": field '" + field + "'";
    return s + ": " + what;
  }
};

// A parameter value refused by its declaration or by Options::Check().
class ParamError : public Error {
 public:
  explicit ParamError(const std::string& message) : Error(message, LF_BAD_PARAMS) {}
};

class Cancelled : public Error {
 public:
  Cancelled() : Error("cancelled", LF_CANCELLED) {}
};

}  // namespace locforge

#endif  // LOCFORGE_ERROR_H_
