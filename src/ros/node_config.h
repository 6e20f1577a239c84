#pragma once
// Parameters of dynaorb_node: the ORB-SLAM2 settings YAML (~settings) with
// any of its keys overridden by a private parameter of the same name, dots
// written as slashes (~Camera/fx, ~ThDepth, ~ORBextractor/nFeatures, ...),
// the System's options (~vocabulary, ~synchronous_mapping, ~loop_closing,
// ~localization_only, ~dynamic) and the node's own (frames, topics, sync,
// cloud). Read, validated and printed once at start-up.
#include <ros/node_handle.h>
#include <sensor_msgs/CameraInfo.h>

#include <string>
#include <vector>

#include "dynaorb/dynamic/stereo_depth.h"
#include "dynaorb/system.h"
#include "support/dense_cloud.h"

namespace dynaorb::node {

struct NodeOptions {
  Sensor sensor = Sensor::kRGBD;
  // REP-105 frames. camera_frame "": the image header's frame_id.
  std::string map_frame = "map", odom_frame = "odom", base_frame = "base_link", camera_frame;
  bool publish_tf = true;
  // true: another node publishes odom -> base_link (wheel odometry); this one
  // looks it up at the image stamp and publishes map -> odom only.
  bool external_odometry = false;
  // base_frame -> camera_frame as a static transform (x y z, roll pitch yaw).
  // The default is the REP-103 body <- optical rotation of a camera looking
  // along base_link's x axis. false: the robot description publishes it.
  bool publish_camera_tf = true;
  std::vector<double> camera_xyz{0.0, 0.0, 0.0};
  std::vector<double> camera_rpy{-1.5707963267948966, 0.0, -1.5707963267948966};
  double tf_timeout = 0.2;  // seconds to wait for a transform

  bool approximate_sync = false;  // ApproximateTime instead of ExactTime
  double sync_max_interval = 0.02;  // s, approximate sync (TUM associates rgb/depth within 0.02 s)
  int queue_size = 10;            // per subscription and in the synchronizer
  bool rectify = false;           // stereo: raw images, rectified with the YAML's LEFT./RIGHT. blocks
  bool use_camera_info = false;   // intrinsics (and bf for stereo) from the first camera_info
  // "raw": sensor_msgs/Image on the image topics; "compressed": image_transport's
  // compressed transports, decoded here (support/compressed_image.h): the image
  // topics' /compressed (jpeg, png) and the depth topic's /compressedDepth.
  std::string image_transport = "raw";

  bool use_labels = true;         // subscribe semantic/labels
  bool wait_for_labels = false;   // each frame waits for labels with its stamp (bags that carry them)
  int max_frames_waiting = 30;    //   at most this many frames wait; older ones go without labels
  double label_wait_timeout = 1.0;  //   nor longer than this (wall-clock s): labels that never come
  double max_label_age = 0.5;     // s: newest labels older than this are not used (live)
  // Live: labels older than their frame are moved onto it by optical flow
  // (dynamic::LiveLabels: chained DIS flows between the frames since the
  // labelled image), at this resolution relative to the image; false: used
  // as they are.
  bool propagate_labels = true;
  double label_flow_scale = 0.5;
  // Live: while a labels publisher is connected and none of its labels have
  // come yet, frames are held (at most max_frames_waiting) and wait for the
  // first labels, at most this long (wall-clock s; 0: no wait). Tracking
  // builds its first map from its first frame: without labels the movers in
  // view would become map points. Held frames that get no labels within
  // max_label_age of theirs are answered as skipped.
  double first_labels_timeout = 10.0;
  // Live: a labels publisher is expected (a segmentation server launched
  // with the node): the first frames wait for the first labels, as above,
  // even before any publisher has connected (the server's process may still
  // be starting); a publisher that connects and then goes away still ends
  // the wait. false: with no publisher connected nothing waits.
  bool expect_labels = false;
  // A frame stamped more than this many seconds before the newest frame so
  // far means time went back (a bag played again or looped, `rosbag play
  // -l`; a simulator reset): the map is dropped and the frames from there on
  // start a new one, as ~reset does (~stats time_jumps); the labels kept
  // that are stamped after it are dropped (the time before's), as they are
  // when labels go back as far. 0: frames older than the newest are refused
  // (rejected: stamp_not_increasing) until time passes it again.
  double time_jump_reset = 1.0;
  // Label ids masked: ~movable_ids; without it, those the segmentation server
  // announces (~movable_ids_from, its ~movable_ids parameter) once labels
  // arrive, else PASCAL VOC's movable classes.
  std::vector<int> movable_ids;
  bool movable_ids_given = false;
  std::string movable_ids_from = "/segmentation_server/movable_ids";

  bool publish_cloud = true;             // per keyframe, camera frame
  bool publish_unfiltered_cloud = false; // also cloud_unfiltered: the same without the mask (diagnostics)
  // Masked pixels filled from earlier keyframes (DDL-SLAM's background
  // inpainting, System::dense_frame(true)); needs a ~dynamic preset. Without
  // one the masked pixels are left out and a warning says so.
  bool inpaint = false;
  // Keyframes whose movable-class regions the filter could not check for
  // motion (no previous frame: the first keyframe, the first after a reset)
  // leave those regions out of their cloud: unverified is not static.
  bool drop_unchecked_movable = true;
  DenseCloudOptions cloud;
  dynamic::StereoDepthOptions sgbm;  // stereo depth for clouds (and for inpainting, into the filter's options)

  // The final trajectory as a TUM file ("": none): the System's, each tracked
  // frame's camera pose through its keyframe's current (loop-closed, bundle-
  // adjusted) pose, in the world of the map's first camera pose, as `dynaorb
  // bag run` writes trajectory.tum. Written at shutdown and on
  // ~save_trajectory with an empty path; a pass ends where the map is
  // replaced (time going back, ~reset, ~load_map), written first, and the
  // next goes to STEM.pass2.SUFFIX and so on (support/trajectory_files.h).
  std::string trajectory_file;
};

struct NodeConfig {
  Settings settings;
  SystemOptions system;
  NodeOptions node;
  std::string vocabulary_path;  // "" none
  std::string dynamic = "off";
};

// Reads the private parameters; throws InputError (or std::invalid_argument)
// naming the parameter or file that is wrong.
NodeConfig read_config(const ros::NodeHandle& pnh);

// Overrides the intrinsics from camera_info: K and D for mono / RGB-D
// (images as the camera gives them), P and no distortion for rectified
// stereo, and bf = -P_right[3] from the right camera's info. Throws
// InputError when the message is unusable.
void apply_camera_info(Settings& settings, Sensor sensor, const sensor_msgs::CameraInfo& left,
                       const sensor_msgs::CameraInfo* right);

// The default vocabulary file `dynaorb vocab default` caches
// ($DYNAORB_VOCAB_CACHE, $XDG_CACHE_HOME/dynaorb/vocab or ~/.cache/dynaorb/vocab).
std::string default_vocabulary_path();

std::string describe(const NodeConfig& config);

}  // namespace dynaorb::node
