#include "locforge/colmap/convert.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <unordered_map>

#include "locforge/colmap/convention.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"

namespace locforge::colmap {

namespace fs = std::filesystem;
using kapture::FeatureKind;

std::string KaptureSensorIdOf(CameraId camera_id) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "cam_%05u", camera_id);
  return buffer;
}

bool ExportOptions::Check(std::string* why) const {
  if (batch_size == 0) {
    if (why) *why = "batch_size must be > 0";
    return false;
  }
  if (two_view_config < 0 || two_view_config > static_cast<int>(TwoViewConfig::kMultiple)) {
    if (why) *why = "two_view_config must be a COLMAP configuration (0..8)";
    return false;
  }
  return true;
}

bool ImportOptions::Check(std::string* why) const {
  if (features_type.empty() || features_type.find('/') != std::string::npos ||
      features_type == "." || features_type == "..") {
    if (why) *why = "features_type must be a plain folder name";
    return false;
  }
  return true;
}

namespace {

constexpr size_t kMaxNotes = 50;

void Note(std::vector<std::string>* notes, const std::string& note) {
  if (notes->size() < kMaxNotes) {
    notes->push_back(note);
  } else if (notes->size() == kMaxNotes) {
    notes->push_back("... (more notes omitted)");
  }
}

// ------------------------------------------------------------------ export

struct ExportImage {
  std::string name;  // records_camera image_path
  Timestamp timestamp = 0;
  std::string sensor_id;
  ImageId image_id = 0;
  CameraId camera_id = 0;
  std::optional<Pose> pose;  // T_camera_world
};

std::string ResolveKeypointsType(const kapture::Kapture& k, const std::string& wanted) {
  const auto sets = k.FeatureSets(FeatureKind::kKeypoints);
  if (!wanted.empty()) {
    k.GetFeatureSet(FeatureKind::kKeypoints, wanted);  // throws InputError when absent
    return wanted;
  }
  if (sets.empty()) return "";
  if (sets.size() > 1) {
    std::string names;
    for (const auto& s : sets) names += (names.empty() ? "" : ", ") + s.type;
    throw InputError(k.root().string(), 0, "keypoints",
                     "several keypoints types (" + names + "): choose one");
  }
  return sets[0].type;
}

std::string ResolveDescriptorsType(const kapture::Kapture& k, const std::string& wanted,
                                   const std::string& keypoints_type) {
  if (!wanted.empty()) {
    k.GetFeatureSet(FeatureKind::kDescriptors, wanted);
    return wanted;
  }
  for (const auto& s : k.FeatureSets(FeatureKind::kDescriptors)) {
    if (s.info.keypoints_type == keypoints_type || s.type == keypoints_type) return s.type;
  }
  return "";
}

KeypointsBlob ToKeypointsBlob(const kapture::FeatureArray& a, const std::string& origin) {
  if (a.dsize < 2) {
    throw InputError(origin, 0, "dsize", "keypoints need at least x and y columns");
  }
  KeypointsBlob k;
  k.rows = static_cast<uint32_t>(a.rows);
  // COLMAP takes 2, 4 (x, y, scale, orientation) or 6 (x, y, affine) columns;
  // 3 columns (x, y, scale) get orientation 0; others keep x, y.
  const int64_t in_cols = a.dsize;
  k.cols = in_cols == 2 || in_cols == 4 || in_cols == 6 ? static_cast<uint32_t>(in_cols)
           : in_cols == 3                                 ? 4
                                                          : 2;
  k.data.assign(static_cast<size_t>(k.rows) * k.cols, 0.0f);
  for (int64_t r = 0; r < a.rows; ++r) {
    float* row = &k.data[static_cast<size_t>(r) * k.cols];
    const Eigen::Vector2d xy =
        ConvertPixel(Eigen::Vector2d(a.At(r, 0), a.At(r, 1)), PixelDirection::kKaptureToColmap);
    row[0] = static_cast<float>(xy.x());
    row[1] = static_cast<float>(xy.y());
    for (uint32_t c = 2; c < k.cols && c < in_cols; ++c) row[c] = static_cast<float>(a.At(r, c));
  }
  return k;
}

FeatureMatches ToFeatureMatches(const std::vector<kapture::Match>& in, uint64_t n1, uint64_t n2,
                                const std::string& origin, std::vector<std::string>* notes) {
  FeatureMatches out;
  out.reserve(in.size());
  int64_t bad = 0;
  for (const kapture::Match& m : in) {
    const bool integral = m.index1 >= 0 && m.index2 >= 0 && m.index1 == std::floor(m.index1) &&
                          m.index2 == std::floor(m.index2);
    if (!integral || m.index1 >= static_cast<double>(n1) || m.index2 >= static_cast<double>(n2)) {
      ++bad;
      continue;
    }
    out.emplace_back(static_cast<Point2DIdx>(m.index1), static_cast<Point2DIdx>(m.index2));
  }
  if (bad > 0) {
    Note(notes, origin + ": " + std::to_string(bad) +
                    " matches skipped (index not an integer or beyond the keypoints)");
  }
  return out;
}

// Mean reprojection error of a point over its track, or -1 (COLMAP's
// "unknown") when no observation is in front of its camera.
double ReprojectionError(const Reconstruction& model,
                         const std::unordered_map<ImageId, size_t>& image_index,
                         const std::unordered_map<CameraId, size_t>& camera_index,
                         const ModelPoint3D& point) {
  double sum = 0;
  int n = 0;
  for (const TrackElement& e : point.track) {
    const ModelImage& image = model.images[image_index.at(e.image_id)];
    const Camera& camera = model.cameras[camera_index.at(image.camera_id)].camera;
    const Eigen::Vector3d p = image.CameraFromWorld() * point.xyz;
    if (p.z() <= 0) continue;
    sum += (camera.Project(p) - image.points2d[e.point2d_idx].xy).norm();
    ++n;
  }
  return n > 0 ? sum / n : -1.0;
}

uint8_t ToColor(double v) {
  return static_cast<uint8_t>(std::clamp(std::lround(v), 0l, 255l));
}


const char kRecordsFile[] = "sensors/records_camera.txt";

// Removes a temporary database (and SQLite's side files) unless renamed away.
struct TempGuard {
  fs::path path;
  ~TempGuard() {
    std::error_code ec;
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
      fs::remove(path.string() + suffix, ec);
    }
  }
};

