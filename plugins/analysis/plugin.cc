// The stages of kind analysis: what explains a method's failures.
#include "locforge/plugin.h"

namespace locforge::analysis {
LOCFORGE_DECLARE_STAGE(AddImageContent);
LOCFORGE_DECLARE_STAGE(AddContentTables);
LOCFORGE_DECLARE_STAGE(AddCrowdSweep);
LOCFORGE_DECLARE_STAGE(AddPersonSegmentation);
LOCFORGE_DECLARE_STAGE(AddPersonDetection);
LOCFORGE_DECLARE_STAGE(AddCrowdednessAgreement);
}  // namespace locforge::analysis

LOCFORGE_PLUGIN("analysis", "1.0.0", "Analyses of localization results by image content: low-frequency score, crowdedness (truth, person segmentation or person detection), the paper's Tables 5 and 6, recall vs crowd density",
                locforge::Exported<locforge::analysis::AddImageContent>,
                locforge::Exported<locforge::analysis::AddContentTables>,
                locforge::Exported<locforge::analysis::AddCrowdSweep>,
                locforge::Exported<locforge::analysis::AddPersonSegmentation>,
                locforge::Exported<locforge::analysis::AddPersonDetection>,
                locforge::Exported<locforge::analysis::AddCrowdednessAgreement>)
