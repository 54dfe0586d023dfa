// Cross-check of every distortion model against the COLMAP 3.8 executable.
//
// A 256x256 image whose red and green channels are the pixel's column and row
// is undistorted by `colmap image_undistorter` (PINHOLE output with the same
// focal lengths and principal point: --min_scale 1 --max_scale 1). COLMAP
// fills undistorted pixel (x, y) by bilinear sampling of the distorted image
// at WorldToImage(ImageToWorld_pinhole(x + 0.5, y + 0.5)) - 0.5, so on the
// ramp image the colour it writes is that distorted position, rounded to
// 8 bits: our Camera::Project of the same ray must land within half a pixel,
// everywhere, for distortions of tens of pixels.
//
// Skipped when no colmap executable is found ($LOCFORGE_COLMAP, else colmap
// on PATH).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "locforge/camera.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "testing.h"

namespace locforge {
namespace {

constexpr int kSize = 256;

std::string FindColmap() {
  if (const char* env = std::getenv("LOCFORGE_COLMAP"); env && *env) return env;
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const fs::path candidate = fs::path(dir) / "colmap";
    if (!dir.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

struct Rgb {
  int width = 0, height = 0;
  std::vector<uint8_t> data;  // RGB rows
};

void WritePpm(const fs::path& path, const Rgb& image) {
  std::string out = "P6\n" + std::to_string(image.width) + " " + std::to_string(image.height) +
                    "\n255\n";
  out.append(reinterpret_cast<const char*>(image.data.data()), image.data.size());
  WriteFileAtomic(path, out);
}

// Binary PPM (P6, 8 bits) as written by COLMAP's FreeImage.
Rgb ReadPpm(const fs::path& path) {
  const std::string bytes = ReadFile(path);
  std::istringstream in(bytes);
  std::string magic;
  int maxval = 0;
  Rgb image;
  in >> magic >> image.width >> image.height >> maxval;
  in.get();  // the single blank after the header
  if (magic != "P6" || maxval != 255 || image.width <= 0 || image.height <= 0)
    throw Error(path.string() + ": not an 8-bit P6 image");
  const size_t offset = static_cast<size_t>(in.tellg());
  const size_t size = static_cast<size_t>(image.width) * image.height * 3;
  if (bytes.size() < offset + size) throw Error(path.string() + ": truncated");
  image.data.assign(bytes.begin() + offset, bytes.begin() + offset + size);
  return image;
}

// COLMAP's cameras.bin: uint64 count, then per camera int32 id, int32 model,
// uint64 width, uint64 height, double params[model's count].
std::map<int, Camera> ReadCamerasBin(const fs::path& path) {
  const std::string bytes = ReadFile(path);
  size_t at = 0;
  auto take = [&](auto* value) {
    if (at + sizeof(*value) > bytes.size()) throw Error(path.string() + ": truncated");
    std::memcpy(value, bytes.data() + at, sizeof(*value));
    at += sizeof(*value);
  };
  uint64_t count = 0;
  take(&count);
  std::map<int, Camera> cameras;
  for (uint64_t i = 0; i < count; ++i) {
    int32_t id = 0, model = 0;
    uint64_t width = 0, height = 0;
    take(&id);
    take(&model);
    take(&width);
    take(&height);
    Camera c;
    c.model = static_cast<CameraModelId>(model);
    c.width = static_cast<int>(width);
    c.height = static_cast<int>(height);
    c.params.resize(CameraModelInfoOf(c.model).num_params);
    for (double& p : c.params) take(&p);
    cameras[id] = c;
  }
  return cameras;
}

TEST(CameraAgainstColmap, UndistorterMatchesEveryModel) {
  const std::string colmap = FindColmap();
  if (colmap.empty()) GTEST_SKIP() << "no colmap executable (set LOCFORGE_COLMAP)";

  // Strong distortion (tens of pixels at the borders) for each model.
  const std::vector<std::pair<std::string, std::string>> models = {
      {"SIMPLE_RADIAL", "200 128 128 -0.3"},
      {"RADIAL", "200 128 128 -0.3 0.1"},
      {"OPENCV", "200 210 128 128 -0.3 0.1 0.01 -0.02"},
      {"OPENCV_FISHEYE", "150 155 128 128 0.1 -0.05 0.02 -0.01"},
      {"FULL_OPENCV", "200 210 128 128 -0.3 0.1 0.01 -0.02 0.01 0.1 -0.05 0.01"},
      {"FOV", "200 210 128 128 0.9"},
      {"SIMPLE_RADIAL_FISHEYE", "150 128 128 0.1"},
      {"RADIAL_FISHEYE", "150 128 128 0.1 -0.05"},
      {"THIN_PRISM_FISHEYE", "150 155 128 128 0.1 -0.05 0.01 -0.02 0.02 -0.01 0.01 -0.01"},
  };

  const fs::path dir = locforge::testing::MakeTempDir("locforge-colmap-camera");
  Rgb ramp;
  ramp.width = ramp.height = kSize;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x)
      ramp.data.insert(ramp.data.end(), {static_cast<uint8_t>(x), static_cast<uint8_t>(y), 0});
  std::string cameras_txt, images_txt;
  for (size_t i = 0; i < models.size(); ++i) {
    const std::string id = std::to_string(i + 1);
    const std::string& name = models[i].first;
    WritePpm(dir / "images" / (name + ".ppm"), ramp);
    cameras_txt += id + " " + name + " 256 256 " + models[i].second + "\n";
    images_txt += id + " 1 0 0 0 0 0 0 " + id + " " + name + ".ppm\n\n";
  }
  WriteFileAtomic(dir / "sparse" / "cameras.txt", cameras_txt);
  WriteFileAtomic(dir / "sparse" / "images.txt", images_txt);
  WriteFileAtomic(dir / "sparse" / "points3D.txt", "");
  const std::string command = "'" + colmap + "' image_undistorter --image_path '" +
                              (dir / "images").string() + "' --input_path '" +
                              (dir / "sparse").string() + "' --output_path '" +
                              (dir / "out").string() +
                              "' --blank_pixels 1 --min_scale 1 --max_scale 1 > '" +
                              (dir / "colmap.log").string() + "' 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command << "\n" << ReadFile(dir / "colmap.log");

  const auto pinholes = ReadCamerasBin(dir / "out" / "sparse" / "cameras.bin");
  ASSERT_EQ(pinholes.size(), models.size());
  for (size_t i = 0; i < models.size(); ++i) {
    const std::string& name = models[i].first;
    std::vector<double> params;
    std::istringstream in(models[i].second);
    for (double v; in >> v;) params.push_back(v);
    const Camera camera = Camera::FromModelName(name, kSize, kSize, params);
    const Camera& pinhole = pinholes.at(static_cast<int>(i + 1));
    ASSERT_EQ(pinhole.model, CameraModelId::kPinhole) << name;
    ASSERT_EQ(pinhole.width, kSize) << name;
    const Rgb undistorted = ReadPpm(dir / "out" / "images" / (name + ".ppm"));
    ASSERT_EQ(undistorted.width, kSize);

    double worst = 0, sum_x = 0, sum_y = 0, largest_shift = 0;
    int compared = 0;
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const uint8_t* rgb = &undistorted.data[(static_cast<size_t>(y) * kSize + x) * 3];
        // 0 is also COLMAP's blank; 255 may be clamped at the far border.
        if (rgb[0] == 0 || rgb[1] == 0 || rgb[0] == 255 || rgb[1] == 255) continue;
        const Eigen::Vector2d at(x + 0.5, y + 0.5);
        const Eigen::Vector2d ours = camera.Project(pinhole.Unproject(at));
        const Eigen::Vector2d theirs(rgb[0] + 0.5, rgb[1] + 0.5);
        worst = std::max(worst, (ours - theirs).cwiseAbs().maxCoeff());
        sum_x += ours.x() - theirs.x();
        sum_y += ours.y() - theirs.y();
        largest_shift = std::max(largest_shift, (ours - at).norm());
        ++compared;
      }
    }
    EXPECT_GT(compared, kSize * kSize / 2) << name;
    // Rounding to 8 bits: at most half a pixel, and no bias.
    EXPECT_LE(worst, 0.5 + 1e-3) << name;
    EXPECT_LT(std::abs(sum_x / compared), 0.02) << name;
    EXPECT_LT(std::abs(sum_y / compared), 0.02) << name;
    // The check means something: the distortion moves pixels a lot.
    EXPECT_GT(largest_shift, 10.0) << name;
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
}

}  // namespace
}  // namespace locforge
