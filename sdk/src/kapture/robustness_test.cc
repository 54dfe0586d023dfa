// Malformed and hostile inputs: each gives a clear InputError naming the
// file (and line and field where there is one); random mutations of the
// sample files never crash a parser.
#include <gtest/gtest.h>

#include <random>
#include <sstream>

#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"
#include "text_parsers.h"

namespace locforge::kapture {
namespace {

// Asserts `fn` throws InputError whose message contains every piece.
template <class Fn>
void ExpectInputError(Fn&& fn, const std::vector<std::string>& pieces) {
  try {
    fn();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const InputError& e) {
    for (const std::string& p : pieces)
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos)
          << "message: " << e.what() << "\nmissing: " << p;
  }
}

// A small writable kapture: one camera, two images, SIFT-like keypoints.
class HostileKapture : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = locforge::testing::MakeTempDir("kapture_hostile");
    WriteFileAtomic(root_ / layout::kSensors,
                    "# kapture format: 1.1\ncam, , camera, PINHOLE, 640, 480, 500, 500, 320, 240\n");
    WriteFileAtomic(root_ / layout::kTrajectories,
                    "# kapture format: 1.1\n# timestamp, device_id, qw, qx, qy, qz, tx, ty, tz\n"
                    "1, cam, 1, 0, 0, 0, 0, 0, 0\n");
    WriteFileAtomic(root_ / layout::kRecordsData / "a.jpg", "jpeg");
    WriteFileAtomic(root_ / "reconstruction/keypoints/kp/keypoints.txt",
                    "# kapture format: 1.1\nkp, float32, 2\n");
    const std::vector<float> xy = {1.5f, 2.5f, 3.5f, 4.5f};
    WriteFeatureFile(root_ / "reconstruction/keypoints/kp/a.jpg.kpt",
                     FeatureArray::From(DType::kFloat32, 2, xy));
  }
  void TearDown() override { fs::remove_all(root_); }
  void Records(const std::string& lines) {
    WriteFileAtomic(root_ / layout::RecordsFile("camera"),
                    "# kapture format: 1.1\n# timestamp, device_id, image_path\n" + lines);
  }
  fs::path root_;
};

TEST_F(HostileKapture, ValidDatasetReads) {
  Records("1, cam, a.jpg\n");
  Kapture k(root_);
  EXPECT_EQ(k.ReadDataRecords("camera").size(), 1u);
  const FeatureArray kp = k.ReadKeypoints("kp", "a.jpg");
  EXPECT_EQ(kp.rows, 2);
  EXPECT_EQ(kp.At(1, 0), 3.5);
  EXPECT_TRUE(InspectKapture(root_).problems.empty());
}

TEST_F(HostileKapture, TruncatedBinaryFile) {
  std::string bytes = ReadFile(root_ / "reconstruction/keypoints/kp/a.jpg.kpt");
  bytes.pop_back();
  WriteFileAtomic(root_ / "reconstruction/keypoints/kp/a.jpg.kpt", bytes);
  Kapture k(root_);
  ExpectInputError([&] { k.ReadKeypoints("kp", "a.jpg"); },
                   {"a.jpg.kpt", "size 15 bytes is not a multiple of dsize 2 x sizeof(float32) = 8"});
  Records("1, cam, a.jpg\n");
  ExpectInputError([&] { CopyKapture(root_, root_.parent_path() / "hostile_copy_out"); },
                   {"a.jpg.kpt", "not a multiple"});
  fs::remove_all(root_.parent_path() / "hostile_copy_out");
}

TEST_F(HostileKapture, WrongDsize) {
  WriteFileAtomic(root_ / "reconstruction/keypoints/kp/keypoints.txt",
                  "# kapture format: 1.1\nkp, float32, 3\n");
  Kapture k(root_);
  ExpectInputError([&] { k.ReadKeypoints("kp", "a.jpg"); },
                   {"a.jpg.kpt", "size 16 bytes", "dsize 3", "wrong dtype/dsize"});
  WriteFileAtomic(root_ / "reconstruction/keypoints/kp/keypoints.txt",
                  "# kapture format: 1.1\nkp, float32, 0\n");
  ExpectInputError([&] { Kapture(root_).ReadKeypoints("kp", "a.jpg"); },
                   {"reconstruction/keypoints/kp/keypoints.txt:2: field 'dsize'"});
  WriteFileAtomic(root_ / "reconstruction/keypoints/kp/keypoints.txt",
                  "# kapture format: 1.1\nkp, float128, 2\n");
  ExpectInputError([&] { Kapture(root_).ReadKeypoints("kp", "a.jpg"); },
                   {"keypoints.txt:2: field 'dtype': unknown numpy dtype 'float128'"});
}

