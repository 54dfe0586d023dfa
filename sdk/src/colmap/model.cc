#include "locforge/colmap/model.h"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <unordered_set>

#include "io_util.h"
#include "locforge/error.h"
#include "locforge/fs.h"

namespace locforge::colmap {

using internal::BinaryReader;
using internal::ParseDouble;
using internal::ParseInt;
using internal::ParseUint;
using internal::TextPos;
using internal::Tokenize;
using internal::Trim;
using internal::WriteLE;

// ---------------------------------------------------------------------------
// Records

Eigen::Vector4d NormalizeQvec(const Eigen::Vector4d& qvec) {
  const double norm = qvec.norm();
  if (norm == 0) return Eigen::Vector4d(1, 0, 0, 0);
  return qvec / norm;
}

namespace {
// COLMAP normalises the quaternion at every write, but normalising is not
// idempotent in floating point (a unit quaternion can move by an ulp), so
// read-write cycles would drift. A quaternion that is already unit to
// rounding is written as it is; any other is normalised as COLMAP does.
Eigen::Vector4d QvecToWrite(const Eigen::Vector4d& qvec) {
  if (std::abs(qvec.squaredNorm() - 1.0) <= 8 * std::numeric_limits<double>::epsilon()) {
    return qvec;
  }
  return NormalizeQvec(qvec);
}
}  // namespace

Pose ModelImage::CameraFromWorld() const {
  return Pose(Eigen::Quaterniond(qvec(0), qvec(1), qvec(2), qvec(3)), tvec);
}

void ModelImage::SetCameraFromWorld(const Pose& T_camera_world) {
  const Eigen::Quaterniond& q = T_camera_world.q;
  qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
  tvec = T_camera_world.t;
}

size_t ModelImage::NumPoints3D() const {
  size_t n = 0;
  for (const Point2D& p : points2d) n += p.HasPoint3D() ? 1 : 0;
  return n;
}

const ModelCamera* Reconstruction::FindCamera(CameraId id) const {
  for (const ModelCamera& c : cameras) {
    if (c.camera_id == id) return &c;
  }
  return nullptr;
}

const ModelImage* Reconstruction::FindImage(ImageId id) const {
  for (const ModelImage& i : images) {
    if (i.image_id == id) return &i;
  }
  return nullptr;
}

const ModelImage* Reconstruction::FindImageByName(const std::string& name) const {
  for (const ModelImage& i : images) {
    if (i.name == name) return &i;
  }
  return nullptr;
}

size_t Reconstruction::NumObservations() const {
  size_t n = 0;
  for (const ModelPoint3D& p : points3d) n += p.track.size();
  return n;
}

double Reconstruction::MeanObservationsPerImage() const {
  // COLMAP: ComputeNumObservations() / reg_image_ids_.size(), where the
  // observations are counted per image (points2D with a 3D point).
  if (images.empty()) return 0.0;
  size_t n = 0;
  for (const ModelImage& i : images) n += i.NumPoints3D();
  return static_cast<double>(n) / static_cast<double>(images.size());
}

double Reconstruction::MeanTrackLength() const {
  if (points3d.empty()) return 0.0;
  return static_cast<double>(NumObservations()) / static_cast<double>(points3d.size());
}

std::string Reconstruction::Validate() const {
  std::unordered_map<CameraId, const ModelCamera*> camera_index;
  for (const ModelCamera& c : cameras) {
    if (!camera_index.emplace(c.camera_id, &c).second) {
      return "camera_id " + std::to_string(c.camera_id) + " appears twice";
    }
    const std::string why = c.camera.Validate();
    if (!why.empty()) return "camera " + std::to_string(c.camera_id) + ": " + why;
  }
  std::unordered_map<ImageId, const ModelImage*> image_index;
  std::unordered_set<std::string> names;
  for (const ModelImage& i : images) {
    if (!image_index.emplace(i.image_id, &i).second) {
      return "image_id " + std::to_string(i.image_id) + " appears twice";
    }
    if (!names.insert(i.name).second) return "image name '" + i.name + "' appears twice";
    if (!camera_index.count(i.camera_id)) {
      return "image " + std::to_string(i.image_id) + " refers to missing camera " +
             std::to_string(i.camera_id);
    }
  }
  std::unordered_set<Point3DId> point_ids;
  for (const ModelPoint3D& p : points3d) {
    const std::string who = "point3D " + std::to_string(p.point3d_id);
    if (!point_ids.insert(p.point3d_id).second) return who + " appears twice";
    for (const TrackElement& e : p.track) {
      const auto it = image_index.find(e.image_id);
      if (it == image_index.end()) {
        return who + " track refers to missing image " + std::to_string(e.image_id);
      }
      const ModelImage& image = *it->second;
      if (e.point2d_idx >= image.points2d.size()) {
        return who + " track refers to point2D " + std::to_string(e.point2d_idx) +
               " of image " + std::to_string(e.image_id) + " which has only " +
               std::to_string(image.points2d.size());
      }
      if (image.points2d[e.point2d_idx].point3d_id != p.point3d_id) {
        return who + " track element (" + std::to_string(e.image_id) + ", " +
               std::to_string(e.point2d_idx) + ") is not linked back to it";
      }
    }
  }
  for (const ModelImage& i : images) {
    for (const Point2D& p : i.points2d) {
      if (p.HasPoint3D() && !point_ids.count(p.point3d_id)) {
        return "image " + std::to_string(i.image_id) + " refers to missing point3D " +
               std::to_string(p.point3d_id);
      }
    }
  }
  return "";
}

// ---------------------------------------------------------------------------
// Text format

namespace {

namespace fs = std::filesystem;

std::ifstream OpenText(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string(), 0, "", "cannot open file");
  return in;
}

bool IsDataLine(std::string_view line) {
  line = Trim(line);
  return !line.empty() && line[0] != '#';
}

Camera ParseCameraModel(std::string_view name, const TextPos& pos) {
  const CameraModelInfo* info = FindCameraModel(std::string(name));
  if (info == nullptr || info->id == CameraModelId::kUnknown) {
    throw InputError(pos.file, pos.line, "MODEL",
                     "unknown COLMAP camera model '" + std::string(name) + "'");
  }
  Camera camera;
  camera.model = info->id;
  return camera;
}

std::vector<ModelCamera> ReadCamerasText(const fs::path& path) {
  std::ifstream in = OpenText(path);
  const std::string file = path.string();
  std::vector<ModelCamera> cameras;
  std::string line;
  int64_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!IsDataLine(line)) continue;
    const TextPos pos{file, line_no};
    const auto tok = Tokenize(line);
    if (tok.size() < 4) {
      throw InputError(file, line_no, "", "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]");
    }
    ModelCamera c;
    c.camera_id = static_cast<CameraId>(ParseUint(tok[0], pos, "CAMERA_ID", UINT32_MAX));
    c.camera = ParseCameraModel(tok[1], pos);
    c.camera.width = static_cast<int>(ParseUint(tok[2], pos, "WIDTH", INT32_MAX));
    c.camera.height = static_cast<int>(ParseUint(tok[3], pos, "HEIGHT", INT32_MAX));
    for (size_t k = 4; k < tok.size(); ++k) {
      c.camera.params.push_back(ParseDouble(tok[k], pos, "PARAMS[" + std::to_string(k - 4) + "]"));
    }
    const int expected = CameraModelInfoOf(c.camera.model).num_params;
    if (static_cast<int>(c.camera.params.size()) != expected) {
      throw InputError(file, line_no, "PARAMS",
                       std::string(CameraModelInfoOf(c.camera.model).name) + " needs " +
                           std::to_string(expected) + " parameters, got " +
                           std::to_string(c.camera.params.size()));
    }
    cameras.push_back(std::move(c));
  }
  return cameras;
}

