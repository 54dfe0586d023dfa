#include "join_consensus.h"

#include <set>

namespace locforge::lidar {

bool JoinConsensusOptions::Check(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(max_translation > 0)) return fail("max_translation must be > 0");
  if (!(max_rotation_deg > 0)) return fail("max_rotation_deg must be > 0");
  if (min_support < 1) return fail("min_support must be >= 1");
  if (min_verified < 0) return fail("min_verified must be >= 0");
  if (!(max_rival_ratio >= 0 && max_rival_ratio <= 1)) return fail("max_rival_ratio must be in [0, 1]");
  return true;
}

bool HypothesesAgree(const JoinCandidate& x, const JoinCandidate& y, const JoinConsensusOptions& o) {
  if (RotationAngleDeg(x.T_A_B.q, y.T_A_B.q) > o.max_rotation_deg) return false;
  // Compared where they are used: at both b keyframes (a heading error moves
  // far keyframes more than the frame's origin).
  for (const Eigen::Vector3d& p : {x.p_b, y.p_b})
    if ((x.T_A_B * p - y.T_A_B * p).norm() > o.max_translation) return false;
  return true;
}

JoinConsensus FindJoinConsensus(const std::vector<JoinCandidate>& c, const JoinConsensusOptions& o) {
  const int n = static_cast<int>(c.size());
  std::vector<std::vector<char>> agree(n, std::vector<char>(n, 0));
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) agree[i][j] = agree[j][i] = HypothesesAgree(c[i], c[j], o);
  std::vector<int> support(n, 0), verified(n, 0);
  std::vector<double> overlap(n, 0);
  for (int i = 0; i < n; ++i) {
    std::set<int> bs, vs;
    for (int j = 0; j < n; ++j)
      if (agree[i][j]) {
        bs.insert(c[j].b);
        if (c[j].predicted) vs.insert(c[j].b);
        overlap[i] += c[j].overlap;
      }
    support[i] = static_cast<int>(bs.size());
    verified[i] = static_cast<int>(vs.size());
  }
  JoinConsensus r;
  r.supports = support;
  r.verifieds = verified;
  auto better = [&](int i, int k) {
    if (verified[i] != verified[k]) return verified[i] > verified[k];
    if (support[i] != support[k]) return support[i] > support[k];
    return overlap[i] > overlap[k];
  };
  for (int i = 0; i < n; ++i)
    if (r.centre < 0 || better(i, r.centre)) r.centre = i;
  if (r.centre < 0) return r;
  r.T_A_B = c[r.centre].T_A_B;
  r.support = support[r.centre];
  r.verified = verified[r.centre];
  for (int j = 0; j < n; ++j) {
    (agree[r.centre][j] ? r.inliers : r.outliers).push_back(j);
    if (!agree[r.centre][j]) r.rival_verified = std::max(r.rival_verified, verified[j]);
  }
  r.found = r.support >= o.min_support && r.verified >= o.min_verified &&
            r.rival_verified <= o.max_rival_ratio * r.verified;
  return r;
}

}  // namespace locforge::lidar