// One export: what is read from the kapture, and the model and report it makes.
struct Exporter {
  const kapture::Kapture& k;
  const ExportOptions& options;
  ExportReport report;
  Reconstruction model;
  std::map<std::string, CameraId> camera_ids;  // by kapture sensor id
  std::vector<ExportImage> images;             // by name, ids from 1
  std::unordered_map<std::string, size_t> image_by_name;
  std::string kp_type, desc_type;               // empty: none exported
  std::vector<uint32_t> num_keypoints;          // by image
  std::unordered_map<ImageId, size_t> model_image_index;
  bool descriptor_dtype_noted = false;

  // Cameras, by sorted sensor id.
  void CollectCameras() {
    std::vector<const kapture::Sensor*> camera_sensors = k.sensors().OfType(kapture::kSensorCamera);
    std::sort(camera_sensors.begin(), camera_sensors.end(),
              [](const kapture::Sensor* a, const kapture::Sensor* b) { return a->id < b->id; });
    for (const kapture::Sensor* s : camera_sensors) {
      if (!s->camera || s->camera->model == CameraModelId::kUnknown) {
        Note(&report.notes, "camera " + s->id + " skipped: no COLMAP camera model (UNKNOWN_CAMERA)");
        continue;
      }
      ModelCamera c;
      c.camera_id = static_cast<CameraId>(model.cameras.size() + 1);
      c.camera = *s->camera;
      camera_ids[s->id] = c.camera_id;
      model.cameras.push_back(c);
    }
  }