TEST_F(HostileKapture, BadFloatNamesFileLineField) {
  WriteFileAtomic(root_ / layout::kTrajectories,
                  "# kapture format: 1.1\n# timestamp, device_id, qw, qx, qy, qz, tx, ty, tz\n"
                  "1, cam, 1, 0, 0, 0, 0, 0, 0\n"
                  "2, cam, abc, 0, 0, 0, 0, 0, 0\n");
  ExpectInputError([&] { Kapture(root_).trajectories(); },
                   {"sensors/trajectories.txt:4: field 'qw': expected a number, got 'abc'"});
  WriteFileAtomic(root_ / layout::kSensors,
                  "# kapture format: 1.1\ncam, , camera, PINHOLE, 640, 480, 5oo, 500, 320, 240\n");
  ExpectInputError([&] { Kapture(root_).sensors(); },
                   {"sensors/sensors.txt:2: field 'fx': expected a number, got '5oo'"});
  Records("1, cam, a.jpg\nx1, cam, a.jpg\n");
  ExpectInputError([&] { Kapture(root_).ReadDataRecords("camera"); },
                   {"sensors/records_camera.txt:4: field 'timestamp': expected an integer, got 'x1'"});
}

TEST_F(HostileKapture, PathTraversalRelative) {
  Records("1, cam, a.jpg\n2, cam, ../../etc/passwd\n");
  ExpectInputError([&] { Kapture(root_).ReadDataRecords("camera"); },
                   {"sensors/records_camera.txt:4", "'../../etc/passwd'", "escapes"});
  const fs::path out = root_.parent_path() / "hostile_traversal_out";
  ExpectInputError([&] { CopyKapture(root_, out); }, {"records_camera.txt:4", "escapes"});
  fs::remove_all(out);
}

TEST_F(HostileKapture, PathTraversalAbsolute) {
  Records("1, cam, /etc/passwd\n");
  ExpectInputError([&] { Kapture(root_).ReadDataRecords("camera"); },
                   {"sensors/records_camera.txt:3", "'/etc/passwd'", "absolute"});
}

// kapture's importers (--image_transfer link_absolute / link_relative) write
// records_data as symbolic links to the original images: links the dataset's
// owner placed are followed wherever they lead; what escapes lexically (an
// absolute record path, "..") is still refused.
TEST_F(HostileKapture, OwnerLinksInRecordsDataAreFollowed) {
  const fs::path originals = root_.parent_path() / (root_.filename().string() + "_originals");
  WriteFileAtomic(originals / "cam/b.jpg", "absolute link target");
  WriteFileAtomic(originals / "cam/c.jpg", "relative link target");
  const fs::path data = root_ / layout::kRecordsData;
  fs::create_directories(data / "cam");
  fs::create_symlink(originals / "cam/b.jpg", data / "cam/b.jpg");                               // link_absolute
  fs::create_symlink(fs::relative(originals / "cam/c.jpg", data / "cam"), data / "cam/c.jpg");  // link_relative
  ASSERT_TRUE(fs::read_symlink(data / "cam/c.jpg").is_relative());
  fs::create_directory_symlink(originals / "cam", data / "linked_folder");  // a whole folder linked
  Records("1, cam, a.jpg\n2, cam, cam/b.jpg\n3, cam, cam/c.jpg\n4, cam, linked_folder/b.jpg\n");
  Kapture k(root_);
  EXPECT_EQ(k.ReadDataRecords("camera").size(), 4u);
  EXPECT_EQ(ReadFile(k.ExistingRecordDataPath("cam/b.jpg")), "absolute link target");
  EXPECT_EQ(ReadFile(k.ExistingRecordDataPath("cam/c.jpg")), "relative link target");
  EXPECT_EQ(ReadFile(k.ExistingRecordDataPath("linked_folder/b.jpg")), "absolute link target");
  const KaptureSummary summary = InspectKapture(root_);
  ASSERT_EQ(summary.records.size(), 1u);
  EXPECT_EQ(summary.records[0].missing_files, 0);
  // A copy holds the files the links name, not links.
  const fs::path out = root_.parent_path() / (root_.filename().string() + "_copy");
  const CopyReport report = CopyKapture(root_, out);
  EXPECT_TRUE(report.missing_data_files.empty());
  EXPECT_FALSE(fs::is_symlink(out / layout::kRecordsData / "cam/c.jpg"));
  EXPECT_EQ(ReadFile(out / layout::kRecordsData / "cam/b.jpg"), "absolute link target");
  EXPECT_EQ(ReadFile(out / layout::kRecordsData / "cam/c.jpg"), "relative link target");
  // Lexical escapes stay refused, links or not.
  Records("1, cam, cam/../../outside.jpg\n");
  ExpectInputError([&] { Kapture(root_).ReadDataRecords("camera"); },
                   {"sensors/records_camera.txt:3", "escapes"});
  Records("1, cam, " + (originals / "cam/b.jpg").string() + "\n");
  ExpectInputError([&] { Kapture(root_).ReadDataRecords("camera"); },
                   {"sensors/records_camera.txt:3", "absolute"});
  ExpectInputError([&] { Kapture(root_).RecordDataPath("../x.jpg", "test"); }, {"test", "escapes"});
  fs::remove_all(out);
  fs::remove_all(originals);
}

