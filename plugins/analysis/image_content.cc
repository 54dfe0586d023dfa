// analysis/image_content: per query image, the paper's low-frequency score and
// its crowdedness (% of person pixels of a mask, or % of the image covered by
// person boxes of analysis/person_detection on real images), for Tables 5 and 6
// (analysis/content_tables). Per image, so it shards like feature extraction.
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <map>
#include <sstream>

#include "detection.h"
#include "image_content.h"
#include "image_read.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::analysis {

namespace {

namespace kp = locforge::kapture;

struct ImageContentOptions {
  double cutoff_cycles_per_width = LowFrequencyOptions{}.cutoff_cycles_per_width;  // Low-pass radius.
  double low_frequency_below = ContentThresholds{}.low_frequency_below;  // Low-frequency image: score < this.
  std::string masks;  // Person masks: <masks>/<image path, extension .png>, 255 on people; "": no crowdedness.
  double crowded_at_least = ContentThresholds{}.crowded_at_least;  // Crowded image: % person pixels >= this.

  static void Declare(ParamSchema<ImageContentOptions>& s) {
    using O = ImageContentOptions;
    s.Add("cutoff_cycles_per_width", &O::cutoff_cycles_per_width,
          "low-pass radius (cycles per image width): the score is the mean |image - low-passed image| in grey levels")
        .Min(1e-3);
    s.Add("low_frequency_below", &O::low_frequency_below, "an image is low-frequency when its score is below this (paper: 20)");
    s.Add("masks", &O::masks,
          "folder of person masks, <masks>/<image path with extension .png>, 255 where a person is (e.g. a "
          "simulator recording's truth/masks; checked per image when the stage runs); empty: no crowdedness");
    s.Add("crowded_at_least", &O::crowded_at_least, "an image is crowded at this % of person pixels or more (paper: 20)")
        .Range(0, 100);
  }
};

fs::path ItemFile(const fs::path& out, const std::string& image) { return out / "items" / (image + ".txt"); }

class ImageContentStage : public PerItemStage<ImageContentOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"analysis", "image_content",
                      "Per image: low-frequency score (mean |I - lowpass(I)|, Fourier domain) and crowdedness "
                      "(% person pixels of a mask, or % of the image covered by person boxes), the inputs of the paper's Tables 5 and 6",
                      {{"images", "kapture.dataset", "the query images"},
                       {"recording", "kapture.dataset",
                        "a simulator recording instead of the masks parameter: its truth/masks (image paths of the "
                        "query kapture relative to the recording, e.g. validation/...)",
                        LF_PORT_OPTIONAL},
                       {"masks", "person.masks", "estimated person masks instead (analysis/person_segmentation)",
                        LF_PORT_OPTIONAL},
                       {"detections", "person.detections",
                        "person boxes instead (analysis/person_detection): crowdedness = % of the image covered by "
                        "the union of its boxes", LF_PORT_OPTIONAL}},
                      {{"content", "report", "content.csv (image, device_id, low_frequency_score, low_frequency, "
                                             "crowdedness_percent, crowded), content.md, crowdedness_source.txt"}}};
    meta.version = "1.3.0";  // 1.2.0: a damaged image fails its item; 1.3.0: detections input
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override { return kp::Kapture(ctx.Input("images")).CameraImages(); }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const cv::Mat gray = image_io::ReadCameraImage(ctx.Input("images"), image, cv::IMREAD_GRAYSCALE);
    LowFrequencyOptions lf;
    lf.cutoff_cycles_per_width = options().cutoff_cycles_per_width;
    std::ostringstream line;
    line.precision(17);
    line << LowFrequencyScore(gray, lf) << ' ';
    const Masks source = MasksOf(ctx);
    const fs::path& masks = source.folder;
    if (masks.empty()) {
      line << -1;
    } else if (source.boxes) {
      line << ReadPersons(masks, image).covered_percent;
    } else {
      line << CrowdednessPercent(ReadPersonMask(masks, image, gray.size(), "masks"));
    }
    line << '\n';
    WriteFileAtomic(ItemFile(ctx.output_dir(), image), line.str());
  }

  // The masks parameter, the recording input's truth/masks, the masks input's masks/ or the
  // detections input's persons/: one of them, with what kind of masks it holds (for the reports
  // built on this one, analysis/crowd_sweep).
  struct Masks {
    fs::path folder;     // empty: no crowdedness
    std::string kind;    // "" without masks
    bool boxes = false;  // folder holds persons files (analysis/person_detection), not masks
  };
  Masks MasksOf(RunContext& ctx) const {
    const int given =
        !options().masks.empty() + ctx.HasInput("recording") + ctx.HasInput("masks") + ctx.HasInput("detections");
    if (given > 1)
      throw ParamError("analysis/image_content: give one source of crowdedness (the masks parameter, the "
                       "recording input, the masks input or the detections input)");
    if (ctx.HasInput("detections"))
      return {ctx.Input("detections") / "persons",
              "person boxes detected by analysis/person_detection (% of the image covered by their union)", true};
    if (ctx.HasInput("masks"))
      return {ctx.Input("masks") / "masks", "person masks estimated by analysis/person_segmentation", false};
    if (!ctx.HasInput("recording"))
      return {options().masks, options().masks.empty() ? "" : "the person masks of a folder", false};
    const fs::path masks = ctx.Input("recording") / "truth" / "masks";
    if (!fs::is_directory(masks))
      throw InputError(masks.string(), 0, "recording", "no person masks (simulate with masks: true)");
    return {masks, "the simulator's true person masks", false};
  }

  void Finalize(RunContext& ctx) override {
    const kp::Kapture dataset(ctx.Input("images"));
    std::map<std::string, std::string> device;
    for (const auto& r : dataset.ReadDataRecords(kp::kSensorCamera)) device[r.path] = r.device_id;
    const auto& o = options();
    evaluation::Table table;
    table.header = {"image", "device_id", "low_frequency_score", "low_frequency", "crowdedness_percent", "crowded"};
    size_t low = 0, crowded = 0, with_mask = 0;
    std::vector<double> scores;
    for (const std::string& image : dataset.CameraImages()) {
      const fs::path item = ItemFile(ctx.output_dir(), image);
      std::istringstream in(ReadFile(item));
      double score = 0, crowd = 0;
      if (!(in >> score >> crowd)) throw InputError(item.string(), 1, "item", "malformed (rerun with --force)");
      const ImageContent c = Classify(image, score, crowd, {o.low_frequency_below, o.crowded_at_least});
      const bool is_low = c.low_frequency, is_crowded = c.crowded;
      low += is_low;
      crowded += is_crowded;
      with_mask += crowd >= 0;
      scores.push_back(score);
      table.rows.push_back({image, device[image], FormatDouble(score), is_low ? "1" : "0",
                            crowd >= 0 ? FormatDouble(crowd) : "", crowd >= 0 ? (is_crowded ? "1" : "0") : ""});
    }
    std::sort(scores.begin(), scores.end());
    auto quantile = [&](double q) {
      const double v = scores.empty() ? 0.0 : scores[static_cast<size_t>(q * (scores.size() - 1) + 0.5)];
      std::ostringstream s;
      s.setf(std::ios::fixed);
      s.precision(2);
      s << v;
      return s.str();
    };
    std::ostringstream md;
    md << "# Image content\n\n" << table.rows.size() << " images; low-frequency score (mean |I - lowpass(I)|, "
       << "low-pass radius " << FormatDouble(o.cutoff_cycles_per_width) << " cycles per image width): "
       << "10th / 50th / 90th percentile " << quantile(0.1) << " / " << quantile(0.5) << " / " << quantile(0.9) << "; " << low << " low-frequency (< "
       << FormatDouble(o.low_frequency_below) << ")";
    if (with_mask)
      md << "; " << crowded << " of " << with_mask << " crowded (>= " << FormatDouble(o.crowded_at_least)
         << " % person pixels)";
    md << ".\n";
    const Masks masks = MasksOf(ctx);
    if (!masks.kind.empty()) md << "\nCrowdedness from " << masks.kind << " (" << masks.folder.string() << ").\n";
    WriteFileAtomic(ctx.output_dir() / kCrowdednessSourceFile, masks.kind + "\n");
    WriteFileAtomic(ctx.output_dir() / "content.csv", evaluation::ToCsv(table));
    WriteFileAtomic(ctx.output_dir() / "content.md", md.str());
    ctx.Info(md.str());
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(ImageContentStage)

}  // namespace locforge::analysis