  // Images of those cameras, by sorted name, with their poses.
  void CollectImages() {
    if (k.HasRecords(kapture::kSensorCamera)) {
      k.ForEachDataRecord(kapture::kSensorCamera, [&](const kapture::DataRecord& r) {
        const kapture::Sensor* sensor = k.sensors().Find(r.device_id);
        if (sensor == nullptr) {
          throw InputError(kRecordsFile, 0, "device_id",
                           "image " + r.path + " has unknown sensor '" + r.device_id + "'");
        }
        if (!camera_ids.count(r.device_id)) {
          Note(&report.notes, "image " + r.path + " skipped: its sensor " + r.device_id +
                                  " is not a COLMAP camera");
          return;
        }
        ExportImage image;
        image.name = r.path;
        image.timestamp = r.timestamp;
        image.sensor_id = r.device_id;
        image.camera_id = camera_ids[r.device_id];
        images.push_back(std::move(image));
      });
    }
    std::sort(images.begin(), images.end(),
              [](const ExportImage& a, const ExportImage& b) { return a.name < b.name; });
    for (size_t i = 0; i < images.size(); ++i) {
      if (i > 0 && images[i].name == images[i - 1].name) {
        throw InputError(kRecordsFile, 0, "image_path",
                         "image '" + images[i].name + "' is recorded twice; COLMAP names must be unique");
      }
      if (i + 1 >= kMaxNumImages) throw Error("more images than COLMAP supports");
      images[i].image_id = static_cast<ImageId>(i + 1);
      images[i].pose = k.DevicePose(images[i].timestamp, images[i].sensor_id);
    }
    for (size_t i = 0; i < images.size(); ++i) image_by_name[images[i].name] = i;
  }

  void ResolveFeatureTypes() {
    kp_type = ResolveKeypointsType(k, options.keypoints_type);
    report.keypoints_type = kp_type;
    desc_type = kp_type.empty() || !options.export_descriptors
                    ? ""
                    : ResolveDescriptorsType(k, options.descriptors_type, kp_type);
  }

  // The database: cameras, images with their features, matches.
  void WriteDatabase(const fs::path& path) {
    num_keypoints.assign(images.size(), 0);
    Database db(path, Database::Mode::kCreate);
    DatabaseWriter writer(&db, options.batch_size);
    for (const ModelCamera& c : model.cameras) {
      writer.WriteCamera({c.camera_id, c.camera, /*prior_focal_length=*/true}, true);
      ++report.cameras;
    }
    for (size_t i = 0; i < images.size(); ++i) {
      WriteImage(writer, images[i]);
      ModelImage* model_image = images[i].pose ? AddModelImage(images[i]) : nullptr;
      WriteKeypoints(writer, i, model_image);
      WriteDescriptors(writer, i);
    }
    if (!kp_type.empty() && options.export_matches) WriteMatches(writer);
    writer.Finish();
  }

  void WriteImage(DatabaseWriter& writer, const ExportImage& image) {
    DbImage row;
    row.image_id = image.image_id;
    row.name = image.name;
    row.camera_id = image.camera_id;
    if (image.pose && options.write_pose_priors) {
      const Eigen::Quaterniond& q = image.pose->q;
      row.prior_qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
      row.prior_tvec = image.pose->t;
    }
    writer.WriteImage(row, true);
    ++report.images;
  }

  // A posed image into the model (valid until the next one is added).
  ModelImage* AddModelImage(const ExportImage& image) {
    ModelImage mi;
    mi.image_id = image.image_id;
    mi.camera_id = image.camera_id;
    mi.name = image.name;
    mi.SetCameraFromWorld(*image.pose);
    model_image_index[mi.image_id] = model.images.size();
    model.images.push_back(std::move(mi));
    return &model.images.back();
  }

