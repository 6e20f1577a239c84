#include "slam_node.h"

#include <boost/bind/bind.hpp>
#include <cv_bridge/cv_bridge.h>
#include <dynaorb/TrackingStatus.h>
#include <nav_msgs/Odometry.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sensor_msgs/image_encodings.h>
#include <tf2/LinearMath/Quaternion.h>
#include <tf2_eigen/tf2_eigen.h>

#include <cmath>
#include <filesystem>

#include "dynaorb/core/grey_image.h"
#include "dynaorb/io/errors.h"
#include "ros_conversions.h"

namespace dynaorb::node {

namespace {

// Stages of the tracking thread (python/dynaorb/runner: FRAME_STAGES).
double frame_ms(const TrackResult& r) {
  double ms = 0.0;
  for (const char* stage : {"preprocess", "extract", "stereo_matching", "tracking"}) {
    auto it = r.stage_ms.find(stage);
    if (it != r.stage_ms.end()) ms += it->second;
  }
  return ms;
}

// Loops and global bundle adjustments move the map under the trajectory.
long map_corrections(const System& s) {
  const SystemCounters& c = s.counters();
  return c.loops_closed + c.global_ba_runs;
}

geometry_msgs::TransformStamped stamped(const Eigen::Isometry3d& T, const ros::Time& stamp, const std::string& parent,
                                        const std::string& child) {
  geometry_msgs::TransformStamped t = tf2::eigenToTransform(T);
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  return t;
}

cv::Mat as_mat3(const cv::Mat& m) {
  cv::Mat out;
  m.convertTo(out, CV_64F);
  return out;
}

}  // namespace

SlamNode::SlamNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : nh_(nh), pnh_(pnh), cfg_(read_config(pnh)), cloud_builder_(cfg_.node.cloud) {
  const NodeOptions& n = cfg_.node;
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_);
  if (!cfg_.vocabulary_path.empty()) {
    if (std::filesystem::is_regular_file(cfg_.vocabulary_path)) {
      vocabulary_ = std::make_shared<const vocab::Vocabulary>(vocab::Vocabulary::load_any(cfg_.vocabulary_path));
    } else if (cfg_.vocabulary_path == default_vocabulary_path()) {
      ROS_WARN("dynaorb_node: no default vocabulary at %s (build it with `dynaorb vocab default`): running "
               "without relocalisation and loop closing",
               cfg_.vocabulary_path.c_str());
      cfg_.vocabulary_path.clear();
    } else {
      throw InputError(cfg_.vocabulary_path, 0, "~vocabulary: file not found");
    }
  }
  cfg_.system.vocabulary = vocabulary_;
  if (n.rectify) {
    const StereoRectification& q = cfg_.settings.rectification;
    const cv::Size size(q.width, q.height);
    cv::initUndistortRectifyMap(q.K_l, q.D_l, q.R_l, q.P_l.colRange(0, 3), size, CV_16SC2, rect_l1_, rect_l2_);
    cv::initUndistortRectifyMap(q.K_r, q.D_r, q.R_r, q.P_r.colRange(0, 3), size, CV_16SC2, rect_r1_, rect_r2_);
  }
  if (!n.use_camera_info) ensure_system();
  if (n.use_labels && !n.wait_for_labels) {
    dynamic::LabelPropagationOptions lo;
    lo.propagate = n.propagate_labels;
    lo.flow_scale = n.label_flow_scale;
    lo.max_age_s = n.max_label_age;
    live_labels_ = std::make_unique<dynamic::LiveLabels>(lo);
    carry_movable_classes();
  }

  pub_odom_ = nh_.advertise<nav_msgs::Odometry>("odom", 50);
  pub_map_points_ = nh_.advertise<sensor_msgs::PointCloud2>("map_points", 1, true);
  if (n.sensor != Sensor::kMono && n.publish_cloud) {
    pub_cloud_ = nh_.advertise<sensor_msgs::PointCloud2>("cloud", 10);
    if (n.publish_unfiltered_cloud) pub_cloud_unfiltered_ = nh_.advertise<sensor_msgs::PointCloud2>("cloud_unfiltered", 10);
  }
  pub_mask_ = nh_.advertise<sensor_msgs::Image>("dynamic_mask", 5);
  pub_status_ = nh_.advertise<dynaorb::TrackingStatus>("tracking_state", 50);

  ros::NodeHandle spnh(pnh_);
  spnh.setCallbackQueue(&service_queue_);
  srv_save_ = spnh.advertiseService("save_map", &SlamNode::on_save_map, this);
  srv_load_ = spnh.advertiseService("load_map", &SlamNode::on_load_map, this);
  srv_reset_ = spnh.advertiseService("reset", &SlamNode::on_reset, this);
  srv_localization_ = spnh.advertiseService("set_localization_mode", &SlamNode::on_localization, this);
  srv_stats_ = spnh.advertiseService("stats", &SlamNode::on_stats, this);
  srv_save_trajectory_ = spnh.advertiseService("save_trajectory", &SlamNode::on_save_trajectory, this);
  service_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &service_queue_);
  service_spinner_->start();

  subscribe();
  ROS_INFO("dynaorb_node: %s", describe(cfg_).c_str());
}