std::vector<ModelImage> ReadImagesText(const fs::path& path) {
  std::ifstream in = OpenText(path);
  const std::string file = path.string();
  std::vector<ModelImage> images;
  std::string line;
  int64_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!IsDataLine(line)) continue;
    const TextPos pos{file, line_no};
    const auto tok = Tokenize(line);
    if (tok.size() < 10) {
      throw InputError(file, line_no, "",
                       "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got " +
                           std::to_string(tok.size()) + " fields");
    }
    ModelImage image;
    image.image_id = static_cast<ImageId>(ParseUint(tok[0], pos, "IMAGE_ID", UINT32_MAX));
    static const char* kQ[] = {"QW", "QX", "QY", "QZ"};
    static const char* kT[] = {"TX", "TY", "TZ"};
    for (int k = 0; k < 4; ++k) image.qvec(k) = ParseDouble(tok[1 + k], pos, kQ[k]);
    for (int k = 0; k < 3; ++k) image.tvec(k) = ParseDouble(tok[5 + k], pos, kT[k]);
    image.camera_id = static_cast<CameraId>(ParseUint(tok[8], pos, "CAMERA_ID", UINT32_MAX));
    // The name is the rest of the line (COLMAP stops at the first space; a
    // name with spaces is kept whole here rather than cut).
    const std::string_view rest = Trim(std::string_view(line).substr(tok[9].data() - line.data()));
    image.name = std::string(rest);

    // The next line holds the points2D, possibly empty.
    std::string points_line;
    if (!std::getline(in, points_line)) {
      throw InputError(file, line_no + 1, "POINTS2D",
                       "missing the points2D line of image " + std::to_string(image.image_id));
    }
    ++line_no;
    const TextPos ppos{file, line_no};
    const auto ptok = Tokenize(points_line);
    if (ptok.size() % 3 != 0) {
      throw InputError(file, line_no, "POINTS2D",
                       "expected (X, Y, POINT3D_ID) triplets, got " + std::to_string(ptok.size()) +
                           " values");
    }
    image.points2d.resize(ptok.size() / 3);
    for (size_t k = 0; k < image.points2d.size(); ++k) {
      Point2D& p = image.points2d[k];
      const std::string idx = "[" + std::to_string(k) + "]";
      p.xy.x() = ParseDouble(ptok[3 * k], ppos, "POINTS2D" + idx + ".X");
      p.xy.y() = ParseDouble(ptok[3 * k + 1], ppos, "POINTS2D" + idx + ".Y");
      const std::string_view id = ptok[3 * k + 2];
      if (id == "-1") {
        p.point3d_id = kInvalidPoint3DId;
      } else {
        p.point3d_id = ParseUint(id, ppos, "POINTS2D" + idx + ".POINT3D_ID", kInvalidPoint3DId - 1);
      }
    }
    images.push_back(std::move(image));
  }
  return images;
}

