#include "locforge/colmap/database.h"

#include <sqlite3.h>

#include <Eigen/Geometry>
#include <cstring>

#include "locforge/error.h"

namespace locforge::colmap {

namespace fs = std::filesystem;

PairId ImagePairToPairId(ImageId image_id1, ImageId image_id2) {
  if (SwapImagePair(image_id1, image_id2)) std::swap(image_id1, image_id2);
  return kMaxNumImages * static_cast<uint64_t>(image_id1) + image_id2;
}

std::pair<ImageId, ImageId> PairIdToImagePair(PairId pair_id) {
  const uint64_t image_id2 = pair_id % kMaxNumImages;
  const uint64_t image_id1 = (pair_id - image_id2) / kMaxNumImages;
  return {static_cast<ImageId>(image_id1), static_cast<ImageId>(image_id2)};
}

TwoViewGeometry TwoViewGeometry::Inverted() const {
  TwoViewGeometry inv = *this;
  inv.F.transposeInPlace();
  inv.E.transposeInPlace();
  inv.H = H.inverse().eval();
  inv.qvec = Eigen::Vector4d(qvec(0), -qvec(1), -qvec(2), -qvec(3));
  const Eigen::Quaterniond q_inv(inv.qvec(0), inv.qvec(1), inv.qvec(2), inv.qvec(3));
  inv.tvec = -(q_inv.normalized() * tvec);
  for (auto& m : inv.inlier_matches) std::swap(m.first, m.second);
  return inv;
}

namespace {

// COLMAP 3.8's CREATE statements (src/base/database.cc), verbatim, so
// sqlite_master holds the same schema text as a database made by `colmap`.
constexpr const char* kCreateCameras =
    "CREATE TABLE IF NOT EXISTS cameras"
    "   (camera_id            INTEGER  PRIMARY KEY AUTOINCREMENT  NOT NULL,"
    "    model                INTEGER                             NOT NULL,"
    "    width                INTEGER                             NOT NULL,"
    "    height               INTEGER                             NOT NULL,"
    "    params               BLOB,"
    "    prior_focal_length   INTEGER                             NOT NULL);";
constexpr const char* kCreateImages =
    "CREATE TABLE IF NOT EXISTS images"
    "   (image_id   INTEGER  PRIMARY KEY AUTOINCREMENT  NOT NULL,"
    "    name       TEXT                                NOT NULL UNIQUE,"
    "    camera_id  INTEGER                             NOT NULL,"
    "    prior_qw   REAL,"
    "    prior_qx   REAL,"
    "    prior_qy   REAL,"
    "    prior_qz   REAL,"
    "    prior_tx   REAL,"
    "    prior_ty   REAL,"
    "    prior_tz   REAL,"
    "CONSTRAINT image_id_check CHECK(image_id >= 0 and image_id < 2147483647),"
    "FOREIGN KEY(camera_id) REFERENCES cameras(camera_id));"
    "CREATE UNIQUE INDEX IF NOT EXISTS index_name ON images(name);";
constexpr const char* kCreateKeypoints =
    "CREATE TABLE IF NOT EXISTS keypoints"
    "   (image_id  INTEGER  PRIMARY KEY  NOT NULL,"
    "    rows      INTEGER               NOT NULL,"
    "    cols      INTEGER               NOT NULL,"
    "    data      BLOB,"
    "FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE);";
constexpr const char* kCreateDescriptors =
    "CREATE TABLE IF NOT EXISTS descriptors"
    "   (image_id  INTEGER  PRIMARY KEY  NOT NULL,"
    "    rows      INTEGER               NOT NULL,"
    "    cols      INTEGER               NOT NULL,"
    "    data      BLOB,"
    "FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE);";
constexpr const char* kCreateMatches =
    "CREATE TABLE IF NOT EXISTS matches"
    "   (pair_id  INTEGER  PRIMARY KEY  NOT NULL,"
    "    rows     INTEGER               NOT NULL,"
    "    cols     INTEGER               NOT NULL,"
    "    data     BLOB);";
constexpr const char* kCreateTwoViewGeometries =
    "CREATE TABLE IF NOT EXISTS two_view_geometries"
    "   (pair_id  INTEGER  PRIMARY KEY  NOT NULL,"
    "    rows     INTEGER               NOT NULL,"
    "    cols     INTEGER               NOT NULL,"
    "    data     BLOB,"
    "    config   INTEGER               NOT NULL,"
    "    F        BLOB,"
    "    E        BLOB,"
    "    H        BLOB,"
    "    qvec     BLOB,"
    "    tvec     BLOB);";
constexpr int kColmapVersionNumber = 3800;  // PRAGMA user_version of 3.8

class Stmt {
 public:
  Stmt(sqlite3* db, const std::string& sql, const std::string& where) : db_(db), where_(where) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK) {
      throw Error(where + ": cannot prepare '" + sql + "': " + sqlite3_errmsg(db));
    }
  }
  ~Stmt() { sqlite3_finalize(stmt_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  sqlite3_stmt* get() { return stmt_; }
  // True when a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw Error(where_ + ": " + sqlite3_errmsg(db_));
  }
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  void Check(int rc) {
    if (rc != SQLITE_OK) throw Error(where_ + ": " + sqlite3_errmsg(db_));
  }
  void BindInt(int col, int64_t v) { Check(sqlite3_bind_int64(stmt_, col, v)); }
  void BindNull(int col) { Check(sqlite3_bind_null(stmt_, col)); }
  void BindDouble(int col, double v) { Check(sqlite3_bind_double(stmt_, col, v)); }
  void BindText(int col, const std::string& s) {
    Check(sqlite3_bind_text(stmt_, col, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT));
  }
  // Empty blobs bind NULL, as COLMAP's sqlite3_bind_blob(nullptr, 0) does.
  void BindBlob(int col, const void* data, size_t bytes) {
    if (bytes == 0) return BindNull(col);
    if (bytes > static_cast<size_t>(INT32_MAX)) throw Error(where_ + ": blob larger than 2 GiB");
    Check(sqlite3_bind_blob(stmt_, col, data, static_cast<int>(bytes), SQLITE_STATIC));
  }
  int64_t Int(int col) { return sqlite3_column_int64(stmt_, col); }
  bool IsNull(int col) { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  double Double(int col) { return sqlite3_column_double(stmt_, col); }
  std::string Text(int col) {
    const auto* p = sqlite3_column_text(stmt_, col);
    return p ? std::string(reinterpret_cast<const char*>(p), sqlite3_column_bytes(stmt_, col))
             : std::string();
  }
  std::pair<const void*, size_t> Blob(int col) {
    const void* p = sqlite3_column_blob(stmt_, col);
    return {p, static_cast<size_t>(sqlite3_column_bytes(stmt_, col))};
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  std::string where_;
};

}  // namespace

struct Database::Impl {
  sqlite3* db = nullptr;
  std::string file;
  std::unique_ptr<Stmt> write_camera, write_image, write_keypoints, write_descriptors,
      write_matches, write_tvg;

  void Exec(const std::string& sql) {
    char* msg = nullptr;
    if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &msg) != SQLITE_OK) {
      const std::string what = msg ? msg : sqlite3_errmsg(db);
      sqlite3_free(msg);
      throw Error(file + ": " + what + " (in '" + sql.substr(0, 80) + "')");
    }
  }
  bool HasColumn(const std::string& table, const std::string& column) {
    Stmt s(db, "PRAGMA table_info(" + table + ");", file);
    while (s.Step()) {
      if (s.Text(1) == column) return true;
    }
    return false;
  }
  bool HasTable(const std::string& table) {
    Stmt s(db, "SELECT name FROM sqlite_master WHERE type='table' AND name=?;", file);
    s.BindText(1, table);
    return s.Step();
  }
  // A blob of `rows x cols` elements of `elem` bytes, named for errors.
  template <typename T>
  void ReadBlob(Stmt& s, int col, uint64_t rows, uint64_t cols, const std::string& field,
                std::vector<T>* out) {
    const auto [data, bytes] = s.Blob(col);
    const uint64_t expected = rows * cols * sizeof(T);
    if (bytes != expected) {
      throw InputError(file, 0, field,
                       "blob has " + std::to_string(bytes) + " bytes, expected rows x cols x " +
                           std::to_string(sizeof(T)) + " = " + std::to_string(rows) + " x " +
                           std::to_string(cols) + " x " + std::to_string(sizeof(T)) + " = " +
                           std::to_string(expected));
    }
    out->resize(rows * cols);
    if (bytes > 0) std::memcpy(out->data(), data, bytes);
  }
  // A fixed-size double blob (F, E, H, qvec, tvec); empty or NULL reads as zeros.
  void ReadFixed(Stmt& s, int col, double* dst, size_t n, const std::string& field) {
    const auto [data, bytes] = s.Blob(col);
    if (bytes == 0) {
      std::fill(dst, dst + n, 0.0);
      return;
    }
    if (bytes != n * sizeof(double)) {
      throw InputError(file, 0, field,
                       "blob has " + std::to_string(bytes) + " bytes, expected " +
                           std::to_string(n * sizeof(double)));
    }
    std::memcpy(dst, data, bytes);
  }
  FeatureMatches ReadMatchesBlob(Stmt& s, int rows_col, const std::string& field) {
    const int64_t rows = s.Int(rows_col);
    const int64_t cols = s.Int(rows_col + 1);
    if (rows < 0 || (rows > 0 && cols != 2)) {
      throw InputError(file, 0, field,
                       "expected rows x 2 matches, got " + std::to_string(rows) + " x " +
                           std::to_string(cols));
    }
    std::vector<uint32_t> raw;
    ReadBlob(s, rows_col + 2, static_cast<uint64_t>(rows), rows > 0 ? 2 : 0, field, &raw);
    FeatureMatches m(static_cast<size_t>(rows));
    for (size_t i = 0; i < m.size(); ++i) m[i] = {raw[2 * i], raw[2 * i + 1]};
    return m;
  }
};