  // Image i's keypoints, into the database and as the model image's points2d.
  void WriteKeypoints(DatabaseWriter& writer, size_t i, ModelImage* model_image) {
    const ExportImage& image = images[i];
    if (kp_type.empty() || !k.HasFeatureFile(FeatureKind::kKeypoints, kp_type, image.name)) return;
    const KeypointsBlob blob = ToKeypointsBlob(k.ReadKeypoints(kp_type, image.name),
                                               "reconstruction/keypoints/" + kp_type + "/" + image.name + ".kpt");
    writer.WriteKeypoints(image.image_id, blob);
    num_keypoints[i] = blob.rows;
    ++report.keypoint_images;
    if (model_image != nullptr) {
      model_image->points2d.resize(blob.rows);
      for (uint32_t r = 0; r < blob.rows; ++r) {
        model_image->points2d[r].xy = Eigen::Vector2d(blob.data[r * blob.cols], blob.data[r * blob.cols + 1]);
      }
    }
  }

  // Image i's descriptors: uint8 ones with a row per keypoint (COLMAP stores no other).
  void WriteDescriptors(DatabaseWriter& writer, size_t i) {
    const ExportImage& image = images[i];
    if (desc_type.empty() || !k.HasFeatureFile(FeatureKind::kDescriptors, desc_type, image.name)) return;
    const kapture::FeatureArray d = k.ReadDescriptors(desc_type, image.name);
    if (d.dtype != kapture::DType::kUint8) {
      if (!descriptor_dtype_noted) {
        Note(&report.notes, "descriptors " + desc_type + " are " + kapture::DTypeName(d.dtype) +
                                ", COLMAP stores uint8 only: not exported");
        descriptor_dtype_noted = true;
      }
    } else if (d.rows != num_keypoints[i]) {
      Note(&report.notes, "descriptors of " + image.name + " skipped: " + std::to_string(d.rows) +
                              " rows for " + std::to_string(num_keypoints[i]) + " keypoints");
    } else {
      DescriptorsBlob blob;
      blob.rows = static_cast<uint32_t>(d.rows);
      blob.cols = static_cast<uint32_t>(d.dsize);
      blob.data = d.bytes;
      writer.WriteDescriptors(image.image_id, blob);
      ++report.descriptor_images;
    }
  }

  // The matches of every pair of exported images (and as verified geometries when asked).
  void WriteMatches(DatabaseWriter& writer) {
    for (const auto& [name1, name2] : k.MatchPairs(kp_type)) {
      const auto it1 = image_by_name.find(name1), it2 = image_by_name.find(name2);
      if (it1 == image_by_name.end() || it2 == image_by_name.end()) {
        Note(&report.notes, "matches " + name1 + " / " + name2 + " skipped: image not exported");
        continue;
      }
      const FeatureMatches matches =
          ToFeatureMatches(k.ReadMatches(kp_type, name1, name2), num_keypoints[it1->second],
                           num_keypoints[it2->second], "matches " + name1 + " / " + name2, &report.notes);
      const ImageId id1 = images[it1->second].image_id, id2 = images[it2->second].image_id;
      writer.WriteMatches(id1, id2, matches);
      if (options.export_two_view_geometries) {
        TwoViewGeometry g;
        g.config = options.two_view_config;
        g.inlier_matches = matches;
        writer.WriteTwoViewGeometry(id1, id2, g);
      }
      ++report.match_pairs;
      report.matches += static_cast<int64_t>(matches.size());
    }
  }