SlamNode::~SlamNode() {
  if (service_spinner_) service_spinner_->stop();
}

void SlamNode::subscribe() {
  const NodeOptions& n = cfg_.node;
  const int q = n.queue_size;
  std::string a, b, info_a, info_b;
  switch (n.sensor) {
    case Sensor::kMono: a = "image", info_a = "camera_info"; break;
    case Sensor::kStereo:
      a = n.rectify ? "left/image_raw" : "left/image_rect";
      b = n.rectify ? "right/image_raw" : "right/image_rect";
      info_a = "left/camera_info";
      info_b = "right/camera_info";
      break;
    case Sensor::kRGBD: a = "rgb/image", b = "depth/image", info_a = "rgb/camera_info"; break;
  }
  // image_transport's topic names for the compressed transports: under the
  // image topic as remapped (a launch file's remap of rgb/image applies).
  const bool compressed = n.image_transport == "compressed";
  const auto subscribe_compressed = [&](const std::string& topic, bool depth,
                                        message_filters::PassThrough<Image>* into) {
    return nh_.subscribe<sensor_msgs::CompressedImage>(
        nh_.resolveName(topic) + (depth ? "/compressedDepth" : "/compressed"), q,
        boost::bind(&SlamNode::on_compressed, this, boost::placeholders::_1, into));
  };
  if (n.sensor == Sensor::kMono) {
    if (compressed) sub_compressed_a_ = subscribe_compressed(a, false, nullptr);
    else sub_mono_ = nh_.subscribe(a, q, &SlamNode::on_mono, this);
  } else {
    using namespace boost::placeholders;
    const auto synchronize = [&](auto& fa, auto& fb) {
      if (n.approximate_sync) {
        approx_ = std::make_unique<message_filters::Synchronizer<ApproxPolicy>>(ApproxPolicy(q), fa, fb);
        approx_->setMaxIntervalDuration(ros::Duration(n.sync_max_interval));
        approx_->registerCallback(boost::bind(&SlamNode::on_pair, this, _1, _2));
      } else {
        exact_ = std::make_unique<message_filters::Synchronizer<ExactPolicy>>(ExactPolicy(q), fa, fb);
        exact_->registerCallback(boost::bind(&SlamNode::on_pair, this, _1, _2));
      }
    };
    if (compressed) {
      pass_a_ = std::make_unique<message_filters::PassThrough<Image>>();
      pass_b_ = std::make_unique<message_filters::PassThrough<Image>>();
      synchronize(*pass_a_, *pass_b_);
      sub_compressed_a_ = subscribe_compressed(a, false, pass_a_.get());
      sub_compressed_b_ = subscribe_compressed(b, n.sensor == Sensor::kRGBD, pass_b_.get());
    } else {
      sub_a_ = std::make_unique<message_filters::Subscriber<Image>>(nh_, a, q);
      sub_b_ = std::make_unique<message_filters::Subscriber<Image>>(nh_, b, q);
      synchronize(*sub_a_, *sub_b_);
    }
  }
  if (n.use_camera_info) {
    sub_info_left_ = nh_.subscribe<sensor_msgs::CameraInfo>(
        info_a, 1, boost::bind(&SlamNode::on_camera_info, this, boost::placeholders::_1, false));
    if (!info_b.empty())
      sub_info_right_ = nh_.subscribe<sensor_msgs::CameraInfo>(
          info_b, 1, boost::bind(&SlamNode::on_camera_info, this, boost::placeholders::_1, true));
  }
  if (n.use_labels) {
    sub_labels_ = nh_.subscribe("semantic/labels", std::max(q, 10), &SlamNode::on_labels, this);
    if (n.wait_for_labels || n.first_labels_timeout > 0)
      label_timer_ = nh_.createWallTimer(ros::WallDuration(0.1), &SlamNode::on_label_timer, this);
  }
}

// ---------------------------------------------------------------- inputs

void SlamNode::count_unreadable(const std::string& error) {
  ++counters_.unreadable;
  ROS_WARN_THROTTLE(5.0, "dynaorb_node: frame skipped: %s (%ld so far)", error.c_str(), counters_.unreadable.load());
}

void SlamNode::on_mono(const sensor_msgs::ImageConstPtr& msg) {
  FrameInput f;
  f.header = msg->header;
  std::string error;
  f.image = image_for_tracking(msg, cfg_.settings.camera.rgb, error);
  if (f.image.empty()) return count_unreadable(error);
  offer(std::move(f));
}

void SlamNode::on_compressed(const sensor_msgs::CompressedImageConstPtr& msg,
                             message_filters::PassThrough<Image>* into) {
  std::string error;
  const sensor_msgs::ImagePtr image = decompress(msg, error);
  if (!image) return count_unreadable(error);
  if (into) into->add(image);  // the pair whose other image does not decode never completes
  else on_mono(image);
}

