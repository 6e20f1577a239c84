#pragma once
// Labels of a network slower than the camera, carried to the frames it has
// not seen (NGD-SLAM's idea): the newest label image is moved to the
// current frame by dense optical flow instead of being used where its
// objects were.
//
// The flow is OpenCV's DIS (ultrafast preset) at a reduced resolution,
// backward (later -> earlier image): for every pixel of the later image,
// where it was in the earlier one; labels are sampled there with nearest
// neighbour, and pixels that come from outside the earlier image get
// background (0). Labels several frames old are moved frame by frame: the
// flows between consecutive frames are chained, never one flow across the
// whole gap: a mover that walks one way while the camera pans the other
// moves too far between distant frames for the flow to follow. On the
// gtest scene (10 Hz; object 8 px a frame right, camera 4 px a frame left;
// test_label_propagation.cc) the chained flows give IoU 0.72 / 0.65 / 0.59
// with the true mask 3 / 4 / 5 frames after the labelled image, the stale
// labels 0.58 / 0.48 / 0.39, one flow across the gap 0.70 / 0.69 / 0.30
// (0.08 at 6 frames, 0 at 8). Full-resolution flow: 0.76 / 0.71 / 0.64.
// The flows are computed over the whole image (DIS's pyramid follows large
// motion), the chain only over the pixels that land, frame by frame, near
// the labelled box: the others can carry no label.
//
// LabelPropagator::warp: one pair of images (the chain of one step).
// LiveLabels: the per-frame choice for a live camera (the ROS node), frames
// in stamp order, label images arriving later for the stamps of the images
// they were computed from. A frame takes the newest label image not later
// than itself whose image it has seen, moved along the frames since. Labels
// older than max_age_s are not used. A label image with only background
// needs no flow.
#include <deque>
#include <map>
#include <string>
#include <vector>
#include <opencv2/core.hpp>
#include <opencv2/video/tracking.hpp>

namespace dynaorb::dynamic {

struct LabelPropagationOptions {
  // Move old labels by optical flow (false: use them as they are, as the
  // ROS node did before).
  bool propagate = true;
  // Resolution of the flow, relative to the image (dynaorb.segmentation's
  // default).
  double flow_scale = 0.5;
  // Labels from an image more than this older than the frame are not used
  // (s): the ROS node's ~max_label_age.
  double max_age_s = 0.5;
  // Frames kept for labels still to come, at most.
  int frames_kept = 64;
  // Non-empty: the label ids carried (the filter's movable classes); the
  // others become background when a label image arrives. Only those ids are
  // read downstream, and a scene without any of them then needs no flow: the
  // PASCAL network labels most of EuRoC V1's room "sofa" (18), which cost a
  // flow and a warp of the whole image on every frame.
  std::vector<int> classes;

  // Refuses values no run can use (InputError naming the option).
  void validate() const;
};

// Buffers the warps reuse (their allocations cost page faults every frame).
struct LabelScratch {
  cv::Mat full_disp;                 // the displacement at full size (CV_32FC2)
  cv::Mat map;                       // CV_32FC2, over the labels' reach
  cv::Mat small_x, small_y, step;    // flow size, chaining
  cv::Mat grid, landed, landing;     // flow size: pixel grid (CV_32FC2), where pixels land, which land in a box
};

class LabelPropagator {
 public:
  explicit LabelPropagator(double flow_scale = 0.5);
  // Labels of the source image -> labels of the destination image. All three
  // the same size; labels 8- or 16-bit, one channel; images 8-bit grey.
  // Throws InputError otherwise. ms (when given): the time taken, 0 when no
  // flow was needed.
  cv::Mat warp(const cv::Mat& labels, const cv::Mat& src_grey, const cv::Mat& dst_grey, double* ms = nullptr);

 private:
  double scale_;
  cv::Ptr<cv::DISOpticalFlow> dis_;
  LabelScratch scratch_;
};

// What LiveLabels::labels_for gave a frame.
struct FrameLabels {
  enum class Source { kNone, kFresh, kPropagated, kAsIs, kStale };
  cv::Mat labels;           // empty: none for this frame
  Source source = Source::kNone;
  double age_s = -1;        // frame stamp - the labelled image's stamp (-1: none)
  double propagate_ms = 0;  // the flows' and the warp's time for this frame
};
const char* to_string(FrameLabels::Source source);

// Throws InputError "<what>: <id> is not a label id (0-65535)" for the first
// id outside the range of 8- and 16-bit label images.
void check_label_ids(const std::vector<int>& ids, const std::string& what);

// labels with every id not in `ids` set to background (0); `ids` empty: labels
// as they are (not copied). Labels one 8- or 16-bit channel (InputError otherwise).
cv::Mat keep_classes(const cv::Mat& labels, const std::vector<int>& ids);

class LiveLabels {
 public:
  explicit LiveLabels(const LabelPropagationOptions& options = {});
  // A label image for the image stamped `stamp` (the network's result),
  // reduced to options.classes.
  void add_labels(double stamp, const cv::Mat& labels);
  // Other classes to carry (a segmentation server announcing its label set
  // after start-up): the label images kept are reduced again, those to come
  // too. Ids not carried before stay lost in the images already reduced.
  void set_classes(const std::vector<int>& ids);
  // The labels for a frame (grey: its 8-bit grey image), frames in stamp
  // order (an older stamp than the last frame's clears the frames kept).
  FrameLabels labels_for(double stamp, const cv::Mat& grey);
  // Forgets frames and labels (a new camera, a reset).
  void clear();
  // Forgets the label images and frames stamped after `stamp` (time went
  // back: a bag played again, a simulator reset; they belong to the time before).
  void forget_after(double stamp);
  // How many of labels_for's answers came from each source.
  long count(FrameLabels::Source source) const { return counts_[static_cast<int>(source)]; }

 private:
  struct Frame {
    double stamp;
    cv::Mat small;            // grey at flow_scale
    cv::Size size;            // full image size
    cv::Mat flow_to_previous; // small, CV_32FC2; empty until needed
  };
  LabelPropagationOptions o_;
  cv::Ptr<cv::DISOpticalFlow> dis_;
  LabelScratch scratch_;
  struct LabelImage {
    cv::Mat labels;
    cv::Rect box;  // of its labelled pixels, found once (empty: background only)
  };
  std::map<double, LabelImage> labels_;  // by the labelled image's stamp
  std::deque<Frame> frames_;          // recent frames, oldest first
  long counts_[5] = {0, 0, 0, 0, 0};
  // The chained displacement from the last frame given propagated labels
  // back to their labelled frame (small, CV_32FC2, over disp_at_): the next
  // frame with the same labels extends it by its own flow instead of
  // chaining them all again.
  cv::Mat disp_;
  double disp_source_ = 0, disp_frame_ = 0;
  bool have_disp_ = false;

  cv::Rect disp_at_;  // the rectangle of the small image disp_ covers: the pixels that may reach a label

  int frame_index(double stamp) const;  // -1: not kept
  void prune(double stamp);
  // labels of frames_[from] moved to frames_.back() (from < size - 1).
  cv::Mat carry(const LabelImage& labels, int from);
  const cv::Mat& flow_to_previous(int j);
};

}  // namespace dynaorb::dynamic
