// Imports a folder of images: hard links (or copies) them under
// sensors/records_data keeping their relative paths, one camera per size.
#include <algorithm>
#include <cctype>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "image_read.h"
#include "locforge/fs.h"
#include "kapture_text.h"
#include "locforge/plugin.h"

namespace locforge::source {

using namespace ::locforge::examples;  // the library this stage wires

struct ImageListOptions {
  std::string root;                                          // Folder imported.
  std::vector<std::string> extensions = {"png", "jpg", "jpeg"};  // Case-insensitive.
  double focal_px = 0;  // Placeholder focal length; 0: 1.2 * max(width, height).
  static void Declare(ParamSchema<ImageListOptions>& s) {
    s.Add("root", &ImageListOptions::root, "Folder of images imported (searched recursively)")
        .Path()
        .Required();
    s.Add("extensions", &ImageListOptions::extensions,
          "File extensions imported, case-insensitive");
    s.Add("focal_px", &ImageListOptions::focal_px,
          "Placeholder focal length in pixels; 0 uses 1.2 * max(width, height)")
        .Min(0);
  }
};

class ImageList : public Stage<ImageListOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"source", "image_list",
            "Imports a folder of images as a kapture dataset (one camera per image size)",
            {},
            {{"images", "kapture.dataset", "Cameras and image records of the folder"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

namespace {

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::vector<std::string> ListImages(const fs::path& root, const std::vector<std::string>& exts) {
  std::vector<std::string> wanted;
  for (const auto& e : exts) wanted.push_back("." + Lower(e));
  std::vector<std::string> out;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!name.empty() && name[0] == '.') {  // hidden files and folders
      if (it->is_directory()) it.disable_recursion_pending();
      continue;
    }
    const std::string ext = Lower(it->path().extension().string());
    if (std::find(wanted.begin(), wanted.end(), ext) == wanted.end()) continue;
    out.push_back(it->path().lexically_relative(root).generic_string());
  }
  if (ec) throw InputError(root.string(), 0, "root", "cannot list folder: " + ec.message());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

void ImageList::Run(RunContext& ctx) {
  const auto& o = options();
  const fs::path root = fs::absolute(o.root);
  if (!fs::is_directory(root))
    throw InputError(o.root, 0, "root", "not a folder");
  const auto images = ListImages(root, o.extensions);
  if (images.empty()) throw InputError(o.root, 0, "root", "no images with the given extensions");

  const fs::path dataset = ctx.output_dir();
  std::vector<PinholeCamera> cameras;
  std::vector<ImageRecord> records;
  for (size_t i = 0; i < images.size(); ++i) {
    ctx.ThrowIfCancelled();
    const std::string& rel = images[i];
    if (rel.find_first_of(",\r\n") != std::string::npos)
      throw InputError(rel, 0, "", "image path contains a comma or line break, which kapture text files cannot hold");
    const fs::path source = SafeJoin(root, rel, o.root);  // refuses links leaving the root
    const cv::Mat image = image_io::ReadImage(source, cv::IMREAD_UNCHANGED);
    auto camera = std::find_if(cameras.begin(), cameras.end(), [&](const PinholeCamera& c) {
      return c.width == image.cols && c.height == image.rows;
    });
    if (camera == cameras.end()) {
      const double f = o.focal_px > 0 ? o.focal_px : 1.2 * std::max(image.cols, image.rows);
      cameras.push_back({"cam" + std::to_string(cameras.size()), "imported", image.cols, image.rows,
                         f, f, image.cols / 2.0, image.rows / 2.0});
      camera = cameras.end() - 1;
    }
    LinkOrCopyFile(source, RecordsDataDir(dataset) / rel);
    records.push_back({static_cast<int64_t>(i), camera->id, rel, 0});
    ctx.Progress(i + 1, images.size(), rel);
  }
  WriteCameraDataset(dataset, cameras, records);
  ctx.Info("imported " + std::to_string(records.size()) + " images, " +
           std::to_string(cameras.size()) + " camera(s)");
}

LOCFORGE_REGISTER_STAGE(ImageList)

}  // namespace locforge::source