std::vector<ModelPoint3D> ReadPoints3DText(const fs::path& path) {
  std::ifstream in = OpenText(path);
  const std::string file = path.string();
  std::vector<ModelPoint3D> points;
  std::string line;
  int64_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!IsDataLine(line)) continue;
    const TextPos pos{file, line_no};
    const auto tok = Tokenize(line);
    if (tok.size() < 8 || (tok.size() - 8) % 2 != 0) {
      throw InputError(file, line_no, "",
                       "expected POINT3D_ID X Y Z R G B ERROR then (IMAGE_ID, POINT2D_IDX) pairs");
    }
    ModelPoint3D p;
    p.point3d_id = ParseUint(tok[0], pos, "POINT3D_ID", kInvalidPoint3DId - 1);
    p.xyz = {ParseDouble(tok[1], pos, "X"), ParseDouble(tok[2], pos, "Y"),
             ParseDouble(tok[3], pos, "Z")};
    static const char* kRGB[] = {"R", "G", "B"};
    for (int k = 0; k < 3; ++k) {
      p.color[k] = static_cast<uint8_t>(ParseUint(tok[4 + k], pos, kRGB[k], 255));
    }
    p.error = ParseDouble(tok[7], pos, "ERROR");
    p.track.resize((tok.size() - 8) / 2);
    for (size_t k = 0; k < p.track.size(); ++k) {
      const std::string idx = "TRACK[" + std::to_string(k) + "]";
      p.track[k].image_id =
          static_cast<ImageId>(ParseUint(tok[8 + 2 * k], pos, idx + ".IMAGE_ID", UINT32_MAX));
      p.track[k].point2d_idx = static_cast<Point2DIdx>(
          ParseUint(tok[9 + 2 * k], pos, idx + ".POINT2D_IDX", UINT32_MAX));
    }
    points.push_back(std::move(p));
  }
  return points;
}

// COLMAP formats every number of its text files with precision 17 (%.17g).
std::ostringstream NumberStream() {
  std::ostringstream s;
  s.precision(17);
  return s;
}

// COLMAP joins fields with a trailing space and then drops the last char.
std::string DropLastChar(const std::string& s) {
  return s.empty() ? s : s.substr(0, s.size() - 1);
}

