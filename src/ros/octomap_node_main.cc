// dynaorb_octomap: occupancy mapping of dynamic-free clouds (see octomap_node.h).
#include <ros/ros.h>

#include "octomap_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "dynaorb_octomap");
  ros::NodeHandle nh, pnh("~");
  std::unique_ptr<dynaorb::node::OctomapNode> node;
  try {
    node = std::make_unique<dynaorb::node::OctomapNode>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_FATAL("dynaorb_octomap: %s", e.what());
    return 1;
  }
  ros::spin();
  return 0;
}
