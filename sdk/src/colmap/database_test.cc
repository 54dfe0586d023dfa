#include "locforge/colmap/database.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstring>
#include <random>

#include "locforge/colmap/run.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "testing.h"

namespace locforge::colmap {
namespace {

namespace fs = std::filesystem;

// sqlite_master of a database made by `colmap database_creator` (3.8).
constexpr const char* kColmap38Schema =
    "CREATE TABLE cameras   (camera_id            INTEGER  PRIMARY KEY AUTOINCREMENT  NOT NULL,    model                INTEGER                             NOT NULL,    width                INTEGER                             NOT NULL,    height               INTEGER                             NOT NULL,    params               BLOB,    prior_focal_length   INTEGER                             NOT NULL)\n"
    "CREATE TABLE descriptors   (image_id  INTEGER  PRIMARY KEY  NOT NULL,    rows      INTEGER               NOT NULL,    cols      INTEGER               NOT NULL,    data      BLOB,FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE)\n"
    "CREATE TABLE images   (image_id   INTEGER  PRIMARY KEY AUTOINCREMENT  NOT NULL,    name       TEXT                                NOT NULL UNIQUE,    camera_id  INTEGER                             NOT NULL,    prior_qw   REAL,    prior_qx   REAL,    prior_qy   REAL,    prior_qz   REAL,    prior_tx   REAL,    prior_ty   REAL,    prior_tz   REAL,CONSTRAINT image_id_check CHECK(image_id >= 0 and image_id < 2147483647),FOREIGN KEY(camera_id) REFERENCES cameras(camera_id))\n"
    "CREATE TABLE keypoints   (image_id  INTEGER  PRIMARY KEY  NOT NULL,    rows      INTEGER               NOT NULL,    cols      INTEGER               NOT NULL,    data      BLOB,FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE)\n"
    "CREATE TABLE matches   (pair_id  INTEGER  PRIMARY KEY  NOT NULL,    rows     INTEGER               NOT NULL,    cols     INTEGER               NOT NULL,    data     BLOB)\n"
    "CREATE TABLE sqlite_sequence(name,seq)\n"
    "CREATE TABLE two_view_geometries   (pair_id  INTEGER  PRIMARY KEY  NOT NULL,    rows     INTEGER               NOT NULL,    cols     INTEGER               NOT NULL,    data     BLOB,    config   INTEGER               NOT NULL,    F        BLOB,    E        BLOB,    H        BLOB,    qvec     BLOB,    tvec     BLOB)\n"
    "CREATE UNIQUE INDEX index_name ON images(name)\n";

std::string ErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

TEST(ColmapPairId, EncodesDecodesAndOrders) {
  EXPECT_EQ(ImagePairToPairId(1, 2), 2147483649u);
  EXPECT_EQ(ImagePairToPairId(2, 1), 2147483649u);
  EXPECT_EQ(ImagePairToPairId(3, 1), 1 * 2147483647ull + 3);
  EXPECT_EQ(PairIdToImagePair(2147483649u), std::make_pair(1u, 2u));
  EXPECT_EQ(PairIdToImagePair(6442450945u), std::make_pair(3u, 4u));  // maupertuis (3, 4)
  const ImageId big = 2147483646;
  EXPECT_EQ(PairIdToImagePair(ImagePairToPairId(big, big - 1)), std::make_pair(big - 1, big));
  EXPECT_EQ(PairIdToImagePair(ImagePairToPairId(0, big)), std::make_pair(0u, big));
  EXPECT_TRUE(SwapImagePair(5, 4));
  EXPECT_FALSE(SwapImagePair(4, 5));
  std::mt19937 rng(7);
  std::uniform_int_distribution<ImageId> id(0, big);
  for (int i = 0; i < 10000; ++i) {
    const ImageId a = id(rng), b = id(rng);
    const auto [lo, hi] = PairIdToImagePair(ImagePairToPairId(a, b));
    EXPECT_EQ(lo, std::min(a, b));
    EXPECT_EQ(hi, std::max(a, b));
  }
}

class ColmapDatabase : public ::testing::Test {
 protected:
  void SetUp() override { tmp_ = testing::MakeTempDir("colmap_db"); }
  void TearDown() override { fs::remove_all(tmp_); }
  fs::path tmp_;
};

TEST_F(ColmapDatabase, SchemaIsColmap38s) {
  {
    Database db(tmp_ / "ours.db", Database::Mode::kCreate);
    EXPECT_EQ(db.SchemaSql(), kColmap38Schema);
    EXPECT_EQ(db.UserVersion(), 3800);
    EXPECT_TRUE(db.HasPoseColumnsInTwoViewGeometries());
  }
  if (FindColmapExecutable().empty()) GTEST_SKIP() << "colmap executable not available";
  RunOptions options;
  options.log_file = tmp_ / "colmap.log";
  options.timeout_s = 60;
  RunColmap({"database_creator", "--database_path", (tmp_ / "colmap.db").string()}, options);
  Database theirs(tmp_ / "colmap.db");
  EXPECT_EQ(theirs.SchemaSql(), kColmap38Schema);
  EXPECT_EQ(theirs.UserVersion(), 3800);
}

TwoViewGeometry SomeGeometry() {
  TwoViewGeometry g;
  g.config = static_cast<int>(TwoViewConfig::kCalibrated);
  g.inlier_matches = {{0, 1}, {2, 3}, {4, 0}};
  for (int i = 0; i < 9; ++i) {
    g.F(i / 3, i % 3) = 0.1 * i + 0.01;
    g.E(i / 3, i % 3) = -0.2 * i + 0.5;
    g.H(i / 3, i % 3) = (i % 4 == 0 ? 1.0 : 0.05 * i);
  }
  const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  g.qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
  g.tvec = Eigen::Vector3d(0.1, -0.2, 0.97);
  return g;
}

TEST_F(ColmapDatabase, WriteThenReadBackEveryBlob) {
  const fs::path path = tmp_ / "rt.db";
  KeypointsBlob k2{3, 2, {1.5f, 2.5f, 3.5f, 4.5f, 5.5f, 6.5f}};
  KeypointsBlob k6{1, 6, {10, 20, 1, 0, 0, 1}};
  DescriptorsBlob d{2, 128, std::vector<uint8_t>(256)};
  for (size_t i = 0; i < d.data.size(); ++i) d.data[i] = static_cast<uint8_t>(i * 7);
  const FeatureMatches m12 = {{0, 0}, {1, 0}, {2, 0}};
  const FeatureMatches m31 = {{0, 2}};  // written as (3, 1): stored swapped
  const TwoViewGeometry g = SomeGeometry();
  {
    Database db(path, Database::Mode::kCreate);
    DatabaseWriter w(&db, 2);  // small batches: several commits
    DbCamera c;
    c.camera_id = 5;
    c.camera.model = CameraModelId::kOpenCV;
    c.camera.width = 1920;
    c.camera.height = 1080;
    c.camera.params = {1000, 1001, 960, 540, 0.1, -0.01, 0.001, 0.0001};
    c.prior_focal_length = true;
    EXPECT_EQ(w.WriteCamera(c, true), 5u);
    DbImage i;
    i.camera_id = 5;
    for (const char* name : {"a.jpg", "b.jpg", "c.jpg"}) {
      i.name = name;
      i.prior_qvec = i.name == "b.jpg" ? std::optional<Eigen::Vector4d>({1, 0, 0, 0}) : std::nullopt;
      i.prior_tvec = i.name == "b.jpg" ? std::optional<Eigen::Vector3d>({1, 2, 3}) : std::nullopt;
      w.WriteImage(i, false);  // autoincrement: 1, 2, 3
    }
    w.WriteKeypoints(1, k2);
    w.WriteKeypoints(2, k6);
    w.WriteDescriptors(1, d);
    w.WriteMatches(1, 2, m12);
    w.WriteMatches(3, 1, m31);
    w.WriteTwoViewGeometry(2, 1, g);  // swapped: stored inverted
    TwoViewGeometry empty;
    empty.config = static_cast<int>(TwoViewConfig::kDegenerate);
    w.WriteTwoViewGeometry(2, 3, empty);
    w.Finish();
  }
  Database db(path);
  const auto cameras = db.ReadCameras();
  ASSERT_EQ(cameras.size(), 1u);
  EXPECT_EQ(cameras[0].camera_id, 5u);
  EXPECT_EQ(cameras[0].camera.model, CameraModelId::kOpenCV);
  EXPECT_EQ(cameras[0].camera.params, (std::vector<double>{1000, 1001, 960, 540, 0.1, -0.01, 0.001, 0.0001}));
  EXPECT_TRUE(cameras[0].prior_focal_length);
  const auto images = db.ReadImages();
  ASSERT_EQ(images.size(), 3u);
  EXPECT_EQ(images[1].image_id, 2u);
  EXPECT_EQ(images[1].name, "b.jpg");
  EXPECT_EQ(*images[1].prior_tvec, Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(images[0].prior_qvec.has_value());
  EXPECT_EQ(db.ReadKeypoints(1)->data, k2.data);
  EXPECT_EQ(db.ReadKeypoints(2)->cols, 6u);
  EXPECT_EQ(db.ReadKeypoints(2)->data, k6.data);
  EXPECT_FALSE(db.ReadKeypoints(3).has_value());
  EXPECT_EQ(db.ReadDescriptors(1)->data, d.data);
  EXPECT_EQ(*db.ReadMatches(1, 2), m12);
  EXPECT_EQ(*db.ReadMatches(3, 1), m31);
  const FeatureMatches m13 = {{2, 0}};
  EXPECT_EQ(*db.ReadMatches(1, 3), m13);  // stored order: (1, 3)
  EXPECT_EQ(db.NumKeypointRows(), 4u);
  EXPECT_EQ(db.NumMatchedPairs(), 2u);
  // Streaming readers visit pairs in pair_id order with id1 < id2.
  std::vector<std::pair<ImageId, ImageId>> pairs;
  db.ForEachMatches([&](ImageId a, ImageId b, const FeatureMatches& m) {
    pairs.emplace_back(a, b);
    EXPECT_EQ(m, a == 1 && b == 2 ? m12 : m13);
    return true;
  });
  EXPECT_EQ(pairs, (std::vector<std::pair<ImageId, ImageId>>{{1, 2}, {1, 3}}));
  // The geometry read in the order it was written is the same; read the
  // other way it is the inverse.
  const TwoViewGeometry back = *db.ReadTwoViewGeometry(2, 1);
  EXPECT_EQ(back.config, g.config);
  EXPECT_EQ(back.inlier_matches, g.inlier_matches);
  EXPECT_LT((back.F - g.F).norm(), 1e-15);
  EXPECT_LT((back.E - g.E).norm(), 1e-15);
  EXPECT_LT((back.H - g.H).norm(), 1e-12);
  EXPECT_LT((back.qvec - g.qvec).norm(), 1e-15);
  EXPECT_LT((back.tvec - g.tvec).norm(), 1e-15);
  const TwoViewGeometry stored = *db.ReadTwoViewGeometry(1, 2);
  EXPECT_EQ(stored.F, g.F.transpose());
  EXPECT_EQ(stored.inlier_matches, (FeatureMatches{{1, 0}, {3, 2}, {0, 4}}));
  // Relative poses compose to identity.
  const Eigen::Quaterniond q(g.qvec(0), g.qvec(1), g.qvec(2), g.qvec(3));
  const Eigen::Quaterniond qi(stored.qvec(0), stored.qvec(1), stored.qvec(2), stored.qvec(3));
  EXPECT_LT(((qi * q).vec()).norm(), 1e-15);
  EXPECT_LT((qi * g.tvec + stored.tvec).norm(), 1e-15);
  const TwoViewGeometry degenerate = *db.ReadTwoViewGeometry(2, 3);
  EXPECT_TRUE(degenerate.inlier_matches.empty());
  EXPECT_EQ(degenerate.config, 1);
  EXPECT_EQ(db.NumTwoViewGeometries(), 2u);
}

TEST_F(ColmapDatabase, BatchedWriterRollsBackUnfinishedBatch) {
  const fs::path path = tmp_ / "rb.db";
  {
    Database db(path, Database::Mode::kCreate);
    DbCamera c;
    c.camera_id = 1;
    c.camera.model = CameraModelId::kSimplePinhole;
    c.camera.width = 10;
    c.camera.height = 10;
    c.camera.params = {5, 5, 5};
    db.WriteCamera(c, true);
    DatabaseWriter w(&db, 1000);
    DbImage i;
    i.camera_id = 1;
    i.name = "x.jpg";
    w.WriteImage(i, false);
  }  // no Finish()
  Database db(path);
  EXPECT_EQ(db.NumCameras(), 1u);
  EXPECT_EQ(db.NumImages(), 0u);
}

TEST_F(ColmapDatabase, RefusesBadInput) {
  const fs::path path = tmp_ / "bad.db";
  {
    Database db(path, Database::Mode::kCreate);
    DbCamera c;
    c.camera_id = 1;
    c.camera.model = CameraModelId::kPinhole;
    c.camera.width = 10;
    c.camera.height = 10;
    c.camera.params = {5, 5, 5};  // PINHOLE needs 4
    EXPECT_NE(ErrorOf([&] { db.WriteCamera(c, true); }).find("bad.db"), std::string::npos);
    c.camera.params.push_back(5);
    db.WriteCamera(c, true);
    DbImage i;
    i.camera_id = 1;
    i.name = "x.jpg";
    db.WriteImage(i, false);
    // Same name twice: UNIQUE constraint.
    EXPECT_NE(ErrorOf([&] { db.WriteImage(i, false); }).find("UNIQUE"), std::string::npos);
    // Foreign key: keypoints of a missing image.
    EXPECT_NE(ErrorOf([&] { db.WriteKeypoints(9, {1, 2, {1, 2}}); }).find("FOREIGN KEY"),
              std::string::npos);
    EXPECT_NE(ErrorOf([&] { db.WriteKeypoints(1, {1, 3, {1, 2, 3}}); }).find("2, 4 or 6"),
              std::string::npos);
    db.WriteKeypoints(1, {2, 2, {1, 2, 3, 4}});
    // Corrupt blobs as another tool might write them.
    db.Execute("UPDATE keypoints SET rows = 3 WHERE image_id = 1;");
    db.Execute("INSERT INTO matches VALUES(2147483649, 2, 2, zeroblob(12));");
    db.Execute("UPDATE cameras SET params = zeroblob(8) WHERE camera_id = 1;");
  }
  Database db(path);
  std::string e = ErrorOf([&] { db.ReadKeypoints(1); });
  EXPECT_NE(e.find("bad.db: field 'keypoints (image_id 1).data': blob has 16 bytes, expected rows x cols x 4 = 3 x 2 x 4 = 24"),
            std::string::npos) << e;
  e = ErrorOf([&] { db.ReadMatches(1, 2); });
  EXPECT_NE(e.find("field 'matches (pair_id 2147483649).data': blob has 12 bytes"), std::string::npos) << e;
  e = ErrorOf([&] { db.ReadCameras(); });
  EXPECT_NE(e.find("field 'cameras (camera_id 1).params'"), std::string::npos) << e;
  // Not a database, not a COLMAP database, missing file.
  WriteFileAtomic(tmp_ / "text.db", std::string(4096, 'x'));
  e = ErrorOf([&] { Database x(tmp_ / "text.db"); });
  EXPECT_NE(e.find("text.db"), std::string::npos) << e;
  EXPECT_NE(e.find("not a database"), std::string::npos) << e;
  e = ErrorOf([&] { Database x(tmp_ / "missing.db"); });
  EXPECT_NE(e.find("missing.db: no such database file"), std::string::npos) << e;
}

// The kapture toolbox's export (maupertuis/colmap/colmap.db) has the older
// two_view_geometries without qvec/tvec; it reads, and its keypoint blobs
// are the kapture keypoint files byte for byte (see convention.h).
TEST_F(ColmapDatabase, ReadsTheMaupertuisDatabase) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/maupertuis");
  Database db(root / "colmap/colmap.db");
  EXPECT_FALSE(db.HasPoseColumnsInTwoViewGeometries());
  ASSERT_EQ(db.ReadCameras().size(), 1u);
  // The database keeps the initial guess (1.2 x width); the model the refined focal.
  EXPECT_EQ(db.ReadCameras()[0].camera.params, (std::vector<double>{1.2 * 1919, 959.5, 539.5}));
  const auto images = db.ReadImages();
  ASSERT_EQ(images.size(), 4u);
  EXPECT_EQ(images[0].name, "00.jpg");
  EXPECT_EQ(db.NumMatchedPairs(), 6u);
  size_t visited = 0;
  db.ForEachKeypoints([&](ImageId id, const KeypointsBlob& k) {
    const std::string kpt = ReadFile(root / "kapture/reconstruction/keypoints/SIFT" /
                                     (images[id - 1].name + ".kpt"));
    EXPECT_EQ(k.cols, 6u);
    EXPECT_EQ(kpt.size(), k.data.size() * sizeof(float));
    EXPECT_EQ(std::memcmp(kpt.data(), k.data.data(), kpt.size()), 0) << images[id - 1].name;
    ++visited;
    return true;
  });
  EXPECT_EQ(visited, 4u);
  const TwoViewGeometry g = *db.ReadTwoViewGeometry(1, 2);
  EXPECT_EQ(g.inlier_matches.size(), 2501u);
  EXPECT_EQ(g.inlier_matches[0], std::make_pair(3u, 1u));
  EXPECT_EQ(g.config, static_cast<int>(TwoViewConfig::kUncalibrated));
  EXPECT_DOUBLE_EQ(g.F(2, 2), 1.0);
  EXPECT_EQ(db.ReadMatches(1, 2)->size(), 2516u);
}

}  // namespace
}  // namespace locforge::colmap
