#pragma once
// The candidate (movable-class) mask cut into object regions, the unit a
// stage decides "moving" or not for (DM-SLAM Sec. 3.2.4: "the corresponding
// object is determined to be moving"). Without instance ids from the network
// the best we have is: connected components of the mask, and where two
// classes touch (a person in front of a car) they are different objects.
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
// same size, or empty. With split_by_label, every candidate pixel belongs to
// the class of its nearest labelled pixel (the candidate mask is the labels
// widened by a margin, so margin pixels carry no label of their own), and
// regions are the 8-connected components per class; otherwise per mask.
// Bad input (empty, wrong type) gives no regions.
CandidateRegions candidate_regions(const cv::Mat& candidates, const cv::Mat& labels, bool split_by_label);

}  // namespace dynaorb::dynamic