Database::Database(const fs::path& path, Mode mode) : impl_(new Impl), path_(path) {
  impl_->file = path.string();
  if (mode != Mode::kCreate && !fs::exists(path)) {
    throw InputError(impl_->file, 0, "", "no such database file");
  }
  const int flags = mode == Mode::kReadOnly ? SQLITE_OPEN_READONLY
                    : mode == Mode::kReadWrite ? SQLITE_OPEN_READWRITE
                                               : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE;
  if (sqlite3_open_v2(impl_->file.c_str(), &impl_->db, flags | SQLITE_OPEN_NOMUTEX, nullptr) !=
      SQLITE_OK) {
    const std::string what = impl_->db ? sqlite3_errmsg(impl_->db) : "out of memory";
    sqlite3_close(impl_->db);
    throw InputError(impl_->file, 0, "", "cannot open SQLite database: " + what);
  }
  try {
    // Fails on a file that is not SQLite ("file is not a database").
    impl_->Exec("SELECT count(*) FROM sqlite_master;");
    if (mode != Mode::kReadOnly) {
      // As COLMAP's Database::Open.
      impl_->Exec("PRAGMA synchronous=OFF;");
      impl_->Exec("PRAGMA journal_mode=WAL;");
      impl_->Exec("PRAGMA temp_store=MEMORY;");
      impl_->Exec("PRAGMA foreign_keys=ON;");
      for (const char* sql : {kCreateCameras, kCreateImages, kCreateKeypoints, kCreateDescriptors,
                              kCreateMatches, kCreateTwoViewGeometries}) {
        impl_->Exec(sql);
      }
      // COLMAP's UpdateSchema for databases of older versions.
      if (!impl_->HasColumn("two_view_geometries", "F")) {
        impl_->Exec("ALTER TABLE two_view_geometries ADD COLUMN F BLOB;");
        impl_->Exec("ALTER TABLE two_view_geometries ADD COLUMN E BLOB;");
        impl_->Exec("ALTER TABLE two_view_geometries ADD COLUMN H BLOB;");
      }
      if (!impl_->HasColumn("two_view_geometries", "qvec")) {
        impl_->Exec("ALTER TABLE two_view_geometries ADD COLUMN qvec BLOB;");
        impl_->Exec("ALTER TABLE two_view_geometries ADD COLUMN tvec BLOB;");
      }
      impl_->Exec("PRAGMA user_version = " + std::to_string(kColmapVersionNumber) + ";");
    } else {
      for (const char* table :
           {"cameras", "images", "keypoints", "descriptors", "matches", "two_view_geometries"}) {
        if (!impl_->HasTable(table)) {
          throw InputError(impl_->file, 0, table, "not a COLMAP database: table missing");
        }
      }
    }
    has_tvg_pose_ = impl_->HasColumn("two_view_geometries", "qvec");
  } catch (const Error& e) {
    sqlite3_close(impl_->db);
    impl_->db = nullptr;
    throw InputError(e.what());
  }
}

