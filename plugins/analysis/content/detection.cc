#include "detection.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/csv.h"

namespace locforge::analysis {

namespace {

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}

// The placement of the scaled image inside the network input, as fractions
// of the input: what letterboxing adds and decoding removes.
struct Placement {
  double offset_x = 0, offset_y = 0;  // padding before the image
  double size_x = 1, size_y = 1;      // the image's extent
};

Placement PlacementOf(cv::Size image, const DarknetInput& input) {
  Placement p;
  if (!input.letter_box) return p;
  // In integers, as Darknet's letterbox_image: the bound axis fills the input exactly.
  int new_w = input.width, new_h = input.height;
  if (static_cast<int64_t>(input.width) * image.height < static_cast<int64_t>(input.height) * image.width)
    new_h = static_cast<int>(static_cast<int64_t>(image.height) * input.width / image.width);
  else
    new_w = static_cast<int>(static_cast<int64_t>(image.width) * input.height / image.height);
  p.size_x = static_cast<double>(new_w) / input.width;
  p.size_y = static_cast<double>(new_h) / input.height;
  p.offset_x = static_cast<double>((input.width - new_w) / 2) / input.width;
  p.offset_y = static_cast<double>((input.height - new_h) / 2) / input.height;
  return p;
}

}  // namespace

DarknetInput ReadDarknetInput(const fs::path& cfg) {
  std::istringstream in(ReadFile(cfg));
  DarknetInput input;
  std::string line, section;
  int64_t number = 0;
  bool seen_net = false;
  while (std::getline(in, line)) {
    ++number;
    line = Trim(line.substr(0, line.find_first_of("#;")));
    if (line.empty()) continue;
    if (line.front() == '[') {
      if (seen_net) break;  // only the first section is [net]
      section = line;
      seen_net = section == "[net]" || section == "[network]";
      if (!seen_net) throw InputError(cfg.string(), number, "[net]", "a Darknet cfg starts with its [net] section");
      continue;
    }
    const size_t eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = Trim(line.substr(0, eq)), value = Trim(line.substr(eq + 1));
    if (key == "width" || key == "height" || key == "letter_box") {
      const double v = kapture::ParseDouble(value, cfg.string(), number, key);
      if (key == "letter_box") {
        input.letter_box = v != 0;
      } else {
        if (!(v >= 32) || v != std::floor(v) || static_cast<int>(v) % 32 != 0)
          throw InputError(cfg.string(), number, key, "expected a multiple of 32, got " + value);
        (key == "width" ? input.width : input.height) = static_cast<int>(v);
      }
    }
  }
  if (!seen_net) throw InputError(cfg.string(), 0, "[net]", "no [net] section (not a Darknet cfg)");
  if (input.width == 0) throw InputError(cfg.string(), 0, "width", "missing from the [net] section");
  if (input.height == 0) throw InputError(cfg.string(), 0, "height", "missing from the [net] section");
  return input;
}

cv::Mat DarknetBlob(const cv::Mat& rgb, const DarknetInput& input) {
  if (rgb.empty() || rgb.type() != CV_8UC3) throw std::invalid_argument("DarknetBlob: needs an 8-bit RGB image");
  if (input.width <= 0 || input.height <= 0) throw std::invalid_argument("DarknetBlob: no input size");
  cv::Mat canvas(input.height, input.width, CV_32FC3, cv::Scalar::all(0.5));
  const Placement p = PlacementOf(rgb.size(), input);
  const cv::Rect roi(static_cast<int>(std::lround(p.offset_x * input.width)),
                     static_cast<int>(std::lround(p.offset_y * input.height)),
                     static_cast<int>(std::lround(p.size_x * input.width)),
                     static_cast<int>(std::lround(p.size_y * input.height)));
  cv::Mat scaled;
  cv::resize(rgb, scaled, roi.size(), 0, 0, cv::INTER_LINEAR);  // Darknet resizes bilinearly
  scaled.convertTo(canvas(roi), CV_32FC3, 1.0 / 255);
  const int sizes[4] = {1, 3, input.height, input.width};
  cv::Mat blob(4, sizes, CV_32F);
  std::vector<cv::Mat> planes;
  for (int c = 0; c < 3; ++c) planes.emplace_back(input.height, input.width, CV_32F, blob.ptr<float>(0, c));
  cv::split(canvas, planes);
  return blob;
}

