#include "texture.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/error.h"

namespace locforge::sim {
namespace {

uint64_t Fnv1a(const std::string& s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

cv::Scalar RandomColor(cv::RNG& rng, int lo = 0, int hi = 255) {
  return cv::Scalar(rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi));
}

// Multi-octave value noise in [0, 1], CV_32F.
cv::Mat ValueNoise(cv::RNG& rng, int size, int base_cells, int octaves) {
  cv::Mat acc = cv::Mat::zeros(size, size, CV_32F);
  double weight = 1, total = 0;
  for (int o = 0, cells = base_cells; o < octaves && cells <= size; ++o, cells *= 2) {
    cv::Mat grid(cells, cells, CV_32F), up;
    rng.fill(grid, cv::RNG::UNIFORM, 0.f, 1.f);
    cv::resize(grid, up, {size, size}, 0, 0, cv::INTER_CUBIC);
    acc += weight * up;
    total += weight;
    weight *= 0.55;
  }
  acc /= total;
  cv::normalize(acc, acc, 0, 1, cv::NORM_MINMAX);
  return acc;
}

// Blends two colours by a [0, 1] map.
cv::Mat Colorize(const cv::Mat& t, const cv::Scalar& a, const cv::Scalar& b) {
  cv::Mat out(t.size(), CV_8UC3);
  for (int y = 0; y < t.rows; ++y)
    for (int x = 0; x < t.cols; ++x) {
      const float w = t.at<float>(y, x);
      for (int c = 0; c < 3; ++c)
        out.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>(a[c] * (1 - w) + b[c] * w);
    }
  return out;
}

void AddGrain(cv::Mat& img, cv::RNG& rng, double sigma) {
  cv::Mat noise(img.size(), CV_16SC3);
  rng.fill(noise, cv::RNG::NORMAL, 0, sigma);
  cv::Mat tmp;
  img.convertTo(tmp, CV_16SC3);
  tmp += noise;
  tmp.convertTo(img, CV_8UC3);
}

std::string RandomWord(cv::RNG& rng, int min_len, int max_len) {
  static const char* kLetters = "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789&%$#@";
  std::string s(rng.uniform(min_len, max_len + 1), ' ');
  for (auto& c : s) c = kLetters[rng.uniform(0, 41)];
  return s;
}

void DrawText(cv::Mat& img, cv::RNG& rng, const cv::Point& at, double scale, const cv::Scalar& color) {
  static const int kFonts[] = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX,
                               cv::FONT_HERSHEY_COMPLEX, cv::FONT_HERSHEY_TRIPLEX};
  cv::putText(img, RandomWord(rng, 3, 9), at, kFonts[rng.uniform(0, 4)], scale, color,
              std::max(1, static_cast<int>(scale * 2)), cv::LINE_AA);
}

cv::Mat Noise(cv::RNG& rng, int n) {
  cv::Mat img = Colorize(ValueNoise(rng, n, rng.uniform(3, 8), 6), RandomColor(rng, 20, 140),
                         RandomColor(rng, 120, 250));
  // Sparse blobs and scratches: corners for detectors.
  for (int i = 0; i < 60; ++i)
    cv::circle(img, {rng.uniform(0, n), rng.uniform(0, n)}, rng.uniform(2, 10),
               RandomColor(rng), cv::FILLED, cv::LINE_AA);
  AddGrain(img, rng, 4);
  return img;
}

cv::Mat Bricks(cv::RNG& rng, int n) {
  cv::Mat img(n, n, CV_8UC3, cv::Scalar(190, 190, 185));  // mortar
  const cv::Scalar base = RandomColor(rng, 40, 200);
  const int rows = 8, cols = 4, bh = n / rows, bw = n / cols;
  for (int r = 0; r < rows; ++r)
    for (int c = -1; c <= cols; ++c) {
      const int x0 = c * bw + (r % 2) * bw / 2;
      cv::Scalar col = base + cv::Scalar::all(rng.uniform(-35, 35));
      cv::rectangle(img, {x0 + 3, r * bh + 3}, {x0 + bw - 3, (r + 1) * bh - 3}, col, cv::FILLED);
    }
  cv::Mat shade = Colorize(ValueNoise(rng, n, 16, 4), cv::Scalar::all(0), cv::Scalar::all(60));
  img -= shade;
  AddGrain(img, rng, 6);
  return img;
}

cv::Mat Tiles(cv::RNG& rng, int n) {
  cv::Mat img(n, n, CV_8UC3, cv::Scalar::all(90));
  const int cells = 4, s = n / cells;
  const cv::Scalar a = RandomColor(rng, 120, 230), b = RandomColor(rng, 60, 180);
  for (int y = 0; y < cells; ++y)
    for (int x = 0; x < cells; ++x) {
      cv::Scalar col = ((x + y) % 2 ? a : b) + cv::Scalar::all(rng.uniform(-15, 15));
      cv::rectangle(img, {x * s + 2, y * s + 2}, {(x + 1) * s - 2, (y + 1) * s - 2}, col, cv::FILLED);
    }
  cv::Mat marble = Colorize(ValueNoise(rng, n, 8, 6), cv::Scalar::all(0), cv::Scalar::all(45));
  img -= marble;
  for (int i = 0; i < 150; ++i)  // speckles and stains
    cv::circle(img, {rng.uniform(0, n), rng.uniform(0, n)}, rng.uniform(1, 5),
               RandomColor(rng, 0, 120), cv::FILLED, cv::LINE_AA);
  AddGrain(img, rng, 5);
  return img;
}

cv::Mat Ceiling(cv::RNG& rng, int n) {
  cv::Mat img = Colorize(ValueNoise(rng, n, 8, 5), cv::Scalar::all(150), cv::Scalar::all(190));
  cv::rectangle(img, {n / 8, n / 3}, {7 * n / 8, 2 * n / 3}, cv::Scalar::all(250), cv::FILLED);
  cv::rectangle(img, {n / 8, n / 3}, {7 * n / 8, 2 * n / 3}, cv::Scalar::all(110), 3);
  cv::line(img, {0, 0}, {n - 1, 0}, cv::Scalar::all(80), 4);
  cv::line(img, {0, 0}, {0, n - 1}, cv::Scalar::all(80), 4);
  cv::circle(img, {n / 6, n / 6}, n / 24, cv::Scalar::all(60), cv::FILLED);  // sprinkler
  AddGrain(img, rng, 3);
  return img;
}

cv::Mat Poster(cv::RNG& rng, int n) {
  cv::Mat img(n, n, CV_8UC3, RandomColor(rng, 30, 240));
  for (int i = 0, shapes = rng.uniform(8, 20); i < shapes; ++i) {
    const cv::Point c(rng.uniform(0, n), rng.uniform(0, n));
    const int r = rng.uniform(n / 30, n / 5);
    switch (rng.uniform(0, 4)) {
      case 0: cv::circle(img, c, r, RandomColor(rng), cv::FILLED, cv::LINE_AA); break;
      case 1: cv::rectangle(img, c, c + cv::Point(r, r * 2 / 3), RandomColor(rng), cv::FILLED); break;
      case 2: {
        std::vector<cv::Point> tri{c, c + cv::Point(r, r / 2), c + cv::Point(-r / 3, r)};
        cv::fillConvexPoly(img, tri, RandomColor(rng), cv::LINE_AA);
        break;
      }
      default: cv::line(img, c, c + cv::Point(rng.uniform(-n / 3, n / 3), rng.uniform(-n / 3, n / 3)),
                        RandomColor(rng), rng.uniform(2, 8), cv::LINE_AA);
    }
  }
  for (int line = 0, lines = rng.uniform(2, 7); line < lines; ++line)
    DrawText(img, rng, {rng.uniform(0, n / 3), rng.uniform(n / 8, n)}, n / 512.0 * rng.uniform(0.8, 2.5),
             RandomColor(rng));
  AddGrain(img, rng, 3);
  return img;
}

cv::Mat Shopfront(cv::RNG& rng, int n) {
  cv::Mat img = Poster(rng, n);
  // Name board on top, window mullions below.
  cv::rectangle(img, {0, 0}, {n, n / 5}, RandomColor(rng, 0, 80), cv::FILLED);
  DrawText(img, rng, {n / 16, n / 7}, n / 512.0 * 2.2, RandomColor(rng, 170, 255));
  for (int x = 0; x <= n; x += n / 4) cv::line(img, {x, n / 5}, {x, n}, cv::Scalar::all(40), 6);
  cv::line(img, {0, 3 * n / 5}, {n, 3 * n / 5}, cv::Scalar::all(40), 6);
  return img;
}

cv::Mat Glossy(cv::RNG& rng, int n) {
  cv::Mat img = Colorize(ValueNoise(rng, n, 2, 3), RandomColor(rng, 10, 50), RandomColor(rng, 40, 90));
  for (int i = 0; i < 6; ++i) {  // faint streaks
    const int x = rng.uniform(0, n);
    cv::line(img, {x, 0}, {x + n / 4, n}, cv::Scalar::all(rng.uniform(70, 110)), rng.uniform(2, 6), cv::LINE_AA);
  }
  return img;
}

cv::Mat Plain(cv::RNG& rng, int n) {
  cv::Mat img(n, n, CV_8UC3, RandomColor(rng, 180, 235));
  AddGrain(img, rng, 1);  // nearly textureless on purpose
  return img;
}

cv::Mat Clothes(cv::RNG& rng, int n) {
  cv::Mat img(n, n, CV_8UC3, RandomColor(rng, 20, 220));
  const int stripes = rng.uniform(0, 6);
  for (int i = 0; i < stripes; ++i) {
    const int y = rng.uniform(0, n);
    cv::rectangle(img, {0, y}, {n, y + rng.uniform(8, n / 6)}, RandomColor(rng), cv::FILLED);
  }
  cv::Mat shade = Colorize(ValueNoise(rng, n, 6, 4), cv::Scalar::all(0), cv::Scalar::all(50));
  img -= shade;
  // Face/skin band at the top (the head of a person maps to v < 0.2).
  cv::rectangle(img, {0, 0}, {n, n / 6}, cv::Scalar(110, 150, 200) + cv::Scalar::all(rng.uniform(-50, 30)), cv::FILLED);
  AddGrain(img, rng, 4);
  return img;
}

cv::Mat Marker(int n) {
  cv::Mat img(n, n, CV_8UC3, cv::Scalar::all(255));
  cv::circle(img, {n / 2, n / 2}, static_cast<int>(0.35 * n), cv::Scalar::all(0), cv::FILLED, cv::LINE_AA, 0);
  return img;
}

}  // namespace

