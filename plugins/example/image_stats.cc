// Per-image intensity statistics: one JSON per image (written atomically, so
// a killed run resumes cleanly), then a CSV summary sorted by image path.
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "image_read.h"
#include "locforge/fs.h"
#include "kapture_text.h"
#include "locforge/plugin.h"

namespace locforge::example {

using namespace ::locforge::examples;  // the library this stage wires

struct ImageStatsOptions {
  int bins = 16;  // Histogram bins over the full intensity range.
  static void Declare(ParamSchema<ImageStatsOptions>& s) {
    s.Add("bins", &ImageStatsOptions::bins, "Histogram bins over the intensity range")
        .Range(1, 256);
  }
};

class ImageStats : public PerItemStage<ImageStatsOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"example", "image_stats",
            "Per-image intensity mean, std, min, max and histogram, plus a CSV summary",
            {{"images", "kapture.dataset", "Dataset whose camera images are measured"}},
            {{"stats", "report", "stats/<image>.json per image and stats.csv"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using PerItemStage::PerItemStage;
  std::vector<std::string> ListItems(RunContext& ctx) override;
  void ProcessItem(RunContext& ctx, const std::string& item) override;
  void Finalize(RunContext& ctx) override;

 private:
  // Records of the input dataset by image path, read once per instance.
  const ImageRecord& Record(RunContext& ctx, const std::string& image);
  void LoadRecords(RunContext& ctx);

  std::mutex mutex_;
  bool loaded_ = false;
  std::map<std::string, ImageRecord> records_;
};

namespace {

struct Stats {
  int width = 0, height = 0, channels = 0;
  double mean = 0, std = 0, min = 0, max = 0;
  std::vector<uint64_t> histogram;
};

template <typename T>
Stats Measure(const cv::Mat& image, int bins, double range) {
  Stats s;
  s.width = image.cols;
  s.height = image.rows;
  s.channels = image.channels();
  s.histogram.assign(bins, 0);
  double sum = 0, sum_sq = 0;
  s.min = range;
  s.max = 0;
  const int values_per_row = image.cols * image.channels();
  for (int y = 0; y < image.rows; ++y) {
    const T* row = image.ptr<T>(y);
    for (int i = 0; i < values_per_row; ++i) {
      const double v = row[i];
      sum += v;
      sum_sq += v * v;
      s.min = std::min(s.min, v);
      s.max = std::max(s.max, v);
      ++s.histogram[static_cast<size_t>(v * bins / range)];
    }
  }
  const double n = static_cast<double>(image.total()) * image.channels();
  s.mean = sum / n;
  s.std = std::sqrt(std::max(0.0, sum_sq / n - s.mean * s.mean));
  return s;
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string ToJson(const std::string& image, const Stats& s) {
  std::ostringstream j;
  j << "{\n  \"image\": " << JsonString(image) << ",\n"
    << "  \"width\": " << s.width << ",\n  \"height\": " << s.height << ",\n"
    << "  \"channels\": " << s.channels << ",\n"
    << "  \"mean\": " << FormatDouble(s.mean) << ",\n  \"std\": " << FormatDouble(s.std) << ",\n"
    << "  \"min\": " << FormatDouble(s.min) << ",\n  \"max\": " << FormatDouble(s.max) << ",\n"
    << "  \"histogram\": [";
  for (size_t i = 0; i < s.histogram.size(); ++i) j << (i ? ", " : "") << s.histogram[i];
  j << "]\n}\n";
  return j.str();
}

// The raw text of `"key": <value>` in our own JSON (numbers only).
std::string JsonField(const std::string& json, const std::string& key, const fs::path& file) {
  const std::string tag = "\"" + key + "\": ";
  const size_t at = json.find(tag);
  if (at == std::string::npos) throw InputError(file.string(), 0, key, "missing");
  const size_t begin = at + tag.size();
  const size_t end = json.find_first_of(",\n", begin);
  return json.substr(begin, end - begin);
}

fs::path StatsFile(const fs::path& output_dir, const std::string& image) {
  return SafeJoin(output_dir / "stats", image + ".json");
}

}  // namespace

void ImageStats::LoadRecords(RunContext& ctx) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (loaded_) return;
  const fs::path dataset = ctx.Input("images");
  const fs::path file = RecordsCameraFile(dataset);
  for (auto& r : ReadImageRecords(dataset)) {
    const auto [it, inserted] = records_.emplace(r.image_path, r);
    if (!inserted)
      throw InputError(file.string(), r.line, "image_path",
                       "image '" + r.image_path + "' is already recorded at line " +
                           std::to_string(it->second.line));
  }
  loaded_ = true;
}

const ImageRecord& ImageStats::Record(RunContext& ctx, const std::string& image) {
  LoadRecords(ctx);
  auto it = records_.find(image);
  if (it == records_.end())
    throw InputError(RecordsCameraFile(ctx.Input("images")).string(), 0, "image_path",
                     "no record of image '" + image + "'");
  return it->second;
}

std::vector<std::string> ImageStats::ListItems(RunContext& ctx) {
  LoadRecords(ctx);
  std::vector<std::string> items;
  for (const auto& [image, record] : records_) items.push_back(image);
  return items;
}

void ImageStats::ProcessItem(RunContext& ctx, const std::string& item) {
  const ImageRecord& record = Record(ctx, item);
  const fs::path dataset = ctx.Input("images");
  const std::string records_file = RecordsCameraFile(dataset).string();
  const std::string origin = records_file + ":" + std::to_string(record.line);
  const fs::path path = SafeJoin(RecordsDataDir(dataset), record.image_path, origin);
  if (!fs::is_regular_file(path))
    throw InputError(records_file, record.line, "image_path",
                     "image '" + record.image_path + "' not found at " + path.string());
  std::string why;
  const cv::Mat image = image_io::TryReadImage(path, cv::IMREAD_UNCHANGED, &why);
  if (image.empty())
    throw InputError(records_file, record.line, "image_path",
                     "unusable image '" + record.image_path + "' at " + path.string() + ": " + why);
  Stats stats;
  const int bins = options().bins;
  switch (image.depth()) {
    case CV_8U: stats = Measure<uint8_t>(image, bins, 256.0); break;
    case CV_16U: stats = Measure<uint16_t>(image, bins, 65536.0); break;
    default:
      throw InputError(records_file, record.line, "image_path",
                       "image '" + record.image_path + "' is neither 8- nor 16-bit");
  }
  WriteFileAtomic(StatsFile(ctx.output_dir(), item), ToJson(item, stats));
}

void ImageStats::Finalize(RunContext& ctx) {
  LoadRecords(ctx);
  std::ostringstream csv;
  csv << "image,width,height,channels,mean,std,min,max\n";
  for (const auto& [image, record] : records_) {  // std::map: sorted by image path
    const fs::path file = StatsFile(ctx.output_dir(), image);
    const std::string json = ReadFile(file);
    csv << image;
    for (const char* key : {"width", "height", "channels", "mean", "std", "min", "max"})
      csv << "," << JsonField(json, key, file);
    csv << "\n";
  }
  WriteFileAtomic(ctx.output_dir() / "stats.csv", csv.str());
}

LOCFORGE_REGISTER_STAGE(ImageStats)

}  // namespace locforge::example
