// Image-content measures of the paper's failure analysis (section 4.3,
// Tables 5 and 6) and the tables built from them:
//  * low-frequency score: mean absolute difference between an image and its
//    version without high frequencies (an ideal low-pass in the Fourier
//    domain); low when the image holds few edges or little texture. An image
//    is "low-frequency" when its score is below a threshold (paper: 20);
//  * crowdedness: percentage of pixels on people, from a person mask; an
//    image is "crowded" at >= 20 % (paper).
#ifndef LOCFORGE_PLUGINS_ANALYSIS_CONTENT_IMAGE_CONTENT_H_
#define LOCFORGE_PLUGINS_ANALYSIS_CONTENT_IMAGE_CONTENT_H_

#include <opencv2/core.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "evaluation.h"

namespace locforge::analysis {

struct LowFrequencyOptions {
  // Radius of the kept (low) frequencies, in cycles per image width (the
  // height's axis scaled to the same physical frequency). 60 is the usual
  // FFT blur-detector radius; per image width it is resolution-independent.
  double cutoff_cycles_per_width = 60;
  bool Check(std::string* why) const;
};

// Mean |I - lowpass(I)| over the pixels of a one-channel image (8-bit or
// float, grey levels 0-255). Throws std::invalid_argument on an empty or
// multi-channel image.
double LowFrequencyScore(const cv::Mat& gray, const LowFrequencyOptions& options = {});

// Percentage (0-100) of the mask's pixels > 127 (one channel, 8-bit).
double CrowdednessPercent(const cv::Mat& mask);

// The content of one query: what eval/localization's per_query.csv is joined with.
struct ContentThresholds {
  double low_frequency_below = 20;  // low-frequency image: score < this (paper: 20)
  double crowded_at_least = 20;     // crowded image: % of person pixels >= this (paper: 20)
};
struct ImageContent {
  std::string image;
  double low_frequency_score = 0;
  double crowdedness_percent = -1;  // < 0: no mask
  bool low_frequency = false;       // as classified by analysis/image_content's thresholds
  bool crowded = false;
};
// A person mask of a masks folder (the simulator's truth/masks layout, and
// analysis/person_segmentation's masks/): <folder>/<image path with .png>,
// kept inside the folder.
std::filesystem::path PersonMaskFile(const std::filesystem::path& folder, const std::string& image);

// Reads that mask as 8-bit grey; InputError naming the file and `field` when
// it is missing, cannot be decoded, or its size is not `size` (the image's).
cv::Mat ReadPersonMask(const std::filesystem::path& folder, const std::string& image, cv::Size size,
                       const std::string& field);

// Classifies a query by `thresholds` (the one place they are applied).
ImageContent Classify(std::string image, double low_frequency_score, double crowdedness_percent,
                      const ContentThresholds& thresholds);

// Tables 5 and 6 for one or several methods: each method's per-query errors
// (as eval/localization wrote them) split by content; the cells are recalls
// "a / b / c" at `thresholds`, columns "<subset> (n=N)". Every query of
// `errors` must have a content row: a missing one throws (a silent partial
// join would bias the table).
struct MethodErrors {
  std::string method;
  std::vector<evaluation::QueryError> errors;
};
evaluation::Table LowFrequencyTable(const std::vector<MethodErrors>& methods,
                                    const std::vector<ImageContent>& content,
                                    const std::vector<evaluation::Threshold>& thresholds);
evaluation::Table CrowdednessTable(const std::vector<MethodErrors>& methods,
                                   const std::vector<ImageContent>& content,
                                   const std::vector<evaluation::Threshold>& thresholds);

// The recalls of `errors` at every threshold as one cell, "a / b / c" ("-": none).
std::string RecallCell(const std::vector<evaluation::QueryError>& errors,
                       const std::vector<evaluation::Threshold>& thresholds);

// analysis/image_content's content.csv back (InputError naming file and line).
std::vector<ImageContent> ParseContent(const evaluation::Table& content, const std::string& file);

// eval/localization's per_query.csv back into errors (InputError naming the
// file and line on a malformed row).
std::vector<evaluation::QueryError> ParsePerQuery(const evaluation::Table& per_query, const std::string& file);

// Thresholds from parallel position (m) and angle (deg) lists, and their
// text "0.1 m / 1 deg, ..." for table notes.
std::vector<evaluation::Threshold> MakeThresholds(const std::vector<double>& positions_m,
                                                  const std::vector<double>& angles_deg, std::string* text);

// The same, read from an analysis/image_content output folder (content.csv)
// and an eval/localization report folder (per_query.csv + the method name).
std::vector<ImageContent> ReadContentReport(const std::filesystem::path& folder);
// analysis/image_content also names the source of its person masks (one line,
// empty without masks), so that tables built on it say what they measured.
inline constexpr const char* kCrowdednessSourceFile = "crowdedness_source.txt";
std::string ReadCrowdednessSource(const std::filesystem::path& folder);  // "": no file, or no masks
MethodErrors ReadMethodReport(const std::filesystem::path& report);

// Queries ordered best first: localized before not, then by position error,
// rotation error and name (a total order, so figures are reproducible).
std::vector<evaluation::QueryError> RankedBestFirst(std::vector<evaluation::QueryError> errors);

}  // namespace locforge::analysis

#endif  // LOCFORGE_PLUGINS_ANALYSIS_CONTENT_IMAGE_CONTENT_H_