bool IsDayDependent(const std::string& key) { return key.rfind("signage", 0) == 0; }

Texture MakeTexture(const std::string& key, int day, int size) {
  const size_t colon = key.find(':');
  const std::string kind = key.substr(0, colon);
  if (colon != std::string::npos) {
    const std::string variant = key.substr(colon + 1);
    if (variant.empty() || variant.find_first_not_of("0123456789") != std::string::npos)
      throw ParamError("texture key '" + key + "': the variant after ':' must be a number");
  }
  uint64_t seed = Fnv1a(key);
  if (IsDayDependent(key)) seed = Fnv1a(std::to_string(day), seed);
  cv::RNG rng(seed);
  const int n = size;
  cv::Mat img;
  if (kind == "noise") img = Noise(rng, n);
  else if (kind == "bricks") img = Bricks(rng, n);
  else if (kind == "tiles") img = Tiles(rng, n);
  else if (kind == "ceiling") img = Ceiling(rng, n);
  else if (kind == "poster" || kind == "signage") img = Poster(rng, n);
  else if (kind == "shopfront") img = Shopfront(rng, n);
  else if (kind == "glossy") img = Glossy(rng, n);
  else if (kind == "plain") img = Plain(rng, n);
  else if (kind == "clothes") img = Clothes(rng, n);
  else if (kind == "marker") img = Marker(n);
  else
    throw ParamError("unknown texture kind '" + kind + "' in key '" + key +
                     "' (noise, bricks, tiles, ceiling, poster, shopfront, signage, glossy, "
                     "plain, clothes, marker)");
  if (kind == "signage") cv::add(img, cv::Scalar::all(40), img);  // emissive screens are bright

  Texture tex;
  cv::Mat level = img;
  while (true) {
    Texture::Level l;
    l.size = level.rows;
    l.rgb.resize(static_cast<size_t>(l.size) * l.size * 3);
    cv::Mat view(l.size, l.size, CV_8UC3, l.rgb.data());
    cv::cvtColor(level, view, cv::COLOR_BGR2RGB);
    tex.levels.push_back(std::move(l));
    if (level.rows <= 4) break;
    cv::Mat next;
    cv::resize(level, next, {level.cols / 2, level.rows / 2}, 0, 0, cv::INTER_AREA);
    level = next;
  }
  return tex;
}

