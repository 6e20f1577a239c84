#include "node_config.h"

#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/dynamic/label_propagation.h"

#include <ros/console.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <utility>

#include "dynaorb/core/thread_priority.h"
#include "dynaorb/io/errors.h"
#include "option_params.h"
#include "ros_params.h"

namespace dynaorb::node {

namespace {

// python/dynaorb/vocab/default.py: FILE_NAME (test/python/test_ros_sources.py keeps them equal).
constexpr const char* kDefaultVocabularyFile = "dynaorb_default_v1_k10_L6.bin";

// PASCAL VOC's movable classes (python/dynaorb/segmentation/labels.py, DynaSLAM's and STDyn-SLAM's set).
const std::vector<int> kPascalVocMovable = {1, 2, 3, 4, 6, 7, 8, 10, 12, 13, 14, 15, 17, 19};

void override_optional(const ros::NodeHandle& pnh, const std::string& key, std::optional<double>& value) {
  double v;
  if (read_param(pnh, key, v)) value = v;
}

// The YAML's keys as parameters: "Camera.fx" -> ~Camera/fx.
void override_settings(const ros::NodeHandle& pnh, Settings& s) {
  CameraSettings& c = s.camera;
  read_param(pnh, "Camera/fx", c.fx);
  read_param(pnh, "Camera/fy", c.fy);
  read_param(pnh, "Camera/cx", c.cx);
  read_param(pnh, "Camera/cy", c.cy);
  const char* dist_keys[] = {"Camera/k1", "Camera/k2", "Camera/p1", "Camera/p2", "Camera/k3"};
  for (int i = 0; i < 5; ++i) {
    double v;
    if (!read_param(pnh, dist_keys[i], v)) continue;
    if (c.dist.cols <= i) {
      cv::Mat grown = cv::Mat::zeros(1, i + 1, CV_64F);
      c.dist.copyTo(grown.colRange(0, c.dist.cols));
      c.dist = grown;
    }
    c.dist.at<double>(i) = v;
  }
  read_param(pnh, "Camera/width", c.width);
  read_param(pnh, "Camera/height", c.height);
  read_param(pnh, "Camera/fps", c.fps);
  int rgb;
  if (read_param(pnh, "Camera/RGB", rgb)) c.rgb = rgb != 0;
  override_optional(pnh, "Camera/bf", c.bf);
  override_optional(pnh, "ThDepth", c.th_depth);
  override_optional(pnh, "DepthMapFactor", c.depth_map_factor);
  ExtractorSettings& e = s.extractor;
  read_param(pnh, "ORBextractor/nFeatures", e.n_features);
  read_param(pnh, "ORBextractor/scaleFactor", e.scale_factor);
  read_param(pnh, "ORBextractor/nLevels", e.n_levels);
  read_param(pnh, "ORBextractor/iniThFAST", e.ini_th_fast);
  read_param(pnh, "ORBextractor/minThFAST", e.min_th_fast);
}

// Three finite numbers (a translation or roll-pitch-yaw), or `fallback` when
// not set; InputError naming the parameter otherwise (a NaN would reach TF).
std::vector<double> triple(const ros::NodeHandle& pnh, const std::string& name, const std::vector<double>& fallback) {
  const std::vector<double> v = param_or(pnh, name, fallback);
  if (v.size() != 3 || !std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); }))
    throw InputError("~" + name + " must hold 3 finite numbers");
  return v;
}

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::string(v) : fallback;
}

}  // namespace

std::string default_vocabulary_path() {
  std::string dir = env_or("DYNAORB_VOCAB_CACHE", "");
  if (dir.empty()) {
    const std::string base = env_or("XDG_CACHE_HOME", env_or("HOME", ".") + "/.cache");
    dir = base + "/dynaorb/vocab";
  }
  return dir + "/" + kDefaultVocabularyFile;
}