void SlamNode::on_pair(const sensor_msgs::ImageConstPtr& a, const sensor_msgs::ImageConstPtr& b) {
  FrameInput f;
  f.header = a->header;
  std::string error;
  f.image = image_for_tracking(a, cfg_.settings.camera.rgb, error);
  if (!f.image.empty()) {
    if (cfg_.node.sensor == Sensor::kStereo) {
      f.right = image_for_tracking(b, cfg_.settings.camera.rgb, error);
    } else {
      f.depth_m = depth_in_metres(b, cfg_.settings.camera.depth_map_factor.value_or(1.0), error);
    }
  }
  if (f.image.empty() || (f.right.empty() && f.depth_m.empty())) return count_unreadable(error);
  offer(std::move(f));
}

void SlamNode::on_camera_info(const sensor_msgs::CameraInfoConstPtr& info, bool right) {
  (right ? info_right_ : info_left_) = info;
  if (system_ || before_info_.empty()) return;
  try {
    if (!ensure_system()) return;
  } catch (const std::exception& e) {
    ROS_ERROR_THROTTLE(5.0, "dynaorb_node: camera_info unusable: %s", e.what());
    return;
  }
  std::deque<Held> held;
  held.swap(before_info_);
  for (const Held& h : held) process(h.frame, h.labels, h.label_age);
}

void SlamNode::on_labels(const sensor_msgs::ImageConstPtr& msg) {
  std::string error;
  cv::Mat labels = label_image(msg, error);
  if (labels.empty()) {
    ++counters_.labels_unreadable;
    ROS_WARN_THROTTLE(5.0, "dynaorb_node: labels skipped: %s", error.c_str());
    return;
  }
  if (counters_.labels_in++ == 0 && !cfg_.node.movable_ids_given && !cfg_.node.movable_ids_from.empty()) {
    std::vector<int> ids;
    if (nh_.getParam(cfg_.node.movable_ids_from, ids) && !ids.empty()) {
      try {
        dynamic::check_label_ids(ids, cfg_.node.movable_ids_from);
      } catch (const InputError& e) {  // a callback must not throw
        ROS_WARN("dynaorb_node: %s: kept the movable classes as they were", e.what());
        ids.clear();
      }
    }
    if (!ids.empty()) {
      {
        std::lock_guard<std::mutex> lk(system_mutex_);  // ~stats reads them
        cfg_.node.movable_ids = ids;
        // The filter's too: the preset's set is another label set's ids.
        cfg_.system.dynamic.movable_classes = ids;
        if (system_) system_->set_movable_classes(ids);
      }
      carry_movable_classes();
      ROS_INFO("dynaorb_node: masking the %zu movable classes of %s", ids.size(), cfg_.node.movable_ids_from.c_str());
    }
  }
  const double stamp = msg->header.stamp.toSec();
  if (const double back = newest_label_.jump_back(stamp, cfg_.node.time_jump_reset)) {
    // Labels of the time before would stand in the new time's way (the newest kept, the oldest dropped first).
    ROS_WARN("dynaorb_node: labels went back %.3f s (%.6f after %.6f): the labels of the time before are dropped",
             back, stamp, stamp + back);
    forget_labels_after(stamp);
  }
  labels_[stamp] = labels;
  while (labels_.size() > 64) labels_.erase(labels_.begin());
  if (live_labels_) live_labels_->add_labels(stamp, labels);
  if (cfg_.node.wait_for_labels) {
    drain_waiting(false);
  } else if (!first_labels_done_) {
    end_first_labels_wait(false);
  }
}

void SlamNode::on_label_timer(const ros::WallTimerEvent&) {
  if (cfg_.node.wait_for_labels) {
    drain_waiting(true);
    return;
  }
  if (first_labels_done_) return;
  const bool connected = labels_publisher_connected();
  if (waiting_.empty()) return;
  // The publisher went away, or its labels take too long: track without them.
  // (~expect_labels: no publisher yet is not one that went away.)
  const double waited = (ros::WallTime::now() - first_wait_start_).toSec();
  const bool gone = !connected && (labels_publisher_seen_ || !cfg_.node.expect_labels);
  if (waited > cfg_.node.first_labels_timeout || gone) end_first_labels_wait(true);
}

void SlamNode::forget_labels_after(double stamp) {
  labels_.erase(labels_.upper_bound(stamp), labels_.end());
  if (live_labels_) live_labels_->forget_after(stamp);
}

void SlamNode::restart_after_time_jump(double stamp, double back) {
  // Frames held for labels belong to the time before: answered as they would have been.
  while (!waiting_.empty()) {
    const FrameInput f = waiting_.front().first;
    waiting_.pop_front();
    ++counters_.labels_missing;
    process(f, cv::Mat(), -1.0);
  }
  // Labels of the time before: every label stamped after this frame (its own may have come already).
  forget_labels_after(stamp);
  {
    std::lock_guard<std::mutex> lk(system_mutex_);
    end_trajectory_pass_locked("time went back");
    if (system_) system_->reset();
    map_restarted_ = true;
    last_tracked_ = false;
  }
  ++counters_.time_jumps;
  ROS_WARN("dynaorb_node: time went back %.3f s (frame %.6f after %.6f: a bag played again, a simulator reset): "
           "map dropped, the frames from here start a new one (~time_jump_reset %.3g s)",
           back, stamp, stamp + back, cfg_.node.time_jump_reset);
}

