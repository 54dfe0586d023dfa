// The simulator's outputs, byte for byte. Three short recordings (people,
// cameras, masks and both LiDARs on; a tiny, a small and a large floor) are
// hashed file by file (SHA-256) against testdata/recording_sha256.txt: any
// change of any output byte fails, so speed work on the ray casting must keep
// every image, mask, point cloud and text file identical. When an output change
// is intended, regenerate the sums (the failure message says how) and say so in
// the README. The fast ray casting (PeopleGrid, SahBvh, ScreenQuads) is also
// checked against the reference World::Cast in-process, hit by hit, scan by
// scan and image by image, which holds on any machine.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>

#include "dataset.h"
#include "lidar.h"
#include "locforge/sha256.h"
#include "render.h"
#include "testing.h"

namespace locforge::sim {
namespace {


std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// "<recording>/<path inside it>" -> SHA-256 of every file of the recording.
void HashTree(const std::string& name, const fs::path& root, std::map<std::string, std::string>* sums) {
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file())
      (*sums)[name + "/" + fs::relative(e.path(), root).generic_string()] = Sha256Hex(Slurp(e.path()));
}

// The recordings whose bytes are pinned: crowded enough that many rays and
// pixels end on people, short enough for a unit test.
std::map<std::string, SimOptions> PinnedRecordings() {
  std::map<std::string, SimOptions> r;
  SimOptions tiny = PresetOptions("tiny");
  tiny.seed = 4;
  tiny.crowdedness = 8;
  tiny.mapping_duration_s = 3;
  tiny.query_duration_s = 2;
  r["tiny"] = tiny;
  SimOptions small = PresetOptions("small");
  small.seed = 1;
  small.crowdedness = 5;
  small.mapping_duration_s = 1;
  small.query_duration_s = 1;
  r["small"] = small;
  // The large floor and crowd (306 people) with the large preset's 0.2 deg
  // LiDAR; small textures and images keep it fast.
  SimOptions large = PresetOptions("large");
  large.mapping_sequences = 1;
  large.validation_sequences = large.test_sequences = 0;
  large.mapping_duration_s = 1;
  large.texture_size = 64;
  large.rig.image_scale = 1.0 / 16;
  r["large"] = large;
  return r;
}

TEST(Recordings, EveryOutputByteMatchesThePinnedSums) {
  const fs::path fixture = LOCFORGE_SIM_TESTDATA "/recording_sha256.txt";
  std::map<std::string, std::string> sums;
  const fs::path dir = locforge::testing::MakeTempDir("sim_identity");
  for (const auto& [name, options] : PinnedRecordings()) {
    GenerateDataset(options, dir / name, 2);
    HashTree(name, dir / name, &sums);
  }
  std::ostringstream actual;  // sha256sum's format: `sha256sum -c` checks it inside `dir`
  for (const auto& [path, sum] : sums) actual << sum << "  " << path << "\n";
  if (const char* out = std::getenv("LOCFORGE_SIM_WRITE_SUMS")) {
    std::ofstream(out, std::ios::binary) << actual.str();
    std::printf("wrote %zu sums to %s\n", sums.size(), out);
  }

  std::map<std::string, std::string> expected;
  std::ifstream in(fixture);
  ASSERT_TRUE(in.good()) << "cannot read " << fixture;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    ASSERT_GT(line.size(), 66u) << fixture << ":" << n << ": expected '<sha256>  <path>'";
    expected[line.substr(66)] = line.substr(0, 64);
  }
  int differing = 0, missing = 0, extra = 0;
  for (const auto& [path, sum] : expected) {
    const auto it = sums.find(path);
    if (it == sums.end()) {
      if (++missing <= 5) ADD_FAILURE() << "not written: " << path;
    } else if (it->second != sum) {
      if (++differing <= 5) ADD_FAILURE() << "bytes differ: " << path;
    }
  }
  for (const auto& [path, sum] : sums)
    if (!expected.count(path) && ++extra <= 5) ADD_FAILURE() << "not in the fixture: " << path;
  std::printf("%zu files compared: %d differ, %d missing, %d extra\n", expected.size(), differing, missing, extra);
  EXPECT_GT(expected.size(), 500u);
  if (differing + missing + extra > 0) {
    ADD_FAILURE() << "outputs left in " << dir << "; if the change is intended, rerun with "
                  << "LOCFORGE_SIM_WRITE_SUMS=" << fixture.string() << " --gtest_filter=Recordings.*";
  } else {
    fs::remove_all(dir);
  }
}

// ---- The fast paths against the reference, in-process.

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