NodeConfig read_config(const ros::NodeHandle& pnh) {
  NodeConfig cfg;
  NodeOptions& n = cfg.node;
  n.sensor = parse_sensor(param_or<std::string>(pnh, "sensor", "rgbd"));

  const std::string settings_path = param_or<std::string>(pnh, "settings", "");
  if (!settings_path.empty()) cfg.settings = Settings::load(settings_path);
  override_settings(pnh, cfg.settings);
  n.use_camera_info = param_or(pnh, "use_camera_info", false);
  // With camera_info the intrinsics come later; the rest must be valid now.
  if (!n.use_camera_info) cfg.settings.validate(n.sensor);

  // System options.
  cfg.system.synchronous_mapping = param_or(pnh, "synchronous_mapping", false);
  cfg.system.loop_closing = param_or(pnh, "loop_closing", true);
  cfg.system.localization_only = param_or(pnh, "localization_only", false);
  // The core's options by their own names (option_params.h): ~tracker/NAME,
  // ~mapping/NAME, ~loop/NAME, as `dynaorb run --tracker NAME=VALUE`.
  for (const auto& [ns, set] :
       {std::pair{"tracker", read_option_params(pnh, "tracker", cfg.system.tracker, "tracker")},
        std::pair{"mapping", read_option_params(pnh, "mapping", cfg.system.mapping, "local mapping")},
        std::pair{"loop", read_option_params(pnh, "loop", cfg.system.loop, "loop closing")}}) {
    std::string line;
    for (const std::string& s : set) line += " " + s;
    if (!line.empty()) ROS_INFO("~%s options set:%s", ns, line.c_str());
  }
  // The shorter names of the launch file, over ~mapping/ and ~loop/ when set.
  read_param(pnh, "ba_threads", cfg.system.mapping.ba_threads);
  // Local mapping, loop closing and global BA run this much nicer than the
  // node (core/thread_priority.h), so tracking gets the CPU first.
  int nice = 0;
  if (read_param(pnh, "background_nice", nice)) {
    check_background_nice(nice, "~background_nice");
    cfg.system.mapping.thread_nice = cfg.system.loop.thread_nice = nice;
  }
  // Lost this long (seconds of image stamps): the map is given up for a new
  // one, whose world is unrelated (TrackingStatus.map counts them); 0: never.
  read_param(pnh, "new_map_after_lost_s", cfg.system.tracker.new_map_after_lost_s);
  // Refused at start-up, naming the option, not at the first image.
  cfg.system.tracker.validate();
  cfg.system.mapping.validate();
  cfg.system.loop.validate();
  // The dynamic-object front end: a preset name (config/dynamic/<name>.yaml of
  // this package) or a preset file; "off": none.
  cfg.dynamic = param_or<std::string>(pnh, "dynamic", "off");
  if (cfg.dynamic != "off") {
    const bool is_file = cfg.dynamic.find('/') != std::string::npos ||
                         (cfg.dynamic.size() > 5 && cfg.dynamic.compare(cfg.dynamic.size() - 5, 5, ".yaml") == 0);
    const std::string path = is_file ? cfg.dynamic : std::string(DYNAORB_CONFIG_DIR) + "/dynamic/" + cfg.dynamic + ".yaml";
    cfg.system.dynamic = dynamic::DynamicFilterOptions::load(path);  // InputError naming the file and key
    cfg.system.dynamic.validate(n.sensor);
  }
  std::string vocabulary = param_or<std::string>(pnh, "vocabulary", "default");
  if (vocabulary == "none") vocabulary.clear();
  cfg.vocabulary_path = vocabulary == "default" ? default_vocabulary_path() : vocabulary;

  // Frames and TF.
  n.map_frame = param_or<std::string>(pnh, "map_frame", n.map_frame);
  n.odom_frame = param_or<std::string>(pnh, "odom_frame", n.odom_frame);
  n.base_frame = param_or<std::string>(pnh, "base_frame", n.base_frame);
  n.camera_frame = param_or<std::string>(pnh, "camera_frame", n.camera_frame);
  n.publish_tf = param_or(pnh, "publish_tf", n.publish_tf);
  n.external_odometry = param_or(pnh, "external_odometry", n.external_odometry);
  n.publish_camera_tf = param_or(pnh, "publish_camera_tf", n.publish_camera_tf);
  n.camera_xyz = triple(pnh, "camera_xyz", n.camera_xyz);
  n.camera_rpy = triple(pnh, "camera_rpy", n.camera_rpy);
  n.tf_timeout = param_or(pnh, "tf_timeout", n.tf_timeout);
  if (n.map_frame.empty() || n.odom_frame.empty() || n.base_frame.empty())
    throw InputError("~map_frame, ~odom_frame and ~base_frame must not be empty");

  // Inputs.
  n.approximate_sync = param_or(pnh, "approximate_sync", n.approximate_sync);
  n.sync_max_interval = param_or(pnh, "sync_max_interval", n.sync_max_interval);
  n.queue_size = param_or(pnh, "queue_size", n.queue_size);
  if (n.queue_size < 1) throw InputError("~queue_size must be >= 1");
  n.rectify = param_or(pnh, "rectify", n.sensor == Sensor::kStereo && cfg.settings.rectification.enabled());
  if (n.rectify && (n.sensor != Sensor::kStereo || !cfg.settings.rectification.enabled()))
    throw InputError("~rectify needs a stereo sensor and LEFT./RIGHT. blocks in the settings");
  if (n.rectify && n.use_camera_info)
    throw InputError("~use_camera_info is for rectified images: with ~rectify the YAML's LEFT./RIGHT. blocks hold the calibration");
  n.image_transport = param_or(pnh, "image_transport", n.image_transport);
  if (n.image_transport != "raw" && n.image_transport != "compressed")
    throw InputError("~image_transport must be 'raw' or 'compressed', got '" + n.image_transport + "'");
  n.use_labels = param_or(pnh, "use_labels", n.use_labels);
  n.wait_for_labels = param_or(pnh, "wait_for_labels", n.wait_for_labels);
  n.max_frames_waiting = param_or(pnh, "max_frames_waiting", n.max_frames_waiting);
  n.label_wait_timeout = seconds_param_or(pnh, "label_wait_timeout", n.label_wait_timeout);
  n.max_label_age = seconds_param_or(pnh, "max_label_age", n.max_label_age);
  n.first_labels_timeout = seconds_param_or(pnh, "first_labels_timeout", n.first_labels_timeout, " (0: no wait)");
  n.expect_labels = param_or(pnh, "expect_labels", n.expect_labels);
  n.time_jump_reset = seconds_param_or(pnh, "time_jump_reset", n.time_jump_reset, " (0: off)");
  n.propagate_labels = param_or(pnh, "propagate_labels", n.propagate_labels);
  n.label_flow_scale = param_or(pnh, "label_flow_scale", n.label_flow_scale);
  if (!(n.label_flow_scale > 0 && n.label_flow_scale <= 1))
    throw InputError("~label_flow_scale must be in (0, 1] (the flow's resolution relative to the image)");
  if (n.max_frames_waiting < 1) throw InputError("~max_frames_waiting must be >= 1");
  n.movable_ids_given = read_param(pnh, "movable_ids", n.movable_ids);
  dynamic::check_label_ids(n.movable_ids, "~movable_ids");
  if (!n.movable_ids_given) n.movable_ids = kPascalVocMovable;
  n.movable_ids_from = param_or<std::string>(pnh, "movable_ids_from", n.movable_ids_from);
  // Ids only mean something in the labels' own set: given, they are the filter's too.
  if (n.movable_ids_given) cfg.system.dynamic.movable_classes = n.movable_ids;

  n.trajectory_file = param_or<std::string>(pnh, "trajectory_file", n.trajectory_file);
  if (!n.trajectory_file.empty()) {  // its folder made now: a path that cannot be written stops the node here
    const std::filesystem::path folder = std::filesystem::absolute(n.trajectory_file).parent_path();
    std::error_code ec;
    std::filesystem::create_directories(folder, ec);
    if (!std::filesystem::is_directory(folder))
      throw InputError("~trajectory_file: cannot make its folder " + folder.string() +
                       (ec ? " (" + ec.message() + ")" : ""));
  }

  // Dense cloud.
  n.publish_cloud = param_or(pnh, "publish_cloud", n.publish_cloud);
  n.publish_unfiltered_cloud = param_or(pnh, "publish_unfiltered_cloud", n.publish_unfiltered_cloud);
  n.inpaint = param_or(pnh, "cloud/inpaint", n.inpaint);
  n.cloud.max_depth = param_or(pnh, "cloud/max_depth", n.cloud.max_depth);
  n.cloud.min_depth = param_or(pnh, "cloud/min_depth", n.cloud.min_depth);
  n.cloud.stride = param_or(pnh, "cloud/stride", n.cloud.stride);
  if (!(n.cloud.max_depth > n.cloud.min_depth) || n.cloud.stride < 1)
    throw InputError("~cloud/max_depth must exceed ~cloud/min_depth and ~cloud/stride be >= 1");
  n.sgbm.num_disparities = param_or(pnh, "sgbm/num_disparities", n.sgbm.num_disparities);
  n.sgbm.block_size = param_or(pnh, "sgbm/block_size", n.sgbm.block_size);
  n.sgbm.uniqueness_ratio = param_or(pnh, "sgbm/uniqueness_ratio", n.sgbm.uniqueness_ratio);
  n.sgbm.speckle_window = param_or(pnh, "sgbm/speckle_window", n.sgbm.speckle_window);
  n.sgbm.speckle_range = param_or(pnh, "sgbm/speckle_range", n.sgbm.speckle_range);
  try {
    n.sgbm.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("~sgbm/*: ") + e.what());
  }
  cfg.system.dynamic.inpainting.stereo = n.sgbm;  // the inpainted stereo clouds use the same depth
  n.drop_unchecked_movable = param_or(pnh, "cloud/drop_unchecked_movable", n.drop_unchecked_movable);
  return cfg;
}

