// eval/depth: depth maps (e.g. gt/lidar_depth's) against reference ones (e.g.
// the simulator's exact truth/depth): coverage, median, 90th percentile and
// share within a tolerance of |estimate - reference|, per camera and overall,
// on every pixel and on the pixels without a person (the LiDAR map holds the
// static scene; people move between the scans and the image).
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <map>
#include <sstream>

#include "depth_projection.h"
#include "evaluation.h"
#include "image_read.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::eval {

namespace {

namespace kp = locforge::kapture;
using evaluation::Table;

struct DepthEvalOptions {
  std::string reference;  // Folder of reference .depth maps at the records' paths.
  std::string masks;      // Folder of person masks at the records' paths (.png); "": none.
  std::string split = "mapping";  // With the recording input: truth/depth/<split>, truth/masks/<split>.
  double tolerance_m = 0.05;

  static void Declare(ParamSchema<DepthEvalOptions>& s) {
    using O = DepthEvalOptions;
    s.Add("reference", &O::reference,
          "folder of reference depth maps at the records' paths (e.g. a simulator recording's truth/depth/mapping)")
        .Path();
    s.Add("masks", &O::masks,
          "folder of person masks at the records' paths with extension .png (e.g. truth/masks/mapping); empty: "
          "no static-pixel rows")
        .Path();
    s.Add("split", &O::split, "with the recording input: the split folder of its truth/depth and truth/masks");
    s.Add("tolerance_m", &O::tolerance_m, "the 'within' column's bound (m)").Min(1e-6);
  }
  bool Check(std::string* why) const {
    if (split.empty() || split.find_first_of("/\\") != std::string::npos || split == "..")
      return *why = "split must be a folder name", false;
    return true;
  }
};

using ByDevice = std::map<std::string, depth::DepthErrors>;  // by device; "" = every camera

// Which pixels of a w x h image hold no person: the mask's dark ones.
std::vector<uint8_t> StaticPixels(const fs::path& mask_file, int w, int h) {
  std::string why;
  const cv::Mat mask = image_io::TryReadImage(mask_file, cv::IMREAD_GRAYSCALE, &why);
  if (mask.empty()) throw InputError(mask_file.string(), 0, "masks", "unusable mask: " + why);
  if (mask.cols != w || mask.rows != h)
    throw InputError(mask_file.string(), 0, "masks", "not " + std::to_string(w) + " x " + std::to_string(h));
  std::vector<uint8_t> keep(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) keep[static_cast<size_t>(y) * w + x] = mask.at<uint8_t>(y, x) <= 127;
  return keep;
}

// The depth errors of all the records, on every pixel and on the static ones (with masks).
struct DepthTally {
  ByDevice all, still;
  std::map<std::string, size_t> images;

