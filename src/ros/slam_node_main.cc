// dynaorb_node: the SLAM node (see slam_node.h for its topics, services and parameters).
#include <ros/ros.h>

#include <cstdio>

#include "slam_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "dynaorb_node");
  ros::NodeHandle nh, pnh("~");
  std::unique_ptr<dynaorb::node::SlamNode> node;
  try {
    node = std::make_unique<dynaorb::node::SlamNode>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_FATAL("dynaorb_node: %s", e.what());
    return 1;
  }
  ros::spin();
  node->finish();  // ~trajectory_file
  // What degraded over the run (rosout is gone by now).
  std::fprintf(stderr, "dynaorb_node: %s\n", node->stats_json().c_str());
  return 0;
}
