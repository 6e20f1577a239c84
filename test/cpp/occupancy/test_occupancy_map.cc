#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <cmath>
#include <limits>

#include "../test_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/occupancy/occupancy_map.h"

namespace dynaorb::occupancy {
namespace {

using Vec3f = Eigen::Vector3f;

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

OccupancyOptions coarse() {
  OccupancyOptions o;
  o.resolution = 0.1;
  return o;
}

TEST(OccupancyMap, RayFreesItsPathAndMarksItsEnd) {
  OccupancyMap map(coarse());
  const InsertStats s = map.insert({Vec3f(2.0f, 0.02f, 0.03f)}, at(0.03, 0.02, 0.03));
  EXPECT_EQ(s.inserted, 1u);
  EXPECT_EQ(s.occupied_cells, 1u);
  EXPECT_GE(s.free_cells, 18u);
  EXPECT_EQ(map.occupied({2.03, 0.04, 0.06}), std::optional<bool>(true));
  EXPECT_EQ(map.occupied({1.0, 0.03, 0.04}), std::optional<bool>(false));
  EXPECT_EQ(map.occupied({3.0, 0.03, 0.04}), std::nullopt);  // behind the hit: never seen
  ASSERT_EQ(map.occupied_cells().size(), 1u);
  EXPECT_NEAR(map.occupied_cells()[0].centre.x(), 2.05, 1e-6);
  EXPECT_NEAR(map.occupied_cells()[0].size, 0.1, 1e-9);
}

TEST(OccupancyMap, PointsAreTakenIntoTheMapFrame) {
  OccupancyMap map(coarse());
  Eigen::Isometry3d T = at(1.03, 2.03, 0.53);
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  map.insert({Vec3f(1.0f, 0.0f, 0.0f)}, T);  // sensor x points along map y
  EXPECT_EQ(map.occupied({1.03, 3.03, 0.53}), std::optional<bool>(true));
  EXPECT_EQ(map.occupied({1.03, 2.53, 0.53}), std::optional<bool>(false));
}

TEST(OccupancyMap, BeyondMaxRangeClearsButMarksNothing) {
  OccupancyOptions o = coarse();
  o.max_range = 2.0;
  OccupancyMap map(o);
  const InsertStats s = map.insert({Vec3f(5.0f, 0.02f, 0.02f)}, at(0.02, 0.02, 0.02));
  EXPECT_EQ(s.beyond_range, 1u);
  EXPECT_EQ(s.inserted, 0u);
  EXPECT_TRUE(map.occupied_cells().empty());
  EXPECT_EQ(map.occupied({1.5, 0.02, 0.02}), std::optional<bool>(false));
  EXPECT_EQ(map.occupied({3.0, 0.02, 0.02}), std::nullopt);
  EXPECT_EQ(map.occupied({5.0, 0.02, 0.02}), std::nullopt);
}

TEST(OccupancyMap, ZLimitsApplyInTheMapFrame) {
  OccupancyOptions o = coarse();
  o.min_z = 0.0;
  o.max_z = 1.0;
  OccupancyMap map(o);
  // The sensor sits 0.5 m up: sensor z -1 is map z -0.5 (dropped), sensor z 0.3 is map z 0.8 (kept).
  const InsertStats s = map.insert({Vec3f(2.0f, 0.0f, -1.0f), Vec3f(2.0f, 0.0f, 0.3f), Vec3f(2.0f, 0.0f, 0.7f)},
                                   at(0.02, 0.02, 0.5));
  EXPECT_EQ(s.outside_z, 2u);
  EXPECT_EQ(s.inserted, 1u);
  EXPECT_EQ(map.counters().outside_z, 2);
}

TEST(OccupancyMap, NonFinitePointsAreCountedNotInserted) {
  OccupancyMap map(coarse());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const InsertStats s = map.insert({Vec3f(nan, 0, 1), Vec3f(0, inf, 1), Vec3f(0.02f, 0.02f, 1.0f)}, at(0, 0, 0));
  EXPECT_EQ(s.non_finite, 2u);
  EXPECT_EQ(s.inserted, 1u);
  // A sensor pose that is not finite inserts nothing.
  Eigen::Isometry3d bad = at(nan, 0, 0);
  const InsertStats b = map.insert({Vec3f(1, 0, 0)}, bad);
  EXPECT_EQ(b.inserted, 0u);
  EXPECT_EQ(b.non_finite, 1u);
  EXPECT_EQ(map.counters().clouds, 2);
}

TEST(OccupancyMap, AHitWinsOverARayOfTheSameCloud) {
  OccupancyMap map(coarse());
  // The first point's cell lies on the second point's ray.
  map.insert({Vec3f(1.03f, 0.03f, 0.03f), Vec3f(2.03f, 0.03f, 0.03f)}, at(0.03, 0.03, 0.03));
  EXPECT_EQ(map.occupied({1.03, 0.03, 0.03}), std::optional<bool>(true));
  EXPECT_EQ(map.occupied({2.03, 0.03, 0.03}), std::optional<bool>(true));
}

TEST(OccupancyMap, RepeatedMissesClearAStaleHit) {
  OccupancyMap map(coarse());
  map.insert({Vec3f(1.03f, 0.03f, 0.03f)}, at(0.03, 0.03, 0.03));
  ASSERT_EQ(map.occupied({1.03, 0.03, 0.03}), std::optional<bool>(true));
  // The object left: rays now pass through its cell to a wall behind it.
  for (int i = 0; i < 5; ++i) map.insert({Vec3f(3.03f, 0.03f, 0.03f)}, at(0.03, 0.03, 0.03));
  EXPECT_EQ(map.occupied({1.03, 0.03, 0.03}), std::optional<bool>(false));
}

TEST(OccupancyMap, ClearBbxAndReset) {
  OccupancyMap map(coarse());
  map.insert({Vec3f(1.03f, 0.03f, 0.03f), Vec3f(0.03f, 1.03f, 0.03f)}, at(0.03, 0.03, 0.03));
  ASSERT_EQ(map.occupied_cells().size(), 2u);
  EXPECT_GE(map.clear_bbx({0.9, -0.1, -0.1}, {1.2, 0.2, 0.2}), 1u);
  EXPECT_EQ(map.occupied({1.03, 0.03, 0.03}), std::optional<bool>(false));
  EXPECT_EQ(map.occupied({0.03, 1.03, 0.03}), std::optional<bool>(true));
  map.reset();
  EXPECT_EQ(map.leaf_count(), 0u);
  EXPECT_EQ(map.counters().clouds, 0);
}

TEST(OccupancyMap, SavesBinaryAndFullTrees) {
  test::ScratchDir dir;
  OccupancyMap map(coarse());
  map.insert({Vec3f(1.03f, 0.03f, 0.03f), Vec3f(0.03f, 1.03f, 0.03f)}, at(0.03, 0.03, 0.03));
  const std::string bt = (dir.path() / "map.bt").string(), ot = (dir.path() / "map.ot").string();
  map.save(bt);
  map.save(ot);
  octomap::OcTree from_bt(bt);
  EXPECT_NEAR(from_bt.getResolution(), 0.1, 1e-9);
  EXPECT_EQ(from_bt.getNumLeafNodes(), map.leaf_count());
  std::unique_ptr<octomap::AbstractOcTree> from_ot(octomap::AbstractOcTree::read(ot));
  ASSERT_TRUE(from_ot);
  auto* tree = dynamic_cast<octomap::OcTree*>(from_ot.get());
  ASSERT_NE(tree, nullptr);
  EXPECT_EQ(tree->getNumLeafNodes(), map.leaf_count());
  EXPECT_TRUE(tree->isNodeOccupied(tree->search(1.03, 0.03, 0.03)));
  EXPECT_THROW(map.save((dir.path() / "map.txt").string()), InputError);
  EXPECT_THROW(map.save((dir.path() / "no_such_dir" / "map.bt").string()), InputError);
}

TEST(OccupancyMap, ProjectsOccupiedOverFree) {
  OccupancyMap map(coarse());
  // A wall at x = 2 seen from the origin; plus a point far above the z window.
  std::vector<Vec3f> wall;
  for (int k = -5; k <= 5; ++k) wall.push_back(Vec3f(2.03f, 0.03f + 0.1f * k, 0.03f));
  wall.push_back(Vec3f(1.03f, 0.03f, 3.03f));
  map.insert(wall, at(0.03, 0.03, 0.03));
  const GridMap2D g = map.project(-0.5, 0.5);
  ASSERT_GT(g.width, 0);
  ASSERT_EQ(g.data.size(), static_cast<std::size_t>(g.width) * g.height);
  auto cell = [&](double x, double y) {
    const int cx = static_cast<int>(std::floor((x - g.origin.x()) / g.resolution));
    const int cy = static_cast<int>(std::floor((y - g.origin.y()) / g.resolution));
    return g.data[static_cast<std::size_t>(cy) * g.width + cx];
  };
  EXPECT_EQ(cell(2.03, 0.03), 100);
  EXPECT_EQ(cell(2.03, 0.43), 100);
  EXPECT_EQ(cell(1.03, 0.03), 0);  // free at z 0; the occupied cell at z 3 is outside the window
  EXPECT_EQ(cell(0.03, 0.53), -1);
  EXPECT_TRUE(OccupancyMap(coarse()).project(-1, 1).data.empty());
}

TEST(OccupancyMap, RejectsBadOptions) {
  OccupancyOptions o;
  o.resolution = 0;
  EXPECT_THROW(OccupancyMap{o}, InputError);
  o = {};
  o.prob_hit = 0.4;
  EXPECT_THROW(OccupancyMap{o}, InputError);
  o = {};
  o.clamping_min = 0.99;
  EXPECT_THROW(OccupancyMap{o}, InputError);
  o = {};
  o.min_z = 2;
  o.max_z = 1;
  EXPECT_THROW(OccupancyMap{o}, InputError);
}

// ------------------------------------------------------------------ moving object scene
// A room (floor, walls) and a person-sized box walking across the view of a
// depth camera that advances through the room. The depth image is ray-cast
// exactly; the dynamic-free cloud drops the pixels that see the mover (what
// the dynamic mask removes). The map built from filtered clouds must hold no
// occupied voxel on the mover's path, the one built from raw clouds must.

struct Box {
  Eigen::Vector3d lo, hi;
};

// Slab test: the ray parameter of the first hit, or infinity.
double hit(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12) {
      if (o[a] < b.lo[a] || o[a] > b.hi[a]) return std::numeric_limits<double>::infinity();
      continue;
    }
    double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 && t0 > 1e-6 ? t0 : std::numeric_limits<double>::infinity();
}

double distance_to_box(const Box& b, const Eigen::Vector3d& p) {
  const Eigen::Vector3d q = p.cwiseMax(b.lo).cwiseMin(b.hi);
  return (p - q).norm();
}

struct Scene {
  std::vector<Box> statics;
  Box mover0;  // at t = 0
  Eigen::Vector3d velocity;
  double duration;
  Box mover_at(double t) const { return {mover0.lo + velocity * t, mover0.hi + velocity * t}; }
  Box swept() const {
    const Box a = mover_at(0), b = mover_at(duration);
    return {a.lo.cwiseMin(b.lo), a.hi.cwiseMax(b.hi)};
  }
};

Scene make_scene() {
  Scene s;
  s.statics = {
      {{-1, -4, -0.2}, {9, 4, 0}},      // floor
      {{8, -4, 0}, {8.2, 4, 3}},        // end wall
      {{-1, -4.2, 0}, {9, -4, 3}},      // right wall
      {{-1, 4, 0}, {9, 4.2, 3}},        // left wall
      {{6.0, 2.0, 0}, {6.8, 3.0, 1.0}}  // a cabinet
  };
  s.mover0 = {{4.75, -3.0, 0.0}, {5.25, -2.5, 1.75}};
  s.velocity = {0.0, 1.2, 0.0};
  s.duration = 4.5;
  return s;
}

// Body (x forward, z up) <- optical (z forward, x right, y down).
Eigen::Matrix3d body_from_optical() {
  Eigen::Matrix3d R;
  R << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return R;
}

void fill_map(OccupancyMap& map, const Scene& scene, bool drop_mover) {
  const int frames = 20, cols = 64, rows = 40;
  const double fx = 32.0, cx = (cols - 1) / 2.0, cy = (rows - 1) / 2.0;  // ~90 deg horizontal field of view
  for (int f = 0; f < frames; ++f) {
    const double t = scene.duration * f / (frames - 1);
    Eigen::Isometry3d T_map_sensor = Eigen::Isometry3d::Identity();
    T_map_sensor.linear() = body_from_optical();
    T_map_sensor.translation() = Eigen::Vector3d(0.5 + 1.5 * t / scene.duration, 0.1, 1.2);
    const Box mover = scene.mover_at(t);
    std::vector<Vec3f> cloud;
    for (int v = 0; v < rows; ++v)
      for (int u = 0; u < cols; ++u) {
        const Eigen::Vector3d ray_c((u - cx) / fx, (v - cy) / fx, 1.0);  // z = 1: t is the depth
        const Eigen::Vector3d o = T_map_sensor.translation(), d = T_map_sensor.linear() * ray_c;
        double best = std::numeric_limits<double>::infinity();
        for (const Box& b : scene.statics) best = std::min(best, hit(b, o, d));
        const double t_mover = hit(mover, o, d);
        const bool sees_mover = t_mover < best;
        if (sees_mover && drop_mover) continue;
        best = std::min(best, t_mover);
        if (std::isfinite(best)) cloud.push_back((ray_c * best).cast<float>());
      }
    map.insert(cloud, T_map_sensor);
  }
}

// Occupied voxels inside the mover's swept volume and away from static
// surfaces (more than a voxel and a half), i.e. left by the mover alone.
// With `behind`: only those away from where the mover ends (cells it left).
int mover_voxels(const OccupancyMap& map, const Scene& scene, bool behind = false) {
  const Box path = scene.swept(), end = scene.mover_at(scene.duration);
  const double margin = 1.5 * map.options().resolution;
  int n = 0;
  for (const OccupiedCell& c : map.occupied_cells()) {
    if (distance_to_box(path, c.centre) > 0.5 * c.size) continue;
    if (behind && distance_to_box(end, c.centre) <= c.size) continue;
    double to_static = std::numeric_limits<double>::infinity();
    for (const Box& b : scene.statics) to_static = std::min(to_static, distance_to_box(b, c.centre));
    if (to_static > margin) ++n;
  }
  return n;
}

int spurious_voxels(const OccupancyMap& map, const Scene& scene) {
  const double margin = 1.5 * map.options().resolution;
  int n = 0;
  for (const OccupiedCell& c : map.occupied_cells()) {
    double to_static = std::numeric_limits<double>::infinity();
    for (const Box& b : scene.statics) to_static = std::min(to_static, distance_to_box(b, c.centre));
    if (to_static > margin) ++n;
  }
  return n;
}

TEST(OccupancyMap, DynamicFreeCloudsLeaveNoTraceOfAMover) {
  const Scene scene = make_scene();
  OccupancyOptions o;
  o.resolution = 0.2;
  o.max_range = 12.0;
  OccupancyMap filtered(o), raw(o);
  fill_map(filtered, scene, true);
  fill_map(raw, scene, false);

  // Both maps hold the static room.
  auto near = [&](const OccupancyMap& map, const Box& b) {
    int n = 0;
    for (const OccupiedCell& c : map.occupied_cells()) n += distance_to_box(b, c.centre) < c.size;
    return n;
  };
  EXPECT_GT(near(filtered, scene.statics[1]), 100);  // the end wall
  EXPECT_GT(near(filtered, scene.statics[4]), 5);    // the cabinet

  const int raw_trace = mover_voxels(raw, scene);
  // 16 here: 8 where the mover ends and 8 it left behind on its path.
  EXPECT_GE(raw_trace, 10) << "the raw clouds should leave the mover in the map";
  EXPECT_GE(mover_voxels(raw, scene, true), 4) << "and traces of it on its path";
  EXPECT_EQ(mover_voxels(filtered, scene), 0);
  // Every occupied voxel of the filtered map lies on the static geometry.
  EXPECT_EQ(spurious_voxels(filtered, scene), 0);
  EXPECT_EQ(spurious_voxels(raw, scene), raw_trace);
}

}  // namespace
}  // namespace dynaorb::occupancy