void SlamNode::offer(FrameInput frame) {
  ++counters_.frames_in;
  const NodeOptions& n = cfg_.node;
  const double stamp = frame.header.stamp.toSec();
  if (const double back = newest_frame_.jump_back(stamp, n.time_jump_reset)) restart_after_time_jump(stamp, back);
  if (!n.use_labels) {
    process(frame, cv::Mat(), -1.0);
    return;
  }
  if (n.wait_for_labels) {
    waiting_.emplace_back(std::move(frame), ros::WallTime::now());
    drain_waiting(false);
    return;
  }
  if (hold_for_first_labels()) {
    if (first_wait_start_.isZero()) {
      first_wait_start_ = ros::WallTime::now();
      ROS_INFO("dynaorb_node: waiting for the first labels on %s (at most %.1f s)", sub_labels_.getTopic().c_str(),
               n.first_labels_timeout);
    }
    waiting_.emplace_back(std::move(frame), ros::WallTime::now());
    if (static_cast<int>(waiting_.size()) > n.max_frames_waiting) {
      skip_before_labels(waiting_.front().first);
      waiting_.pop_front();
    }
    return;
  }
  process_live(frame);
}

bool SlamNode::hold_for_first_labels() {
  if (first_labels_done_) return false;
  // Somebody publishes labels (a segmentation server, maybe still loading
  // its network), or is expected to (~expect_labels), but none came yet:
  // the first map waits for them.
  const bool connected = labels_publisher_connected();
  if (cfg_.node.first_labels_timeout > 0 && counters_.labels_in == 0 &&
      (!waiting_.empty() || cfg_.node.expect_labels || connected))
    return true;
  // No publisher, or labels already here: no wait, now or later (a server
  // started after the first map changes nothing the wait could mend).
  first_labels_done_ = true;
  return false;
}

bool SlamNode::labels_publisher_connected() {
  const bool connected = sub_labels_.getNumPublishers() > 0;
  labels_publisher_seen_ = labels_publisher_seen_ || connected;
  return connected;
}

void SlamNode::end_first_labels_wait(bool timed_out) {
  first_labels_done_ = true;
  if (waiting_.empty()) return;
  const double waited = (ros::WallTime::now() - first_wait_start_).toSec();
  std::deque<std::pair<FrameInput, ros::WallTime>> held;
  held.swap(waiting_);
  if (timed_out) {
    ++counters_.first_labels_timed_out;
    ROS_WARN("dynaorb_node: no labels on %s after %.1f s (%s): tracking without them",
             sub_labels_.getTopic().c_str(), waited,
             sub_labels_.getNumPublishers() > 0 ? "~first_labels_timeout"
             : labels_publisher_seen_          ? "its publisher went away"
                                               : "no publisher appeared within ~first_labels_timeout");
    for (const auto& h : held) process_live(h.first);
    return;
  }
  // The first map starts from the first held frame with labels close enough
  // in time; older frames are answered as skipped.
  const long skipped_before = counters_.skipped_before_labels;
  bool started = false;
  for (const auto& h : held) {
    double age = 0.0;
    const bool usable = nearest_labels(h.first.header.stamp.toSec(), age) && std::abs(age) <= cfg_.node.max_label_age;
    if (started || usable) {
      started = true;
      process_live(h.first);
    } else {
      skip_before_labels(h.first);
    }
  }
  ROS_INFO("dynaorb_node: first labels after %.2f s; %zu frames held, %ld skipped", waited, held.size(),
           counters_.skipped_before_labels - skipped_before);
}

void SlamNode::skip_before_labels(const FrameInput& frame) {
  ++counters_.skipped_before_labels;
  ROS_WARN_THROTTLE(5.0, "dynaorb_node: frame %.6f skipped: no labels for it before the first map (%ld so far)",
                    frame.header.stamp.toSec(), counters_.skipped_before_labels.load());
  try {
    if (!ensure_system()) return;  // no camera_info yet: counted, not answered
  } catch (const std::exception&) {
    return;  // camera_info unusable: process() reports it with the next frame
  }
  camera_extrinsics(frame.header);
  TrackResult r;  // the system saw no image: NO_IMAGES_YET
  r.message = "skipped: the first map waits for the first labels (~first_labels_timeout)";
  publish_status(frame, r, -1.0, "waiting_for_labels");
}

const cv::Mat* SlamNode::nearest_labels(double stamp, double& age) const {
  const cv::Mat* best = nullptr;
  for (const auto& [s, labels] : labels_) {
    if (!best || std::abs(stamp - s) < std::abs(age)) {
      best = &labels;
      age = stamp - s;
    }
  }
  return best;
}