void apply_camera_info(Settings& s, Sensor sensor, const sensor_msgs::CameraInfo& left,
                       const sensor_msgs::CameraInfo* right) {
  if (left.width == 0 || left.height == 0) throw InputError("camera_info: width and height must be set");
  CameraSettings& c = s.camera;
  if (sensor == Sensor::kStereo) {
    // Rectified images: the projection matrix holds their intrinsics.
    if (left.P[0] <= 0.0 || left.P[5] <= 0.0) throw InputError("camera_info: P has no focal length");
    c.fx = left.P[0];
    c.fy = left.P[5];
    c.cx = left.P[2];
    c.cy = left.P[6];
    c.dist = cv::Mat::zeros(1, 4, CV_64F);
    if (right) {
      const double bf = -right->P[3];
      if (!(bf > 0.0)) throw InputError("right camera_info: P[3] must be -fx * baseline < 0");
      c.bf = bf;
    }
  } else {
    if (left.K[0] <= 0.0 || left.K[4] <= 0.0) throw InputError("camera_info: K has no focal length");
    c.fx = left.K[0];
    c.fy = left.K[4];
    c.cx = left.K[2];
    c.cy = left.K[5];
    const bool radtan = left.distortion_model.empty() || left.distortion_model == "plumb_bob" ||
                        left.distortion_model == "rational_polynomial";
    if (!radtan) throw InputError("camera_info: distortion model '" + left.distortion_model + "' is not plumb_bob");
    const int n = static_cast<int>(std::min<std::size_t>(left.D.size(), 5));
    c.dist = cv::Mat::zeros(1, std::max(n, 4), CV_64F);
    for (int i = 0; i < n; ++i) c.dist.at<double>(i) = left.D[i];
  }
  c.width = static_cast<int>(left.width);
  c.height = static_cast<int>(left.height);
  s.validate(sensor);
}