Database::~Database() {
  if (!impl_) return;
  impl_->write_camera.reset();
  impl_->write_image.reset();
  impl_->write_keypoints.reset();
  impl_->write_descriptors.reset();
  impl_->write_matches.reset();
  impl_->write_tvg.reset();
  if (impl_->db) sqlite3_close(impl_->db);
}

namespace {
size_t CountRows(sqlite3* db, const std::string& file, const std::string& sql) {
  Stmt s(db, sql, file);
  return s.Step() ? static_cast<size_t>(s.Int(0)) : 0;
}
}  // namespace

size_t Database::NumCameras() const {
  return CountRows(impl_->db, impl_->file, "SELECT COUNT(*) FROM cameras;");
}
size_t Database::NumImages() const {
  return CountRows(impl_->db, impl_->file, "SELECT COUNT(*) FROM images;");
}
size_t Database::NumKeypointRows() const {
  return CountRows(impl_->db, impl_->file, "SELECT IFNULL(SUM(rows), 0) FROM keypoints;");
}
size_t Database::NumMatchedPairs() const {
  return CountRows(impl_->db, impl_->file, "SELECT COUNT(*) FROM matches;");
}
size_t Database::NumTwoViewGeometries() const {
  return CountRows(impl_->db, impl_->file, "SELECT COUNT(*) FROM two_view_geometries;");
}

