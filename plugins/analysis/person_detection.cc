// analysis/person_detection: people in every image from a Darknet YOLO person
// detector (e.g. Yolo-Fastest body), run by OpenCV dnn: per image the boxes,
// their count and the share of the image they cover (area of their union),
// an alternative source of crowdedness for analysis/image_content on real
// images; with a simulator recording, the true crowdedness beside it.
#include <opencv2/dnn.hpp>

#include <cmath>
#include <map>
#include <numeric>
#include <sstream>

#include "detection.h"
#include "evaluation.h"
#include "image_content.h"
#include "image_input.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"

namespace locforge::analysis {
namespace {

namespace kp = locforge::kapture;

struct PersonDetectionOptions {
  std::string cfg;      // Darknet .cfg (required).
  std::string weights;  // Darknet .weights (required).
  int width = 0;        // Network input; 0: the cfg's [net] width.
  int height = 0;       // 0: the cfg's [net] height.
  double score_threshold = DetectionOptions{}.score_threshold;
  double nms_iou = DetectionOptions{}.nms_iou;
  int person_class = DetectionOptions{}.person_class;

  static void Declare(ParamSchema<PersonDetectionOptions>& s) {
    using O = PersonDetectionOptions;
    s.Add("cfg", &O::cfg, "the detector's Darknet .cfg (e.g. ../shared/models/yolo_fastest_body/yolo-fastest-1.1_body.cfg)")
        .Path().Required();
    s.Add("weights", &O::weights, "the detector's Darknet .weights").Path().Required();
    s.Add("width", &O::width,
          "network input width, a multiple of 32 (larger finds smaller people, slower); 0: the cfg's").Min(0);
    s.Add("height", &O::height, "network input height, a multiple of 32; 0: the cfg's").Min(0);
    s.Add("score_threshold", &O::score_threshold,
          "a box is kept when objectness x person probability >= this (Darknet's default 0.25; OpenCV's YOLO "
          "layer already zeroes scores below 0.2)")
        .Range(0.2, 1);
    s.Add("nms_iou", &O::nms_iou,
          "greedy non-maximum suppression: a box whose IoU with a better kept box is > this is dropped "
          "(Darknet's 0.45)")
        .Range(0, 1);
    s.Add("person_class", &O::person_class, "the person's class index in the detector's classes (0 for a "
                                            "one-class body detector; 0 in COCO too)").Min(0);
  }
  bool Check(std::string* why) const {
    if (width % 32 != 0 || height % 32 != 0) return *why = "width and height must be multiples of 32 (or 0)", false;
    return true;
  }
};

// The files' size and modification time: a model rewritten at the same path
// between two runs of one process is reloaded (as learned::ThreadNet does).
std::string Stamp(const std::string& file) {
  std::error_code ec;
  const auto size = fs::file_size(file, ec);
  const auto time = fs::last_write_time(file, ec);
  return ec ? "" : std::to_string(size) + "@" + std::to_string(time.time_since_epoch().count());
}

// cv::dnn::Net is not thread-safe: one per thread and model.
cv::dnn::Net& ThreadDarknet(const std::string& cfg, const std::string& weights) {
  thread_local std::map<std::string, cv::dnn::Net> nets;
  const std::string key = cfg + "@" + Stamp(cfg) + "\n" + weights + "@" + Stamp(weights);
  auto it = nets.find(key);
  if (it != nets.end()) return it->second;
  nets.clear();  // an older version of these files, or another model: one net per thread is enough
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromDarknet(cfg, weights);
  } catch (const cv::Exception& e) {
    throw InputError(weights, 0, "weights", std::string("cannot load the Darknet model (cfg " + cfg + "): ") + e.what());
  }
  if (net.empty()) throw InputError(weights, 0, "weights", "cannot load the Darknet model (cfg " + cfg + ")");
  return nets[key] = std::move(net);
}

class PersonDetectionStage : public PerItemStage<PersonDetectionOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"analysis", "person_detection",
                      "People in every image from a Darknet YOLO person detector (OpenCV dnn): boxes, count and "
                      "the % of the image they cover (area of their union); with a simulator recording, the true "
                      "crowdedness beside it",
                      {{"images", "kapture.dataset", "the images (records_camera.txt)"},
                       {"recording", "kapture.dataset",
                        "a simulator recording whose truth/masks give the true crowdedness (image paths relative "
                        "to it, e.g. validation/...)", LF_PORT_OPTIONAL}},
                      {{"detections", "person.detections",
                        "persons/<image path>.txt (line 1: person_count covered_percent; then x y width height "
                        "score per box, pixels), persons.csv, detections.csv, detection.md"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override { return kp::Kapture(ctx.Input("images")).CameraImages(); }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const cv::Mat rgb = learned::ReadRgb(ctx.Input("images"), image);
    cv::dnn::Net& net = ThreadDarknet(options().cfg, options().weights);
    const DarknetInput input = Geometry();
    net.setInput(DarknetBlob(rgb, input));
    std::vector<cv::Mat> outputs;
    net.forward(outputs, net.getUnconnectedOutLayersNames());
    Persons persons;
    try {
      persons.boxes = DecodeYoloRows(outputs, rgb.size(), input, Detection());
    } catch (const std::invalid_argument& e) {
      throw InputError(options().cfg, 0, "person_class", e.what());
    }
    persons.covered_percent = CoveredPercent(persons.boxes, rgb.size());
    double true_percent = -1;
    if (ctx.HasInput("recording"))
      true_percent = CrowdednessPercent(
          ReadPersonMask(ctx.Input("recording") / "truth" / "masks", image, rgb.size(), "recording"));
    std::ostringstream truth;
    truth.precision(17);
    truth << true_percent << '\n';
    WriteFileAtomic(SafeJoin(ctx.output_dir() / "items", image + ".txt"), truth.str());
    WriteFileAtomic(PersonsFile(ctx.output_dir() / "persons", image), FormatPersons(persons));
  }

  void Finalize(RunContext& ctx) override {
    const kp::Kapture dataset(ctx.Input("images"));
    evaluation::Table per_image, boxes;
    per_image.header = {"image", "person_count", "covered_percent", "true_crowdedness_percent"};
    boxes.header = {"image", "x", "y", "width", "height", "score"};
    std::vector<double> covered, count, truth;
    for (const std::string& image : dataset.CameraImages()) {
      const Persons p = ReadPersons(ctx.output_dir() / "persons", image);
      const fs::path truth_file = SafeJoin(ctx.output_dir() / "items", image + ".txt");
      std::istringstream in(ReadFile(truth_file));
      double t = -1;
      if (!(in >> t)) throw InputError(truth_file.string(), 1, "true_crowdedness", "malformed (rerun with --force)");
      per_image.rows.push_back({image, std::to_string(p.boxes.size()), FormatDouble(p.covered_percent),
                                t < 0 ? "" : FormatDouble(t)});
      for (const PersonBox& b : p.boxes)
        boxes.rows.push_back({image, FormatDouble(b.x), FormatDouble(b.y), FormatDouble(b.width),
                              FormatDouble(b.height), FormatDouble(b.score)});
      covered.push_back(p.covered_percent);
      count.push_back(static_cast<double>(p.boxes.size()));
      if (t >= 0) truth.push_back(t);
    }
    WriteFileAtomic(ctx.output_dir() / "persons.csv", evaluation::ToCsv(per_image));
    WriteFileAtomic(ctx.output_dir() / "detections.csv", evaluation::ToCsv(boxes));
    const DarknetInput input = Geometry();
    std::ostringstream md;
    md.precision(3);
    const double n = static_cast<double>(covered.size());
    md << "# Person detection\n\n" << covered.size() << " images, detector " << options().cfg << " at "
       << input.width << "x" << input.height << (input.letter_box ? " (letterboxed)" : " (resized)")
       << ", score >= " << options().score_threshold << ", NMS IoU > " << options().nms_iou << ": "
       << std::accumulate(count.begin(), count.end(), 0.0) << " persons, mean covered "
       << (n > 0 ? std::accumulate(covered.begin(), covered.end(), 0.0) / n : 0.0)
       << " % of the image (area of the union of the boxes).\n";
    if (!truth.empty()) {
      const auto r = [](double v) {  // NaN: one of the samples is constant (e.g. no people at all)
        std::ostringstream s;
        s.precision(3);
        if (std::isnan(v)) return std::string("- (constant)");
        s << v;
        return s.str();
      };
      md << "\nAgainst the true masks: mean true crowdedness "
         << std::accumulate(truth.begin(), truth.end(), 0.0) / n << " %; Pearson / Spearman of the covered % with "
         << "the true % " << r(PearsonCorrelation(covered, truth)) << " / " << r(SpearmanCorrelation(covered, truth))
         << ", of the count with the true % " << r(PearsonCorrelation(count, truth)) << " / "
         << r(SpearmanCorrelation(count, truth)) << ".\n";
    }
    WriteFileAtomic(ctx.output_dir() / "detection.md", md.str());
    ctx.Info(md.str());
  }

 private:
  // The cfg's geometry unless overridden (the cfg is re-read per image: a few
  // kB, nothing beside the network; errors name it).
  DarknetInput Geometry() const {
    DarknetInput input = ReadDarknetInput(options().cfg);
    if (options().width > 0) input.width = options().width;
    if (options().height > 0) input.height = options().height;
    return input;
  }
  DetectionOptions Detection() const {
    DetectionOptions d;
    d.score_threshold = options().score_threshold;
    d.nms_iou = options().nms_iou;
    d.person_class = options().person_class;
    return d;
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(PersonDetectionStage)

}  // namespace locforge::analysis
