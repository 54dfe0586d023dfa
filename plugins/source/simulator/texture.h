// Procedural textures, generated from a key "kind:variant" (and, for digital
// signage, the day), with a mip pyramid for filtered lookups.
//
// Kinds: noise (value noise), bricks, tiles, ceiling (light panels), poster
// (shapes + glyph-like text), shopfront, signage (a poster whose content depends
// on the day), glossy (dark panel; pair with Material::glossy), plain
// (textureless temporary wall), clothes (people), marker (black disc on white,
// centred, radius 0.35 of the texture; used by tests).
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_TEXTURE_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_TEXTURE_H_

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace locforge::sim {

struct Texture {
  struct Level {
    int size = 0;                // square
    std::vector<uint8_t> rgb;    // size * size * 3, row 0 at the top
  };
  std::vector<Level> levels;     // levels[0] full resolution, each next one half

  // Bilinear lookup with wrap-around; (u, v) in texture units (1 = one period),
  // v = 0 at the top row. `footprint` is the pixel footprint in level-0 texels
  // and picks the mip level. Returns RGB in [0, 255].
  Eigen::Vector3f Sample(double u, double v, double footprint) const;
};

// Builds the texture of `key` for `day` (only signage depends on the day).
// Throws ParamError for an unknown kind or malformed key.
Texture MakeTexture(const std::string& key, int day, int size = 512);

// True when a key's content depends on the day.
bool IsDayDependent(const std::string& key);

// Thread-safe cache of textures by (key, day).
class TextureLibrary {
 public:
  explicit TextureLibrary(int size = 512) : size_(size) {}
  const Texture* Get(const std::string& key, int day);

 private:
  int size_;
  std::mutex mutex_;
  std::map<std::pair<std::string, int>, std::unique_ptr<Texture>> cache_;
};

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_TEXTURE_H_