void WriteCamerasText(const Reconstruction& model, const fs::path& path) {
  AtomicFile out(path, /*binary=*/false);
  std::ostream& f = out.stream();
  f.precision(17);
  f << "# Camera list with one line of data per camera:\n";
  f << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n";
  f << "# Number of cameras: " << model.cameras.size() << "\n";
  for (const ModelCamera& c : model.cameras) {
    std::ostringstream line = NumberStream();
    line << c.camera_id << " " << CameraModelInfoOf(c.camera.model).name << " " << c.camera.width
         << " " << c.camera.height << " ";
    for (const double p : c.camera.params) line << p << " ";
    f << DropLastChar(line.str()) << "\n";
  }
  out.Commit();
}

void WriteImagesText(const Reconstruction& model, const fs::path& path) {
  AtomicFile out(path, /*binary=*/false);
  std::ostream& f = out.stream();
  f.precision(17);
  f << "# Image list with two lines of data per image:\n";
  f << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n";
  f << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  f << "# Number of images: " << model.images.size()
    << ", mean observations per image: " << model.MeanObservationsPerImage() << "\n";
  for (const ModelImage& image : model.images) {
    std::ostringstream line = NumberStream();
    const Eigen::Vector4d q = QvecToWrite(image.qvec);
    line << image.image_id << " " << q(0) << " " << q(1) << " " << q(2) << " " << q(3) << " "
         << image.tvec(0) << " " << image.tvec(1) << " " << image.tvec(2) << " "
         << image.camera_id << " " << image.name;
    f << line.str() << "\n";
    std::ostringstream points = NumberStream();
    for (const Point2D& p : image.points2d) {
      points << p.xy.x() << " " << p.xy.y() << " ";
      if (p.HasPoint3D()) {
        points << p.point3d_id << " ";
      } else {
        points << -1 << " ";
      }
    }
    f << DropLastChar(points.str()) << "\n";
  }
  out.Commit();
}

void WritePoints3DText(const Reconstruction& model, const fs::path& path) {
  AtomicFile out(path, /*binary=*/false);
  std::ostream& f = out.stream();
  f.precision(17);
  f << "# 3D point list with one line of data per point:\n";
  f << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  f << "# Number of points: " << model.points3d.size()
    << ", mean track length: " << model.MeanTrackLength() << "\n";
  for (const ModelPoint3D& p : model.points3d) {
    std::ostringstream line = NumberStream();
    line << p.point3d_id << " " << p.xyz.x() << " " << p.xyz.y() << " " << p.xyz.z() << " "
         << static_cast<int>(p.color[0]) << " " << static_cast<int>(p.color[1]) << " "
         << static_cast<int>(p.color[2]) << " " << p.error << " ";
    for (const TrackElement& e : p.track) line << e.image_id << " " << e.point2d_idx << " ";
    f << DropLastChar(line.str()) << "\n";
  }
  out.Commit();
}

// ---------------------------------------------------------------------------
// Binary format

std::vector<ModelCamera> ReadCamerasBinary(const fs::path& path) {
  BinaryReader r(path);
  const uint64_t n = r.Read<uint64_t>("num_cameras");
  r.CheckCount(n, 4 + 4 + 8 + 8, "num_cameras");
  std::vector<ModelCamera> cameras(n);
  for (uint64_t i = 0; i < n; ++i) {
    const std::string rec = "camera #" + std::to_string(i) + ".";
    ModelCamera& c = cameras[i];
    c.camera_id = r.Read<uint32_t>(rec + "camera_id");
    const int32_t model_id = r.Read<int32_t>(rec + "model_id");
    if (model_id < 0 || model_id > static_cast<int>(CameraModelId::kThinPrismFisheye)) {
      r.Fail(rec + "model_id", "unknown COLMAP camera model id " + std::to_string(model_id));
    }
    c.camera.model = static_cast<CameraModelId>(model_id);
    const uint64_t width = r.Read<uint64_t>(rec + "width");
    const uint64_t height = r.Read<uint64_t>(rec + "height");
    if (width > INT32_MAX || height > INT32_MAX) r.Fail(rec + "width", "image size too large");
    c.camera.width = static_cast<int>(width);
    c.camera.height = static_cast<int>(height);
    c.camera.params.resize(CameraModelInfoOf(c.camera.model).num_params);
    for (double& p : c.camera.params) p = r.Read<double>(rec + "params");
  }
  if (r.remaining() != 0) r.Fail("", std::to_string(r.remaining()) + " unexpected trailing bytes");
  return cameras;
}

