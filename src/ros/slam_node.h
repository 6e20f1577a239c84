#pragma once
// dynaorb_node: a thin roscpp adapter over dynaorb::System.
//
// Subscribes  mono: image | stereo: left/image_rect + right/image_rect (with
//             ~rectify: left/image_raw + right/image_raw, rectified by the
//             core with the YAML's LEFT./RIGHT. blocks) | rgbd: rgb/image +
//             depth/image (16UC1 scaled by DepthMapFactor, or 32FC1 metres);
//             camera_info beside the (left / rgb, and right) image with
//             ~use_camera_info; semantic/labels (mono8 class ids) unless
//             ~use_labels is false. Stereo and RGB-D pairs go through
//             message_filters with exact or approximate (~approximate_sync) time.
// Publishes   odom (nav_msgs/Odometry of base_frame in map_frame, image stamp),
//             TF map -> odom (and odom -> base_link unless ~external_odometry)
//             and the static base_link -> camera (~publish_camera_tf),
//             map_points (PointCloud2, map frame, after each keyframe),
//             cloud (per keyframe: dense, dynamic-free, camera frame, keyframe
//             stamp), dynamic_mask (mono8, 255 = masked), tracking_state
//             (dynaorb/TrackingStatus, every frame).
// Services    ~save_map, ~load_map (dynaorb/MapFile), ~reset (std_srvs/Trigger),
//             ~set_localization_mode (std_srvs/SetBool), ~stats (Trigger, JSON counters),
//             ~save_trajectory (MapFile: the final trajectory now, to `path`, or
//             with an empty path to ~trajectory_file's file of this pass).
// Writes      ~trajectory_file (TUM, one file per pass) at shutdown (finish()).
#include <message_filters/pass_through.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <mutex>

#include "dynaorb/MapFile.h"
#include "dynaorb/dynamic/label_propagation.h"
#include "dynaorb/system.h"
#include "node_config.h"
#include "time_jump.h"
#include "support/dense_cloud.h"
#include "support/odom_chain.h"

namespace dynaorb::node {

// One frame's inputs, converted.
struct FrameInput {
  std_msgs::Header header;
  cv::Mat image;    // grey, or colour in the settings' channel order
  cv::Mat right;    // stereo
  cv::Mat depth_m;  // rgbd: metres
};

// Degradations, counted (read by the ~stats service from its own thread).
struct NodeCounters {
  std::atomic<long> frames_in{0}, unreadable{0}, waiting_for_camera_info{0};
  std::atomic<long> labels_in{0}, labels_unreadable{0}, labels_used{0}, labels_missing{0}, labels_stale{0};
  // Live: frames given older labels moved by optical flow (~propagate_labels),
  // given them as they are, and the flows' total time (microseconds).
  std::atomic<long> labels_propagated{0}, labels_as_is{0}, label_propagation_us{0};
  // Live: frames answered as skipped while waiting for the first labels
  // (~first_labels_timeout), and waits that ended without labels.
  std::atomic<long> skipped_before_labels{0}, first_labels_timed_out{0};
  std::atomic<long> tf_failures{0}, clouds{0}, cloud_failures{0}, inpainted_clouds{0};
  // Keyframe clouds that left out movable-class regions the filter could not check (no previous frame).
  std::atomic<long> unchecked_clouds{0};
  // Frames stamped more than ~time_jump_reset before the newest one: time went back, the map was dropped.
  std::atomic<long> time_jumps{0};
  // ~trajectory_file: passes written, and writes that failed (logged; the node goes on).
  std::atomic<long> trajectory_passes{0}, trajectory_write_failures{0};
};

class SlamNode {
 public:
  SlamNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~SlamNode();
  std::string stats_json() const;
  // At shutdown: the trajectory of the pass so far to ~trajectory_file's pass file.
  void finish();

 private:
  using Image = sensor_msgs::Image;
  using ExactPolicy = message_filters::sync_policies::ExactTime<Image, Image>;
  using ApproxPolicy = message_filters::sync_policies::ApproximateTime<Image, Image>;