std::vector<PersonBox> DecodeYoloRows(const std::vector<cv::Mat>& outputs, cv::Size image, const DarknetInput& input,
                                      const DetectionOptions& options) {
  const Placement p = PlacementOf(image, input);
  std::vector<PersonBox> boxes;
  const int column = 5 + options.person_class;
  for (const cv::Mat& out : outputs) {
    if (out.dims != 2 || out.type() != CV_32F || out.cols <= column)
      throw std::invalid_argument("DecodeYoloRows: expected N x (5 + classes) float rows with class " +
                                  std::to_string(options.person_class));
    for (int r = 0; r < out.rows; ++r) {
      const float* row = out.ptr<float>(r);
      if (!(row[column] >= options.score_threshold)) continue;
      // Normalised to the network input -> normalised to the image -> pixels.
      const double cx = (row[0] - p.offset_x) / p.size_x * image.width;
      const double cy = (row[1] - p.offset_y) / p.size_y * image.height;
      const double w = row[2] / p.size_x * image.width, h = row[3] / p.size_y * image.height;
      const double x0 = std::clamp(cx - w / 2, 0.0, static_cast<double>(image.width));
      const double y0 = std::clamp(cy - h / 2, 0.0, static_cast<double>(image.height));
      const double x1 = std::clamp(cx + w / 2, 0.0, static_cast<double>(image.width));
      const double y1 = std::clamp(cy + h / 2, 0.0, static_cast<double>(image.height));
      if (x1 <= x0 || y1 <= y0) continue;
      boxes.push_back({x0, y0, x1 - x0, y1 - y0, row[column]});
    }
  }
  return NonMaximumSuppression(std::move(boxes), options.nms_iou);
}

double BoxIou(const PersonBox& a, const PersonBox& b) {
  const double iw = std::min(a.x + a.width, b.x + b.width) - std::max(a.x, b.x);
  const double ih = std::min(a.y + a.height, b.y + b.height) - std::max(a.y, b.y);
  if (iw <= 0 || ih <= 0) return 0;
  const double inter = iw * ih, uni = a.width * a.height + b.width * b.height - inter;
  return uni > 0 ? inter / uni : 0;
}

std::vector<PersonBox> NonMaximumSuppression(std::vector<PersonBox> boxes, double iou) {
  // Stable: equal scores keep their input order, so the result is reproducible.
  std::stable_sort(boxes.begin(), boxes.end(), [](const PersonBox& a, const PersonBox& b) { return a.score > b.score; });
  std::vector<PersonBox> kept;
  for (const PersonBox& b : boxes) {
    bool suppressed = false;
    for (const PersonBox& k : kept)
      if (BoxIou(b, k) > iou) {
        suppressed = true;
        break;
      }
    if (!suppressed) kept.push_back(b);
  }
  return kept;
}

double CoveredPercent(const std::vector<PersonBox>& boxes, cv::Size image) {
  if (image.width <= 0 || image.height <= 0) throw std::invalid_argument("CoveredPercent: empty image");
  const double W = image.width, H = image.height;
  std::vector<double> xs = {0, W}, ys = {0, H};
  struct Clipped {
    double x0, y0, x1, y1;
  };
  std::vector<Clipped> clipped;
  for (const PersonBox& b : boxes) {
    const Clipped c{std::clamp(b.x, 0.0, W), std::clamp(b.y, 0.0, H), std::clamp(b.x + b.width, 0.0, W),
                    std::clamp(b.y + b.height, 0.0, H)};
    if (c.x1 <= c.x0 || c.y1 <= c.y0) continue;
    clipped.push_back(c);
    xs.insert(xs.end(), {c.x0, c.x1});
    ys.insert(ys.end(), {c.y0, c.y1});
  }
  std::sort(xs.begin(), xs.end());
  xs.erase(std::unique(xs.begin(), xs.end()), xs.end());
  std::sort(ys.begin(), ys.end());
  ys.erase(std::unique(ys.begin(), ys.end()), ys.end());
  // Each cell of the compressed grid is inside a box or not: at most
  // (2n+1)^2 cells, a few hundred boxes per image at most.
  double area = 0;
  for (size_t i = 0; i + 1 < xs.size(); ++i) {
    const double mx = (xs[i] + xs[i + 1]) / 2;
    for (size_t j = 0; j + 1 < ys.size(); ++j) {
      const double my = (ys[j] + ys[j + 1]) / 2;
      for (const Clipped& c : clipped)
        if (mx > c.x0 && mx < c.x1 && my > c.y0 && my < c.y1) {
          area += (xs[i + 1] - xs[i]) * (ys[j + 1] - ys[j]);
          break;
        }
    }
  }
  return 100.0 * area / (W * H);
}