  // The kapture's points with their tracks over the posed images' keypoints.
  std::vector<ModelPoint3D> TrackedPoints() {
    const auto& points = k.points3d();
    std::vector<ModelPoint3D> candidates(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      candidates[i].point3d_id = static_cast<Point3DId>(i + 1);
      candidates[i].xyz = Eigen::Vector3d(points[i].x, points[i].y, points[i].z);
      candidates[i].color = {ToColor(points[i].r), ToColor(points[i].g), ToColor(points[i].b)};
    }
    int64_t skipped = 0;
    for (const kapture::ObservationsEntry& entry : k.observations()) {
      if (!entry.keypoints_type.empty() && entry.keypoints_type != kp_type) continue;
      if (entry.point3d_id < 0 || entry.point3d_id >= static_cast<int64_t>(points.size())) {
        throw InputError("reconstruction/observations.txt", 0, "point3d_id",
                         "point " + std::to_string(entry.point3d_id) + " is not in points3d.txt (" +
                             std::to_string(points.size()) + " points)");
      }
      ModelPoint3D& point = candidates[entry.point3d_id];
      for (const auto& [name, feature_id] : entry.features) skipped += !AddToTrack(name, feature_id, &point);
    }
    if (skipped > 0) {
      Note(&report.notes, std::to_string(skipped) +
                              " observations skipped (image without pose, feature id beyond the "
                              "keypoints, or keypoint already observing another point)");
    }
    return candidates;
  }

  // Keypoint feature_id of image `name` into the point's track; false when
  // the image has no pose or was not exported, the id is beyond the
  // keypoints, or the keypoint is already in a track.
  bool AddToTrack(const std::string& name, int64_t feature_id, ModelPoint3D* point) {
    const auto it = image_by_name.find(name);
    const auto mit = it == image_by_name.end() ? model_image_index.end()
                                               : model_image_index.find(images[it->second].image_id);
    if (mit == model_image_index.end()) return false;
    ModelImage& image = model.images[mit->second];
    if (feature_id < 0 || feature_id >= static_cast<int64_t>(image.points2d.size()) ||
        image.points2d[feature_id].HasPoint3D())
      return false;
    image.points2d[feature_id].point3d_id = point->point3d_id;
    point->track.push_back({image.image_id, static_cast<Point2DIdx>(feature_id)});
    return true;
  }

  // Points and tracks: the points with a track, with their reprojection errors.
  void AddPoints() {
    std::vector<ModelPoint3D> candidates = TrackedPoints();
    std::unordered_map<CameraId, size_t> camera_index;
    for (size_t i = 0; i < model.cameras.size(); ++i) camera_index[model.cameras[i].camera_id] = i;
    double error_sum = 0;
    int64_t error_count = 0;
    for (ModelPoint3D& point : candidates) {
      if (point.track.empty()) continue;
      point.error = ReprojectionError(model, model_image_index, camera_index, point);
      if (point.error >= 0) {
        error_sum += point.error;
        ++error_count;
      }
      report.observations += static_cast<int64_t>(point.track.size());
      model.points3d.push_back(std::move(point));
    }
    report.points3d = static_cast<int64_t>(model.points3d.size());
    report.mean_reprojection_error = error_count > 0 ? error_sum / error_count : 0;
  }
};

}  // namespace

ExportReport ExportToColmap(const kapture::Kapture& k, const fs::path& database,
                            const fs::path& model_dir, const ExportOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw ParamError("colmap export: " + why);
  if (fs::exists(database) && !options.overwrite) {
    throw Error(database.string() + " exists (choose another path or allow overwriting)");
  }
  Exporter e{k, options};
  e.CollectCameras();
  e.CollectImages();
  e.ResolveFeatureTypes();
  // Database into a temp file, renamed at the end.
  if (database.has_parent_path()) fs::create_directories(database.parent_path());
  const fs::path temp = TempSibling(database);
  TempGuard guard{temp};
  e.WriteDatabase(temp);
  if (options.export_points3d && !e.kp_type.empty()) e.AddPoints();
  e.report.posed_images = static_cast<int64_t>(e.model.images.size());

  const std::string problem = e.model.Validate();
  if (!problem.empty()) throw Error("colmap export: inconsistent model: " + problem);
  if (!model_dir.empty()) WriteModel(e.model, model_dir, options.model_format);

  std::error_code ec;
  fs::rename(temp, database, ec);
  if (ec) throw Error("cannot write " + database.string() + ": " + ec.message());
  return e.report;
}