void SlamNode::process_live(const FrameInput& frame) {
  // Live: the newest labels not later than the frame, moved onto it along
  // the frames since (a segmentation server drops frames it cannot keep up
  // with), if recent enough.
  dynamic::FrameLabels l;
  try {
    cv::Mat grey;  // stays empty for an image the core cannot read: refused below, as by the System
    to_grey(frame.image, cfg_.settings.camera.rgb, grey);
    l = live_labels_->labels_for(frame.header.stamp.toSec(), grey);
  } catch (const std::exception& e) {  // a non-finite stamp, an unusable image: the core refuses the frame itself
    ROS_WARN_THROTTLE(5.0, "dynaorb_node: no labels for frame %.6f: %s", frame.header.stamp.toSec(), e.what());
  }
  using Source = dynamic::FrameLabels::Source;
  switch (l.source) {
    case Source::kNone: ++counters_.labels_missing; break;
    case Source::kStale:
      ++counters_.labels_stale;
      if (!labels_.empty() && labels_.rbegin()->second.size() != frame.image.size())
        ROS_WARN_THROTTLE(5.0, "dynaorb_node: labels of %dx%d are not used on %dx%d images (counted as stale)",
                          labels_.rbegin()->second.cols, labels_.rbegin()->second.rows, frame.image.cols,
                          frame.image.rows);
      break;
    case Source::kPropagated:
      ++counters_.labels_propagated;
      counters_.label_propagation_us += static_cast<long>(l.propagate_ms * 1000.0);
      break;
    case Source::kAsIs: ++counters_.labels_as_is; break;
    case Source::kFresh: break;
  }
  process(frame, l.labels, l.labels.empty() ? -1.0 : l.age_s);
}

void SlamNode::drain_waiting(bool timed_out) {
  const NodeOptions& n = cfg_.node;
  while (!waiting_.empty()) {
    const FrameInput& f = waiting_.front().first;
    const double stamp = f.header.stamp.toSec();
    auto it = labels_.lower_bound(stamp - 1e-6);
    if (it != labels_.end() && it->first <= stamp + 1e-6) {
      process(f, it->second, 0.0);
      waiting_.pop_front();
      continue;
    }
    // Labels arrive in stamp order: newer ones mean this frame's never come.
    const bool passed = !labels_.empty() && labels_.rbegin()->first > stamp + 1e-6;
    const bool too_many = static_cast<int>(waiting_.size()) > n.max_frames_waiting;
    const bool too_long = timed_out && (ros::WallTime::now() - waiting_.front().second).toSec() > n.label_wait_timeout;
    if (!(passed || too_many || too_long)) break;
    ++counters_.labels_missing;
    process(f, cv::Mat(), -1.0);
    waiting_.pop_front();
  }
}

bool SlamNode::ensure_system() {
  if (system_) return true;
  Settings settings = cfg_.settings;
  if (cfg_.node.use_camera_info) {
    const bool need_right = cfg_.node.sensor == Sensor::kStereo;
    if (!info_left_ || (need_right && !info_right_)) return false;
    apply_camera_info(settings, cfg_.node.sensor, *info_left_, need_right ? info_right_.get() : nullptr);
    cfg_.settings = settings;
    ROS_INFO("dynaorb_node: intrinsics from camera_info: fx %.3f fy %.3f cx %.3f cy %.3f%s", settings.camera.fx,
             settings.camera.fy, settings.camera.cx, settings.camera.cy,
             settings.camera.bf ? (", bf " + std::to_string(*settings.camera.bf)).c_str() : "");
  }
  system_ = std::make_unique<System>(settings, cfg_.node.sensor, cfg_.system);
  carry_movable_classes();
  return true;
}

void SlamNode::carry_movable_classes() {
  // Only the classes that are read downstream are moved from frame to frame
  // (LabelPropagationOptions::classes): the filter's, or those the node masks
  // itself. Before the System with a filter exists: every class.
  if (!live_labels_) return;
  if (cfg_.system.dynamic.enabled(cfg_.node.sensor))
    live_labels_->set_classes(system_ ? system_->movable_classes() : std::vector<int>());
  else
    live_labels_->set_classes(cfg_.node.movable_ids);
}

// ---------------------------------------------------------------- hooks

TrackResult SlamNode::track(const FrameInput& f, const cv::Mat& labels, cv::Mat& exclusion) {
  // With a dynamic preset the labels go to the System's filter, which decides
  // what of the movable classes moves; without one, every movable-class pixel
  // is kept out of tracking (the drop policy).
  const bool filter = cfg_.system.dynamic.enabled(cfg_.node.sensor);
  exclusion = labels.empty() || filter ? cv::Mat() : movable_mask(labels, cfg_.node.movable_ids);
  const cv::Mat to_filter = filter ? labels : cv::Mat();
  if (!labels.empty()) ++counters_.labels_used;
  const double stamp = f.header.stamp.toSec();
  TrackResult r;
  switch (cfg_.node.sensor) {
    case Sensor::kMono: r = system_->track_mono(f.image, stamp, exclusion, to_filter); break;
    case Sensor::kStereo: r = system_->track_stereo(f.image, f.right, stamp, exclusion, to_filter); break;
    case Sensor::kRGBD: {
      // The System divides depth by DepthMapFactor whatever its type: metres scaled back.
      cv::Mat depth;
      f.depth_m.convertTo(depth, CV_32F, cfg_.settings.camera.depth_map_factor.value_or(1.0));
      r = system_->track_rgbd(f.image, depth, stamp, exclusion, to_filter);
      break;
    }
  }
  // The filter's mask (input pixels) is what the outputs leave out.
  if (filter && r.rejected == RejectReason::kNone) exclusion = system_->last_dynamic_mask();
  return r;
}