bool SameHit(const Hit& a, const Hit& b) {
  for (int i = 0; i < 3; ++i)
    if (!SameBits(a.point[i], b.point[i]) || !SameBits(a.normal[i], b.normal[i])) return false;
  return SameBits(a.t, b.t) && a.quad == b.quad && a.person == b.person && SameBits(a.tex_uv.x(), b.tex_uv.x()) &&
         SameBits(a.tex_uv.y(), b.tex_uv.y()) && SameBits(a.period_m, b.period_m);
}

// The large preset's floor and crowd (306 people), small textures.
struct LargeWorld {
  LargeWorld() : spec(GenerateFloor(PresetOptions("large").floor, 0)), scene(BuildScene(spec)),
                 crowd(MakeCrowd(spec, 3.0, 1)), textures(64), world(scene, crowd, &textures, 0) {}
  SceneSpec spec;
  Scene scene;
  Crowd crowd;
  TextureLibrary textures;
  World world;
};

TEST(FastPaths, PeopleGridListsEveryCylinderARayHits) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> ux(0, 30), uy(0, 20), ur(0.05, 1.5), un(-1, 1), u01(0, 1);
  std::vector<Cylinder> cylinders;
  std::vector<PeopleGrid::Bound> bounds;
  for (int i = 0; i < 400; ++i) {
    Cylinder c;
    c.center = {ux(rng), uy(rng)};
    if (i % 50 == 1) c.center = cylinders.back().center;  // people standing on the same spot
    c.radius = 0.1 + 0.3 * u01(rng);
    c.z0 = 2 * u01(rng);
    c.z1 = c.z0 + ur(rng);
    cylinders.push_back(c);
    bounds.push_back({c.center, c.radius, c.z0, c.z1});
  }
  const PeopleGrid grid(bounds, 1.0);
  std::vector<int> candidates;
  size_t hits = 0, listed = 0;
  for (int r = 0; r < 20000; ++r) {
    const Eigen::Vector3d o(ux(rng) * 1.4 - 6, uy(rng) * 1.4 - 4, 4 * u01(rng) - 0.5);
    Eigen::Vector3d d(un(rng), un(rng), 0.3 * un(rng));
    if (r % 7 == 0) d[r % 3] = 0;                       // axis-parallel components
    if (r % 11 == 0) d = Eigen::Vector3d(0, 0, un(rng));  // vertical rays
    if (d.norm() < 1e-3) continue;
    d.normalize();
    const double t0 = r % 5 == 0 ? 0.5 * u01(rng) : 1e-6;
    const double t1 = r % 3 == 0 ? std::numeric_limits<double>::infinity() : 40 * u01(rng);
    grid.Candidates(o, d, t0, t1, &candidates);
    ASSERT_TRUE(std::is_sorted(candidates.begin(), candidates.end()));
    ASSERT_TRUE(std::adjacent_find(candidates.begin(), candidates.end()) == candidates.end());
    listed += candidates.size();
    for (int i = 0; i < static_cast<int>(cylinders.size()); ++i) {
      Hit hit;
      hit.t = t1;
      if (!IntersectCylinder(cylinders[i], o, d, t0, &hit)) continue;
      ++hits;
      ASSERT_TRUE(std::binary_search(candidates.begin(), candidates.end(), i))
          << "ray " << r << " hits cylinder " << i << " at t " << hit.t << " but the grid does not list it";
    }
  }
  EXPECT_GT(hits, 2000u);
  // And it culls: a ray gets a few percent of the crowd.
  EXPECT_LT(double(listed) / 20000, 0.05 * cylinders.size());
}

