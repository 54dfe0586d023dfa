// libFuzzer target: every kapture text parser on arbitrary bytes. It must
// never crash; only locforge errors may be thrown (and are caught inside).
// Built with -DLOCFORGE_BUILD_FUZZERS=ON under clang (tests/fuzz/).
#include <cstddef>
#include <cstdint>

#include "text_parsers.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  locforge::kapture::internal::RunAllTextParsers(data, size);
  return 0;
}