TEST_F(HostileKapture, FeatureNameTraversal) {
  Kapture k(root_);
  ExpectInputError([&] { k.ReadKeypoints("kp", "../../../etc/passwd"); }, {"escapes"});
}

TEST_F(HostileKapture, MissingImage) {
  Records("1, cam, a.jpg\n2, cam, b.jpg\n");
  Kapture k(root_);
  const auto records = k.ReadDataRecords("camera");
  ExpectInputError([&] { k.ExistingRecordDataPath(records[1].path, "sensors/records_camera.txt:4"); },
                   {"sensors/records_camera.txt:4: missing file 'b.jpg'"});
  const KaptureSummary s = InspectKapture(root_);
  ASSERT_EQ(s.records.size(), 1u);
  EXPECT_EQ(s.records[0].missing_files, 1);
  EXPECT_EQ(s.features[0].camera_records_without_file, 1);
  bool named = false;
  for (const auto& p : s.problems)
    named |= p == "sensors/records_camera.txt: missing file sensors/records_data/b.jpg";
  EXPECT_TRUE(named);
  // Copy goes on and lists it.
  const fs::path out = root_.parent_path() / "hostile_missing_out";
  const CopyReport r = CopyKapture(root_, out);
  EXPECT_EQ(r.missing_data_files, (std::vector<std::string>{"sensors/records_data/b.jpg"}));
  fs::remove_all(out);
}

TEST_F(HostileKapture, UnknownSensorsAndWrongColumnCounts) {
  Records("1, ghost, a.jpg\n");
  const KaptureSummary s = InspectKapture(root_);
  EXPECT_EQ(s.records[0].unknown_devices, 1);
  Records("1, cam, a.jpg, extra\n");
  ExpectInputError([&] { Kapture(root_).ReadDataRecords("camera"); },
                   {"sensors/records_camera.txt:3", "expected 3 fields", "got 4"});
  WriteFileAtomic(root_ / layout::kRigs, "# kapture format: 1.1\nrig, cam, 1, 0, 0\n");
  ExpectInputError([&] { Kapture(root_).rigs(); }, {"sensors/rigs.txt:2", "expected 9 fields"});
}

TEST_F(HostileKapture, BinaryGarbageInTextFile) {
  WriteFileAtomic(root_ / layout::kSensors, std::string("cam, , lidar\n\0\x01\x02, x\n", 20));
  ExpectInputError([&] { Kapture(root_).sensors(); }, {"sensors/sensors.txt:2", "NUL"});
}

TEST_F(HostileKapture, MatchesOfWrongSize) {
  WriteFileAtomic(root_ / "reconstruction/matches/kp/a.jpg.overlapping/b.jpg.matches",
                  std::string(25, '\0'));
  Kapture k(root_);
  ExpectInputError([&] { k.ReadMatches("kp", "a.jpg", "b.jpg"); },
                   {"b.jpg.matches", "not a multiple", "float64"});
  ExpectInputError([&] { k.ReadMatches("kp", "a.jpg", "c.jpg"); }, {"missing matches file"});
}

// ------------------------------------------------------------ mutations

std::vector<std::string> SampleTexts() {
  std::vector<std::string> texts;
  const fs::path root = locforge::testing::SharedDir() / "data/kapture";
  if (!fs::exists(root)) return texts;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator();
       ++it) {
    if (!it->is_regular_file() || it->path().extension() != ".txt") continue;
    if (it->path().string().find("colmap") != std::string::npos) continue;
    if (it->path().string().find("LICENSE") != std::string::npos) continue;
    std::string text = ReadFile(it->path());
    if (text.size() > 8000) text.resize(text.rfind('\n', 8000) + 1);  // keep each run fast
    texts.push_back(text);
  }
  return texts;
}