std::string describe(const NodeConfig& cfg) {
  const NodeOptions& n = cfg.node;
  std::ostringstream wait;
  if (n.first_labels_timeout > 0)
    wait << "; the first waited for at most " << n.first_labels_timeout << " s"
         << (n.expect_labels ? ", publisher or not (~expect_labels)" : "");
  const std::string first_wait = wait.str();
  std::ostringstream jump;
  if (n.time_jump_reset > 0) jump << "; a new map when time goes back over " << n.time_jump_reset << " s";
  else jump << "; frames older than the newest refused";
  std::ostringstream out;
  out << "sensor " << to_string(n.sensor) << ", settings " << (cfg.settings.source.empty() ? "<params>" : cfg.settings.source)
      << ", vocabulary " << (cfg.vocabulary_path.empty() ? "none" : cfg.vocabulary_path) << ", dynamic "
      << cfg.dynamic << ", " << (cfg.system.synchronous_mapping ? "synchronous" : "concurrent") << " mapping, loop closing "
      << (cfg.system.loop_closing ? "on" : "off") << "; frames " << n.map_frame << " -> " << n.odom_frame << " -> "
      << n.base_frame << " -> " << (n.camera_frame.empty() ? "<image frame_id>" : n.camera_frame)
      << (n.external_odometry ? " (odom -> base from TF)" : "") << "; " << (n.approximate_sync ? "approximate" : "exact")
      << " sync, queue " << n.queue_size << (n.rectify ? ", rectifying raw stereo" : "")
      << (n.image_transport == "compressed" ? ", compressed images" : "")
      << (n.use_camera_info ? ", intrinsics from camera_info" : "")
      << (n.use_labels ? (n.wait_for_labels ? ", labels (waited for)"
                                            : ", labels (newest" + first_wait +
                                                  (n.propagate_labels ? "; moved by optical flow" : "; as they are") + ")") : ", no labels")
      << jump.str()
      << (n.trajectory_file.empty() ? "" : "; trajectory to " + n.trajectory_file)
      << "; cloud " << (n.publish_cloud ? "max depth " + std::to_string(n.cloud.max_depth) + " m, stride " +
                                               std::to_string(n.cloud.stride)
                                         : "off");
  return out.str();
}

}  // namespace dynaorb::node