  void Add(const kp::Kapture& estimate, const kp::DataRecord& r, const fs::path& reference, const fs::path& masks,
           double tolerance_m) {
    const kp::Sensor* sensor = estimate.sensors().Find(r.device_id);
    if (!sensor || !sensor->camera)
      throw InputError((estimate.root() / kp::layout::kSensors).string(), 0, r.device_id, "no depth sensor intrinsics");
    const int w = sensor->camera->width, h = sensor->camera->height;
    const fs::path est_file = estimate.ExistingRecordDataPath(r.path, "records_depth.txt");
    const fs::path ref_file = SafeJoin(reference, r.path, "records_depth.txt");
    if (!fs::exists(ref_file)) throw InputError(ref_file.string(), 0, "reference", "no reference depth map for " + r.path);
    const depth::DepthMap e = depth::DecodeDepth(ReadFile(est_file), w, h, est_file.string());
    const depth::DepthMap ref = depth::DecodeDepth(ReadFile(ref_file), w, h, ref_file.string());
    depth::DepthErrors one;
    depth::AccumulateDepthErrors(e, ref, nullptr, tolerance_m, &one);
    all[r.device_id].Merge(one);
    all[""].Merge(one);
    if (!masks.empty()) {
      const fs::path mask_file = SafeJoin(masks, fs::path(r.path).replace_extension(".png").generic_string(), r.path);
      const std::vector<uint8_t> keep = StaticPixels(mask_file, w, h);
      depth::DepthErrors s;
      depth::AccumulateDepthErrors(e, ref, &keep, tolerance_m, &s);
      still[r.device_id].Merge(s);
      still[""].Merge(s);
    }
    ++images[r.device_id];
    ++images[""];
  }
};

Table DepthTable(const DepthTally& tally, double tolerance_m) {
  Table t;
  const std::string within = "within_" + FormatDouble(tolerance_m) + "m_percent";
  const std::string tol = FormatDouble(tolerance_m);
  t.header = {"camera", "pixels", "images", "coverage_percent", "median_m", "p90_m", within,
              "nearer_by_" + tol + "m_percent", "farther_by_" + tol + "m_percent"};
  auto f = [](double v) {
    std::ostringstream s;
    s.precision(4);
    s << v;
    return s.str();
  };
  auto add = [&](const std::string& device, const std::string& pixels, const depth::DepthErrors& d) {
    t.rows.push_back({device.empty() ? "all" : device, pixels, std::to_string(tally.images.at(device)),
                      f(100 * d.Coverage()), f(d.Quantile(0.5)), f(d.Quantile(0.9)), f(100 * d.FractionWithin(tolerance_m)),
                      f(100.0 * d.nearer / std::max<size_t>(1, d.compared)),
                      f(100.0 * d.farther / std::max<size_t>(1, d.compared))});
  };
  for (const auto& [device, d] : tally.all) add(device, "all", d);
  for (const auto& [device, d] : tally.still) add(device, "without people", d);
  return t;
}

class DepthEvalStage : public Stage<DepthEvalOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"eval", "depth",
                      "Depth maps against reference depth maps: coverage, median and 90th percentile of the "
                      "absolute error, share within a tolerance; per camera, all pixels and pixels without people",
                      {{"estimate", "kapture.dataset", "depth records (records_depth.txt), e.g. gt/lidar_depth"},
                       {"recording", "kapture.dataset",
                        "a simulator recording instead of the reference and masks parameters: its truth/depth/<split> "
                        "and truth/masks/<split>", LF_PORT_OPTIONAL}},
                      {{"report", "report", "depth.{md,csv}"}}};
    meta.version = "1.1.0";  // 1.1.0: a damaged mask fails
    return meta;
  }
  using Stage::Stage;

  // The reference depth maps and the masks: the parameters, or the recording's truth.
  void ReferenceFolders(RunContext& ctx, fs::path* reference, fs::path* masks) const {
    const auto& o = options();
    *reference = o.reference;
    *masks = o.masks;
    if (ctx.HasInput("recording")) {
      if (!reference->empty() || !masks->empty())
        throw ParamError("eval/depth: the recording input replaces the reference and masks parameters; keep one");
      *reference = ctx.Input("recording") / "truth" / "depth" / o.split;
      *masks = ctx.Input("recording") / "truth" / "masks" / o.split;
      if (!fs::is_directory(*reference))
        throw InputError(reference->string(), 0, "recording", "no exact depth maps (simulate with depth: true)");
      if (!fs::is_directory(*masks)) masks->clear();
    } else if (reference->empty()) {
      throw ParamError("eval/depth: set the reference parameter (a folder of depth maps) or wire the recording input");
    }
  }

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const kp::Kapture estimate(ctx.Input("estimate"));
    fs::path reference, masks;
    ReferenceFolders(ctx, &reference, &masks);
    const auto records = estimate.ReadDataRecords(kp::kSensorDepth);
    if (records.empty())
      throw InputError((estimate.root() / kp::layout::RecordsFile(kp::kSensorDepth)).string(), 0, "records",
                       "no depth records");
    DepthTally tally;
    size_t done = 0;
    for (const auto& r : records) {
      ctx.ThrowIfCancelled();
      tally.Add(estimate, r, reference, masks, o.tolerance_m);
      ctx.Progress(++done, records.size(), "depth maps");
    }
    const Table t = DepthTable(tally, o.tolerance_m);
    const fs::path out = ctx.output_dir();
    WriteFileAtomic(out / "depth.md", "# Depth maps against the reference\n\n"
                                      "coverage: share of the reference's valid pixels that have a depth; errors "
                                      "|estimate - reference| over the pixels with both (0.5 mm bins); nearer / "
                                      "farther: the estimate off by more than the tolerance towards / away from the "
                                      "camera (an occluder the reference lacks / a surface seen through a gap).\n\n" +
                                          evaluation::ToMarkdown(t));
    WriteFileAtomic(out / "depth.csv", evaluation::ToCsv(t));
    ctx.Info(evaluation::ToMarkdown(t));
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(DepthEvalStage)

}  // namespace locforge::eval
