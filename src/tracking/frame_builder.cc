#include "dynaorb/tracking/frame_builder.h"

#include <algorithm>
#include <cmath>
#include <chrono>
#include <atomic>
#include <future>
#include <thread>
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
  // The pyramid levels shared between this thread and the helper (idle for
  // mono and RGB-D, which have no right image), the largest first: the same
  // features as one OrbExtractor::extract call.
  features::OrbDetection d = extractor.start(grey);
  const cv::Mat* region = count ? &count->region : nullptr;
  helper_.share(extractor.n_levels(), [&](int level) {
    extractor.detect_level(d, level);
    extractor.describe_level(d, level, exclude, region);
  });
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
  // The two images' pyramids, then their levels (left and right alternately,
  // the largest first), shared between this thread and the helper: the same
  // features as one OrbExtractor::extract call per image.
  right_.set_n_features(right_budget(exclude));
  const auto t0 = Clock::now();
  features::OrbDetection dl, dr;
  helper_.share(2, [&](int i) {
    if (i == 0) dl = left_.start(left);
    else dr = right_.start(right);
  });
  const cv::Mat* region = count ? &count->region : nullptr;
  helper_.share(2 * left_.n_levels(), [&](int k) {
    const int level = k / 2;
    if (k % 2 == 0) {
      left_.detect_level(dl, level);
      left_.describe_level(dl, level, exclude, region);
    } else {
      right_.detect_level(dr, level);
      right_.describe_level(dr, level, cv::Mat());
    }
  });
  left_.finish(std::move(dl), f->keys, f->descriptors, count);
  right_.finish(std::move(dr), keys_r, desc_r);
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
  // Both images' detection (their pyramids, then their levels, the right
  // image's first, the largest first) starts on the helper thread while this
  // one computes the mask, and this one joins it once the mask is there;
  // then the levels' description (the right image's budget set by the mask)
  // is shared the same way. The caller never waits for the helper to start
  // (HelperThread::share_async). Before, the helper had the right image's
  // detection and description, this thread the left ones (unless the
  // helper began the left detection first). DynamicFilterOptions::
  // overlap_extraction has the measurements of the overlap itself.
  features::OrbDetection detected[2];  // right, left
  features::OrbExtractor* extractor[2] = {&right_, &left_};
  const cv::Mat* image[2] = {&right, &left};
  std::atomic<bool> started[2] = {false, false};
  const int levels = left_.n_levels();
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<double> helper_ms{0.0};
  {
    HelperThread::Shared detection = helper_.share_async(2 + 2 * levels, [&](int k) {
      const auto tk = Clock::now();
      if (k < 2) {
        try {
          detected[k] = extractor[k]->start(*image[k]);
        } catch (...) {
          started[k] = true;  // nothing to detect on: its levels end at once, this is rethrown
          throw;
        }
        started[k] = true;
      } else {
        const int which = k % 2, level = (k - 2) / 2;
        while (!started[which]) {
        }  // its pyramid, claimed before: being built or done
        if (detected[which].pyramid.empty()) return;
        extractor[which]->detect_level(detected[which], level);
      }
      if (std::this_thread::get_id() != caller) helper_ms = helper_ms + ms_since(tk);  // one helper: no race
    });
    const cv::Mat mask = exclude();
    const auto t1 = Clock::now();
    detection.join();
    right_.set_n_features(right_budget(mask));
    const cv::Mat* region = count ? &count->region : nullptr;
    helper_.share(2 * levels, [&](int k) {
      const int level = k / 2;
      if (k % 2 == 0) left_.describe_level(detected[1], level, mask, region);
      else right_.describe_level(detected[0], level, cv::Mat());
    });
    left_.finish(std::move(detected[1]), f->keys, f->descriptors, count);
    right_.finish(std::move(detected[0]), keys_r, desc_r);
    t["extract"] = ms_since(t1);
  }
  t["extract_overlapped"] = helper_ms;  // the detection's time on the helper
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
