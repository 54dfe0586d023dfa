// What the two PCL back-ends share (Eigen only, no PCL types): options and
// result statistics computed with our own KD-tree at PCL's solution, so all
// back-ends report inliers, error and information the same way.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_PCL_COMMON_H_
#define LOCFORGE_PLUGINS_REGISTRATION_PCL_COMMON_H_

#include "locforge/params.h"

namespace locforge::pclreg {

struct PclOptions {
  double voxel_size = 0;                     // Downsample both clouds first (metres); 0 = off.
  double max_correspondence_distance = 1.0;  // Pairs farther apart are rejected (metres).
  int max_iterations = 64;                   // Iterations at most.
  double transformation_epsilon = 1e-6;      // Converged when the transform changes less.
  int k_neighbors = 20;                      // Neighbours per normal / covariance.

  static void Declare(ParamSchema<PclOptions>& s) {
    s.Add("voxel_size", &PclOptions::voxel_size, "Voxel downsampling of both clouds, metres; 0 = off")
        .Range(0, 100);
    s.Add("max_correspondence_distance", &PclOptions::max_correspondence_distance,
          "Correspondences farther apart are rejected, metres")
        .Range(1e-6, 1e4);
    s.Add("max_iterations", &PclOptions::max_iterations, "Iterations at most").Range(1, 10000);
    s.Add("transformation_epsilon", &PclOptions::transformation_epsilon,
          "Converged when the transform changes less than this (PCL's squared measure)")
        .Range(0, 1);
    s.Add("k_neighbors", &PclOptions::k_neighbors, "Neighbours per normal or covariance")
        .Range(3, 200);
  }
};

}  // namespace locforge::pclreg

#endif  // LOCFORGE_PLUGINS_REGISTRATION_PCL_COMMON_H_
