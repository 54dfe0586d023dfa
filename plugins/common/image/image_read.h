// The one place stages read image files: each file is checked whole first
// (locforge/image_check.h), so a truncated or corrupt image fails its item
// instead of being processed half-decoded.
#ifndef LOCFORGE_PLUGINS_COMMON_IMAGE_IMAGE_READ_H_
#define LOCFORGE_PLUGINS_COMMON_IMAGE_IMAGE_READ_H_

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

namespace locforge::image_io {

// cv::imread(file, flags) of an intact image; an empty Mat with `why` set
// (damaged, not decodable) otherwise, for callers that name their own origin.
cv::Mat TryReadImage(const std::filesystem::path& file, int flags, std::string* why);

// Same; throws InputError naming the file and why.
cv::Mat ReadImage(const std::filesystem::path& file, int flags);

// The image of a camera record (`image`: its path in records_camera.txt) of
// the kapture at `dataset`; throws InputError naming records_camera.txt, the
// field image_path, the image, its file and why.
cv::Mat ReadCameraImage(const std::filesystem::path& dataset, const std::string& image, int flags);

}  // namespace locforge::image_io

#endif  // LOCFORGE_PLUGINS_COMMON_IMAGE_IMAGE_READ_H_