std::vector<ModelImage> ReadImagesBinary(const fs::path& path) {
  BinaryReader r(path);
  const uint64_t n = r.Read<uint64_t>("num_reg_images");
  r.CheckCount(n, 4 + 7 * 8 + 4 + 1 + 8, "num_reg_images");
  std::vector<ModelImage> images(n);
  for (uint64_t i = 0; i < n; ++i) {
    const std::string rec = "image #" + std::to_string(i) + ".";
    ModelImage& image = images[i];
    image.image_id = r.Read<uint32_t>(rec + "image_id");
    for (int k = 0; k < 4; ++k) image.qvec(k) = r.Read<double>(rec + "qvec");
    for (int k = 0; k < 3; ++k) image.tvec(k) = r.Read<double>(rec + "tvec");
    image.camera_id = r.Read<uint32_t>(rec + "camera_id");
    image.name = r.ReadNulTerminated(rec + "name");
    const uint64_t num_points2d = r.Read<uint64_t>(rec + "num_points2D");
    r.CheckCount(num_points2d, 8 + 8 + 8, rec + "num_points2D");
    image.points2d.resize(num_points2d);
    for (Point2D& p : image.points2d) {
      p.xy.x() = r.Read<double>(rec + "points2D.x");
      p.xy.y() = r.Read<double>(rec + "points2D.y");
      p.point3d_id = r.Read<uint64_t>(rec + "points2D.point3D_id");
    }
  }
  if (r.remaining() != 0) r.Fail("", std::to_string(r.remaining()) + " unexpected trailing bytes");
  return images;
}

std::vector<ModelPoint3D> ReadPoints3DBinary(const fs::path& path) {
  BinaryReader r(path);
  const uint64_t n = r.Read<uint64_t>("num_points3D");
  r.CheckCount(n, 8 + 3 * 8 + 3 + 8 + 8, "num_points3D");
  std::vector<ModelPoint3D> points(n);
  for (uint64_t i = 0; i < n; ++i) {
    const std::string rec = "point3D #" + std::to_string(i) + ".";
    ModelPoint3D& p = points[i];
    p.point3d_id = r.Read<uint64_t>(rec + "point3D_id");
    for (int k = 0; k < 3; ++k) p.xyz(k) = r.Read<double>(rec + "xyz");
    for (int k = 0; k < 3; ++k) p.color[k] = r.Read<uint8_t>(rec + "color");
    p.error = r.Read<double>(rec + "error");
    const uint64_t track_length = r.Read<uint64_t>(rec + "track_length");
    r.CheckCount(track_length, 8, rec + "track_length");
    p.track.resize(track_length);
    for (TrackElement& e : p.track) {
      e.image_id = r.Read<uint32_t>(rec + "track.image_id");
      e.point2d_idx = r.Read<uint32_t>(rec + "track.point2D_idx");
    }
  }
  if (r.remaining() != 0) r.Fail("", std::to_string(r.remaining()) + " unexpected trailing bytes");
  return points;
}

void WriteCamerasBinary(const Reconstruction& model, const fs::path& path) {
  AtomicFile out(path);
  std::ostream& f = out.stream();
  WriteLE<uint64_t>(f, model.cameras.size());
  for (const ModelCamera& c : model.cameras) {
    if (c.camera.model == CameraModelId::kUnknown) {
      throw Error("camera " + std::to_string(c.camera_id) +
                  ": UNKNOWN_CAMERA has no COLMAP model id");
    }
    WriteLE<uint32_t>(f, c.camera_id);
    WriteLE<int32_t>(f, static_cast<int32_t>(c.camera.model));
    WriteLE<uint64_t>(f, static_cast<uint64_t>(c.camera.width));
    WriteLE<uint64_t>(f, static_cast<uint64_t>(c.camera.height));
    for (const double p : c.camera.params) WriteLE<double>(f, p);
  }
  out.Commit();
}

