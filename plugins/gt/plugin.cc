// The stages of kind gt; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::sfm_gt {
LOCFORGE_DECLARE_STAGE(AddImages);
LOCFORGE_DECLARE_STAGE(AddSplineBA);
LOCFORGE_DECLARE_STAGE(AddLidarDepth);
}  // namespace locforge::sfm_gt

LOCFORGE_PLUGIN("gt", "1.0.0", "SfM half of the ground truth: images with LiDAR poses, spline bundle adjustment outer loop, depth maps from the LiDAR map",
                locforge::Exported<locforge::sfm_gt::AddImages>,
                locforge::Exported<locforge::sfm_gt::AddSplineBA>,
                locforge::Exported<locforge::sfm_gt::AddLidarDepth>)
