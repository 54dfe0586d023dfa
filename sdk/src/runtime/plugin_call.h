// Calling into plugin code safely: every call gets a fresh LfError, and an
// exception a badly written plugin lets escape is caught here, so it becomes
// an ordinary error instead of unwinding through (or terminating) the host.
#ifndef LOCFORGE_SDK_SRC_RUNTIME_PLUGIN_CALL_H_
#define LOCFORGE_SDK_SRC_RUNTIME_PLUGIN_CALL_H_

#include <cstdint>
#include <exception>
#include <string>
#include <utility>

#include "locforge/abi.h"
#include "locforge/error.h"

namespace locforge::runtime::internal {

struct CallStatus {
  int32_t code = LF_OK;
  std::string message;
  bool ok() const { return code == LF_OK; }
};

// Runs `call(LfError*) -> int32_t` and collects its status and message.
template <typename F>
CallStatus CallPlugin(F&& call) {
  LfError err{};
  err.struct_size = sizeof(LfError);
  CallStatus status;
  try {
    status.code = std::forward<F>(call)(&err);
  } catch (const std::exception& e) {
    status.code = LF_ERROR;
    status.message = std::string("plugin let a C++ exception escape through the ABI: ") + e.what();
    return status;
  } catch (...) {
    status.code = LF_ERROR;
    status.message = "plugin let an exception escape through the ABI";
    return status;
  }
  err.message[sizeof(err.message) - 1] = '\0';
  if (status.code != LF_OK) {
    status.message = err.message;
    if (status.message.empty()) status.message = "failed without a message (status " +
                                                 std::to_string(status.code) + ")";
  }
  return status;
}

// Throws the error class matching a failed status, prefixed with `where`.
[[noreturn]] inline void ThrowStatus(const std::string& where, const CallStatus& s) {
  const std::string message = where + ": " + s.message;
  switch (s.code) {
    case LF_BAD_PARAMS: throw ParamError(message);
    case LF_BAD_INPUT: throw InputError(message);
    case LF_CANCELLED: throw Cancelled();
    default: throw Error(message, s.code == LF_OK ? LF_ERROR : s.code);
  }
}

}  // namespace locforge::runtime::internal

#endif  // LOCFORGE_SDK_SRC_RUNTIME_PLUGIN_CALL_H_
