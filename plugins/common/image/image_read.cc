#include "image_read.h"

#include <opencv2/imgcodecs.hpp>

#include "locforge/error.h"
#include "locforge/image_check.h"
#include "locforge/kapture/kapture.h"

namespace locforge::image_io {

cv::Mat TryReadImage(const std::filesystem::path& file, int flags, std::string* why) {
  *why = ImageFileDamage(file);
  if (!why->empty()) return {};
  cv::Mat image = cv::imread(file.string(), flags);
  if (image.empty()) *why = "OpenCV cannot decode it";
  return image;
}

cv::Mat ReadImage(const std::filesystem::path& file, int flags) {
  std::string why;
  cv::Mat image = TryReadImage(file, flags, &why);
  if (image.empty()) throw InputError(file.string(), 0, "", "unusable image: " + why);
  return image;
}

cv::Mat ReadCameraImage(const std::filesystem::path& dataset, const std::string& image, int flags) {
  const std::string records = kapture::layout::RecordsFile(kapture::kSensorCamera);
  const std::filesystem::path file = kapture::Kapture(dataset).RecordDataPath(image, records);
  std::string why;
  cv::Mat out = TryReadImage(file, flags, &why);
  if (out.empty())
    throw InputError(records, 0, "image_path",
                     "unusable image '" + image + "' at " + file.string() + ": " + why);
  return out;
}

}  // namespace locforge::image_io