void WriteImagesBinary(const Reconstruction& model, const fs::path& path) {
  AtomicFile out(path);
  std::ostream& f = out.stream();
  WriteLE<uint64_t>(f, model.images.size());
  for (const ModelImage& image : model.images) {
    WriteLE<uint32_t>(f, image.image_id);
    const Eigen::Vector4d q = QvecToWrite(image.qvec);
    for (int k = 0; k < 4; ++k) WriteLE<double>(f, q(k));
    for (int k = 0; k < 3; ++k) WriteLE<double>(f, image.tvec(k));
    WriteLE<uint32_t>(f, image.camera_id);
    f.write(image.name.c_str(), static_cast<std::streamsize>(image.name.size() + 1));
    WriteLE<uint64_t>(f, image.points2d.size());
    for (const Point2D& p : image.points2d) {
      WriteLE<double>(f, p.xy.x());
      WriteLE<double>(f, p.xy.y());
      WriteLE<uint64_t>(f, p.point3d_id);
    }
  }
  out.Commit();
}

void WritePoints3DBinary(const Reconstruction& model, const fs::path& path) {
  AtomicFile out(path);
  std::ostream& f = out.stream();
  WriteLE<uint64_t>(f, model.points3d.size());
  for (const ModelPoint3D& p : model.points3d) {
    WriteLE<uint64_t>(f, p.point3d_id);
    for (int k = 0; k < 3; ++k) WriteLE<double>(f, p.xyz(k));
    for (int k = 0; k < 3; ++k) WriteLE<uint8_t>(f, p.color[k]);
    WriteLE<double>(f, p.error);
    WriteLE<uint64_t>(f, p.track.size());
    for (const TrackElement& e : p.track) {
      WriteLE<uint32_t>(f, e.image_id);
      WriteLE<uint32_t>(f, e.point2d_idx);
    }
  }
  out.Commit();
}

void CheckWritable(const Reconstruction& model) {
  for (const ModelImage& image : model.images) {
    if (image.name.find('\0') != std::string::npos || image.name.find('\n') != std::string::npos) {
      throw Error("image " + std::to_string(image.image_id) +
                  ": name contains a NUL or newline character");
    }
  }
}

}  // namespace

bool HasModel(const fs::path& dir, ModelFormat format) {
  const char* ext = format == ModelFormat::kBinary ? ".bin" : ".txt";
  for (const char* stem : {"cameras", "images", "points3D"}) {
    if (!fs::is_regular_file(dir / (std::string(stem) + ext))) return false;
  }
  return true;
}

Reconstruction ReadModelText(const fs::path& dir) {
  Reconstruction model;
  model.cameras = ReadCamerasText(dir / "cameras.txt");
  model.images = ReadImagesText(dir / "images.txt");
  model.points3d = ReadPoints3DText(dir / "points3D.txt");
  return model;
}

Reconstruction ReadModelBinary(const fs::path& dir) {
  Reconstruction model;
  model.cameras = ReadCamerasBinary(dir / "cameras.bin");
  model.images = ReadImagesBinary(dir / "images.bin");
  model.points3d = ReadPoints3DBinary(dir / "points3D.bin");
  return model;
}

Reconstruction ReadModel(const fs::path& dir) {
  if (HasModel(dir, ModelFormat::kBinary)) return ReadModelBinary(dir);
  if (HasModel(dir, ModelFormat::kText)) return ReadModelText(dir);
  throw InputError(dir.string(), 0, "",
                   "no COLMAP model here (needs cameras, images and points3D as .bin or .txt)");
}

void WriteModelText(const Reconstruction& model, const fs::path& dir) {
  CheckWritable(model);
  fs::create_directories(dir);
  WriteCamerasText(model, dir / "cameras.txt");
  WriteImagesText(model, dir / "images.txt");
  WritePoints3DText(model, dir / "points3D.txt");
}

void WriteModelBinary(const Reconstruction& model, const fs::path& dir) {
  CheckWritable(model);
  fs::create_directories(dir);
  WriteCamerasBinary(model, dir / "cameras.bin");
  WriteImagesBinary(model, dir / "images.bin");
  WritePoints3DBinary(model, dir / "points3D.bin");
}

void WriteModel(const Reconstruction& model, const fs::path& dir, ModelFormat format) {
  if (format == ModelFormat::kBinary) {
    WriteModelBinary(model, dir);
  } else {
    WriteModelText(model, dir);
  }
}

}  // namespace locforge::colmap
