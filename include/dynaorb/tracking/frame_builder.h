#pragma once
// Turns images into Features: ORB extraction (left and right in parallel for
// stereo, the right image on a HelperThread; for mono and RGB-D the pyramid
// levels split between the calling thread and the HelperThread), keypoint undistortion, stereo
// matching along rectified rows or the RGB-D virtual right coordinate from
// depth, and the search grid.
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
