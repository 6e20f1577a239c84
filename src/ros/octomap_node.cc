#include "octomap_node.h"

#include <nav_msgs/OccupancyGrid.h>
#include <octomap/OcTree.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_eigen/tf2_eigen.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <limits>
#include <map>

#include "ros_conversions.h"
#include "ros_params.h"

namespace dynaorb::node {

OctomapNode::OctomapNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  occupancy::OccupancyOptions o;
  o.resolution = param_or(pnh_, "resolution", o.resolution);
  o.prob_hit = param_or(pnh_, "sensor_model/hit", o.prob_hit);
  o.prob_miss = param_or(pnh_, "sensor_model/miss", o.prob_miss);
  o.clamping_min = param_or(pnh_, "sensor_model/min", o.clamping_min);
  o.clamping_max = param_or(pnh_, "sensor_model/max", o.clamping_max);
  o.max_range = param_or(pnh_, "sensor_model/max_range", o.max_range);
  o.min_z = param_or(pnh_, "pointcloud_min_z", -inf);
  o.max_z = param_or(pnh_, "pointcloud_max_z", inf);
  map_ = std::make_unique<occupancy::OccupancyMap>(o);  // throws InputError on bad values
  occupancy_min_z_ = param_or(pnh_, "occupancy_min_z", -inf);
  occupancy_max_z_ = param_or(pnh_, "occupancy_max_z", inf);
  frame_id_ = param_or<std::string>(pnh_, "frame_id", "map");
  projected_map_ = param_or(pnh_, "projected_map", true);
  const bool latch = param_or(pnh_, "latch", true);
  time_jump_reset_ = seconds_param_or(pnh_, "time_jump_reset", time_jump_reset_, " (0: off)");

  pub_centres_ = nh_.advertise<sensor_msgs::PointCloud2>("octomap_point_cloud_centers", 1, latch);
  pub_markers_ = nh_.advertise<visualization_msgs::MarkerArray>("occupied_cells_vis_array", 1, latch);
  if (projected_map_) pub_grid_ = nh_.advertise<nav_msgs::OccupancyGrid>("projected_map", 1, latch);
  srv_reset_ = pnh_.advertiseService("reset", &OctomapNode::on_reset, this);
  srv_clear_ = pnh_.advertiseService("clear_bbx", &OctomapNode::on_clear_bbx, this);
  srv_save_ = pnh_.advertiseService("save", &OctomapNode::on_save, this);

  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_);
  // octomap_server queues 5 clouds; a node that maps every keyframe of a bag needs more.
  const int queue = std::max(1, param_or(pnh_, "queue_size", 5));
  sub_ = std::make_unique<message_filters::Subscriber<sensor_msgs::PointCloud2>>(nh_, "cloud_in", queue);
  filter_ = std::make_unique<tf2_ros::MessageFilter<sensor_msgs::PointCloud2>>(*sub_, tf_buffer_, frame_id_, queue, nh_);
  filter_->registerCallback(&OctomapNode::on_cloud, this);
  filter_->registerFailureCallback(
      [this](const sensor_msgs::PointCloud2ConstPtr& cloud, tf2_ros::filter_failure_reasons::FilterFailureReason) {
        ++tf_failures_;
        ROS_WARN_THROTTLE(5.0, "dynaorb_octomap: cloud at %.3f dropped: no transform %s <- %s (%ld so far)",
                          cloud->header.stamp.toSec(), frame_id_.c_str(), cloud->header.frame_id.c_str(), tf_failures_);
      });
  ROS_INFO("dynaorb_octomap: resolution %.3f m in %s, hit %.2f miss %.2f clamping [%.2f, %.2f], max range %.1f m",
           o.resolution, frame_id_.c_str(), o.prob_hit, o.prob_miss, o.clamping_min, o.clamping_max, o.max_range);
}

