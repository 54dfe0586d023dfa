// The outer loop of the paper's SfM refinement (section 3.2): repeat COLMAP
// point_triangulator from the current poses and intrinsics (its filter
// threshold lowered round by round) and the continuous-time spline bundle
// adjustment with auto-calibration (ba/spline_ba.h), until the poses and the
// reprojection error stop changing. The stage gt/spline_ba (../spline_ba.cc)
// declares OuterLoopOptions as its parameters and runs OuterLoop.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_OUTER_LOOP_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_OUTER_LOOP_H_

#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "locforge/units.h"
#include "locforge/camera.h"
#include "locforge/colmap/kapture_database.h"
#include "locforge/colmap/model.h"
#include "locforge/kapture/kapture.h"
#include "locforge/params.h"
#include "locforge/plugin.h"
#include "locforge/pose.h"
#include "sfm_gt_common.h"
#include "spline_ba.h"

namespace locforge::sfm_gt {

struct OuterLoopOptions {
  int rounds = 6;  // Most rounds of triangulation + bundle adjustment.
  // COLMAP filter_max_reproj_error of round i (px); the last value repeats.
  std::vector<double> filter_max_reproj_error = {16, 8, 4, 2};
  // The bundle adjustment of every round: its defaults are the stage's.
  // num_threads is the run's thread count.
  sfm::SplineBAOptions ba;
  double pose_tolerance_m = 0.0005;       // Converged when the RMS camera-centre change of a round is below...
  double rotation_tolerance_deg = 0.005;  // ...and the RMS camera rotation change is below...
  double reproj_tolerance_px = 0.02;      // ...and the mean reprojection error changed less than this.
  double seconds_per_unit = kDefaultSecondsPerUnit;
  double sequence_gap_s = 2.0;            // Rig poses further apart start a new trajectory.
  std::string rig = "rig";                // Device id of the platform poses in trajectories.txt.
  std::string keypoints_type;             // Empty: the only one of the features.
  int min_num_matches = 15;               // COLMAP Mapper.min_num_matches.
  double timeout_s = 0;                   // Kill colmap after this long (0: never).

  // The parameters of gt/spline_ba (defined with the stage, ../spline_ba.cc).
  static void Declare(ParamSchema<OuterLoopOptions>& s);
  // The loop's own rules, then the bundle adjuster's (SplineBAOptions::CheckMessage).
  bool Check(std::string* why) const;
};

// Everything the loop refines.
struct State {
  struct CameraState {
    Camera camera;
    std::optional<Pose> T_cam_rig;  // absent when the camera is in no rig
    double time_offset_s = 0;       // clock offset (estimate_time_offsets), carried across rounds
  };
  struct ImageState {
    std::string device;
    Timestamp timestamp = 0;
    Pose T_cam_world;
  };
  std::map<std::string, CameraState> cameras;  // by sensor id
  std::map<std::string, ImageState> images;    // by image name
  std::vector<RigSequence> sequences;          // platform poses per trajectory
};

// Mean reprojection error (px) of the observations of a model under the
// state's cameras and poses (the model's own poses are ignored); points
// behind their camera are left out.
struct ReprojStats {
  double mean_px = 0;
  int64_t observations = 0;
};
ReprojStats MeanReprojection(const colmap::Reconstruction& model, const State& state,
                             const std::map<colmap::CameraId, std::string>& sensor_of);

// The spline BA problem of a model: one trajectory per platform sequence
// (times relative to t0), one sensor per camera, the model's images that lie
// in a sequence (within 0.5 s of its ends) and whose camera is in a rig, and
// the points seen by at least two of them.
struct ProblemIndex {
  std::vector<std::string> sensor_ids;   // problem sensor index -> sensor id
  std::vector<std::string> image_names;  // problem image index -> name
  int skipped_images = 0;
};
sfm::BAProblem BuildProblem(const colmap::Reconstruction& model, const State& state,
                            const std::map<colmap::CameraId, std::string>& sensor_of,
                            const OuterLoopOptions& o, Timestamp t0, ProblemIndex* index);

// Pose change of the images between two states (RMS over the images of `a`).
struct PoseChange {
  double position_m = 0, rotation_deg = 0;
};
PoseChange Compare(const State& a, const State& b);

// True once a round at the last filter threshold changed the poses and the
// mean reprojection error less than the tolerances (`last_reproj` < 0: the
// first round, never converged).
bool Converged(const OuterLoopOptions& o, bool last_threshold, const PoseChange& change,
               double last_reproj, double reproj);

// The loop over one map, its features and matches; writes the refined
// kapture, the COLMAP model and the reports into ctx.output_dir().
class OuterLoop {
 public:
  OuterLoop(RunContext& ctx, const OuterLoopOptions& o) : ctx_(ctx), o_(o), out_(ctx.output_dir()) {}
  void Run();

 private:
  struct RoundResult {
    double after_px = 0;
    PoseChange change;
  };
  void LoadInputs();
  void BuildDatabase();
  colmap::Reconstruction Triangulate(double threshold, const std::string& name);
  RoundResult RunRound(int round, double threshold);
  fs::path ImagePath() const;
  void WriteOutputs(const colmap::Reconstruction& model);
  // table4, rounds, time offsets, sequence alignments, spline_ba.json.
  void WriteReports(const colmap::Reconstruction& model, const ReprojStats& final_reproj,
                    const PoseChange& total, bool converged, int rounds_done,
                    std::chrono::steady_clock::time_point start);

  RunContext& ctx_;
  const OuterLoopOptions& o_;
  const fs::path out_;
  std::unique_ptr<kapture::Kapture> map_, features_, matches_;
  std::string type_;
  State state_;
  std::vector<std::vector<Pose>> fitted_;  // spline-evaluated rig poses of the last round
  std::vector<Pose> alignments_;          // per sequence, last round (align_trajectories)
  std::vector<double> scales_;            // per sequence, last round (scale_trajectories)
  Timestamp t0_ = 0;
  colmap::DbImages ids_;
  std::map<colmap::CameraId, std::string> sensor_of_;
  TextTable rounds_;
};

}  // namespace locforge::sfm_gt

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_OUTER_LOOP_H_
