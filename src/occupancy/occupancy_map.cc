#include "dynaorb/occupancy/occupancy_map.h"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "dynaorb/io/errors.h"

namespace dynaorb::occupancy {

namespace {

bool in_unit_interval(double p) { return p > 0.0 && p < 1.0; }

octomap::point3d to_octo(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

}  // namespace

void OccupancyOptions::validate() const {
  auto fail = [](const std::string& what) { throw InputError("occupancy map: " + what); };
  if (!(resolution > 0.0) || !std::isfinite(resolution)) fail("resolution must be positive");
  if (!in_unit_interval(prob_hit) || prob_hit <= 0.5) fail("sensor_model/hit must lie in (0.5, 1)");
  if (!in_unit_interval(prob_miss) || prob_miss >= 0.5) fail("sensor_model/miss must lie in (0, 0.5)");
  if (!in_unit_interval(clamping_min) || !in_unit_interval(clamping_max) || clamping_min >= clamping_max)
    fail("sensor_model/min and max must satisfy 0 < min < max < 1");
  if (std::isnan(max_range)) fail("sensor_model/max_range must be a number");
  if (std::isnan(min_z) || std::isnan(max_z) || min_z > max_z)
    fail("pointcloud_min_z must not exceed pointcloud_max_z");
}

OccupancyMap::OccupancyMap(const OccupancyOptions& options) : options_(options) {
  options_.validate();
  tree_ = std::make_unique<octomap::OcTree>(options_.resolution);
  tree_->setProbHit(options_.prob_hit);
  tree_->setProbMiss(options_.prob_miss);
  tree_->setClampingThresMin(options_.clamping_min);
  tree_->setClampingThresMax(options_.clamping_max);
}

OccupancyMap::~OccupancyMap() = default;

InsertStats OccupancyMap::insert(const std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& T_map_sensor) {
  InsertStats s;
  s.points = points.size();
  const Eigen::Vector3d origin_d = T_map_sensor.translation();
  const octomap::point3d origin = to_octo(origin_d);
  octomap::OcTreeKey origin_key;
  if (!origin_d.allFinite() || !tree_->coordToKeyChecked(origin, origin_key)) {
    // A sensor outside the octree's addressable cube: nothing can be raycast from it.
    s.non_finite = s.points;
    counters_.points += static_cast<long>(s.points);
    counters_.non_finite += static_cast<long>(s.non_finite);
    ++counters_.clouds;
    return s;
  }
  const double max_range = options_.max_range;
  octomap::KeySet free_cells, occupied_cells;
  octomap::KeyRay ray;
  for (const Eigen::Vector3f& p_sensor : points) {
    if (!p_sensor.allFinite()) {
      ++s.non_finite;
      continue;
    }
    const Eigen::Vector3d p = T_map_sensor * p_sensor.cast<double>();
    if (p.z() < options_.min_z || p.z() > options_.max_z) {
      ++s.outside_z;
      continue;
    }
    const double range = (p - origin_d).norm();
    if (max_range < 0.0 || range <= max_range) {
      if (tree_->computeRayKeys(origin, to_octo(p), ray)) free_cells.insert(ray.begin(), ray.end());
      octomap::OcTreeKey key;
      if (tree_->coordToKeyChecked(to_octo(p), key)) {
        occupied_cells.insert(key);
        ++s.inserted;
      }
    } else {
      ++s.beyond_range;
      const Eigen::Vector3d end = origin_d + (p - origin_d) * (max_range / range);
      if (tree_->computeRayKeys(origin, to_octo(end), ray)) free_cells.insert(ray.begin(), ray.end());
    }
  }
  // A cell one point ends in stays occupied even when another ray of this
  // cloud passes through it (octomap_server's rule).
  for (const octomap::OcTreeKey& key : occupied_cells) free_cells.erase(key);
  for (const octomap::OcTreeKey& key : free_cells) tree_->updateNode(key, false);
  for (const octomap::OcTreeKey& key : occupied_cells) tree_->updateNode(key, true);
  s.free_cells = free_cells.size();
  s.occupied_cells = occupied_cells.size();

  ++counters_.clouds;
  counters_.points += static_cast<long>(s.points);
  counters_.non_finite += static_cast<long>(s.non_finite);
  counters_.outside_z += static_cast<long>(s.outside_z);
  counters_.beyond_range += static_cast<long>(s.beyond_range);
  counters_.inserted += static_cast<long>(s.inserted);
  return s;
}

std::vector<OccupiedCell> OccupancyMap::occupied_cells() const {
  std::vector<OccupiedCell> out;
  for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
    if (!tree_->isNodeOccupied(*it)) continue;
    const octomap::point3d c = it.getCoordinate();
    out.push_back({Eigen::Vector3d(c.x(), c.y(), c.z()), it.getSize(), static_cast<int>(it.getDepth())});
  }
  return out;
}

std::optional<bool> OccupancyMap::occupied(const Eigen::Vector3d& p) const {
  const octomap::OcTreeNode* node = tree_->search(to_octo(p));
  if (!node) return std::nullopt;
  return tree_->isNodeOccupied(node);
}

std::size_t OccupancyMap::clear_bbx(const Eigen::Vector3d& min, const Eigen::Vector3d& max) {
  std::size_t changed = 0;
  const float free_log_odds = octomap::logodds(options_.clamping_min);
  for (auto it = tree_->begin_leafs_bbx(to_octo(min), to_octo(max)), end = tree_->end_leafs_bbx(); it != end;
       ++it) {
    it->setLogOdds(free_log_odds);
    ++changed;
  }
  tree_->updateInnerOccupancy();
  return changed;
}

void OccupancyMap::reset() {
  tree_->clear();
  counters_ = {};
}

void OccupancyMap::save(const std::string& path) const {
  const std::string ext = std::filesystem::path(path).extension().string();
  bool ok = false;
  if (ext == ".bt") {
    ok = tree_->writeBinaryConst(path);
  } else if (ext == ".ot") {
    ok = tree_->write(path);
  } else {
    throw InputError(path, 0, "unknown map file extension '" + ext + "' (use .bt or .ot)");
  }
  if (!ok) throw InputError(path, 0, "cannot write the octomap file");
}

GridMap2D OccupancyMap::project(double min_z, double max_z) const {
  GridMap2D g;
  g.resolution = options_.resolution;
  if (tree_->size() == 0) return g;
  double x0, y0, z0, x1, y1, z1;
  tree_->getMetricMin(x0, y0, z0);
  tree_->getMetricMax(x1, y1, z1);
  const double r = g.resolution;
  g.origin = {std::floor(x0 / r) * r, std::floor(y0 / r) * r};
  g.width = static_cast<int>(std::ceil((x1 - g.origin.x()) / r - 1e-6));
  g.height = static_cast<int>(std::ceil((y1 - g.origin.y()) / r - 1e-6));
  g.width = std::max(g.width, 1);
  g.height = std::max(g.height, 1);
  g.data.assign(static_cast<std::size_t>(g.width) * g.height, -1);
  for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
    const double z = it.getZ();
    if (z < min_z || z > max_z) continue;
    const bool occ = tree_->isNodeOccupied(*it);
    const double half = it.getSize() / 2.0;
    // A pruned leaf covers several grid cells.
    const int cx0 = std::max(0, static_cast<int>(std::floor((it.getX() - half - g.origin.x()) / r + 1e-6)));
    const int cy0 = std::max(0, static_cast<int>(std::floor((it.getY() - half - g.origin.y()) / r + 1e-6)));
    const int cx1 = std::min(g.width, static_cast<int>(std::floor((it.getX() + half - g.origin.x()) / r + 1e-6)));
    const int cy1 = std::min(g.height, static_cast<int>(std::floor((it.getY() + half - g.origin.y()) / r + 1e-6)));
    for (int y = cy0; y < std::max(cy1, cy0 + 1) && y < g.height; ++y)
      for (int x = cx0; x < std::max(cx1, cx0 + 1) && x < g.width; ++x) {
        std::int8_t& cell = g.data[static_cast<std::size_t>(y) * g.width + x];
        if (occ) cell = 100;
        else if (cell != 100) cell = 0;
      }
  }
  return g;
}

std::size_t OccupancyMap::leaf_count() const { return tree_->getNumLeafNodes(); }

}  // namespace dynaorb::occupancy