std::vector<DbCamera> Database::ReadCameras() const {
  Stmt s(impl_->db,
         "SELECT camera_id, model, width, height, params, prior_focal_length FROM cameras "
         "ORDER BY camera_id;",
         impl_->file);
  std::vector<DbCamera> cameras;
  while (s.Step()) {
    DbCamera c;
    c.camera_id = static_cast<CameraId>(s.Int(0));
    const std::string field = "cameras (camera_id " + std::to_string(c.camera_id) + ")";
    const int64_t model = s.Int(1);
    if (model < 0 || model > static_cast<int>(CameraModelId::kThinPrismFisheye)) {
      throw InputError(impl_->file, 0, field + ".model",
                       "unknown COLMAP camera model id " + std::to_string(model));
    }
    c.camera.model = static_cast<CameraModelId>(model);
    c.camera.width = static_cast<int>(s.Int(2));
    c.camera.height = static_cast<int>(s.Int(3));
    const uint64_t n = CameraModelInfoOf(c.camera.model).num_params;
    impl_->ReadBlob(s, 4, n, 1, field + ".params", &c.camera.params);
    c.prior_focal_length = s.Int(5) != 0;
    cameras.push_back(std::move(c));
  }
  return cameras;
}

std::vector<DbImage> Database::ReadImages() const {
  Stmt s(impl_->db,
         "SELECT image_id, name, camera_id, prior_qw, prior_qx, prior_qy, prior_qz, prior_tx, "
         "prior_ty, prior_tz FROM images ORDER BY image_id;",
         impl_->file);
  std::vector<DbImage> images;
  while (s.Step()) {
    DbImage image;
    image.image_id = static_cast<ImageId>(s.Int(0));
    image.name = s.Text(1);
    image.camera_id = static_cast<CameraId>(s.Int(2));
    bool has_q = true, has_t = true;
    for (int k = 3; k < 7; ++k) has_q = has_q && !s.IsNull(k);
    for (int k = 7; k < 10; ++k) has_t = has_t && !s.IsNull(k);
    if (has_q) image.prior_qvec = Eigen::Vector4d(s.Double(3), s.Double(4), s.Double(5), s.Double(6));
    if (has_t) image.prior_tvec = Eigen::Vector3d(s.Double(7), s.Double(8), s.Double(9));
    images.push_back(std::move(image));
  }
  return images;
}