// ------------------------------------------------------------------ import

namespace {

fs::path FeaturePath(const fs::path& root, FeatureKind kind, const std::string& type,
                     const std::string& image) {
  const fs::path dir = root / "reconstruction" / kapture::FeatureKindFolder(kind) / type;
  return SafeJoin(dir, image + kapture::FeatureKindExtension(kind), "image name '" + image + "'");
}

bool IsEmptyDir(const fs::path& p) {
  return !fs::exists(p) || (fs::is_directory(p) && fs::is_empty(p));
}


// One import: the database and model read, the kapture written.
struct Importer {
  const fs::path& database;
  const fs::path& model_dir;
  const fs::path& kapture_out;
  const ImportOptions& options;
  ImportReport report;
  std::unique_ptr<Database> db;  // null: no database
  Reconstruction model;
  bool has_model = false;
  std::map<CameraId, Camera> cameras;
  std::map<ImageId, std::pair<std::string, CameraId>> images;  // id -> (name, camera)

  void Open() {
    if (!database.empty()) db = std::make_unique<Database>(database);
    has_model = !model_dir.empty();
    if (has_model) {
      model = ReadModel(model_dir);
      const std::string problem = model.Validate();
      if (!problem.empty()) throw InputError(model_dir.string(), 0, "", problem);
    }
  }

  // Cameras: refined ones from the model, else the database's.
  void CollectCameras() {
    if (has_model) {
      for (const ModelCamera& c : model.cameras) cameras[c.camera_id] = c.camera;
    }
    if (db) {
      for (const DbCamera& c : db->ReadCameras()) cameras.emplace(c.camera_id, c.camera);
    }
  }

  // Images: the database's, checked against the model's.
  void CollectImages() {
    if (db) {
      for (const DbImage& i : db->ReadImages()) images[i.image_id] = {i.name, i.camera_id};
    }
    for (const ModelImage& i : model.images) {
      const auto it = images.find(i.image_id);
      if (it == images.end()) {
        images[i.image_id] = {i.name, i.camera_id};
      } else if (it->second.first != i.name) {
        throw InputError(model_dir.string(), 0, "images",
                         "image " + std::to_string(i.image_id) + " is '" + i.name + "' in the model but '" +
                             it->second.first + "' in the database");
      }
    }
    for (const auto& [id, image] : images) {
      if (!cameras.count(image.second)) {
        throw InputError(database.empty() ? model_dir.string() : database.string(), 0, "camera_id",
                         "image " + image.first + " refers to missing camera " + std::to_string(image.second));
      }
    }
  }

  // sensors/: the cameras, an image record per image (its id as timestamp),
  // the model's poses.
  void WriteSensorFiles() {
    kapture::Sensors sensors;
    for (const auto& [id, camera] : cameras) {
      sensors.Add(kapture::MakeCameraSensor(KaptureSensorIdOf(id), "", camera));
      ++report.cameras;
    }
    kapture::WriteSensors(kapture_out / "sensors/sensors.txt", sensors);
    std::vector<kapture::DataRecord> records;
    for (const auto& [id, image] : images) {
      records.push_back({static_cast<Timestamp>(id), KaptureSensorIdOf(image.second), image.first});
    }
    kapture::WriteRecords(kapture_out / "sensors/records_camera.txt", kapture::RecordKind::kCamera, records);
    report.images = static_cast<int64_t>(records.size());
    if (has_model) {
      kapture::Trajectories trajectories;
      for (const ModelImage& i : model.images) {
        trajectories.Set(static_cast<Timestamp>(i.image_id), KaptureSensorIdOf(i.camera_id), i.CameraFromWorld());
      }
      kapture::WriteTrajectories(kapture_out / "sensors/trajectories.txt", trajectories);
      report.posed_images = static_cast<int64_t>(model.images.size());
    }
  }

