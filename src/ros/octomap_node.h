#pragma once
// dynaorb_octomap: an octomap_server-like node on liboctomap (octomap_server
// and octomap_msgs are not in Debian). An adapter over occupancy::OccupancyMap.
//
// Subscribes  cloud_in (PointCloud2 in the sensor frame): held until TF has
//             frame_id <- sensor at the cloud's stamp (tf2_ros::MessageFilter),
//             whose translation is the origin of the rays.
// Publishes   octomap_point_cloud_centers (PointCloud2, occupied cell centres),
//             occupied_cells_vis_array (MarkerArray: a CUBE_LIST per octree depth),
//             projected_map (nav_msgs/OccupancyGrid, ~projected_map true) -
//             after every cloud; latched with ~latch.
// Services    ~reset (std_srvs/Empty), ~clear_bbx (dynaorb/ClearBBX),
//             ~save (dynaorb/MapFile: .bt binary, .ot full).
// Parameters  as octomap_server: ~resolution (0.05), ~frame_id (map),
//             ~sensor_model/{hit 0.7, miss 0.4, min 0.12, max 0.97, max_range -1},
//             ~pointcloud_min_z / ~pointcloud_max_z (unbounded), ~occupancy_min_z /
//             ~occupancy_max_z (cells published and projected; unbounded), ~latch
//             (true), ~projected_map (true), ~queue_size (clouds waiting for TF or
//             insertion, 5); ours: ~time_jump_reset (1 s: a cloud stamped more than
//             this before the newest one, time went back - a bag played again, a
//             simulator reset, as dynaorb_node drops its map then - resets the map;
//             0: off).
#include <message_filters/subscriber.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/message_filter.h>
#include <tf2_ros/transform_listener.h>

#include <memory>

#include "dynaorb/ClearBBX.h"
#include "dynaorb/MapFile.h"
#include "dynaorb/occupancy/occupancy_map.h"
#include "time_jump.h"

namespace dynaorb::node {

class OctomapNode {
 public:
  OctomapNode(ros::NodeHandle nh, ros::NodeHandle pnh);

 private:
  void on_cloud(const sensor_msgs::PointCloud2ConstPtr& cloud);
  void publish(const ros::Time& stamp);
  bool on_reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool on_clear_bbx(dynaorb::ClearBBX::Request& req, dynaorb::ClearBBX::Response& res);
  bool on_save(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res);

  ros::NodeHandle nh_, pnh_;
  std::string frame_id_;
  double occupancy_min_z_, occupancy_max_z_;
  bool projected_map_ = true;
  std::unique_ptr<occupancy::OccupancyMap> map_;

  tf2_ros::Buffer tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<message_filters::Subscriber<sensor_msgs::PointCloud2>> sub_;
  std::unique_ptr<tf2_ros::MessageFilter<sensor_msgs::PointCloud2>> filter_;
  ros::Publisher pub_centres_, pub_markers_, pub_grid_;
  ros::ServiceServer srv_reset_, srv_clear_, srv_save_;
  long tf_failures_ = 0;
  double time_jump_reset_ = 1.0;
  NewestStamp newest_;  // of the clouds
  long time_jumps_ = 0;
};

}  // namespace dynaorb::node
