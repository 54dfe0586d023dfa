// Internal: every kapture text parser run on one buffer, for the libFuzzer
// target (kapture_text_fuzz.cc) and the mutation test (robustness_test.cc).
#ifndef LOCFORGE_SDK_SRC_KAPTURE_TEXT_PARSERS_H_
#define LOCFORGE_SDK_SRC_KAPTURE_TEXT_PARSERS_H_

#include <cstddef>
#include <cstdint>

namespace locforge::kapture::internal {

// Runs each text parser (sensors, rigs, trajectories, every records kind,
// the three feature .txt kinds, points3d, observations) on `data`. A parser
// may only succeed or throw a locforge::Error; those are caught here, any
// other exception propagates (a bug the fuzzer reports). Returns how many
// parsers accepted the input.
int RunAllTextParsers(const uint8_t* data, size_t size);

}  // namespace locforge::kapture::internal

#endif  // LOCFORGE_SDK_SRC_KAPTURE_TEXT_PARSERS_H_
