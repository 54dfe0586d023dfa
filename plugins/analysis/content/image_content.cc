#include "image_content.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <map>

#include "image_read.h"
#include "locforge/fs.h"
#include <stdexcept>

#include "locforge/error.h"
#include "locforge/kapture/csv.h"
#include "locforge/params.h"

namespace locforge::analysis {

using evaluation::QueryError;
using evaluation::Table;
using evaluation::Threshold;

bool LowFrequencyOptions::Check(std::string* why) const {
  if (!(cutoff_cycles_per_width > 0) || !std::isfinite(cutoff_cycles_per_width)) {
    *why = "cutoff_cycles_per_width must be > 0";
    return false;
  }
  return true;
}

double LowFrequencyScore(const cv::Mat& gray, const LowFrequencyOptions& options) {
  if (gray.empty() || gray.channels() != 1) throw std::invalid_argument("LowFrequencyScore: needs a one-channel image");
  cv::Mat image;
  gray.convertTo(image, CV_64F);
  const int w = image.cols, h = image.rows;
  cv::Mat spectrum;
  cv::dft(image, spectrum, cv::DFT_COMPLEX_OUTPUT);
  // I - lowpass(I) = highpass(I): zero the kept low frequencies (DC included)
  // and transform back. Index k of an axis of n samples is frequency
  // min(k, n - k) / n cycles per pixel; times w: cycles per image width.
  const double r2 = options.cutoff_cycles_per_width * options.cutoff_cycles_per_width;
  for (int v = 0; v < h; ++v) {
    const double fy = static_cast<double>(std::min(v, h - v)) / h * w;
    auto* row = spectrum.ptr<cv::Vec2d>(v);
    for (int u = 0; u < w; ++u) {
      const double fx = std::min(u, w - u);
      if (fx * fx + fy * fy <= r2) row[u] = cv::Vec2d(0, 0);
    }
  }
  cv::Mat high;
  cv::idft(spectrum, high, cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
  return cv::mean(cv::abs(high))[0];
}

double CrowdednessPercent(const cv::Mat& mask) {
  if (mask.empty() || mask.channels() != 1 || mask.depth() != CV_8U)
    throw std::invalid_argument("CrowdednessPercent: needs a one-channel 8-bit mask");
  return 100.0 * cv::countNonZero(mask > 127) / static_cast<double>(mask.total());
}

fs::path PersonMaskFile(const fs::path& folder, const std::string& image) {
  return SafeJoin(folder, fs::path(image).replace_extension(".png").generic_string());
}

cv::Mat ReadPersonMask(const fs::path& folder, const std::string& image, cv::Size size, const std::string& field) {
  const fs::path file = PersonMaskFile(folder, image);
  if (!fs::exists(file)) throw InputError(file.string(), 0, field, "no person mask for image " + image);
  std::string why;
  const cv::Mat mask = image_io::TryReadImage(file, cv::IMREAD_GRAYSCALE, &why);
  if (mask.empty()) throw InputError(file.string(), 0, field, "unusable mask: " + why);
  if (mask.size() != size)
    throw InputError(file.string(), 0, field, "mask size differs from the image's (" + image + ")");
  return mask;
}

std::string RecallCell(const std::vector<QueryError>& errors, const std::vector<Threshold>& thresholds) {
  if (errors.empty()) return "-";
  std::string cell;
  for (size_t i = 0; i < thresholds.size(); ++i)
    cell += (i ? " / " : "") + evaluation::Percent(evaluation::Recall(errors, thresholds[i]));
  return cell;
}

namespace {

// Splits each method's errors in two by a predicate on the query's content.
template <class Predicate>
Table SplitTable(const std::vector<MethodErrors>& methods, const std::vector<ImageContent>& content,
                 const std::vector<Threshold>& thresholds, const std::string& yes, const std::string& no,
                 Predicate in_subset) {
  std::map<std::string, const ImageContent*> by_image;
  for (const auto& c : content) by_image[c.image] = &c;
  Table table;
  size_t yes_count = 0, no_count = 0;
  for (const auto& m : methods) {
    std::vector<QueryError> a, b;
    for (const auto& e : m.errors) {
      const auto it = by_image.find(e.image);
      if (it == by_image.end())
        throw InputError("method '" + m.method + "': query " + e.image +
                         " has no image-content row (were both computed on the same queries?)");
      (in_subset(*it->second) ? a : b).push_back(e);
    }
    if (table.rows.empty()) yes_count = a.size(), no_count = b.size();
    table.rows.push_back({m.method, RecallCell(a, thresholds), RecallCell(b, thresholds), RecallCell(m.errors, thresholds)});
  }
  table.header = {"method", yes + " (n=" + std::to_string(yes_count) + ")", no + " (n=" + std::to_string(no_count) + ")",
                  "all"};
  return table;
}

}  // namespace

ImageContent Classify(std::string image, double low_frequency_score, double crowdedness_percent,
                      const ContentThresholds& t) {
  ImageContent c;
  c.image = std::move(image);
  c.low_frequency_score = low_frequency_score;
  c.crowdedness_percent = crowdedness_percent;
  c.low_frequency = low_frequency_score < t.low_frequency_below;
  c.crowded = crowdedness_percent >= 0 && crowdedness_percent >= t.crowded_at_least;
  return c;
}

Table LowFrequencyTable(const std::vector<MethodErrors>& methods, const std::vector<ImageContent>& content,
                        const std::vector<Threshold>& thresholds) {
  return SplitTable(methods, content, thresholds, "low-frequency", "other",
                    [](const ImageContent& c) { return c.low_frequency; });
}

Table CrowdednessTable(const std::vector<MethodErrors>& methods, const std::vector<ImageContent>& content,
                       const std::vector<Threshold>& thresholds) {
  for (const auto& c : content)
    if (c.crowdedness_percent < 0)
      throw InputError("image " + c.image + " has no crowdedness (image_content ran without person masks)");
  return SplitTable(methods, content, thresholds, "crowded", "other", [](const ImageContent& c) { return c.crowded; });
}

namespace {

// A 0/1 flag field ("" allowed when `may_be_empty`), as both CSV files write them.
bool ParseFlag(const std::string& text, const std::string& file, int64_t line, const std::string& field,
               bool may_be_empty = false) {
  if (text == "1") return true;
  if (text == "0" || (may_be_empty && text.empty())) return false;
  throw InputError(file, line, field, "expected 0 or 1, got '" + text + "'");
}

}  // namespace

std::vector<ImageContent> ParseContent(const Table& content, const std::string& file) {
  const std::vector<std::string> expected = {"image", "device_id", "low_frequency_score", "low_frequency",
                                             "crowdedness_percent", "crowded"};
  if (content.header != expected) throw InputError(file, 1, "header", "not an analysis/image_content content.csv");
  std::vector<ImageContent> out;
  for (size_t r = 0; r < content.rows.size(); ++r) {
    const auto& row = content.rows[r];
    const int64_t line = static_cast<int64_t>(r) + 2;
    if (row.size() != expected.size()) throw InputError(file, line, "row", "expected 6 fields");
    ImageContent c;
    c.image = row[0];
    c.low_frequency_score = kapture::ParseDouble(row[2], file, line, expected[2]);
    c.crowdedness_percent = row[4].empty() ? -1 : kapture::ParseDouble(row[4], file, line, expected[4]);
    c.low_frequency = ParseFlag(row[3], file, line, expected[3]);
    c.crowded = ParseFlag(row[5], file, line, expected[5], /*may_be_empty=*/row[4].empty());
    out.push_back(c);
  }
  return out;
}

std::vector<QueryError> ParsePerQuery(const Table& per_query, const std::string& file) {
  const std::vector<std::string> expected = {"image", "device_id", "group", "split", "localized", "position_error_m",
                                             "rotation_error_deg"};
  if (per_query.header != expected)
    throw InputError(file, 1, "header", "not an eval/localization per_query.csv (image,device_id,group,split,...)");
  std::vector<QueryError> out;
  for (size_t r = 0; r < per_query.rows.size(); ++r) {
    const auto& row = per_query.rows[r];
    const int64_t line = static_cast<int64_t>(r) + 2;
    if (row.size() != expected.size()) throw InputError(file, line, "row", "expected 7 fields");
    QueryError e;
    e.image = row[0];
    e.device = row[1];
    e.group = row[2];
    e.split = row[3];
    e.localized = ParseFlag(row[4], file, line, expected[4]);
    if (e.localized) {
      e.position_m = kapture::ParseDouble(row[5], file, line, expected[5]);
      e.rotation_deg = kapture::ParseDouble(row[6], file, line, expected[6]);
    }
    out.push_back(e);
  }
  return out;
}

std::vector<QueryError> RankedBestFirst(std::vector<QueryError> errors) {
  std::sort(errors.begin(), errors.end(), [](const QueryError& a, const QueryError& b) {
    if (a.localized != b.localized) return a.localized;
    if (a.localized) {
      if (a.position_m != b.position_m) return a.position_m < b.position_m;
      if (a.rotation_deg != b.rotation_deg) return a.rotation_deg < b.rotation_deg;
    }
    return a.image < b.image;
  });
  return errors;
}

std::vector<Threshold> MakeThresholds(const std::vector<double>& positions_m, const std::vector<double>& angles_deg,
                                      std::string* text) {
  std::vector<Threshold> out;
  text->clear();
  for (size_t i = 0; i < positions_m.size() && i < angles_deg.size(); ++i) {
    out.push_back({positions_m[i], angles_deg[i]});
    *text += (i ? ", " : "") + FormatDouble(positions_m[i]) + " m / " + FormatDouble(angles_deg[i]) + " deg";
  }
  return out;
}

std::vector<ImageContent> ReadContentReport(const std::filesystem::path& folder) {
  const fs::path file = folder / "content.csv";
  return ParseContent(evaluation::FromCsv(ReadFile(file), file.string()), file.string());
}

std::string ReadCrowdednessSource(const std::filesystem::path& folder) {
  const fs::path file = folder / kCrowdednessSourceFile;
  if (!fs::exists(file)) return "";
  std::string text = ReadFile(file);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  return text;
}

MethodErrors ReadMethodReport(const std::filesystem::path& report) {
  const fs::path per_query = report / "per_query.csv";
  MethodErrors m;
  m.method = evaluation::ReportMethod(report);
  m.errors = ParsePerQuery(evaluation::FromCsv(ReadFile(per_query), per_query.string()), per_query.string());
  return m;
}

}  // namespace locforge::analysis
