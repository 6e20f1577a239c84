#pragma once
// A probabilistic 3D occupancy map on OctoMap (Hornung et al., Autonomous
// Robots 2013), filled the way octomap_server fills it: every cloud is taken
// into the map frame, cut to [min_z, max_z], and inserted by casting a ray
// from the sensor origin to each point (cells on the ray updated as free, the
// end cell as occupied; a cell hit by one point and crossed by another ray of
// the same cloud counts as occupied). Points beyond max_range clear their ray
// up to max_range and mark nothing. ROS-free: the dynaorb_octomap node is an
// adapter over this class.
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace octomap {
class OcTree;
}

namespace dynaorb::occupancy {

// Defaults are octomap_server's (parameter names in the comments).
struct OccupancyOptions {
  double resolution = 0.05;    // resolution
  double prob_hit = 0.7;       // sensor_model/hit
  double prob_miss = 0.4;      // sensor_model/miss
  double clamping_min = 0.12;  // sensor_model/min
  double clamping_max = 0.97;  // sensor_model/max
  double max_range = -1.0;     // sensor_model/max_range [m]; < 0: unlimited
  // pointcloud_min_z / pointcloud_max_z: points outside, in the map frame, are dropped.
  double min_z = -std::numeric_limits<double>::infinity();
  double max_z = std::numeric_limits<double>::infinity();

  // Throws InputError naming the first value out of range.
  void validate() const;
};

// What one insert() did with its points.
struct InsertStats {
  std::size_t points = 0;       // points given
  std::size_t non_finite = 0;   // NaN / infinite coordinates: dropped
  std::size_t outside_z = 0;    // outside [min_z, max_z]: dropped
  std::size_t beyond_range = 0; // farther than max_range: ray cleared up to max_range only
  std::size_t inserted = 0;     // points that marked their end cell occupied
  std::size_t occupied_cells = 0, free_cells = 0;  // distinct cells updated
};

struct OccupiedCell {
  Eigen::Vector3d centre;
  double size = 0;  // edge length [m]: the resolution, or larger for pruned inner nodes
  int depth = 0;    // octree depth (16 = finest)
};

// A 2D projection (octomap_server's projected_map): cells of the map
// resolution over the tree's x-y extent, -1 unknown, 0 free, 100 occupied.
struct GridMap2D {
  double resolution = 0;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // corner of cell (0, 0)
  int width = 0, height = 0;
  std::vector<std::int8_t> data;                     // row-major, row = y
};

struct OccupancyCounters {
  long clouds = 0;
  long points = 0, non_finite = 0, outside_z = 0, beyond_range = 0, inserted = 0;
};

class OccupancyMap {
 public:
  explicit OccupancyMap(const OccupancyOptions& options = {});
  ~OccupancyMap();
  OccupancyMap(const OccupancyMap&) = delete;
  OccupancyMap& operator=(const OccupancyMap&) = delete;

  // points: in the sensor frame; T_map_sensor: the sensor's pose at the
  // cloud's stamp (its translation is the origin of the rays).
  InsertStats insert(const std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& T_map_sensor);

  // Leaves above the occupancy threshold (0.5): the cells octomap_server publishes.
  std::vector<OccupiedCell> occupied_cells() const;
  // true occupied, false free, nullopt never observed.
  std::optional<bool> occupied(const Eigen::Vector3d& p) const;
  // Every known leaf inside the box set to the free clamping value (octomap_server's
  // ~clear_bbx); returns the leaves changed.
  std::size_t clear_bbx(const Eigen::Vector3d& min, const Eigen::Vector3d& max);
  void reset();
  // .bt: the binary (maximum-likelihood) tree; .ot: the full tree with
  // probabilities. Throws InputError for another extension or an unwritable file.
  void save(const std::string& path) const;
  // Leaves with centres in [min_z, max_z] projected onto the x-y plane;
  // occupied wins over free. An empty map gives a 0x0 grid.
  GridMap2D project(double min_z, double max_z) const;

  std::size_t leaf_count() const;
  const OccupancyOptions& options() const { return options_; }
  const OccupancyCounters& counters() const { return counters_; }
  const octomap::OcTree& tree() const { return *tree_; }

 private:
  OccupancyOptions options_;
  OccupancyCounters counters_;
  std::unique_ptr<octomap::OcTree> tree_;
};

}  // namespace dynaorb::occupancy