namespace {

KeypointsBlob ReadKeypointsRow(Database::Impl& impl, Stmt& s, ImageId image_id, int col) {
  KeypointsBlob k;
  const std::string field = "keypoints (image_id " + std::to_string(image_id) + ")";
  const int64_t rows = s.Int(col), cols = s.Int(col + 1);
  if (rows < 0 || (rows > 0 && cols != 2 && cols != 4 && cols != 6)) {
    throw InputError(impl.file, 0, field + ".cols",
                     "expected 2, 4 or 6 columns, got " + std::to_string(cols));
  }
  k.rows = static_cast<uint32_t>(rows);
  k.cols = static_cast<uint32_t>(cols);
  impl.ReadBlob(s, col + 2, k.rows, k.cols, field + ".data", &k.data);
  return k;
}

DescriptorsBlob ReadDescriptorsRow(Database::Impl& impl, Stmt& s, ImageId image_id, int col) {
  DescriptorsBlob d;
  const std::string field = "descriptors (image_id " + std::to_string(image_id) + ")";
  const int64_t rows = s.Int(col), cols = s.Int(col + 1);
  if (rows < 0 || cols < 0) throw InputError(impl.file, 0, field + ".rows", "negative size");
  d.rows = static_cast<uint32_t>(rows);
  d.cols = static_cast<uint32_t>(cols);
  impl.ReadBlob(s, col + 2, d.rows, d.cols, field + ".data", &d.data);
  return d;
}

TwoViewGeometry ReadTvgRow(Database::Impl& impl, Stmt& s, PairId pair_id, bool has_pose) {
  const std::string field = "two_view_geometries (pair_id " + std::to_string(pair_id) + ")";
  TwoViewGeometry g;
  g.inlier_matches = impl.ReadMatchesBlob(s, 1, field + ".data");
  g.config = static_cast<int>(s.Int(4));
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> m;
  impl.ReadFixed(s, 5, m.data(), 9, field + ".F");
  g.F = m;
  impl.ReadFixed(s, 6, m.data(), 9, field + ".E");
  g.E = m;
  impl.ReadFixed(s, 7, m.data(), 9, field + ".H");
  g.H = m;
  if (has_pose) {
    impl.ReadFixed(s, 8, g.qvec.data(), 4, field + ".qvec");
    impl.ReadFixed(s, 9, g.tvec.data(), 3, field + ".tvec");
  } else {
    g.qvec.setZero();
    g.tvec.setZero();
  }
  return g;
}

std::string TvgSelect(bool has_pose) {
  return std::string("SELECT pair_id, rows, cols, data, config, F, E, H") +
         (has_pose ? ", qvec, tvec" : "") + " FROM two_view_geometries";
}

}  // namespace

std::optional<KeypointsBlob> Database::ReadKeypoints(ImageId image_id) const {
  Stmt s(impl_->db, "SELECT rows, cols, data FROM keypoints WHERE image_id = ?;", impl_->file);
  s.BindInt(1, image_id);
  if (!s.Step()) return std::nullopt;
  return ReadKeypointsRow(*impl_, s, image_id, 0);
}

std::optional<DescriptorsBlob> Database::ReadDescriptors(ImageId image_id) const {
  Stmt s(impl_->db, "SELECT rows, cols, data FROM descriptors WHERE image_id = ?;", impl_->file);
  s.BindInt(1, image_id);
  if (!s.Step()) return std::nullopt;
  return ReadDescriptorsRow(*impl_, s, image_id, 0);
}

std::optional<FeatureMatches> Database::ReadMatches(ImageId image_id1, ImageId image_id2) const {
  const PairId pair_id = ImagePairToPairId(image_id1, image_id2);
  Stmt s(impl_->db, "SELECT pair_id, rows, cols, data FROM matches WHERE pair_id = ?;",
         impl_->file);
  s.BindInt(1, static_cast<int64_t>(pair_id));
  if (!s.Step()) return std::nullopt;
  FeatureMatches m = impl_->ReadMatchesBlob(s, 1, "matches (pair_id " + std::to_string(pair_id) + ").data");
  if (SwapImagePair(image_id1, image_id2)) {
    for (auto& p : m) std::swap(p.first, p.second);
  }
  return m;
}

std::optional<TwoViewGeometry> Database::ReadTwoViewGeometry(ImageId image_id1,
                                                             ImageId image_id2) const {
  const PairId pair_id = ImagePairToPairId(image_id1, image_id2);
  Stmt s(impl_->db, TvgSelect(has_tvg_pose_) + " WHERE pair_id = ?;", impl_->file);
  s.BindInt(1, static_cast<int64_t>(pair_id));
  if (!s.Step()) return std::nullopt;
  TwoViewGeometry g = ReadTvgRow(*impl_, s, pair_id, has_tvg_pose_);
  if (SwapImagePair(image_id1, image_id2)) return g.Inverted();
  return g;
}

void Database::ForEachKeypoints(
    const std::function<bool(ImageId, const KeypointsBlob&)>& fn) const {
  Stmt s(impl_->db, "SELECT image_id, rows, cols, data FROM keypoints ORDER BY image_id;",
         impl_->file);
  while (s.Step()) {
    const auto id = static_cast<ImageId>(s.Int(0));
    if (!fn(id, ReadKeypointsRow(*impl_, s, id, 1))) return;
  }
}

