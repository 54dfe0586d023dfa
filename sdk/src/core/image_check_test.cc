// ImageFileDamage on real images of ../shared: intact ones pass; truncated
// ones, ones corrupted in the middle and files not of their kind are named
// with the reason.
#include "locforge/image_check.h"

#include <gtest/gtest.h>

#include "locforge/fs.h"
#include "testing.h"

namespace locforge {
namespace {

constexpr char kJpeg[] =
    "data/kapture/virtual_gallery_tutorial/query/sensors/records_data/testing/"
    "gallery_light1_occlusion1/frames/rgb/camera_0/rgb_00446.jpg";
constexpr char kPng[] = "models/r2d2/reference/boat.png";

class ImageCheckTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::MakeTempDir("locforge-image-check"); }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path Write(const std::string& name, const std::string& bytes) {
    WriteFileAtomic(dir_ / name, bytes);
    return dir_ / name;
  }
  static bool Has(const std::string& text, const std::string& piece) {
    return text.find(piece) != std::string::npos;
  }
  fs::path dir_;
};

TEST_F(ImageCheckTest, IntactImagesPass) {
  LOCFORGE_SHARED_PATH_OR_SKIP(jpeg, kJpeg);
  LOCFORGE_SHARED_PATH_OR_SKIP(png, kPng);
  EXPECT_EQ(ImageFileDamage(jpeg), "");
  EXPECT_EQ(ImageFileDamage(png), "");
  // Bytes after the end marker are not damage.
  EXPECT_EQ(ImageFileDamage(Write("tail.jpg", ReadFile(jpeg) + "trailer")), "");
}

TEST_F(ImageCheckTest, TruncatedJpegAnywhereIsTruncated) {
  LOCFORGE_SHARED_PATH_OR_SKIP(jpeg, kJpeg);
  const std::string data = ReadFile(jpeg);
  ASSERT_GT(data.size(), 100000u);
  // 30 kB, as in the incident; half; all but the last entropy bytes; all but EOI.
  for (size_t size : {size_t{30000}, data.size() / 2, data.size() - 100, data.size() - 2}) {
    const std::string why = ImageFileDamage(Write("cut.jpg", data.substr(0, size)));
    EXPECT_TRUE(Has(why, "truncated JPEG")) << size << " bytes: " << why;
    EXPECT_TRUE(Has(why, "Premature end of JPEG file")) << size << " bytes: " << why;
  }
}

TEST_F(ImageCheckTest, JpegCorruptedInTheMiddleIsCorrupt) {
  LOCFORGE_SHARED_PATH_OR_SKIP(jpeg, kJpeg);
  std::string data = ReadFile(jpeg);
  // An end-of-image marker inside the entropy-coded data: the decoder stops
  // there and fills the rest (libjpeg's "premature end of data segment").
  std::string marker = data;
  marker.replace(data.size() / 2, 2, "\xff\xd9");
  std::string why = ImageFileDamage(Write("marker.jpg", marker));
  EXPECT_TRUE(Has(why, "corrupt JPEG")) << why;
  // A kilobyte of garbage (no 0xFF) in the middle.
  std::string garbage = data;
  for (size_t i = 0; i < 1024; ++i)
    garbage[data.size() / 2 + i] = static_cast<char>((i * 37 + 11) % 255);
  why = ImageFileDamage(Write("garbage.jpg", garbage));
  EXPECT_TRUE(Has(why, "corrupt JPEG") || Has(why, "truncated JPEG")) << why;
  EXPECT_EQ(ImageFileDamage(Write("whole.jpg", data)), "");  // the same bytes, intact
}

TEST_F(ImageCheckTest, TruncatedOrCorruptPng) {
  LOCFORGE_SHARED_PATH_OR_SKIP(png, kPng);
  const std::string data = ReadFile(png);
  for (size_t size : {size_t{100}, data.size() / 2, data.size() - 1}) {
    const std::string why = ImageFileDamage(Write("cut.png", data.substr(0, size)));
    EXPECT_TRUE(Has(why, "truncated PNG")) << size << " bytes: " << why;
  }
  std::string flipped = data;
  flipped[data.size() / 2] ^= 0x01;
  const std::string why = ImageFileDamage(Write("flipped.png", flipped));
  EXPECT_TRUE(Has(why, "corrupt PNG (CRC mismatch in chunk 'IDAT'")) << why;
}

TEST_F(ImageCheckTest, FilesNotOfTheirKind) {
  EXPECT_EQ(ImageFileDamage(Write("empty.jpg", "")), "empty file");
  EXPECT_TRUE(Has(ImageFileDamage(Write("text.jpg", "hello")), "not a JPEG"));
  EXPECT_TRUE(Has(ImageFileDamage(Write("text.PNG", "hello")), "not a PNG"));
  EXPECT_TRUE(Has(ImageFileDamage(dir_ / "absent.jpg"), "cannot open"));
  EXPECT_EQ(ImageFileDamage(Write("other.bmp", "BM whatever")), "");  // not checked
}

}  // namespace
}  // namespace locforge
