// The stages of kind global; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::retrieval {
LOCFORGE_DECLARE_STAGE(AddDenseVladVocabulary);
LOCFORGE_DECLARE_STAGE(AddDenseVlad);
LOCFORGE_DECLARE_STAGE(AddGlobalImport);
}  // namespace locforge::retrieval

namespace locforge::learned {
LOCFORGE_DECLARE_STAGE(AddNetVlad);
LOCFORGE_DECLARE_STAGE(AddApGem);
LOCFORGE_DECLARE_STAGE(AddDelg);
}  // namespace locforge::learned

LOCFORGE_PLUGIN("global", "1.0.0", "Global image descriptors: DenseVLAD, NetVLAD, AP-GeM, DELG (ONNX), import",
                locforge::Exported<locforge::retrieval::AddDenseVladVocabulary>,
                locforge::Exported<locforge::retrieval::AddDenseVlad>,
                locforge::Exported<locforge::retrieval::AddGlobalImport>,
                locforge::Exported<locforge::learned::AddNetVlad>,
                locforge::Exported<locforge::learned::AddApGem>,
                locforge::Exported<locforge::learned::AddDelg>)