std::string FormatPersons(const Persons& persons) {
  std::ostringstream out;
  out.precision(17);
  out << persons.boxes.size() << ' ' << persons.covered_percent << '\n';
  for (const PersonBox& b : persons.boxes)
    out << b.x << ' ' << b.y << ' ' << b.width << ' ' << b.height << ' ' << b.score << '\n';
  return out.str();
}

Persons ParsePersons(const std::string& text, const std::string& file) {
  std::istringstream in(text);
  std::string line;
  Persons persons;
  size_t count = 0;
  if (!std::getline(in, line)) throw InputError(file, 1, "person_count", "empty persons file");
  {
    std::istringstream head(line);
    std::string extra;
    if (!(head >> count >> persons.covered_percent) || (head >> extra) || !(persons.covered_percent >= 0) ||
        persons.covered_percent > 100)
      throw InputError(file, 1, "person_count", "expected '<person_count> <covered_percent>'");
  }
  int64_t number = 1;
  while (std::getline(in, line)) {
    ++number;
    if (Trim(line).empty()) continue;
    std::istringstream row(line);
    PersonBox b;
    std::string extra;
    if (!(row >> b.x >> b.y >> b.width >> b.height >> b.score) || (row >> extra) || !(b.width > 0) || !(b.height > 0))
      throw InputError(file, number, "box", "expected '<x> <y> <width> <height> <score>' with a positive size");
    persons.boxes.push_back(b);
  }
  if (persons.boxes.size() != count)
    throw InputError(file, 1, "person_count",
                     std::to_string(count) + " announced, " + std::to_string(persons.boxes.size()) + " boxes listed");
  return persons;
}

fs::path PersonsFile(const fs::path& folder, const std::string& image) { return SafeJoin(folder, image + ".txt"); }

Persons ReadPersons(const fs::path& folder, const std::string& image) {
  const fs::path file = PersonsFile(folder, image);
  if (!fs::exists(file)) throw InputError(file.string(), 0, "detections", "no person detections for image " + image);
  return ParsePersons(ReadFile(file), file.string());
}

namespace {

std::vector<double> Ranks(const std::vector<double>& v) {
  std::vector<size_t> order(v.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return v[a] < v[b]; });
  std::vector<double> rank(v.size());
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j + 1 < order.size() && v[order[j + 1]] == v[order[i]]) ++j;
    const double mean_rank = (i + j) / 2.0 + 1;  // ties share their mean rank
    for (size_t k = i; k <= j; ++k) rank[order[k]] = mean_rank;
    i = j + 1;
  }
  return rank;
}

}  // namespace

double PearsonCorrelation(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size()) throw std::invalid_argument("PearsonCorrelation: samples of different sizes");
  const size_t n = x.size();
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  if (sxx <= 0 || syy <= 0) return std::numeric_limits<double>::quiet_NaN();
  return sxy / std::sqrt(sxx * syy);
}

double SpearmanCorrelation(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size()) throw std::invalid_argument("SpearmanCorrelation: samples of different sizes");
  return PearsonCorrelation(Ranks(x), Ranks(y));
}

}  // namespace locforge::analysis
