#pragma once
// Small conversions between ROS messages and what the core and the support
// code take: images through cv_bridge (always copied out of the message),
// clouds into PointCloud2.
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace dynaorb::node {

// An image for the System: 8-bit grey stays grey; anything with colour is
// converted to rgb8 (rgb_order) or bgr8; 16-bit grey is scaled to 8 bits.
// Empty Mat and `error` set when cv_bridge cannot read it.
cv::Mat image_for_tracking(const sensor_msgs::ImageConstPtr& msg, bool rgb_order, std::string& error);

// Depth in metres (32FC1): 16UC1 / mono16 divided by depth_map_factor
// (the YAML's DepthMapFactor: 1000 for millimetres, 5000 for TUM's PNGs),
// 32FC1 taken as metres (REP-118). Empty Mat and `error` otherwise.
cv::Mat depth_in_metres(const sensor_msgs::ImageConstPtr& msg, double depth_map_factor, std::string& error);

// The Image a sensor_msgs/CompressedImage was made from (image_transport's
// compressed / compressedDepth formats: support/compressed_image.h), with its
// header; nullptr and `error` naming the format when it does not decode.
sensor_msgs::ImagePtr decompress(const sensor_msgs::CompressedImageConstPtr& msg, std::string& error);

// Label image (mono8 / 8UC1 / mono16 / 16UC1); empty Mat and `error` otherwise.
cv::Mat label_image(const sensor_msgs::ImageConstPtr& msg, std::string& error);

// x y z (float32) and, when rgb is not empty, rgb packed into a float32 as PCL does.
sensor_msgs::PointCloud2 to_cloud_msg(const std::vector<Eigen::Vector3f>& xyz,
                                      const std::vector<std::array<std::uint8_t, 3>>& rgb);

}  // namespace dynaorb::node