  void subscribe();
  void on_mono(const sensor_msgs::ImageConstPtr& image);
  // ~image_transport compressed: decoded, then as a raw image (mono) or into
  // the pair's synchronizer (`into`); one that does not decode is counted.
  void on_compressed(const sensor_msgs::CompressedImageConstPtr& msg, message_filters::PassThrough<Image>* into);
  void count_unreadable(const std::string& error);
  void on_pair(const sensor_msgs::ImageConstPtr& a, const sensor_msgs::ImageConstPtr& b);
  void on_labels(const sensor_msgs::ImageConstPtr& labels);
  void on_camera_info(const sensor_msgs::CameraInfoConstPtr& info, bool right);
  void on_label_timer(const ros::WallTimerEvent&);

  // Labels join: frames wait for theirs (~wait_for_labels) or take the newest.
  void offer(FrameInput frame);
  // Time went back to `stamp`, by `back` seconds: the frames held for labels
  // are answered, then the map is dropped as by ~reset; the next frame starts a new one.
  void restart_after_time_jump(double stamp, double back);
  // Drops the labels kept that are stamped after `stamp` (the time before a jump back:
  // labels come in stamp order, so none of the new time's is later than its newest frame or label).
  void forget_labels_after(double stamp);
  void drain_waiting(bool timed_out);
  // Live: the newest labels within ~max_label_age (moved onto the frame by
  // optical flow with ~propagate_labels), or none (counted).
  void process_live(const FrameInput& frame);
  // The labels nearest in time to `stamp` (nullptr: none yet); age = stamp - theirs.
  const cv::Mat* nearest_labels(double stamp, double& age) const;
  bool hold_for_first_labels();
  // Whether a labels publisher is connected now (and remembers that one was).
  bool labels_publisher_connected();
  void end_first_labels_wait(bool timed_out);
  void skip_before_labels(const FrameInput& frame);
  void process(const FrameInput& frame, const cv::Mat& labels, double label_age);
  // The live labels carry the movable classes in use (the filter's, or ~movable_ids).
  void carry_movable_classes();
  bool ensure_system();

  // ---- hooks: where the dynamic-object front end plugs in (see the report / README).
  // Labels -> what the System is given. Now: the exclusion mask of the movable ids.
  TrackResult track(const FrameInput& frame, const cv::Mat& labels, cv::Mat& exclusion);
  // The dynamic mask published on dynamic_mask. Now: the exclusion mask.
  cv::Mat dynamic_mask(const FrameInput& frame, const cv::Mat& exclusion) const;
  // Depth (metres), colour, mask and intrinsics of the keyframe's dense cloud,
  // in the input camera frame (rotation R_cam_depth applied to the points).
  // Now: the frame's own depth (RGB-D) or SGBM on the (rectified) pair.
  struct DenseView {
    cv::Mat depth_m, colour, exclude, K, dist;
    Eigen::Matrix3f R_cam_depth = Eigen::Matrix3f::Identity();
  };
  // filtered: the exclusion (and with ~cloud/inpaint the inpainting) applied; else the raw view.
  bool dense_view(const FrameInput& frame, const cv::Mat& exclusion, bool filtered, DenseView& view);
  // ----

  void publish_pose(const FrameInput& frame, const Pose& T_wc, const std::string& method);
  void publish_keyframe_outputs(const FrameInput& frame, const cv::Mat& exclusion);
  // rejected: the node's own reason when it did not track the frame ("" the core's).
  void publish_status(const FrameInput& frame, const TrackResult& r, double label_age,
                      const std::string& rejected = "");
  bool camera_extrinsics(const std_msgs::Header& header);