std::string Mutate(std::string s, std::mt19937& rng) {
  static const char* kTokens[] = {",",   ", ",   "\n",   "\r\n", "#",    "# kapture format: 1.0\n",
                                  "-",   "e",    "e999", "nan",  "inf",  "..",
                                  "/",   "../",  "/etc/passwd",   "0x1", "1e-400", " ",
                                  "\t",  "\"",   "\0",   "99999999999999999999", "-0.0",
                                  "UNKNOWN_CAMERA", "PINHOLE", "camera", "float16", ".5"};
  const int edits = 1 + static_cast<int>(rng() % 4);
  for (int e = 0; e < edits; ++e) {
    const size_t pos = s.empty() ? 0 : rng() % (s.size() + 1);
    switch (rng() % 7) {
      case 0:  // flip a byte
        if (!s.empty()) s[pos % s.size()] = static_cast<char>(rng() & 0xff);
        break;
      case 1:  // delete a span
        if (!s.empty()) s.erase(pos % s.size(), 1 + rng() % 16);
        break;
      case 2:  // insert a token
      case 3: {
        const char* t = kTokens[rng() % (sizeof(kTokens) / sizeof(kTokens[0]))];
        s.insert(pos, std::string(t, t[0] == '\0' ? 1 : std::strlen(t)));
        break;
      }
      case 4:  // truncate
        s.resize(pos);
        break;
      case 5: {  // duplicate a chunk
        const size_t n = std::min<size_t>(64, s.size() - std::min(pos, s.size()));
        s.insert(pos, s.substr(pos, n));
        break;
      }
      case 6:  // swap two bytes
        if (s.size() > 1) std::swap(s[pos % s.size()], s[rng() % s.size()]);
        break;
    }
  }
  return s;
}

TEST(TextParsersMutation, SamplesParseAndMutationsNeverCrash) {
  const std::vector<std::string> texts = SampleTexts();
  if (texts.empty()) {
    if (locforge::testing::SharedRequired()) FAIL() << "shared data missing";
    GTEST_SKIP() << "shared data absent";
  }
  // Every sample file is accepted by at least one parser.
  for (const std::string& t : texts)
    EXPECT_GE(internal::RunAllTextParsers(reinterpret_cast<const uint8_t*>(t.data()), t.size()), 1)
        << t.substr(0, 200);
  std::mt19937 rng(20240611);
  int accepted = 0;
  const int kMutations = 4000;
  for (int i = 0; i < kMutations; ++i) {
    const std::string m = Mutate(texts[rng() % texts.size()], rng);
    int ok = 0;
    ASSERT_NO_THROW(ok = internal::RunAllTextParsers(reinterpret_cast<const uint8_t*>(m.data()),
                                                     m.size()))
        << "mutation " << i;
    accepted += ok > 0;
  }
  // Sanity: the mutations are not all trivially rejected nor all accepted.
  EXPECT_GT(accepted, kMutations / 20);
  EXPECT_LT(accepted, kMutations);
}

TEST(TextParsersMutation, AcceptedTrajectoriesRoundTrip) {
  // Whatever a mutated trajectories file parses to is written and read back
  // to the same values.
  LOCFORGE_SHARED_PATH_OR_SKIP(src, "data/kapture/m1x_metadata/sensors/trajectories.txt");
  const std::string text = ReadFile(src);
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_rt");
  std::mt19937 rng(99);
  int checked = 0;
  for (int i = 0; i < 400; ++i) {
    std::istringstream in(Mutate(text, rng));
    Trajectories t;
    try {
      t = ParseTrajectories(in, "t");
    } catch (const InputError&) {
      continue;
    }
    WriteTrajectories(tmp / "t.txt", t);
    const Trajectories back = ReadTrajectories(tmp / "t.txt");
    ASSERT_EQ(back.size(), t.size());
    for (const auto& [key, pose] : t.poses) {
      const Pose* b = back.Find(key.first, key.second);
      ASSERT_TRUE(b);
      EXPECT_TRUE(b->q.coeffs() == pose.q.coeffs() || (pose.q.coeffs().array().isNaN().any()));
      EXPECT_TRUE(b->t == pose.t);
    }
    EXPECT_EQ(back.partial, t.partial);
    ++checked;
  }
  EXPECT_GT(checked, 20);
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace locforge::kapture
