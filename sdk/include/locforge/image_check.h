// Whether an image file decodes whole. Decoders read a truncated or corrupt
// file as far as they can and return the rest grey (libjpeg only warns on
// stderr), so a damaged image would be processed silently: stages check
// first, and `locforge kapture info --check-images` checks a whole kapture.
#ifndef LOCFORGE_IMAGE_CHECK_H_
#define LOCFORGE_IMAGE_CHECK_H_

#include <filesystem>
#include <string>

namespace locforge {

// "" when the file is intact, else why it is not, e.g. "truncated JPEG
// (libjpeg: Premature end of JPEG file)". Recognised by content: JPEG is
// entropy-decoded whole by libjpeg, every warning of lost or skipped data
// counting as damage; PNG is walked chunk by chunk (lengths, CRCs, an IEND).
// A file named .jpg/.jpeg/.png that is not of its kind, and an empty or
// unreadable file, are damaged; other formats are not checked (""). Never throws.
std::string ImageFileDamage(const std::filesystem::path& file);

}  // namespace locforge

#endif  // LOCFORGE_IMAGE_CHECK_H_