Eigen::Vector3f Texture::Sample(double u, double v, double footprint) const {
  int li = footprint > 1 ? static_cast<int>(std::log2(footprint)) : 0;
  li = std::min<int>(li, static_cast<int>(levels.size()) - 1);
  const Level& l = levels[li];
  const int n = l.size;
  // Texel centres at (i + 0.5) / n.
  double x = u * n - 0.5, y = v * n - 0.5;
  x -= std::floor(x / n) * n;
  y -= std::floor(y / n) * n;
  int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  // a % n, without the integer division when a is already in [0, n) (nearly always).
  const auto mod = [n](int a) { return static_cast<unsigned>(a) < static_cast<unsigned>(n) ? a : a % n; };
  x0 = mod(x0);
  y0 = mod(y0);
  const int x1 = mod(x0 + 1), y1 = mod(y0 + 1);
  const auto px = [&](int xx, int yy) {
    const uint8_t* p = &l.rgb[(static_cast<size_t>(yy) * n + xx) * 3];
    return Eigen::Vector3f(p[0], p[1], p[2]);
  };
  return (px(x0, y0) * (1 - fx) + px(x1, y0) * fx) * (1 - fy) +
         (px(x0, y1) * (1 - fx) + px(x1, y1) * fx) * fy;
}

const Texture* TextureLibrary::Get(const std::string& key, int day) {
  const int effective_day = IsDayDependent(key) ? day : 0;
  std::lock_guard<std::mutex> lock(mutex_);
  auto& slot = cache_[{key, effective_day}];
  if (!slot) slot = std::make_unique<Texture>(MakeTexture(key, effective_day, size_));
  return slot.get();
}

}  // namespace locforge::sim