void Database::ForEachDescriptors(
    const std::function<bool(ImageId, const DescriptorsBlob&)>& fn) const {
  Stmt s(impl_->db, "SELECT image_id, rows, cols, data FROM descriptors ORDER BY image_id;",
         impl_->file);
  while (s.Step()) {
    const auto id = static_cast<ImageId>(s.Int(0));
    if (!fn(id, ReadDescriptorsRow(*impl_, s, id, 1))) return;
  }
}

void Database::ForEachMatches(
    const std::function<bool(ImageId, ImageId, const FeatureMatches&)>& fn) const {
  Stmt s(impl_->db, "SELECT pair_id, rows, cols, data FROM matches ORDER BY pair_id;",
         impl_->file);
  while (s.Step()) {
    const auto pair_id = static_cast<PairId>(s.Int(0));
    const auto [id1, id2] = PairIdToImagePair(pair_id);
    if (!fn(id1, id2,
            impl_->ReadMatchesBlob(s, 1, "matches (pair_id " + std::to_string(pair_id) + ").data"))) {
      return;
    }
  }
}

void Database::ForEachTwoViewGeometry(
    const std::function<bool(ImageId, ImageId, const TwoViewGeometry&)>& fn) const {
  Stmt s(impl_->db, TvgSelect(has_tvg_pose_) + " ORDER BY pair_id;", impl_->file);
  while (s.Step()) {
    const auto pair_id = static_cast<PairId>(s.Int(0));
    const auto [id1, id2] = PairIdToImagePair(pair_id);
    if (!fn(id1, id2, ReadTvgRow(*impl_, s, pair_id, has_tvg_pose_))) return;
  }
}

// ---------------------------------------------------------------- writing

namespace {
Stmt& Prepared(std::unique_ptr<Stmt>* slot, sqlite3* db, const char* sql, const std::string& file) {
  if (!*slot) slot->reset(new Stmt(db, sql, file));
  (*slot)->Reset();
  return **slot;
}

void CheckImageId(ImageId id, const std::string& file) {
  if (id >= kMaxNumImages) {
    throw Error(file + ": image_id " + std::to_string(id) + " exceeds COLMAP's limit 2147483646");
  }
}
}  // namespace

CameraId Database::WriteCamera(const DbCamera& camera, bool use_camera_id) {
  if (camera.camera.model == CameraModelId::kUnknown) {
    throw Error(impl_->file + ": UNKNOWN_CAMERA cannot be stored in a COLMAP database");
  }
  const std::string why = camera.camera.Validate();
  if (!why.empty()) throw Error(impl_->file + ": camera " + std::to_string(camera.camera_id) + ": " + why);
  Stmt& s = Prepared(&impl_->write_camera, impl_->db,
                     "INSERT INTO cameras(camera_id, model, width, height, params, "
                     "prior_focal_length) VALUES(?, ?, ?, ?, ?, ?);",
                     impl_->file + " (cameras)");
  if (use_camera_id) {
    s.BindInt(1, camera.camera_id);
  } else {
    s.BindNull(1);
  }
  s.BindInt(2, static_cast<int>(camera.camera.model));
  s.BindInt(3, camera.camera.width);
  s.BindInt(4, camera.camera.height);
  s.BindBlob(5, camera.camera.params.data(), camera.camera.params.size() * sizeof(double));
  s.BindInt(6, camera.prior_focal_length ? 1 : 0);
  s.Step();
  return static_cast<CameraId>(sqlite3_last_insert_rowid(impl_->db));
}

ImageId Database::WriteImage(const DbImage& image, bool use_image_id) {
  Stmt& s = Prepared(&impl_->write_image, impl_->db,
                     "INSERT INTO images(image_id, name, camera_id, prior_qw, prior_qx, prior_qy, "
                     "prior_qz, prior_tx, prior_ty, prior_tz) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?);",
                     impl_->file + " (images)");
  if (use_image_id) {
    CheckImageId(image.image_id, impl_->file);
    s.BindInt(1, image.image_id);
  } else {
    s.BindNull(1);
  }
  s.BindText(2, image.name);
  s.BindInt(3, image.camera_id);
  for (int k = 0; k < 4; ++k) {
    if (image.prior_qvec) s.BindDouble(4 + k, (*image.prior_qvec)(k)); else s.BindNull(4 + k);
  }
  for (int k = 0; k < 3; ++k) {
    if (image.prior_tvec) s.BindDouble(8 + k, (*image.prior_tvec)(k)); else s.BindNull(8 + k);
  }
  s.Step();
  return static_cast<ImageId>(sqlite3_last_insert_rowid(impl_->db));
}