  const std::string& NameOf(ImageId id) const {
    const auto it = images.find(id);
    if (it == images.end()) {
      throw InputError(database.string(), 0, "image_id", "features refer to missing image " + std::to_string(id));
    }
    return it->second.first;
  }

  // reconstruction/keypoints (streamed, one image at a time).
  void ImportKeypoints() {
    const std::string& type = options.features_type;
    int64_t cols = -1;
    db->ForEachKeypoints([&](ImageId id, const KeypointsBlob& k) {
      if (k.rows == 0) return true;
      if (cols >= 0 && cols != k.cols) {
        throw InputError(database.string(), 0, "keypoints (image_id " + std::to_string(id) + ").cols",
                         std::to_string(k.cols) + " columns where other images have " + std::to_string(cols) +
                             "; kapture needs one dsize per type");
      }
      cols = k.cols;
      std::vector<float> data = k.data;
      for (size_t r = 0; r < k.rows; ++r) {
        const Eigen::Vector2f xy = ConvertPixel(Eigen::Vector2f(data[r * k.cols], data[r * k.cols + 1]),
                                                PixelDirection::kColmapToKapture);
        data[r * k.cols] = xy.x();
        data[r * k.cols + 1] = xy.y();
      }
      kapture::WriteFeatureFile(FeaturePath(kapture_out, FeatureKind::kKeypoints, type, NameOf(id)),
                                kapture::FeatureArray::From(kapture::DType::kFloat32, k.cols, data));
      ++report.keypoint_images;
      return true;
    });
    if (cols > 0) {
      kapture::FeatureInfo info;
      info.kind = FeatureKind::kKeypoints;
      info.name = type;
      info.dtype_name = "float32";
      info.dtype = kapture::DType::kFloat32;
      info.dsize = cols;
      kapture::WriteFeatureInfo(kapture_out / "reconstruction/keypoints" / type / "keypoints.txt", info);
    }
  }

  // reconstruction/descriptors (streamed, one image at a time).
  void ImportDescriptors() {
    const std::string& type = options.features_type;
    int64_t cols = -1;
    db->ForEachDescriptors([&](ImageId id, const DescriptorsBlob& d) {
      if (d.rows == 0) return true;
      if (cols >= 0 && cols != d.cols) {
        throw InputError(database.string(), 0, "descriptors (image_id " + std::to_string(id) + ").cols",
                         "descriptor sizes differ between images");
      }
      cols = d.cols;
      kapture::WriteFeatureFile(FeaturePath(kapture_out, FeatureKind::kDescriptors, type, NameOf(id)),
                                kapture::FeatureArray::From(kapture::DType::kUint8, d.cols, d.data));
      ++report.descriptor_images;
      return true;
    });
    if (cols > 0) {
      kapture::FeatureInfo info;
      info.kind = FeatureKind::kDescriptors;
      info.name = type;
      info.dtype_name = "uint8";
      info.dtype = kapture::DType::kUint8;
      info.dsize = cols;
      info.keypoints_type = type;
      info.metric_type = "L2";
      kapture::WriteFeatureInfo(kapture_out / "reconstruction/descriptors" / type / "descriptors.txt", info);
    }
  }

  // One pair's matches, in the file of the smaller name first.
  bool WriteMatchPair(ImageId id1, ImageId id2, const FeatureMatches& m) {
    if (m.empty()) return true;
    std::string n1 = NameOf(id1), n2 = NameOf(id2);
    const bool swap = n2 < n1;
    if (swap) std::swap(n1, n2);
    std::vector<kapture::Match> matches(m.size());
    for (size_t i = 0; i < m.size(); ++i) {
      matches[i].index1 = swap ? m[i].second : m[i].first;
      matches[i].index2 = swap ? m[i].first : m[i].second;
    }
    const fs::path dir = kapture_out / "reconstruction/matches" / options.features_type;
    kapture::WriteFeatureFile(
        SafeJoin(dir, kapture::layout::MatchesFile(n1, n2), "images '" + n1 + "', '" + n2 + "'"),
        kapture::MatchesToArray(matches));
    ++report.match_pairs;
    return true;
  }