cv::Mat SlamNode::dynamic_mask(const FrameInput&, const cv::Mat& exclusion) const { return exclusion; }

bool SlamNode::dense_view(const FrameInput& f, const cv::Mat& exclusion, bool filtered, DenseView& view) {
  const CameraSettings& c = system_->settings().camera;
  const Sensor sensor = cfg_.node.sensor;
  const bool filter = filtered && cfg_.system.dynamic.enabled(sensor);
  const bool inpaint = cfg_.node.inpaint && filter && sensor != Sensor::kMono;
  if (filtered && cfg_.node.inpaint && !inpaint)
    ROS_WARN_ONCE("dynaorb_node: ~cloud/inpaint works for RGB-D and stereo with a ~dynamic preset: the masked "
                  "pixels are left out of the cloud, not inpainted");
  // Points of the rectified camera into the input camera: x_cam = R_l^T x_rect.
  auto rectified_to_input = [this, &view] {
    const cv::Mat R = as_mat3(cfg_.settings.rectification.R_l);
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) view.R_cam_depth(r, k) = static_cast<float>(R.at<double>(k, r));
  };
  cv::Mat unchecked;  // movable-class regions the filter had no previous frame to check (tracked pixels)
  // They join the exclusion of the view whose image (of this size) is in the tracked pixels.
  auto exclude_unchecked = [&view, &unchecked](const cv::Size& size) {
    if (!unchecked.empty() && unchecked.size() == size)
      view.exclude = view.exclude.empty() ? unchecked : (view.exclude | unchecked);
  };
  if (filter) {
    DenseFrame d;
    {
      std::lock_guard<std::mutex> lk(system_mutex_);
      d = system_->dense_frame(inpaint);
    }
    if (std::abs(d.stamp - f.header.stamp.toSec()) < 1e-6) {
      if (!d.motion_checked && cfg_.node.drop_unchecked_movable && !d.candidates.empty() &&
          cv::countNonZero(d.candidates) > 0) {
        unchecked = d.candidates;
        ++counters_.unchecked_clouds;
      }
      if (d.inpainted && !d.depth.empty()) {
        // DDL-SLAM's background inpainting: the keyframe's dynamic pixels
        // filled from the filter's last keyframes; pixels none of them saw
        // have depth 0 and stay out of the cloud.
        view.depth_m = d.depth;
        if (c.rgb) cv::cvtColor(d.colour, view.colour, cv::COLOR_BGR2RGB);
        else view.colour = d.colour;
        view.K = (cv::Mat_<double>(3, 3) << d.fx, 0, d.cx, 0, d.fy, d.cy, 0, 0, 1);
        view.dist = d.dist;
        view.exclude = unchecked;
        if (sensor == Sensor::kStereo && cfg_.node.rectify) rectified_to_input();
        ++counters_.inpainted_clouds;
        return true;
      }
    }
  }
  cv::Mat K = (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  view.exclude = exclusion.empty() || !filtered ? cv::Mat() : exclusion;
  if (sensor == Sensor::kRGBD) {
    exclude_unchecked(f.image.size());
    view.depth_m = f.depth_m;
    view.colour = f.image;
    view.K = K;
    view.dist = c.dist;
    return true;
  }
  if (sensor != Sensor::kStereo || !c.bf) return false;
  cv::Mat left = f.image, right = f.right;
  view.K = K;
  if (cfg_.node.rectify) {
    const StereoRectification& q = cfg_.settings.rectification;
    cv::remap(f.image, left, rect_l1_, rect_l2_, cv::INTER_LINEAR);
    cv::remap(f.right, right, rect_r1_, rect_r2_, cv::INTER_LINEAR);
    if (!view.exclude.empty()) cv::remap(exclusion, view.exclude, rect_l1_, rect_l2_, cv::INTER_NEAREST);
    view.K = as_mat3(q.P_l.colRange(0, 3));
    rectified_to_input();
  }
  exclude_unchecked(left.size());
  view.depth_m = dynamic::stereo_depth(left, right, *c.bf, cfg_.node.sgbm);
  view.colour = left;
  return !view.depth_m.empty();
}

// ---------------------------------------------------------------- processing