TEST(FastPaths, CastNearEqualsCastBitForBit) {
  const LargeWorld w;
  const std::vector<Cylinder> people = w.crowd.At(12.5);
  std::vector<PeopleGrid::Bound> bounds;
  for (int i = 0; i < static_cast<int>(w.crowd.people().size()); ++i)
    bounds.push_back({people[2 * i].center, people[2 * i].radius, people[2 * i].z0, people[2 * i + 1].z1});
  const PeopleGrid grid(bounds);
  const auto cylinders_of = [&](int k) { return std::make_pair(&people[2 * k], &people[2 * k] + 2); };
  std::vector<int> scratch;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u01(0, 1), un(-1, 1);
  const auto& quads = w.world.quads();
  int on_people = 0, on_quads = 0;
  for (int r = 0; r < 30000; ++r) {
    // From the corridors (where people walk), at sensor heights.
    const Eigen::Vector2d node = w.spec.walk.nodes[rng() % w.spec.walk.nodes.size()];
    const Eigen::Vector3d o(node.x() + 3 * un(rng), node.y() + 3 * un(rng), 0.2 + 2.5 * u01(rng));
    Eigen::Vector3d d;
    if (r % 4 == 0) {  // aimed at a quad corner or edge: exact ties between neighbours
      const Quad& q = quads[rng() % quads.size()];
      const double a = (r % 8 == 0) ? 0.0 : u01(rng);
      d = q.origin + a * q.u_edge - o;
    } else if (r % 13 == 0) {  // along an axis
      d = Eigen::Vector3d::Zero();
      d[r % 3] = r % 2 ? 1 : -1;
    } else {
      d = Eigen::Vector3d(un(rng), un(rng), 0.4 * un(rng));
    }
    if (d.norm() < 1e-9) continue;
    d.normalize();
    Hit reference, fast;
    w.world.Cast(o, d, people, &reference);
    w.world.CastNear(o, d, grid, cylinders_of, &scratch, &fast);
    ASSERT_TRUE(SameHit(reference, fast)) << "ray " << r << ": quad " << reference.quad << " vs " << fast.quad
                                          << ", person " << reference.person << " vs " << fast.person;
    on_people += reference.person >= 0;
    on_quads += reference.quad >= 0;
  }
  EXPECT_GT(on_people, 500);
  EXPECT_GT(on_quads, 20000);
}

// Every wall panel twice, in the same place (and neighbours sharing edges):
// every hit is a tie, which only QuadBvh's test order decides, and the two
// trees order the twins differently. The fast paths must hand those rays over.
TEST(FastPaths, TiesGoToTheReferenceOrder) {
  Scene scene;
  for (int copy = 0; copy < 2; ++copy)
    for (int k = 0; k < 24; ++k) {
      Quad wall;
      wall.origin = {5, -12.0 + k, 0};
      wall.u_edge = {0, 1, 0};
      wall.v_edge = {0, 0, 3};
      wall.normal = {1, 0, 0};
      wall.material = static_cast<int>(scene.quads.size());
      scene.quads.push_back(wall);
      Material m;
      m.texture = "plain:" + std::to_string(scene.quads.size());
      scene.materials.push_back(m);
    }
  Crowd crowd;
  TextureLibrary textures(16);
  const World world(scene, crowd, &textures, 0);
  const PeopleGrid grid({});
  const auto none = [](int) { return std::pair<const Cylinder*, const Cylinder*>(nullptr, nullptr); };
  std::vector<int> scratch;
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> un(-1, 1);
  int hits = 0, second_copy = 0;
  for (int r = 0; r < 4000; ++r) {
    const Eigen::Vector3d o(0, 10 * un(rng), 1.5 + un(rng));
    const Eigen::Vector3d d = Eigen::Vector3d(1, 0.3 * un(rng), 0.2 * un(rng)).normalized();
    Hit reference, fast;
    world.Cast(o, d, {}, &reference);
    world.CastNear(o, d, grid, none, &scratch, &fast);
    ASSERT_TRUE(SameHit(reference, fast)) << "ray " << r << ": quad " << reference.quad << " vs " << fast.quad;
    hits += reference.quad >= 0;
    second_copy += reference.quad >= 24;
  }
  EXPECT_GT(hits, 3000);
  EXPECT_GT(second_copy, 0);  // QuadBvh does not always test the lower index first
}

TEST(FastPaths, ScansAndImagesEqualTheReference) {
  const LargeWorld w;
  SimOptions o = PresetOptions("large");
  o.rig.image_scale = 1.0 / 8;
  const Rig rig = MakeRig(o.rig, 0);
  std::vector<Eigen::Vector2d> waypoints;
  std::mt19937_64 rng(1);
  for (int n : PlanRoute(w.spec.walk, w.spec.start_node, 40, rng)) waypoints.push_back(w.spec.walk.nodes[n]);
  const Trajectory traj = Drive(waypoints, {}, 0, o.limits, 20, 0.1);
  for (const double start : {0.0, 7.3}) {
    for (const LidarOptions& lidar : rig.lidars) {
      const LidarScan reference = SimulateScan(w.world, traj, lidar, start, 9, true);
      const LidarScan fast = SimulateScan(w.world, traj, lidar, start, 9, false);
      ASSERT_EQ(reference.points.size(), fast.points.size()) << lidar.id << " at " << start;
      for (size_t i = 0; i < fast.points.size(); ++i) {
        const LidarPoint &a = reference.points[i], &b = fast.points[i];
        ASSERT_TRUE(a.xyz == b.xyz && a.intensity == b.intensity && a.ring == b.ring && SameBits(a.time, b.time))
            << lidar.id << " at " << start << ", point " << i;
      }
    }
    // Camera 0 at time 0 looks along an axis (the platform starts at yaw 0).
    for (size_t c : {size_t(0), size_t(3), size_t(7)}) {
      const CameraOptions& cam = rig.cameras[c];
      RenderOptions ro;
      ro.noise_seed = 3;
      RenderedImage reference, fast;
      const Pose T = traj.PoseAt(start) * cam.T_platform_camera;
      ro.reference_raycast = true;
      Render(w.world, w.crowd.At(start), cam.intrinsics, T, ro, &reference);
      ro.reference_raycast = false;
      Render(w.world, w.crowd.At(start), cam.intrinsics, T, ro, &fast);
      EXPECT_EQ(reference.rgb, fast.rgb) << cam.id << " at " << start;
      EXPECT_EQ(reference.person_mask, fast.person_mask) << cam.id << " at " << start;
    }
  }
}