void OctomapNode::on_cloud(const sensor_msgs::PointCloud2ConstPtr& cloud) {
  const double stamp = cloud->header.stamp.toSec();
  if (const double back = newest_.jump_back(stamp, time_jump_reset_)) {
    map_->reset();
    ++time_jumps_;
    ROS_WARN("dynaorb_octomap: time went back %.3f s (cloud %.6f after %.6f: a bag played again, a simulator "
             "reset): map reset (%ld so far; ~time_jump_reset %.3g s)",
             back, stamp, stamp + back, time_jumps_, time_jump_reset_);
  }
  Eigen::Isometry3d T_map_sensor;
  try {
    T_map_sensor = tf2::transformToEigen(
        tf_buffer_.lookupTransform(frame_id_, cloud->header.frame_id, cloud->header.stamp));
  } catch (const tf2::TransformException& e) {
    ++tf_failures_;
    ROS_WARN_THROTTLE(5.0, "dynaorb_octomap: cloud dropped: %s", e.what());
    return;
  }
  std::vector<Eigen::Vector3f> points;
  points.reserve(static_cast<std::size_t>(cloud->width) * cloud->height);
  try {
    sensor_msgs::PointCloud2ConstIterator<float> x(*cloud, "x"), y(*cloud, "y"), z(*cloud, "z");
    for (; x != x.end(); ++x, ++y, ++z) points.emplace_back(*x, *y, *z);
  } catch (const std::runtime_error& e) {  // no x / y / z field
    ROS_WARN_THROTTLE(5.0, "dynaorb_octomap: cloud dropped: %s", e.what());
    return;
  }
  const occupancy::InsertStats s = map_->insert(points, T_map_sensor);
  ROS_DEBUG("dynaorb_octomap: %zu points, %zu inserted, %zu outside z, %zu beyond range, %zu non-finite", s.points,
            s.inserted, s.outside_z, s.beyond_range, s.non_finite);
  publish(cloud->header.stamp);
}

void OctomapNode::publish(const ros::Time& stamp) {
  std::vector<occupancy::OccupiedCell> cells = map_->occupied_cells();
  std::vector<Eigen::Vector3f> centres;
  std::map<int, std::vector<const occupancy::OccupiedCell*>> by_depth;
  for (const occupancy::OccupiedCell& c : cells) {
    if (c.centre.z() < occupancy_min_z_ || c.centre.z() > occupancy_max_z_) continue;
    centres.push_back(c.centre.cast<float>());
    by_depth[c.depth].push_back(&c);
  }
  sensor_msgs::PointCloud2 cloud = to_cloud_msg(centres, {});
  cloud.header.stamp = stamp;
  cloud.header.frame_id = frame_id_;
  pub_centres_.publish(cloud);

  // One CUBE_LIST per depth of the tree (octomap_server's layout); empty ones deleted.
  visualization_msgs::MarkerArray markers;
  const int max_depth = static_cast<int>(map_->tree().getTreeDepth());
  for (int depth = 0; depth <= max_depth; ++depth) {
    visualization_msgs::Marker m;
    m.header.stamp = stamp;
    m.header.frame_id = frame_id_;
    m.ns = "map";
    m.id = depth;
    m.type = visualization_msgs::Marker::CUBE_LIST;
    m.pose.orientation.w = 1.0;
    const double size = map_->tree().getNodeSize(static_cast<unsigned>(depth));
    m.scale.x = m.scale.y = m.scale.z = size;
    m.color.b = 1.0f;
    m.color.a = 1.0f;
    auto it = by_depth.find(depth);
    if (it == by_depth.end()) {
      m.action = visualization_msgs::Marker::DELETE;
    } else {
      m.action = visualization_msgs::Marker::ADD;
      for (const occupancy::OccupiedCell* c : it->second) {
        geometry_msgs::Point p;
        p.x = c->centre.x();
        p.y = c->centre.y();
        p.z = c->centre.z();
        m.points.push_back(p);
      }
    }
    markers.markers.push_back(m);
  }
  pub_markers_.publish(markers);

  if (!projected_map_) return;
  const occupancy::GridMap2D g = map_->project(occupancy_min_z_, occupancy_max_z_);
  nav_msgs::OccupancyGrid grid;
  grid.header.stamp = stamp;
  grid.header.frame_id = frame_id_;
  grid.info.map_load_time = stamp;
  grid.info.resolution = static_cast<float>(g.resolution);
  grid.info.width = static_cast<std::uint32_t>(g.width);
  grid.info.height = static_cast<std::uint32_t>(g.height);
  grid.info.origin.position.x = g.origin.x();
  grid.info.origin.position.y = g.origin.y();
  grid.info.origin.orientation.w = 1.0;
  grid.data = g.data;
  pub_grid_.publish(grid);
}

bool OctomapNode::on_reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  map_->reset();
  publish(ros::Time::now());
  ROS_INFO("dynaorb_octomap: map reset");
  return true;
}

bool OctomapNode::on_clear_bbx(dynaorb::ClearBBX::Request& req, dynaorb::ClearBBX::Response& res) {
  res.cleared = static_cast<std::int64_t>(
      map_->clear_bbx({req.min.x, req.min.y, req.min.z}, {req.max.x, req.max.y, req.max.z}));
  publish(ros::Time::now());
  return true;
}

bool OctomapNode::on_save(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res) {
  try {
    map_->save(req.path);
    res.success = true;
    res.message = "saved " + std::to_string(map_->leaf_count()) + " leaves to " + req.path;
  } catch (const std::exception& e) {
    res.message = e.what();
  }
  return true;
}

}  // namespace dynaorb::node
