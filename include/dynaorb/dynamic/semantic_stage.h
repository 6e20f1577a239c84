#pragma once
// The semantic prior: which pixels a segmentation network says belong to a
// movable class (people, vehicles, animals), widened by a margin at the mask
// edges. Two policies, as the papers differ:
//  - drop (DynaSLAM, STDyn-SLAM Sec. III-B, DDL-SLAM Sec. III-A): every
//    movable-class pixel is dynamic, moving or not;
//  - static_until_proven (DM-SLAM Sec. 3.2): movable-class regions are only
//    candidates; a later stage (dm, ddl, ...) decides which of them move.
// Both set ctx.current.candidates (CV_8UC1 255), which the shared motion cues
// and later stages read.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/dynamic/stage.h"

namespace dynaorb::dynamic {

// Movable classes of the label sets the segmentation models use (0 = background).
// PASCAL VOC 2012 ids: the 14 classes DynaSLAM, STDyn-SLAM and DDL-SLAM (Sec.
// III-A) treat as movable: aeroplane 1, bicycle 2, bird 3, boat 4, bus 6, car
// 7, cat 8, cow 10, dog 12, horse 13, motorbike 14, person 15, sheep 17, train 19.
const std::vector<int>& voc_movable_classes();
// COCO: DM-SLAM Sec. 3.2.1's 20 potentially moving classes, as COCO category
// ids (the annotation files' and torchvision Mask R-CNN's 1..90 numbering):
// person 1, bicycle 2, car 3, motorcycle 4, airplane 5, bus 6, train 7, truck
// 8, boat 9, bird 16, cat 17, dog 18, horse 19, sheep 20, cow 21, elephant 22,
// bear 23, zebra 24, giraffe 25, frisbee 34.
const std::vector<int>& coco_movable_classes();
// Cityscapes train ids: person 11, rider 12, car 13, truck 14, bus 15,
// train 16, motorcycle 17, bicycle 18.
const std::vector<int>& cityscapes_movable_classes();

struct SemanticOptions {
  enum class Policy { kDrop, kStaticUntilProven };
  // Key `classes`: voc | coco | cityscapes, or an explicit list of ids [15, 7].
  std::string classes = "voc";  // the set's name, or "list" for explicit ids
  std::vector<int> ids = voc_movable_classes();
  // Key `margin`, px: movable regions widened by a disc of this radius. DM-SLAM
  // Sec. 3.2.1 also discards "feature points that are too close to the edge of
  // the regions" without a value; 15 px is the elliptic dilation of DynaSLAM's
  // released code (dilation_size = 15), the masks STDyn-SLAM and DDL-SLAM
  // inherit. 0: none.
  int margin = 15;
  // Key `policy`: drop | static_until_proven.
  Policy policy = Policy::kDrop;
  // Keys `drop_unchecked_stereo`, `drop_unchecked_rgbd` and
  // `drop_unchecked_mono` (`drop_unchecked` sets the first two), ours:
  // under static_until_proven, a frame with no previous frame (the first one,
  // the first after a reset) gives no later stage anything to prove motion
  // with; its candidates are dropped as under `drop` (1) or left static (0,
  // DM-SLAM to the letter, the default). A monocular map starts from a two-view
  // reconstruction whose reference is that frame, and movers in it corrupt
  // the H / F model; a stereo or RGB-D map starts from depth, with the
  // movers' points in it until they fail tracking as they move. The `full`
  // preset drops them for mono and RGB-D (config/dynamic/full.yaml has the
  // measurements; stereo, with less texture left to start from, lost more
  // than it gained over the seeds suite).
  bool drop_unchecked_stereo = false;
  bool drop_unchecked_rgbd = false;
  bool drop_unchecked_mono = false;
  bool drop_unchecked_for(Sensor sensor) const;

  // Missing keys keep their defaults; a wrong type or value is an InputError
  // naming the key.
  void read(const cv::FileNode& node);
};

std::string to_string(SemanticOptions::Policy policy);

// CV_8UC1 255 at the pixels within Euclidean distance `radius` of a non-zero
// pixel of `mask` (CV_8UC1): dilation by the disc x^2 + y^2 <= radius^2, the
// pixels cv::distanceTransform (DIST_L2, DIST_MASK_PRECISE) puts at
// <= radius. radius <= 0: the mask itself as 0 / 255.
cv::Mat widen_by_disc(const cv::Mat& mask, int radius);

class SemanticStage : public Stage {
 public:
  explicit SemanticStage(const SemanticOptions& options = {});
  std::string name() const override { return "semantic"; }
  bool supports(Sensor) const override { return true; }
  // Marks nothing without labels (report "skipped_no_labels" = 1) or with
  // labels of another size than the image ("skipped_bad_labels" = 1).
  // Reports candidate_fraction (of the image), candidate_regions (connected
  // movable regions after the margin) and, for drop (or an unchecked frame
  // under drop_unchecked_<sensor>, reported as unchecked_dropped = 1), regions = those regions.
  void process(Context& ctx, StageReport& report) override;

  // The label source's own movable ids (a labels.json, a model card) replace
  // the configured set: ids only mean something in the network's label set.
  void set_movable_classes(const std::vector<int>& ids);
  const SemanticOptions& options() const { return o_; }

  // CV_8UC1 255 where labels (CV_8UC1 or CV_16UC1) hold a movable id, widened
  // by the margin; empty for empty or unsupported labels.
  cv::Mat candidates(const cv::Mat& labels) const;

 private:
  void build_lookup();

  SemanticOptions o_;
  cv::Mat lut8_;                  // 1x256 CV_8U: 255 for movable ids
  std::vector<unsigned char> lut16_;  // 65536 entries, for 16-bit labels
};

}  // namespace dynaorb::dynamic