void Database::WriteKeypoints(ImageId image_id, const KeypointsBlob& k) {
  if (k.rows > 0 && k.cols != 2 && k.cols != 4 && k.cols != 6) {
    throw Error(impl_->file + ": keypoints of image " + std::to_string(image_id) +
                " must have 2, 4 or 6 columns, not " + std::to_string(k.cols));
  }
  if (k.data.size() != static_cast<size_t>(k.rows) * k.cols) {
    throw Error(impl_->file + ": keypoints of image " + std::to_string(image_id) +
                ": data size does not match rows x cols");
  }
  Stmt& s = Prepared(&impl_->write_keypoints, impl_->db,
                     "INSERT INTO keypoints(image_id, rows, cols, data) VALUES(?, ?, ?, ?);",
                     impl_->file + " (keypoints)");
  s.BindInt(1, image_id);
  s.BindInt(2, k.rows);
  s.BindInt(3, k.cols);
  s.BindBlob(4, k.data.data(), k.data.size() * sizeof(float));
  s.Step();
}

void Database::WriteDescriptors(ImageId image_id, const DescriptorsBlob& d) {
  if (d.data.size() != static_cast<size_t>(d.rows) * d.cols) {
    throw Error(impl_->file + ": descriptors of image " + std::to_string(image_id) +
                ": data size does not match rows x cols");
  }
  Stmt& s = Prepared(&impl_->write_descriptors, impl_->db,
                     "INSERT INTO descriptors(image_id, rows, cols, data) VALUES(?, ?, ?, ?);",
                     impl_->file + " (descriptors)");
  s.BindInt(1, image_id);
  s.BindInt(2, d.rows);
  s.BindInt(3, d.cols);
  s.BindBlob(4, d.data.data(), d.data.size());
  s.Step();
}

namespace {
std::vector<uint32_t> MatchesBlob(const FeatureMatches& matches, bool swap) {
  std::vector<uint32_t> raw(matches.size() * 2);
  for (size_t i = 0; i < matches.size(); ++i) {
    raw[2 * i] = swap ? matches[i].second : matches[i].first;
    raw[2 * i + 1] = swap ? matches[i].first : matches[i].second;
  }
  return raw;
}
}  // namespace

void Database::WriteMatches(ImageId image_id1, ImageId image_id2, const FeatureMatches& matches) {
  CheckImageId(image_id1, impl_->file);
  CheckImageId(image_id2, impl_->file);
  const std::vector<uint32_t> raw = MatchesBlob(matches, SwapImagePair(image_id1, image_id2));
  Stmt& s = Prepared(&impl_->write_matches, impl_->db,
                     "INSERT INTO matches(pair_id, rows, cols, data) VALUES(?, ?, ?, ?);",
                     impl_->file + " (matches)");
  s.BindInt(1, static_cast<int64_t>(ImagePairToPairId(image_id1, image_id2)));
  s.BindInt(2, static_cast<int64_t>(matches.size()));
  s.BindInt(3, 2);
  s.BindBlob(4, raw.data(), raw.size() * sizeof(uint32_t));
  s.Step();
}

void Database::WriteTwoViewGeometry(ImageId image_id1, ImageId image_id2,
                                    const TwoViewGeometry& tvg) {
  CheckImageId(image_id1, impl_->file);
  CheckImageId(image_id2, impl_->file);
  if (!has_tvg_pose_) {
    throw Error(impl_->file + ": two_view_geometries has no qvec/tvec columns (read-only old schema)");
  }
  const TwoViewGeometry g = SwapImagePair(image_id1, image_id2) ? tvg.Inverted() : tvg;
  const std::vector<uint32_t> raw = MatchesBlob(g.inlier_matches, false);
  Stmt& s = Prepared(&impl_->write_tvg, impl_->db,
                     "INSERT INTO two_view_geometries(pair_id, rows, cols, data, config, F, E, H, "
                     "qvec, tvec) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?);",
                     impl_->file + " (two_view_geometries)");
  s.BindInt(1, static_cast<int64_t>(ImagePairToPairId(image_id1, image_id2)));
  s.BindInt(2, static_cast<int64_t>(g.inlier_matches.size()));
  s.BindInt(3, 2);
  s.BindBlob(4, raw.data(), raw.size() * sizeof(uint32_t));
  s.BindInt(5, g.config);
  // Row-major, as COLMAP writes the transposed (column-major) Eigen matrix.
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> F = g.F, E = g.E, H = g.H;
  if (!g.inlier_matches.empty()) {
    s.BindBlob(6, F.data(), 9 * sizeof(double));
    s.BindBlob(7, E.data(), 9 * sizeof(double));
    s.BindBlob(8, H.data(), 9 * sizeof(double));
    s.BindBlob(9, g.qvec.data(), 4 * sizeof(double));
    s.BindBlob(10, g.tvec.data(), 3 * sizeof(double));
  } else {
    for (int col = 6; col <= 10; ++col) s.BindNull(col);
  }
  s.Step();
}

