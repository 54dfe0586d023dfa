// eval/joins (joins_stage.cc): the sequences of a multi-sequence LiDAR map
// against a simulated recording's truth.
#ifndef LOCFORGE_PLUGINS_TRAJECTORY_EVAL_JOINS_STAGE_H_
#define LOCFORGE_PLUGINS_TRAJECTORY_EVAL_JOINS_STAGE_H_

#include <string>

#include "locforge/plugin.h"

namespace locforge::eval {

struct JoinsEvalOptions {
  std::string device = "rig";
  double seconds_per_unit = 1e-6;
  double max_diff = 0.001;        // s, association of poses
  double wrong_translation = 0.25;  // m
  double wrong_rotation = 1.0;      // deg
  static void Declare(ParamSchema<JoinsEvalOptions>& s) {
    using O = JoinsEvalOptions;
    s.Add("device", &O::device, "kapture device evaluated (the platform rig)");
    s.Add("seconds_per_unit", &O::seconds_per_unit, "kapture timestamp unit (s)").Range(1e-12, 1);
    s.Add("max_diff", &O::max_diff, "Largest timestamp difference of associated poses (s)").Min(0);
    s.Add("wrong_translation", &O::wrong_translation,
          "A joined sequence is wrong when the rigid alignment of its own poses and the first sequence's differ "
          "by more than this over its poses (m RMS) ...").Min(1e-6);
    s.Add("wrong_rotation", &O::wrong_rotation, "... or by more than this rotation (deg)").Min(1e-6);
  }
};

class JoinsEval : public Stage<JoinsEvalOptions> {
 public:
  static StageMeta Meta() {
    return {"eval", "joins",
            "Joins of a multi-sequence LiDAR map against a simulated truth: right / wrong / refused per sequence, "
            "whole-recording ATE after one rigid alignment",
            {{"estimate", "kapture.trajectories", "slam/pose_graph output (trajectories.txt, joins.csv)"},
             {"reference", "kapture.dataset",
              "the simulated recording: sensors/trajectories.txt (truth), truth/sequences.txt (each sequence's "
              "time span)"}},
            {{"report", "report", "joins_eval.csv (per sequence), summary.json, report.md"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

}  // namespace locforge::eval

#endif  // LOCFORGE_PLUGINS_TRAJECTORY_EVAL_JOINS_STAGE_H_