void SlamNode::process(const FrameInput& f, const cv::Mat& labels, double label_age) {
  try {
    if (!ensure_system()) {
      // Held until the camera_info (which may follow its image) arrives; the oldest dropped beyond the queue.
      before_info_.push_back({f, labels, label_age});
      if (static_cast<int>(before_info_.size()) > cfg_.node.queue_size) {
        before_info_.pop_front();
        ++counters_.waiting_for_camera_info;
        ROS_WARN_THROTTLE(5.0, "dynaorb_node: waiting for camera_info (%ld frames dropped)",
                          counters_.waiting_for_camera_info.load());
      }
      return;
    }
  } catch (const std::exception& e) {
    ++counters_.waiting_for_camera_info;
    ROS_ERROR_THROTTLE(5.0, "dynaorb_node: camera_info unusable: %s", e.what());
    return;
  }
  const bool have_extrinsics = camera_extrinsics(f.header);
  cv::Mat exclusion;
  TrackResult r;
  long corrections = 0;
  bool restarted = false;
  {
    std::lock_guard<std::mutex> lk(system_mutex_);
    r = track(f, labels, exclusion);
    corrections = map_corrections(*system_);
    restarted = map_restarted_;
  }
  publish_status(f, r, label_age);
  if (pub_mask_.getNumSubscribers() > 0) {
    cv::Mat mask = dynamic_mask(f, exclusion);
    if (mask.empty()) mask = cv::Mat::zeros(f.image.size(), CV_8UC1);
    pub_mask_.publish(cv_bridge::CvImage(f.header, sensor_msgs::image_encodings::MONO8, mask).toImageMsg());
  }
  const bool ok = r.state == TrackingState::kOk && r.pose.has_value();
  if (ok && have_extrinsics) {
    const bool continuous = last_tracked_ && !restarted && corrections == last_corrections_ && r.method != "init" &&
                            r.method != "relocalization";
    if (!continuous) chain_.restart();
    publish_pose(f, *r.pose, r.method);
    if (r.new_keyframe) publish_keyframe_outputs(f, exclusion);
  }
  last_tracked_ = ok;
  last_corrections_ = corrections;
}

bool SlamNode::camera_extrinsics(const std_msgs::Header& header) {
  if (T_base_cam_) return true;
  const NodeOptions& n = cfg_.node;
  if (camera_frame_.empty()) {
    camera_frame_ = !n.camera_frame.empty() ? n.camera_frame : header.frame_id;
    if (camera_frame_.empty()) {
      camera_frame_ = "camera_optical_frame";
      ROS_WARN("dynaorb_node: images carry no frame_id and ~camera_frame is not set: using '%s'",
               camera_frame_.c_str());
    }
  }
  if (n.publish_camera_tf) {
    tf2::Quaternion q;
    q.setRPY(n.camera_rpy[0], n.camera_rpy[1], n.camera_rpy[2]);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(n.camera_xyz[0], n.camera_xyz[1], n.camera_xyz[2]);
    static_broadcaster_.sendTransform(stamped(T, header.stamp, n.base_frame, camera_frame_));
    T_base_cam_ = T;
    return true;
  }
  try {
    T_base_cam_ = tf2::transformToEigen(
        tf_buffer_.lookupTransform(n.base_frame, camera_frame_, ros::Time(0), ros::Duration(n.tf_timeout)));
    return true;
  } catch (const tf2::TransformException& e) {
    ++counters_.tf_failures;
    ROS_WARN_THROTTLE(5.0, "dynaorb_node: no transform %s -> %s yet (%s): poses not published", n.base_frame.c_str(),
                      camera_frame_.c_str(), e.what());
    return false;
  }
}

void SlamNode::publish_pose(const FrameInput& f, const Pose& T_wc, const std::string& method) {
  const NodeOptions& n = cfg_.node;
  const Eigen::Isometry3d& B = *T_base_cam_;
  const Eigen::Isometry3d T_world_base = B * T_wc * B.inverse();  // base pose in the first base frame
  Eigen::Isometry3d T_map_base;
  {
    std::lock_guard<std::mutex> lk(system_mutex_);
    if (map_restarted_) {
      // A new map after ~reset: its world is put where the robot was last
      // seen (a guess: the two maps are not related).
      T_map_world_ = last_T_map_base_ ? *last_T_map_base_ * T_world_base.inverse() : Eigen::Isometry3d::Identity();
      map_restarted_ = false;
    }
    T_map_base = T_map_world_ * T_world_base;
  }
  last_T_map_base_ = T_map_base;
  const ros::Time& stamp = f.header.stamp;
  chain_.update(T_map_base, stamp.toSec(), true);

  if (n.publish_tf) {
    if (n.external_odometry) {
      try {
        const Eigen::Isometry3d T_odom_base = tf2::transformToEigen(
            tf_buffer_.lookupTransform(n.odom_frame, n.base_frame, stamp, ros::Duration(n.tf_timeout)));
        tf_broadcaster_.sendTransform(stamped(T_map_base * T_odom_base.inverse(), stamp, n.map_frame, n.odom_frame));
      } catch (const tf2::TransformException& e) {
        ++counters_.tf_failures;
        ROS_WARN_THROTTLE(5.0, "dynaorb_node: no odometry %s -> %s at %.3f (%s): map -> odom not published",
                          n.odom_frame.c_str(), n.base_frame.c_str(), stamp.toSec(), e.what());
      }
    } else {
      tf_broadcaster_.sendTransform({stamped(chain_.T_map_odom(), stamp, n.map_frame, n.odom_frame),
                                     stamped(chain_.T_odom_base(), stamp, n.odom_frame, n.base_frame)});
    }
  }
  nav_msgs::Odometry odom;
  odom.header.stamp = stamp;
  odom.header.frame_id = n.map_frame;
  odom.child_frame_id = n.base_frame;
  odom.pose.pose = tf2::toMsg(T_map_base);
  if (chain_.velocity_valid()) {
    odom.twist.twist.linear.x = chain_.linear().x();
    odom.twist.twist.linear.y = chain_.linear().y();
    odom.twist.twist.linear.z = chain_.linear().z();
    odom.twist.twist.angular.x = chain_.angular().x();
    odom.twist.twist.angular.y = chain_.angular().y();
    odom.twist.twist.angular.z = chain_.angular().z();
  }
  pub_odom_.publish(odom);
}

