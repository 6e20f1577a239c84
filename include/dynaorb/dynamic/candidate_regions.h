#pragma once
// The candidate (movable-class) mask cut into object regions, the unit a
// stage decides "moving" or not for (DM-SLAM Sec. 3.2.4: "the corresponding
// object is determined to be moving"). Without instance ids from the network
// the best we have is: connected components of the mask, and where two
// classes touch (a person in front of a car) they are different objects.
#include <list>
#include <opencv2/core.hpp>
#include <vector>

namespace dynaorb::dynamic {

struct CandidateRegions {
  cv::Mat ids;                     // CV_32SC1: 0 = outside, 1..count = region
  int count = 0;
  std::vector<unsigned char> label;  // class id of region r at label[r - 1] (0: unknown)
  std::vector<int> pixels;           // area of region r at pixels[r - 1]
};

// candidates: CV_8UC1 (non-zero = candidate). labels: CV_8UC1 class ids of the
// same size, or empty. Regions are the 8-connected components of the mask.
// With split_by_label, a component holding two classes or more (instances
// of different classes touching) is split: each of its pixels belongs to
// the class of the nearest pixel of those classes inside the component's
// bounding box (the candidate mask is the labels widened by a margin, so
// margin pixels carry no label of their own), and its regions are the
// 8-connected components per class. label[] is the component's class, or
// 0 when it holds no labelled pixel.
// Bad input (empty, wrong type) gives no regions.
CandidateRegions candidate_regions(const cv::Mat& candidates, const cv::Mat& labels, bool split_by_label);

// The splitting rule of candidate_regions: for each pixel, the class of
// `present` (ascending ids) whose pixels in `lab` (CV_8UC1 class ids) are
// nearest by OpenCV's 5x5 chamfer distance (distanceTransform, DIST_L2,
// DIST_MASK_5), ties to the lower id: the same answer as one such distance
// transform per class and a running minimum, in one pair of passes. Pixels
// outside `where` (CV_8UC1, lab's size) are answered too, exactly only
// where their nearest class is closer than 256 px.
cv::Mat nearest_class(const cv::Mat& lab, const std::vector<unsigned char>& present, const cv::Mat& where);
// The rule itself, as nearest_class states it: one distanceTransform per
// class of `present` and a running minimum (nearest_class's fallback where
// floats would round the distances).
cv::Mat nearest_class_by_transforms(const cv::Mat& lab, const std::vector<unsigned char>& present);

// The first step of candidate_regions: the mask's 8-connected components
// (connectedComponentsWithStats: comp, stats, count without the background),
// which do not depend on the labels. Bad input gives count 0, comp empty.
struct CandidateBlobs {
  cv::Mat comp, stats;
  int count = 0;
};
CandidateBlobs candidate_blobs(const cv::Mat& candidates);
CandidateRegions candidate_regions(const CandidateBlobs& blobs, const cv::Mat& labels, bool split_by_label);

// The arguments of one candidate_regions call (Stage::regions_wanted).
struct RegionsRequest {
  cv::Mat candidates, labels;
  bool split_by_label = false;
};

// candidate_regions for one frame, cut once for all the stages that ask with
// the same inputs (the same pixels, not only the same buffers): DM-SLAM's
// and STDyn-SLAM's stages decide on the same objects. The result is shared
// (do not write into its ids) and lives as long as the memo.
class RegionsMemo {
 public:
  // Not thread-safe: DynamicFilter calls it from its worker thread only
  // while no stage runs (it waits for that job first).
  const CandidateRegions& get(const cv::Mat& candidates, const cv::Mat& labels, bool split_by_label);
  const CandidateRegions& get(const RegionsRequest& r) { return get(r.candidates, r.labels, r.split_by_label); }

 private:
  struct Result {
    cv::Mat labels;  // a copy: the stages' inputs may change after the call
    bool split = false;
    CandidateRegions regions;
  };
  struct Entry {
    cv::Mat candidates;  // a copy, likewise
    CandidateBlobs blobs;  // cut once, whatever labels split them
    std::list<Result> results;  // lists: the references given out stay valid
  };
  std::list<Entry> entries_;
};

}  // namespace dynaorb::dynamic