// People racing past the sensors within a few metres (15 m/s: 1.5 m during a
// LiDAR scan, more than a grid cell), so the grid must bound where they are
// over the whole scan, not where they stand at its start; and the cameras
// among them.
TEST(FastPaths, SensorsAmongFastWalkersEqualTheReference) {
  const SceneSpec spec = GenerateFloor(PresetOptions("small").floor, 0);
  const Scene scene = BuildScene(spec);
  const Eigen::Vector2d centre = spec.walk.nodes[spec.start_node];
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> un(-1, 1);
  std::vector<Person> walkers;
  for (int i = 0; i < 60; ++i) {
    Person p;
    const Eigen::Vector2d a = centre + 4 * Eigen::Vector2d(un(rng), un(rng));
    const Eigen::Vector2d b = centre + 4 * Eigen::Vector2d(un(rng), un(rng));
    if ((a - centre).norm() < 0.8 || (b - centre).norm() < 0.8) continue;  // not through the platform
    p.path = {a, b};
    p.speed = 15;
    p.phase_m = 10 * (un(rng) + 1);
    p.texture = "clothes:" + std::to_string(i % 24);
    walkers.push_back(p);
  }
  const Crowd crowd(walkers);
  TextureLibrary textures(64);
  const World world(scene, crowd, &textures, 0);
  SimOptions o = PresetOptions("large");
  const Rig rig = MakeRig(o.rig, 0);
  const Trajectory still = Drive({centre, centre + Eigen::Vector2d(0.5, 0)}, {}, 0.3, o.limits, 5, 0.1);
  size_t points = 0;
  for (const double start : {0.0, 0.5, 1.0, 1.5, 2.0}) {
    const LidarOptions& lidar = rig.lidars[0];
    const LidarScan reference = SimulateScan(world, still, lidar, start, 4, true);
    const LidarScan fast = SimulateScan(world, still, lidar, start, 4, false);
    ASSERT_EQ(reference.points.size(), fast.points.size()) << "scan at " << start;
    for (size_t i = 0; i < fast.points.size(); ++i) {
      const LidarPoint &a = reference.points[i], &b = fast.points[i];
      ASSERT_TRUE(a.xyz == b.xyz && a.intensity == b.intensity && a.ring == b.ring && SameBits(a.time, b.time))
          << "scan at " << start << ", point " << i;
    }
    points += fast.points.size();
  }
  EXPECT_GT(points, 100000u);
  // The cameras among them: people fill much of each image, some reach
  // behind the image plane.
  SimOptions so = PresetOptions("small");
  so.rig.image_scale = 1.0 / 8;
  const Rig small_rig = MakeRig(so.rig, 0);
  double person_pixels = 0;
  for (const double time : {0.0, 1.9})
    for (const size_t c : {0, 2, 4, 7}) {
      const CameraOptions& cam = small_rig.cameras[c];
      RenderOptions ro;
      RenderedImage reference, fast;
      const Pose T = still.PoseAt(time) * cam.T_platform_camera;
      ro.reference_raycast = true;
      Render(world, crowd.At(time), cam.intrinsics, T, ro, &reference);
      ro.reference_raycast = false;
      Render(world, crowd.At(time), cam.intrinsics, T, ro, &fast);
      ASSERT_EQ(reference.rgb, fast.rgb) << cam.id << " at " << time;
      ASSERT_EQ(reference.person_mask, fast.person_mask) << cam.id << " at " << time;
      person_pixels += fast.PersonFraction() / 8;
    }
  EXPECT_GT(person_pixels, 0.1);
}

}  // namespace
}  // namespace locforge::sim
