#include "ros_conversions.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <cstring>
#include <stdexcept>

#include "support/compressed_image.h"

namespace dynaorb::node {

namespace enc = sensor_msgs::image_encodings;

cv::Mat image_for_tracking(const sensor_msgs::ImageConstPtr& msg, bool rgb_order, std::string& error) {
  try {
    const std::string& e = msg->encoding;
    // Copies: frames may wait for their labels after the message is gone.
    if (e == enc::MONO8 || e == enc::TYPE_8UC1) return cv_bridge::toCvShare(msg)->image.clone();
    if (e == enc::MONO16 || e == enc::TYPE_16UC1) {
      cv::Mat grey;
      cv_bridge::toCvShare(msg)->image.convertTo(grey, CV_8U, 1.0 / 256.0);
      return grey;
    }
    return cv_bridge::toCvCopy(msg, rgb_order ? enc::RGB8 : enc::BGR8)->image;
  } catch (const cv_bridge::Exception& ex) {
    error = std::string("cannot read a '") + msg->encoding + "' image: " + ex.what();
    return {};
  }
}

sensor_msgs::ImagePtr decompress(const sensor_msgs::CompressedImageConstPtr& msg, std::string& error) {
  try {
    DecodedImage d = decode_compressed(msg->format, msg->data);
    return cv_bridge::CvImage(msg->header, d.encoding, d.image).toImageMsg();
  } catch (const std::invalid_argument& e) {
    error = e.what();
  } catch (const cv::Exception& e) {
    error = "compressed image ('" + msg->format + "'): " + e.what();
  }
  return nullptr;
}

cv::Mat depth_in_metres(const sensor_msgs::ImageConstPtr& msg, double depth_map_factor, std::string& error) {
  try {
    const std::string& e = msg->encoding;
    if (e == enc::TYPE_32FC1) return cv_bridge::toCvShare(msg)->image.clone();
    if (e == enc::TYPE_16UC1 || e == enc::MONO16) {
      cv::Mat m;
      cv_bridge::toCvShare(msg)->image.convertTo(m, CV_32F, 1.0 / depth_map_factor);
      return m;
    }
    error = "depth encoding '" + e + "' is neither 16UC1 nor 32FC1";
  } catch (const cv_bridge::Exception& ex) {
    error = std::string("cannot read the depth image: ") + ex.what();
  }
  return {};
}

cv::Mat label_image(const sensor_msgs::ImageConstPtr& msg, std::string& error) {
  const std::string& e = msg->encoding;
  if (e != enc::MONO8 && e != enc::TYPE_8UC1 && e != enc::MONO16 && e != enc::TYPE_16UC1) {
    error = "labels must be mono8 / mono16, not '" + e + "'";
    return {};
  }
  try {
    return cv_bridge::toCvShare(msg)->image.clone();
  } catch (const cv_bridge::Exception& ex) {
    error = std::string("cannot read the labels: ") + ex.what();
    return {};
  }
}

sensor_msgs::PointCloud2 to_cloud_msg(const std::vector<Eigen::Vector3f>& xyz,
                                      const std::vector<std::array<std::uint8_t, 3>>& rgb) {
  sensor_msgs::PointCloud2 msg;
  sensor_msgs::PointCloud2Modifier modifier(msg);
  const bool colour = !rgb.empty() && rgb.size() == xyz.size();
  if (colour) modifier.setPointCloud2FieldsByString(2, "xyz", "rgb");
  else modifier.setPointCloud2FieldsByString(1, "xyz");
  modifier.resize(xyz.size());
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(xyz.size());
  msg.is_dense = true;
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  for (std::size_t i = 0; i < xyz.size(); ++i, ++x, ++y, ++z) {
    *x = xyz[i].x();
    *y = xyz[i].y();
    *z = xyz[i].z();
  }
  if (colour) {
    sensor_msgs::PointCloud2Iterator<std::uint8_t> r(msg, "r"), g(msg, "g"), b(msg, "b");
    for (std::size_t i = 0; i < rgb.size(); ++i, ++r, ++g, ++b) {
      *r = rgb[i][0];
      *g = rgb[i][1];
      *b = rgb[i][2];
    }
  }
  return msg;
}

}  // namespace dynaorb::node