std::string Database::SchemaSql() const {
  Stmt s(impl_->db,
         "SELECT sql FROM sqlite_master WHERE sql IS NOT NULL ORDER BY type DESC, name;",
         impl_->file);
  std::string schema;
  while (s.Step()) schema += s.Text(0) + "\n";
  return schema;
}

int Database::UserVersion() const {
  Stmt s(impl_->db, "PRAGMA user_version;", impl_->file);
  return s.Step() ? static_cast<int>(s.Int(0)) : 0;
}

void Database::Execute(const std::string& sql) { impl_->Exec(sql); }

void Database::BeginTransaction() { impl_->Exec("BEGIN TRANSACTION;"); }
void Database::CommitTransaction() { impl_->Exec("COMMIT;"); }
void Database::RollbackTransaction() { impl_->Exec("ROLLBACK;"); }

// ------------------------------------------------------------ DatabaseWriter

DatabaseWriter::DatabaseWriter(Database* db, size_t batch_size)
    : db_(db), batch_size_(batch_size == 0 ? 1 : batch_size) {}

DatabaseWriter::~DatabaseWriter() {
  if (open_) {
    try {
      db_->RollbackTransaction();
    } catch (...) {
      // Destructors do not throw; the database stays at its last commit.
    }
  }
}

void DatabaseWriter::Step() {
  if (!open_) {
    db_->BeginTransaction();
    open_ = true;
  }
}

#define LOCFORGE_BATCHED(call)                  \
  Step();                                       \
  auto result = call;                           \
  if (++pending_ >= batch_size_) {              \
    db_->CommitTransaction();                   \
    open_ = false;                              \
    pending_ = 0;                               \
  }                                             \
  return result

#define LOCFORGE_BATCHED_VOID(call)             \
  Step();                                       \
  call;                                         \
  if (++pending_ >= batch_size_) {              \
    db_->CommitTransaction();                   \
    open_ = false;                              \
    pending_ = 0;                               \
  }

CameraId DatabaseWriter::WriteCamera(const DbCamera& camera, bool use_camera_id) {
  LOCFORGE_BATCHED(db_->WriteCamera(camera, use_camera_id));
}
ImageId DatabaseWriter::WriteImage(const DbImage& image, bool use_image_id) {
  LOCFORGE_BATCHED(db_->WriteImage(image, use_image_id));
}
void DatabaseWriter::WriteKeypoints(ImageId image_id, const KeypointsBlob& keypoints) {
  LOCFORGE_BATCHED_VOID(db_->WriteKeypoints(image_id, keypoints));
}
void DatabaseWriter::WriteDescriptors(ImageId image_id, const DescriptorsBlob& descriptors) {
  LOCFORGE_BATCHED_VOID(db_->WriteDescriptors(image_id, descriptors));
}
void DatabaseWriter::WriteMatches(ImageId id1, ImageId id2, const FeatureMatches& matches) {
  LOCFORGE_BATCHED_VOID(db_->WriteMatches(id1, id2, matches));
}
void DatabaseWriter::WriteTwoViewGeometry(ImageId id1, ImageId id2, const TwoViewGeometry& tvg) {
  LOCFORGE_BATCHED_VOID(db_->WriteTwoViewGeometry(id1, id2, tvg));
}

#undef LOCFORGE_BATCHED
#undef LOCFORGE_BATCHED_VOID

void DatabaseWriter::Finish() {
  if (open_) {
    db_->CommitTransaction();
    open_ = false;
    pending_ = 0;
  }
}

}  // namespace locforge::colmap
