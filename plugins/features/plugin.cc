// The stages of kind features; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::sift {
LOCFORGE_DECLARE_STAGE(AddSift);
LOCFORGE_DECLARE_STAGE(AddImport);
}  // namespace locforge::sift

namespace locforge::learned {
LOCFORGE_DECLARE_STAGE(AddR2d2);
LOCFORGE_DECLARE_STAGE(AddD2net);
LOCFORGE_DECLARE_STAGE(AddXfeat);
LOCFORGE_DECLARE_STAGE(AddAlike);
}  // namespace locforge::learned

LOCFORGE_PLUGIN("features", "1.0.0", "Local features: OpenCV SIFT, R2D2, D2-Net, XFeat and ALIKE (ONNX), import of kapture features",
                locforge::Exported<locforge::sift::AddSift>,
                locforge::Exported<locforge::sift::AddImport>,
                locforge::Exported<locforge::learned::AddR2d2>,
                locforge::Exported<locforge::learned::AddD2net>,
                locforge::Exported<locforge::learned::AddXfeat>,
                locforge::Exported<locforge::learned::AddAlike>)