  bool on_save_map(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res);
  bool on_load_map(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res);
  bool on_reset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res);
  bool on_localization(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res);
  bool on_stats(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res);
  bool on_save_trajectory(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res);
  // ~trajectory_file's file for the current pass ("" when none is set).
  std::string pass_file() const;
  // With system_mutex_ held: the pass's trajectory to `path` (nothing for
  // ""); the frames written (0: none tracked, nothing written). A failed
  // write is logged and counted, and `error` (when given) says why.
  size_t write_trajectory_locked(const std::string& path, const char* when, std::string* error = nullptr);
  // With system_mutex_ held, before the System's trajectory restarts (a new
  // map): the pass's frames written, and the next pass begun if it had any.
  void end_trajectory_pass_locked(const char* why);
  // With system_mutex_ held: the next frames go to the next pass's file.
  void advance_trajectory_pass_locked();

  ros::NodeHandle nh_, pnh_;
  NodeConfig cfg_;
  std::shared_ptr<const vocab::Vocabulary> vocabulary_;
  std::unique_ptr<System> system_;
  mutable std::mutex system_mutex_;  // image callbacks (spinner thread) vs services (their own thread)

  // Inputs.
  std::unique_ptr<message_filters::Subscriber<Image>> sub_a_, sub_b_;
  // ~image_transport compressed: the decoded images enter the synchronizer here.
  std::unique_ptr<message_filters::PassThrough<Image>> pass_a_, pass_b_;
  ros::Subscriber sub_compressed_a_, sub_compressed_b_;
  std::unique_ptr<message_filters::Synchronizer<ExactPolicy>> exact_;
  std::unique_ptr<message_filters::Synchronizer<ApproxPolicy>> approx_;
  ros::Subscriber sub_mono_, sub_labels_, sub_info_left_, sub_info_right_;
  sensor_msgs::CameraInfoConstPtr info_left_, info_right_;
  std::map<double, cv::Mat> labels_;  // by stamp, newest kept
  NewestStamp newest_frame_, newest_label_;  // ~time_jump_reset
  std::unique_ptr<dynamic::LiveLabels> live_labels_;  // live: which labels each frame gets
  // Frames waiting for labels: each for its own (~wait_for_labels), or live
  // all for the first labels (~first_labels_timeout).
  std::deque<std::pair<FrameInput, ros::WallTime>> waiting_;
  // Live: the first labels came (or the wait for them ended); from then on
  // each frame takes the newest labels.
  bool first_labels_done_ = false;
  bool labels_publisher_seen_ = false;  // a labels publisher has been connected
  ros::WallTime first_wait_start_;  // the first frame held for them
  // Frames (with their labels) that came before the first camera_info.
  struct Held {
    FrameInput frame;
    cv::Mat labels;
    double label_age;
  };
  std::deque<Held> before_info_;
  ros::WallTimer label_timer_;

  // Outputs.
  ros::Publisher pub_odom_, pub_map_points_, pub_cloud_, pub_cloud_unfiltered_, pub_mask_, pub_status_;
  tf2_ros::Buffer tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::string camera_frame_;
  std::optional<Eigen::Isometry3d> T_base_cam_;
  // The SLAM world (first camera of the current map) in the map frame, as a
  // base pose: T_map_base = T_map_world_ * T_base_cam * T_wc * T_cam_base.
  Eigen::Isometry3d T_map_world_ = Eigen::Isometry3d::Identity();
  std::optional<Eigen::Isometry3d> last_T_map_base_;
  bool map_restarted_ = false;
  OdomChain chain_;
  bool last_tracked_ = false;
  long last_corrections_ = 0;

  DenseCloudBuilder cloud_builder_;
  cv::Mat rect_l1_, rect_l2_, rect_r1_, rect_r2_;  // raw stereo -> rectified, for SGBM

  // Services on their own queue and thread: a long track call does not block them.
  ros::CallbackQueue service_queue_;
  std::unique_ptr<ros::AsyncSpinner> service_spinner_;
  ros::ServiceServer srv_save_, srv_load_, srv_reset_, srv_localization_, srv_stats_, srv_save_trajectory_;
  int trajectory_pass_ = 1;  // ~trajectory_file: the pass whose frames the System holds

  NodeCounters counters_;
};

}  // namespace dynaorb::node
