// Person detection with a Darknet YOLO network (analysis/person_detection):
// the input geometry its cfg asks for, the decoding of OpenCV's YOLO rows
// into boxes of the image, greedy non-maximum suppression as Darknet does it,
// the share of the image the boxes cover (area of their union), the
// per-image persons file, and the correlations of the crowdedness check.
#ifndef LOCFORGE_PLUGINS_ANALYSIS_CONTENT_DETECTION_H_
#define LOCFORGE_PLUGINS_ANALYSIS_CONTENT_DETECTION_H_

#include <opencv2/core.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace locforge::analysis {

// The [net] section of a Darknet cfg: the input size it was trained at and
// whether it letterboxes (letter_box=1: the image scaled with its aspect
// kept and padded with grey 0.5; 0, Darknet's default: plainly resized).
struct DarknetInput {
  int width = 0;
  int height = 0;
  bool letter_box = false;
};
// InputError naming the file and field when the section or a size is missing.
DarknetInput ReadDarknetInput(const std::filesystem::path& cfg);

// The network input of an 8-bit RGB image: `input` x (width, height) as the
// cfg says (resized or letterboxed), pixels / 255, 1x3xHxW float (RGB).
cv::Mat DarknetBlob(const cv::Mat& rgb, const DarknetInput& input);

// A person box in the pixels of the image (top-left corner, size), and its
// score = objectness x class probability.
struct PersonBox {
  double x = 0, y = 0, width = 0, height = 0;
  double score = 0;
};

struct DetectionOptions {
  double score_threshold = 0.25;  // Darknet's default -thresh
  double nms_iou = 0.45;          // Darknet's detector NMS: a box overlapping a better one by IoU > this goes
  int person_class = 0;           // class column of the person (0 of Yolo-Fastest body's one class)
};

// The rows of OpenCV's YOLO/region outputs (N x (5 + classes): centre x, y,
// width, height normalised to the network input, objectness, per-class
// score already multiplied by the objectness) of all output layers: boxes
// of `person_class` scoring >= score_threshold, mapped back to the image
// (undoing the letterbox when there is one), clipped to it, then
// NonMaximumSuppression. Throws std::invalid_argument on rows too short.
std::vector<PersonBox> DecodeYoloRows(const std::vector<cv::Mat>& outputs, cv::Size image, const DarknetInput& input,
                                      const DetectionOptions& options);

double BoxIou(const PersonBox& a, const PersonBox& b);

// Greedy NMS: boxes by decreasing score, each kept unless its IoU with a
// kept one is > iou. Returns the kept boxes, best first.
std::vector<PersonBox> NonMaximumSuppression(std::vector<PersonBox> boxes, double iou);

// 100 x area of the union of the boxes (clipped to the image) / image area:
// overlapping people count once. Exact (coordinate compression).
double CoveredPercent(const std::vector<PersonBox>& boxes, cv::Size image);

// The per-image persons file (persons/<image path>.txt of person_detection):
//   line 1: "<person_count> <covered_percent>"
//   then one line per box: "<x> <y> <width> <height> <score>" (pixels, best first).
struct Persons {
  std::vector<PersonBox> boxes;
  double covered_percent = 0;
};
std::string FormatPersons(const Persons& persons);
// InputError naming `file` and the line on a malformed or inconsistent file.
Persons ParsePersons(const std::string& text, const std::string& file);
std::filesystem::path PersonsFile(const std::filesystem::path& folder, const std::string& image);
Persons ReadPersons(const std::filesystem::path& folder, const std::string& image);

// Pearson's r and Spearman's rho (Pearson's r of the ranks, ties averaged) of
// paired samples; NaN with fewer than 2 pairs or a constant sample.
double PearsonCorrelation(const std::vector<double>& x, const std::vector<double>& y);
double SpearmanCorrelation(const std::vector<double>& x, const std::vector<double>& y);

}  // namespace locforge::analysis

#endif  // LOCFORGE_PLUGINS_ANALYSIS_CONTENT_DETECTION_H_
