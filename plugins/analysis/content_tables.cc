// analysis/content_tables: the paper's Tables 5 and 6 (recall of low-frequency
// vs other queries, crowded vs other) for any number of methods, and the
// best/worst figure (the 5 best and 5 worst queries of each method with both
// content scores).
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <map>
#include <sstream>

#include "image_content.h"
#include "image_read.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::analysis {

namespace {

namespace kp = locforge::kapture;
using evaluation::Table;

struct ContentTablesOptions {
  std::vector<double> positions_m = {0.1, 0.25, 1.0};  // Position thresholds (<=), the paper's.
  std::vector<double> angles_deg = {1.0, 2.0, 5.0};    // Angle thresholds (<=), one per position.
  int best_worst = 5;          // Queries per row of the best/worst figure.
  int thumbnail_width = 240;   // Pixels per thumbnail of the figure.

  static void Declare(ParamSchema<ContentTablesOptions>& s) {
    using O = ContentTablesOptions;
    s.Add("positions_m", &O::positions_m, "position thresholds in metres (<=)");
    s.Add("angles_deg", &O::angles_deg, "angle thresholds in degrees (<=), one per position");
    s.Add("best_worst", &O::best_worst, "queries in each row (best, worst) of the figure; 0: no figure").Range(0, 50);
    s.Add("thumbnail_width", &O::thumbnail_width, "width of each thumbnail of the figure (px)").Range(64, 2048);
  }
  bool Check(std::string* why) const {
    if (positions_m.empty() || positions_m.size() != angles_deg.size())
      return *why = "positions_m and angles_deg need the same, non-zero length", false;
    return true;
  }
};

std::string Slug(const std::string& s) {
  std::string out;
  for (char c : s) out += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return out.empty() ? "method" : out;
}

// One thumbnail: the image scaled to `width`, framed (green: best, red:
// worst), its errors and both content scores written under it; a score
// beyond its threshold is drawn in orange (low-frequency, crowded).
cv::Mat Thumbnail(const cv::Mat& image, int width, bool best, const evaluation::QueryError& e, const ImageContent& c) {
  cv::Mat scaled;
  const double f = static_cast<double>(width) / image.cols;
  cv::resize(image, scaled, cv::Size(width, std::max(1, static_cast<int>(image.rows * f + 0.5))), 0, 0, cv::INTER_AREA);
  const int text_h = 54, border = 4;
  cv::Mat tile(scaled.rows + text_h + 2 * border, width + 2 * border, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar frame = best ? cv::Scalar(60, 170, 60) : cv::Scalar(50, 50, 220);
  tile(cv::Rect(0, 0, tile.cols, scaled.rows + 2 * border)).setTo(frame);
  scaled.copyTo(tile(cv::Rect(border, border, scaled.cols, scaled.rows)));
  const cv::Scalar black(20, 20, 20), orange(0, 130, 240);
  auto text = [&](const std::string& s, int line, const cv::Scalar& colour) {
    cv::putText(tile, s, cv::Point(border + 2, scaled.rows + 2 * border + 15 + 17 * line), cv::FONT_HERSHEY_SIMPLEX,
                0.42, colour, 1, cv::LINE_AA);
  };
  std::ostringstream err;
  err.precision(3);
  if (e.localized)
    err << e.position_m << " m, " << e.rotation_deg << " deg";
  else
    err << "not localized";
  text(err.str(), 0, black);
  std::ostringstream lf, crowd;
  lf.precision(3);
  lf << "low-frequency score " << c.low_frequency_score;
  text(lf.str(), 1, c.low_frequency ? orange : black);
  if (c.crowdedness_percent >= 0) {
    crowd.precision(3);
    crowd << "crowdedness " << c.crowdedness_percent << " %";
    text(crowd.str(), 2, c.crowded ? orange : black);
  }
  return tile;
}

cv::Mat Row(std::vector<cv::Mat> tiles, const std::string& label, int width) {
  int h = 0;
  for (const auto& t : tiles) h = std::max(h, t.rows);
  cv::Mat row(h + 24, std::max<int>(1, static_cast<int>(tiles.size())) * (width + 14), CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(row, label, cv::Point(4, 17), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(20, 20, 20), 1, cv::LINE_AA);
  for (size_t i = 0; i < tiles.size(); ++i)
    tiles[i].copyTo(row(cv::Rect(static_cast<int>(i) * (width + 14), 24, tiles[i].cols, tiles[i].rows)));
  return row;
}

class ContentTablesStage : public Stage<ContentTablesOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"analysis", "content_tables",
                      "The paper's Tables 5 (low-frequency vs other queries) and 6 (crowded vs other) for every "
                      "method, and the figure of each method's best and worst queries with both content scores",
                      {{"content", "report", "analysis/image_content of the queries"},
                       {"reports", "report", "eval/localization reports (per_query.csv), one per method", LF_PORT_MULTIPLE},
                       {"images", "kapture.dataset", "the query images, for the best/worst figure", LF_PORT_OPTIONAL}},
                      {{"tables", "report", "table5.{md,csv,tex}, table6.{md,csv,tex}, best_worst_<method>.png"}}};
    meta.version = "1.1.0";  // 1.1.0: a damaged image fails
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const fs::path content_file = ctx.Input("content") / "content.csv";
    const std::vector<ImageContent> content = ReadContentReport(ctx.Input("content"));
    std::map<std::string, const ImageContent*> by_image;
    for (const auto& c : content) by_image[c.image] = &c;
    std::vector<MethodErrors> methods;
    for (const fs::path& report : ctx.Inputs("reports")) methods.push_back(ReadMethodReport(report));
    std::string threshold_text;
    const std::vector<evaluation::Threshold> thresholds = MakeThresholds(o.positions_m, o.angles_deg, &threshold_text);
    const fs::path out = ctx.output_dir();
    const Table t5 = LowFrequencyTable(methods, content, thresholds);
    const std::string note = "Recall (%) at (" + threshold_text + "); unlocalized queries count as failures.\n\n";
    WriteFileAtomic(out / "table5.md", "# Table 5: low-frequency queries vs the others\n\n" + note + evaluation::ToMarkdown(t5));
    WriteFileAtomic(out / "table5.csv", evaluation::ToCsv(t5));
    WriteFileAtomic(out / "table5.tex", evaluation::ToLatex(t5));
    ctx.Info(evaluation::ToMarkdown(t5));
    const bool have_crowd =
        std::all_of(content.begin(), content.end(), [](const ImageContent& c) { return c.crowdedness_percent >= 0; });
    if (have_crowd) {
      const Table t6 = CrowdednessTable(methods, content, thresholds);
      WriteFileAtomic(out / "table6.md", "# Table 6: crowded queries vs the others\n\n" + note + evaluation::ToMarkdown(t6));
      WriteFileAtomic(out / "table6.csv", evaluation::ToCsv(t6));
      WriteFileAtomic(out / "table6.tex", evaluation::ToLatex(t6));
      ctx.Info(evaluation::ToMarkdown(t6));
    } else {
      ctx.Warn("no crowdedness in " + content_file.string() + " (image_content without masks): no Table 6");
    }
    if (o.best_worst == 0 || !ctx.HasInput("images")) return;
    const kp::Kapture images(ctx.Input("images"));
    for (const auto& m : methods) {
      const auto ranked = RankedBestFirst(m.errors);
      const size_t n = std::min<size_t>(static_cast<size_t>(o.best_worst), ranked.size() / 2);
      std::vector<cv::Mat> best, worst;
      for (size_t i = 0; i < n; ++i)
        for (bool is_best : {true, false}) {
          const auto& e = is_best ? ranked[i] : ranked[ranked.size() - 1 - i];
          const cv::Mat image = image_io::ReadCameraImage(images.root(), e.image, cv::IMREAD_COLOR);
          (is_best ? best : worst).push_back(Thumbnail(image, o.thumbnail_width, is_best, e, *by_image.at(e.image)));
        }
      cv::Mat figure;
      cv::vconcat(Row(best, m.method + ": " + std::to_string(n) + " best queries", o.thumbnail_width),
                  Row(worst, m.method + ": " + std::to_string(n) + " worst queries (worst first)", o.thumbnail_width),
                  figure);
      std::vector<uchar> png;
      cv::imencode(".png", figure, png);
      WriteFileAtomic(out / ("best_worst_" + Slug(m.method) + ".png"),
                      std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
    }
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(ContentTablesStage)

}  // namespace locforge::analysis
