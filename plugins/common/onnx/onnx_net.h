// Shared helpers of the learned plugin: one cv::dnn::Net per thread and model
// file (cv::dnn::Net is not thread-safe), and HxWx3 float images to 1x3xHxW
// blobs.
#ifndef LOCFORGE_PLUGINS_COMMON_ONNX_ONNX_NET_H_
#define LOCFORGE_PLUGINS_COMMON_ONNX_ONNX_NET_H_

#include <chrono>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <filesystem>
#include <string>

namespace locforge::learned {

// The network of `model` (an .onnx file) for the calling thread, loaded on
// first use and again when the file changes (size or modification time).
// Throws InputError naming the file when it cannot be loaded.
cv::dnn::Net& ThreadNet(const std::string& model);

// HxWx3 CV_32FC3 -> 1x3xHxW CV_32F (channel c of the blob = channel c of the image).
cv::Mat ToBlob(const cv::Mat& image);

// Seconds since `start` (steady clock).
double SecondsSince(const std::chrono::steady_clock::time_point& start);

// The image of a records_camera.txt entry of `dataset` as 8-bit RGB;
// InputError naming it when unreadable.
cv::Mat ReadRgb(const std::filesystem::path& dataset, const std::string& image);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_COMMON_ONNX_ONNX_NET_H_
