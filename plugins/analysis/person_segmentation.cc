// analysis/person_segmentation: person masks from an ONNX segmentation
// network (contract in README.md), the crowdedness they give, and with a
// simulator recording their agreement with its true masks.
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "evaluation.h"
#include "image_content.h"
#include "image_input.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"
#include "segmentation.h"

namespace locforge::analysis {
namespace {

namespace kp = locforge::kapture;

struct PersonSegmentationOptions : learned::InputOptions {
  std::string model;              // .onnx file (required).
  std::string output = "person";  // 1x1xhxw person probability in [0, 1].
  double threshold = 0.5;         // Probability from which a pixel is a person.

  PersonSegmentationOptions() { width = 160, height = 128; }
  static void Declare(ParamSchema<PersonSegmentationOptions>& s) {
    s.Add("model", &PersonSegmentationOptions::model,
          "the network (.onnx file, contract in plugins/analysis/README.md)").Path().Required();
    learned::DeclareInputOptions(s);
    s.Add("output", &PersonSegmentationOptions::output, "output tensor: person probability, 1x1xhxw in [0, 1]");
    s.Add("threshold", &PersonSegmentationOptions::threshold, "probability from which a pixel is a person")
        .Range(0, 1);
  }
  bool Check(std::string* why) const { return InputOptions::Check(why); }
};

class PersonSegmentationStage : public PerItemStage<PersonSegmentationOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"analysis", "person_segmentation",
                      "Person masks of every image from a segmentation network (ONNX, OpenCV dnn), their "
                      "crowdedness, and with a simulator recording their IoU and crowdedness against its true masks",
                      {{"images", "kapture.dataset", "the images (records_camera.txt)"},
                       {"recording", "kapture.dataset",
                        "a simulator recording whose truth/masks hold the reference masks (image paths relative "
                        "to it, e.g. validation/...)", LF_PORT_OPTIONAL}},
                      {{"masks", "person.masks",
                        "masks/<image path, .png> (255 on people), segmentation.{csv,md}"}}};
    meta.version = "1.1.0";  // 1.1.0: a damaged image fails its item
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override { return kp::Kapture(ctx.Input("images")).CameraImages(); }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const cv::Mat rgb = learned::ReadRgb(ctx.Input("images"), image);
    cv::dnn::Net& net = learned::ThreadNet(options().model);
    net.setInput(learned::InputBlob(rgb, options()), options().input);
    const cv::Mat out = net.forward(options().output);
    const int dims = out.dims;
    if (dims < 2 || out.total() != static_cast<size_t>(out.size[dims - 2]) * out.size[dims - 1])
      throw InputError(options().model, 0, "output", "expected a 1x1xhxw person probability map");
    const cv::Mat probability(out.size[dims - 2], out.size[dims - 1], CV_32F, const_cast<float*>(out.ptr<float>()));
    const cv::Mat mask = PersonMask(probability, rgb.size(), options().threshold);
    std::vector<uchar> png;
    cv::imencode(".png", mask, png);
    WriteFileAtomic(PersonMaskFile(ctx.output_dir() / "masks", image),
                    std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
    std::ostringstream line;
    line.precision(17);
    if (ctx.HasInput("recording")) {
      const cv::Mat truth = ReadPersonMask(ctx.Input("recording") / "truth" / "masks", image, mask.size(), "recording");
      const MaskAgreement a = CompareMasks(mask, truth);
      line << a.estimated_percent << ' ' << a.reference_percent << ' ' << a.iou << '\n';
    } else {
      line << CrowdednessPercent(mask) << " -1 -1\n";
    }
    WriteFileAtomic(SafeJoin(ctx.output_dir() / "items", image + ".txt"), line.str());
  }

  void Finalize(RunContext& ctx) override {
    const kp::Kapture dataset(ctx.Input("images"));
    evaluation::Table table;
    table.header = {"image", "estimated_crowdedness_percent", "true_crowdedness_percent", "iou"};
    const double kCrowded = ContentThresholds().crowded_at_least;  // the paper's 20 %
    double iou_sum = 0, error_sum = 0;
    size_t compared = 0, agree_crowded = 0;
    for (const std::string& image : dataset.CameraImages()) {
      const fs::path item = SafeJoin(ctx.output_dir() / "items", image + ".txt");
      std::istringstream in(ReadFile(item));
      double estimated = 0, reference = 0, iou = 0;
      if (!(in >> estimated >> reference >> iou)) throw InputError(item.string(), 1, "item", "malformed (rerun with --force)");
      table.rows.push_back({image, FormatDouble(estimated), reference < 0 ? "" : FormatDouble(reference),
                            iou < 0 ? "" : FormatDouble(iou)});
      if (reference >= 0) {
        ++compared;
        iou_sum += iou;
        error_sum += std::abs(estimated - reference);
        agree_crowded += (estimated >= kCrowded) == (reference >= kCrowded);
      }
    }
    WriteFileAtomic(ctx.output_dir() / "segmentation.csv", evaluation::ToCsv(table));
    std::ostringstream md;
    md.precision(3);
    md << "# Person segmentation\n\n" << table.rows.size() << " images, model " << options().model << ", threshold "
       << options().threshold << "\n\n";
    if (compared > 0) {
      md << "Against the true masks (" << compared << " images): mean IoU " << iou_sum / compared
         << ", mean |crowdedness error| " << error_sum / compared << " percentage points, crowded (>= " << kCrowded << " %) "
         << "classification agrees on " << 100.0 * agree_crowded / compared << " %.\n";
    }
    WriteFileAtomic(ctx.output_dir() / "segmentation.md", md.str());
    ctx.Info(md.str());
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(PersonSegmentationStage)

}  // namespace locforge::analysis
