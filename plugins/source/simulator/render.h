// The ray-casting renderer: one ray per pixel through the pixel centre, the
// nearest surface (scene or person), its texture (bilinear, mip level from
// the pixel footprint), simple shading, glossy highlights, then the session's
// exposure/gain and sensor noise. Also gives the true per-pixel person mask
// and depth.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_RENDER_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_RENDER_H_

#include <cstdint>
#include <vector>

#include "camera_rig.h"
#include "raycast.h"

namespace locforge::sim {

struct RenderOptions {
  double exposure = 1.0;      // session exposure time factor
  double gain = 1.0;          // session sensor gain
  double noise_sigma = 1.5;   // read noise in grey levels (before gain)
  uint64_t noise_seed = 0;    // per image
  bool shading = true;        // false: raw albedo (tests)
  bool reference_raycast = false;  // World::Cast on every pixel (QuadBvh, every visible person):
                                   // the slow reference the default equals bit for bit (tests, bench)
};

struct RenderedImage {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;          // row-major, 3 bytes a pixel
  std::vector<uint8_t> person_mask;  // 255 where a person is the nearest surface
  std::vector<float> depth;          // z of the nearest surface in the camera frame (m), 0: none
  double PersonFraction() const;
};

// Renders rows [row_begin, row_end) (all when row_end < 0) into `out`, which
// is (re)sized on first use; split rows across threads to parallelise.
void Render(const World& world, const std::vector<Cylinder>& people, const PinholeCamera& camera,
            const Pose& T_world_camera, const RenderOptions& options, RenderedImage* out,
            int row_begin = 0, int row_end = -1);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_RENDER_H_