  // reconstruction/matches: the verified ones when asked and there are some.
  void ImportMatches() {
    auto write_pair = [&](ImageId id1, ImageId id2, const FeatureMatches& m) { return WriteMatchPair(id1, id2, m); };
    if (options.verified_matches && db->NumTwoViewGeometries() > 0) {
      db->ForEachTwoViewGeometry(
          [&](ImageId a, ImageId b, const TwoViewGeometry& g) { return write_pair(a, b, g.inlier_matches); });
    } else {
      db->ForEachMatches(write_pair);
    }
  }
};

}  // namespace

ImportReport ImportFromColmap(const fs::path& database, const fs::path& model_dir,
                              const fs::path& kapture_out, const ImportOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw ParamError("colmap import: " + why);
  if (database.empty() && model_dir.empty()) {
    throw ParamError("colmap import: give a database, a model folder, or both");
  }
  if (!IsEmptyDir(kapture_out) && !options.overwrite) {
    throw Error(kapture_out.string() + " is not empty (choose another folder or allow overwriting)");
  }
  Importer im{database, model_dir, kapture_out, options};
  im.Open();
  im.CollectCameras();
  im.CollectImages();
  im.WriteSensorFiles();
  if (im.db && options.import_keypoints) im.ImportKeypoints();
  if (im.db && options.import_descriptors) im.ImportDescriptors();
  if (im.db && options.import_matches) im.ImportMatches();
  // reconstruction/points3d.txt + observations.txt, in the model's order.
  if (im.has_model && options.import_points3d && !im.model.points3d.empty()) {
    im.report.observations += WriteKapturePoints(im.model, options.features_type, kapture_out);
    im.report.points3d = static_cast<int64_t>(im.model.points3d.size());
  }
  return im.report;
}

int64_t WriteKapturePoints(const Reconstruction& model, const std::string& keypoints_type,
                           const fs::path& kapture_root) {
  std::vector<kapture::Point3d> points;
  kapture::Observations observations;
  points.reserve(model.points3d.size());
  std::unordered_map<ImageId, const std::string*> names;
  for (const ModelImage& i : model.images) names[i.image_id] = &i.name;
  int64_t count = 0;
  for (const ModelPoint3D& p : model.points3d) {
    kapture::Point3d q;
    q.x = p.xyz.x();
    q.y = p.xyz.y();
    q.z = p.xyz.z();
    q.r = p.color[0];
    q.g = p.color[1];
    q.b = p.color[2];
    kapture::ObservationsEntry entry;
    entry.point3d_id = static_cast<int64_t>(points.size());
    entry.keypoints_type = keypoints_type;
    for (const TrackElement& e : p.track) {
      const auto name = names.find(e.image_id);
      if (name == names.end()) {
        throw Error("COLMAP model: point " + std::to_string(p.point3d_id) + " observed in image_id " +
                    std::to_string(e.image_id) + ", which the model does not have");
      }
      entry.features.emplace_back(*name->second, static_cast<int64_t>(e.point2d_idx));
    }
    count += static_cast<int64_t>(entry.features.size());
    points.push_back(q);
    if (!entry.features.empty()) observations.push_back(std::move(entry));
  }
  fs::create_directories(kapture_root / "reconstruction");
  kapture::WritePoints3d(kapture_root / "reconstruction/points3d.txt", points);
  kapture::WriteObservations(kapture_root / "reconstruction/observations.txt", observations);
  return count;
}

}  // namespace locforge::colmap
