#pragma once
// Turns images into Features: ORB extraction (the pyramid levels of the
// image, or of both stereo images, shared level by level between the calling
// thread and a HelperThread: HelperThread::share), keypoint undistortion,
// stereo matching along rectified rows or the RGB-D virtual right coordinate
// from depth, and the search grid.
//
// Shared rather than split in fixed halves (before: the right image, or half
// of the levels, submitted to the helper, the rest here, then a wait for the
// helper's half): with asynchronous local mapping busy on the other core, the
// helper woke 1-5 ms late on about a quarter of the frames (Linux 6.18's
// EEVDF lets the nice-10 mapping thread finish its slice), and the tracking
// thread waited for it. Now it takes what the helper has not begun. Track
// call medians, 2 cores, asynchronous mapping, unpaced, interleaved runs
// (before -> after, means of the runs' medians):
//   synthetic mono, 3 movers, `full` + labels     10.75 -> 9.69 ms (4 + 4)
//   synthetic RGB-D, 3 movers, `full` + labels    10.46 -> 9.89 ms (4 + 4)
//   synthetic stereo, 3 movers, `full` + labels   15.90 -> 15.04 ms (4 + 4)
//   synthetic stereo, no movers, off               9.15 -> 8.83 ms (4 + 4)
//   KITTI 06 stereo, off                          13.09 -> 12.07 ms (4 + 4)
//   KITTI 06 stereo, `full` + network             20.87 -> 19.02 ms (3 + 3)
//   EuRoC V1_01 stereo, off                        9.95 -> 9.92 ms (3 + 3)
//   EuRoC V1_01 stereo, `full` + network          12.49 -> 12.13 ms (3 + 3)
//   EuRoC MH_05 mono, `full` + network             9.35 -> 7.35 ms (3 + 3)
// 28 of the 31 pairs faster (the others slower by 0.04-0.37 ms, where the
// mapping leaves the helper alone); the means of the per-frame extraction times
// fell more (KITTI off 9.4 -> 7.8 ms), the features are the same
// (OrbExtractor.LevelsOnTwoThreadsAreExtract).
#include <functional>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "dynaorb/core/helper_thread.h"
#include "dynaorb/features/orb_extractor.h"
#include "dynaorb/map/features.h"

namespace dynaorb::tracking {

using StageTimes = std::map<std::string, double>;

// Computes the exclusion mask (e.g. runs the dynamic filter) on the calling
// thread while the mask-independent part of the extraction
// (OrbExtractor::detect: pyramids, FAST corners, blurred levels) runs on a
// worker thread. It may set the count's region before returning.
using ExclusionSource = std::function<cv::Mat()>;

class FrameBuilder {
 public:
  // init_feature_factor: the monocular initialisation extracts this many
  // times nFeatures (ORB-SLAM2: 2, ORB-SLAM3: 5; see TrackerOptions).
  // right_budget_max_factor: with an exclusion mask covering a fraction m of
  // the left image, the right image is extracted with nFeatures / (1 - m)
  // keypoints, at most this many times nFeatures (1: always nFeatures; see
  // TrackerOptions::stereo_right_budget_max_factor).
  FrameBuilder(const Settings& settings, std::shared_ptr<const map::Calibration> calib,
               int init_feature_factor = 2, double right_budget_max_factor = 1.0);

  // grey: CV_8UC1 tracked image; exclude: empty or CV_8UC1, non-zero pixels
  // get no keypoints. depth: CV_32F metres, 0 = no measurement.
  // initializing: while a monocular map is being initialised, init_feature_factor
  // times the features (mpIniORBextractor), for enough two-view matches.
  // count (optional): what the exclusion cost inside count->region (the
  // dynamic filter's mask) in the left / only image (OrbExtractor).
  std::shared_ptr<const map::Features> mono(const cv::Mat& grey, const cv::Mat& exclude, StageTimes& t,
                                            bool initializing = false, features::ExcludedCount* count = nullptr);
  std::shared_ptr<const map::Features> stereo(const cv::Mat& left, const cv::Mat& right,
                                              const cv::Mat& exclude, StageTimes& t,
                                              features::ExcludedCount* count = nullptr);
  std::shared_ptr<const map::Features> rgbd(const cv::Mat& grey, const cv::Mat& depth,
                                            const cv::Mat& exclude, StageTimes& t,
                                            features::ExcludedCount* count = nullptr);

  // The same with the mask from `exclude`, computed beside the detection:
  // the same features as with that mask given up front. Stage times:
  // "extract" is what the extraction adds after the mask is known (waiting
  // for the detection, then describing), "extract_overlapped" the detection's
  // own time on the worker.
  std::shared_ptr<const map::Features> mono(const cv::Mat& grey, const ExclusionSource& exclude, StageTimes& t,
                                            bool initializing = false, features::ExcludedCount* count = nullptr);
  std::shared_ptr<const map::Features> stereo(const cv::Mat& left, const cv::Mat& right,
                                              const ExclusionSource& exclude, StageTimes& t,
                                              features::ExcludedCount* count = nullptr);
  std::shared_ptr<const map::Features> rgbd(const cv::Mat& grey, const cv::Mat& depth,
                                            const ExclusionSource& exclude, StageTimes& t,
                                            features::ExcludedCount* count = nullptr);
  const std::shared_ptr<const map::Calibration>& calib() const { return calib_; }
  // The margin around excluded pixels (OrbExtractor::set_exclude_margin) of
  // the masked image (left / only; the right image is never masked).
  void set_exclude_margin(int level_px);

 private:
  std::shared_ptr<map::Features> extract(features::OrbExtractor& extractor, const cv::Mat& grey,
                                         const cv::Mat& exclude, StageTimes& t, features::ExcludedCount* count);
  std::shared_ptr<map::Features> extract(features::OrbExtractor& extractor, const cv::Mat& grey,
                                         const ExclusionSource& exclude, StageTimes& t,
                                         features::ExcludedCount* count);
  void finish(map::Features& f) const;  // undistortion and grid
  // Stereo matching against the right keypoints, then finish().
  void match_stereo(map::Features& f, const std::vector<cv::KeyPoint>& keys_r, const cv::Mat& desc_r,
                    StageTimes& t) const;
  void add_depth(map::Features& f, const cv::Mat& depth) const;  // RGB-D: finish(), then depth per keypoint
  int right_budget(const cv::Mat& exclude) const;

  std::shared_ptr<const map::Calibration> calib_;
  features::OrbExtractor left_, right_, init_;
  int n_features_;
  double right_budget_max_factor_;
  // The stereo right image's extraction (or description); for mono and
  // RGB-D half of the pyramid levels.
  HelperThread helper_;
};

}  // namespace dynaorb::tracking
