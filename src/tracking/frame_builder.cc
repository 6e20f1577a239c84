#include "dynaorb/tracking/frame_builder.h"

#include <algorithm>
#include <cmath>
#include <chrono>
#include <atomic>
#include <future>
#include <utility>
#include <opencv2/calib3d.hpp>

#include "dynaorb/features/stereo_matcher.h"
#include "dynaorb/core/stopwatch.h"

namespace dynaorb::tracking {

namespace {
ExtractorSettings scaled(ExtractorSettings s, int factor) {
  s.n_features *= std::max(factor, 1);
  return s;
}
}  // namespace

FrameBuilder::FrameBuilder(const Settings& settings, std::shared_ptr<const map::Calibration> calib,
                           int init_feature_factor, double right_budget_max_factor)
    : calib_(std::move(calib)), left_(settings.extractor), right_(settings.extractor),
      init_(scaled(settings.extractor, init_feature_factor)), n_features_(settings.extractor.n_features),
      right_budget_max_factor_(std::max(right_budget_max_factor, 1.0)) {}

void FrameBuilder::set_exclude_margin(int level_px) {
  left_.set_exclude_margin(level_px);
  init_.set_exclude_margin(level_px);
}

int FrameBuilder::right_budget(const cv::Mat& exclude) const {
  // The left budget goes to the pixels the mask leaves (OrbExtractor), so
  // there the left keypoints are 1 / (1 - m) times denser than without a
  // mask, while the right image, unmasked, spends a fraction m of its budget
  // on the excluded objects. Keeping the two densities equal on the rest of
  // the image keeps the share of left keypoints that find a right match.
  // A mask of the wrong type is refused by the left extraction, with its message.
  if (exclude.empty() || exclude.type() != CV_8UC1 || right_budget_max_factor_ <= 1.0) return n_features_;
  const double m = static_cast<double>(cv::countNonZero(exclude)) / static_cast<double>(exclude.total());
  const double factor = std::min(1.0 / std::max(1.0 - m, 1e-6), right_budget_max_factor_);
  return static_cast<int>(std::lround(n_features_ * factor));
}

std::shared_ptr<map::Features> FrameBuilder::extract(features::OrbExtractor& extractor,
                                                     const cv::Mat& grey, const cv::Mat& exclude,
                                                     StageTimes& t, features::ExcludedCount* count) {
  auto f = std::make_shared<map::Features>();
  f->calib = calib_;
  const auto t0 = Clock::now();
  // The pyramid levels split between this thread and the helper (idle for
  // mono and RGB-D, which have no right image): the same features as one
  // OrbExtractor::extract call.
  features::OrbDetection d = extractor.start(grey);
  const std::vector<std::vector<int>> groups = extractor.level_groups(2);
  const cv::Mat* region = count ? &count->region : nullptr;
  const auto levels = [&](const std::vector<int>& which) {
    for (int level : which) {
      extractor.detect_level(d, level);
      extractor.describe_level(d, level, exclude, region);
    }
  };
  HelperThread::Job other = helper_.submit([&] { levels(groups[1]); });
  levels(groups[0]);
  other.get();
  extractor.finish(std::move(d), f->keys, f->descriptors, count);
  t["extract"] = ms_since(t0);
  f->u_right.assign(f->keys.size(), -1.0f);
  f->depth.assign(f->keys.size(), -1.0f);
  return f;
}

std::shared_ptr<map::Features> FrameBuilder::extract(features::OrbExtractor& extractor,
                                                     const cv::Mat& grey, const ExclusionSource& exclude,
                                                     StageTimes& t, features::ExcludedCount* count) {
  auto f = std::make_shared<map::Features>();
  f->calib = calib_;
  double detect_ms = 0;
  // The detection on a thread of its own, placed by the scheduler: on the
  // HelperThread (helper_thread.h) RGB-D `full` measured 1.1-1.8 ms per frame
  // slower (2 vCPUs, the motion cues' worker busy beside it).
  auto detection = std::async(std::launch::async, [&extractor, &grey, &detect_ms] {
    const auto t0 = Clock::now();
    features::OrbDetection d = extractor.detect(grey);
    detect_ms = ms_since(t0);
    return d;
  });
  const cv::Mat mask = exclude();
  const auto t1 = Clock::now();
  extractor.describe(detection.get(), mask, f->keys, f->descriptors, count);
  t["extract"] = ms_since(t1);
  t["extract_overlapped"] = detect_ms;
  f->u_right.assign(f->keys.size(), -1.0f);
  f->depth.assign(f->keys.size(), -1.0f);
  return f;
}

void FrameBuilder::finish(map::Features& f) const {
  f.keys_un = f.keys;
  if (!calib_->dist.empty() && !f.keys.empty()) {
    std::vector<cv::Point2f> pts, un;
    pts.reserve(f.keys.size());
    for (const cv::KeyPoint& k : f.keys) pts.push_back(k.pt);
    cv::undistortPoints(pts, un, calib_->K, calib_->dist, cv::noArray(), calib_->K);
    for (size_t i = 0; i < un.size(); ++i) f.keys_un[i].pt = un[i];
  }
  f.build_grid();
}

std::shared_ptr<const map::Features> FrameBuilder::mono(const cv::Mat& grey, const cv::Mat& exclude,
                                                        StageTimes& t, bool initializing,
                                                        features::ExcludedCount* count) {
  auto f = extract(initializing ? init_ : left_, grey, exclude, t, count);
  finish(*f);
  return f;
}

std::shared_ptr<const map::Features> FrameBuilder::mono(const cv::Mat& grey, const ExclusionSource& exclude,
                                                        StageTimes& t, bool initializing,
                                                        features::ExcludedCount* count) {
  auto f = extract(initializing ? init_ : left_, grey, exclude, t, count);
  finish(*f);
  return f;
}

std::shared_ptr<const map::Features> FrameBuilder::stereo(const cv::Mat& left, const cv::Mat& right,
                                                          const cv::Mat& exclude, StageTimes& t,
                                                          features::ExcludedCount* count) {
  auto f = std::make_shared<map::Features>();
  f->calib = calib_;
  std::vector<cv::KeyPoint> keys_r;
  cv::Mat desc_r;
  // The right image is extracted on a second thread while this one does the left.
  right_.set_n_features(right_budget(exclude));
  const auto t0 = Clock::now();
  HelperThread::Job right_job = helper_.submit([&] { right_.extract(right, cv::Mat(), keys_r, desc_r); });
  left_.extract(left, exclude, f->keys, f->descriptors, count);
  right_job.get();
  t["extract"] = ms_since(t0);
  match_stereo(*f, keys_r, desc_r, t);
  return f;
}

std::shared_ptr<const map::Features> FrameBuilder::stereo(const cv::Mat& left, const cv::Mat& right,
                                                          const ExclusionSource& exclude, StageTimes& t,
                                                          features::ExcludedCount* count) {
  auto f = std::make_shared<map::Features>();
  f->calib = calib_;
  std::vector<cv::KeyPoint> keys_r;
  cv::Mat desc_r;
  // Both images' detection on the helper thread, the right image's first,
  // while this one computes the mask; then the helper describes the right
  // image (its budget set by the mask) while this thread describes the left
  // once its detection is done. On the persistent helper rather than a thread
  // of their own (std::async), which was slower than no overlap
  // (DynamicFilterOptions::overlap_extraction has the measurements).
  // A filter that ends before the helper has begun the left image (one with
  // nothing to decide on takes 0.3 ms) takes the left detection back, so the
  // two images are detected side by side as without the overlap (EuRoC V1
  // stereo `full`, left to the helper: 21.2 ms against 13.6 without the
  // overlap). The right description goes to the helper first.
  features::OrbDetection detected_left, detected_right;
  double right_ms = 0, left_ms = 0;
  std::atomic<bool> left_claimed{false};
  const auto detect_left = [&] {
    const auto t0 = Clock::now();
    detected_left = left_.detect(left);
    left_ms = ms_since(t0);
  };
  HelperThread::Job right_detect = helper_.submit([&] {
    const auto t0 = Clock::now();
    detected_right = right_.detect(right);
    right_ms = ms_since(t0);
  });
  HelperThread::Job left_detect = helper_.submit([&] {
    if (!left_claimed.exchange(true)) detect_left();
  });
  const cv::Mat mask = exclude();
  const auto t1 = Clock::now();
  const bool left_here = !left_claimed.exchange(true);
  right_.set_n_features(right_budget(mask));
  HelperThread::Job right_job =  // after the right detection, in the helper's order
      helper_.submit([&] { right_.describe(std::move(detected_right), cv::Mat(), keys_r, desc_r); });
  if (left_here) detect_left();
  else left_detect.get();
  left_.describe(std::move(detected_left), mask, f->keys, f->descriptors, count);
  right_detect.get();  // what the detections threw, as the description's
  right_job.get();
  t["extract"] = ms_since(t1);
  t["extract_overlapped"] = right_ms + (left_here ? 0.0 : left_ms);
  match_stereo(*f, keys_r, desc_r, t);
  return f;
}

void FrameBuilder::match_stereo(map::Features& f, const std::vector<cv::KeyPoint>& keys_r, const cv::Mat& desc_r,
                                StageTimes& t) const {
  const auto t1 = Clock::now();
  features::StereoMatchOptions opt;
  opt.bf = calib_->bf;
  opt.fx = calib_->fx;
  features::StereoMatches m = features::match_stereo(f.keys, f.descriptors, keys_r, desc_r, left_.pyramid(),
                                                     right_.pyramid(), left_.scale_factors(), opt);
  f.u_right = std::move(m.u_right);
  f.depth = std::move(m.depth);
  t["stereo_matching"] = ms_since(t1);
  finish(f);
}

std::shared_ptr<const map::Features> FrameBuilder::rgbd(const cv::Mat& grey, const cv::Mat& depth,
                                                        const cv::Mat& exclude, StageTimes& t,
                                                        features::ExcludedCount* count) {
  auto f = extract(left_, grey, exclude, t, count);
  add_depth(*f, depth);
  return f;
}

std::shared_ptr<const map::Features> FrameBuilder::rgbd(const cv::Mat& grey, const cv::Mat& depth,
                                                        const ExclusionSource& exclude, StageTimes& t,
                                                        features::ExcludedCount* count) {
  auto f = extract(left_, grey, exclude, t, count);
  add_depth(*f, depth);
  return f;
}

void FrameBuilder::add_depth(map::Features& f, const cv::Mat& depth) const {
  finish(f);
  // Depth at the detected (distorted) pixel; the virtual right coordinate
  // from the undistorted one (ORB-SLAM2's ComputeStereoFromRGBD).
  for (size_t i = 0; i < f.keys.size(); ++i) {
    const int u = cvRound(f.keys[i].pt.x), v = cvRound(f.keys[i].pt.y);
    if (u < 0 || v < 0 || u >= depth.cols || v >= depth.rows) continue;
    const float d = depth.at<float>(v, u);
    if (d > 0) {
      f.depth[i] = d;
      f.u_right[i] = static_cast<float>(f.keys_un[i].pt.x - calib_->bf / d);
    }
  }
}

}  // namespace dynaorb::tracking