void SlamNode::publish_keyframe_outputs(const FrameInput& f, const cv::Mat& exclusion) {
  const NodeOptions& n = cfg_.node;
  {  // latched: always published, so that a late subscriber gets the current map
    std::vector<Eigen::Vector3d> world;
    Eigen::Isometry3d T_map_cam0;
    {
      std::lock_guard<std::mutex> lk(system_mutex_);
      world = system_->map_points();
      T_map_cam0 = T_map_world_ * *T_base_cam_;
    }
    std::vector<Eigen::Vector3f> points;
    points.reserve(world.size());
    for (const Eigen::Vector3d& p : world) points.push_back((T_map_cam0 * p).cast<float>());
    sensor_msgs::PointCloud2 msg = to_cloud_msg(points, {});
    msg.header.stamp = f.header.stamp;
    msg.header.frame_id = n.map_frame;
    pub_map_points_.publish(msg);
  }
  if (!pub_cloud_) return;
  auto publish = [&](ros::Publisher& pub, bool filtered) {
    DenseView view;
    if (!dense_view(f, exclusion, filtered, view)) {
      ++counters_.cloud_failures;
      ROS_WARN_THROTTLE(5.0, "dynaorb_node: no depth for the keyframe cloud");
      return false;
    }
    DenseCloud cloud =
        cloud_builder_.build(view.depth_m, view.colour, cfg_.settings.camera.rgb, view.exclude, view.K, view.dist);
    if (!cloud_builder_.error().empty()) {
      ++counters_.cloud_failures;
      ROS_WARN_THROTTLE(5.0, "dynaorb_node: keyframe cloud skipped: %s", cloud_builder_.error().c_str());
      return false;
    }
    if (!view.R_cam_depth.isIdentity())
      for (Eigen::Vector3f& p : cloud.xyz) p = view.R_cam_depth * p;
    sensor_msgs::PointCloud2 msg = to_cloud_msg(cloud.xyz, cloud.rgb);
    msg.header.stamp = f.header.stamp;
    msg.header.frame_id = camera_frame_;
    pub.publish(msg);
    return true;
  };
  if (publish(pub_cloud_, true)) ++counters_.clouds;
  // The same keyframe as the camera saw it: no mask, no inpainting.
  if (pub_cloud_unfiltered_) publish(pub_cloud_unfiltered_, false);
}

void SlamNode::publish_status(const FrameInput& f, const TrackResult& r, double label_age,
                              const std::string& rejected) {
  dynaorb::TrackingStatus s;
  s.header.stamp = f.header.stamp;
  s.header.frame_id = camera_frame_;
  s.state = to_string(r.state);
  s.method = r.method;
  s.rejected = rejected.empty() ? to_string(r.rejected) : rejected;
  s.message = r.message;
  s.keypoints = r.keypoints;
  s.tracked_points = r.tracked_points;
  s.new_keyframe = r.new_keyframe;
  s.mask_used = r.mask_used || r.labels_used;  // a mask, or labels the dynamic filter used
  s.label_age = label_age;
  s.frame_ms = frame_ms(r);
  s.map = r.map;
  s.map_dropped = r.map_dropped;
  {
    std::lock_guard<std::mutex> lk(system_mutex_);
    const MapSummary m = system_->map_summary();
    s.keyframes = m.keyframes;
    s.map_points = m.points;
    const SystemCounters& c = system_->counters();
    s.frames = c.frames;
    s.tracked = c.tracked;
    s.lost = c.lost;
    s.refused = c.rejected;
  }
  pub_status_.publish(s);
  if (r.rejected != RejectReason::kNone)
    ROS_WARN_THROTTLE(5.0, "dynaorb_node: frame %.6f rejected: %s", f.header.stamp.toSec(), r.message.c_str());
  if (r.map_dropped) ROS_WARN("dynaorb_node: frame %.6f: %s", f.header.stamp.toSec(), r.message.c_str());
}

}  // namespace dynaorb::node
