#pragma once
// ORB features as ORB-SLAM describes them: a scale pyramid, FAST per grid
// cell with the iniThFAST/minThFAST fallback, a quadtree that spreads the
// keypoints of each level over the image, orientation by intensity centroid
// and rotated BRIEF (OpenCV's learned 256-bit pattern, so descriptors are
// compatible with ORB-SLAM2 vocabularies).
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/io/settings.h"

namespace dynaorb::features {

// What an exclusion cost inside one of its parts (the dynamic filter's mask
// within the whole exclusion mask).
struct ExcludedCount {
  cv::Mat region;     // in: CV_8UC1 of the image size, non-zero = count here
  int corners = 0;    // out: FAST corners (all levels) dropped inside `region`
  // out: keypoints an extraction without the exclusion would have kept inside
  // `region`: per level where corners were dropped there, the quadtree also
  // distributes the level's corners as if nothing were excluded, and its
  // keypoints inside `region` are counted.
  int keypoints = 0;
};

// The part of an extraction that neither the exclusion mask nor the keypoint
// budget changes: the scale pyramid, each level's FAST corners (with the
// per-cell fallback) and the blurred levels the descriptors sample. Made by
// OrbExtractor::detect, which may run on another thread while the mask is
// being computed; OrbExtractor::describe finishes the extraction.
struct OrbDetection {
  std::vector<cv::Mat> pyramid;                    // level 0 = a copy of the image
  std::vector<cv::Mat> blurred;                    // 7x7 Gaussian, sigma 2, per level
  std::vector<std::vector<cv::KeyPoint>> corners;  // per level, in level pixels
  // What OrbExtractor::describe_level leaves per level for finish(): the
  // kept keypoints (level pixels, oriented), their descriptors, and what the
  // exclusion cost there (ExcludedCount's corners and keypoints).
  std::vector<std::vector<cv::KeyPoint>> kept;
  std::vector<cv::Mat> descriptors;
  std::vector<int> excluded_corners, excluded_keypoints;
};

class OrbExtractor {
 public:
  explicit OrbExtractor(const ExtractorSettings& settings);

  // image: CV_8UC1. exclude: empty or CV_8UC1 of the image size; keypoints at
  // non-zero pixels (or near them: set_exclude_margin) are dropped before the
  // quadtree distribution, so the feature budget goes to the rest of the
  // image. Keypoints come in level-0 pixel coordinates with octave = pyramid
  // level, angle in degrees, size = patch diameter at that level.
  // descriptors: N x 32 CV_8U. count (optional): what the exclusion cost
  // inside count->region.
  void extract(const cv::Mat& image, const cv::Mat& exclude, std::vector<cv::KeyPoint>& keypoints,
               cv::Mat& descriptors, ExcludedCount* count = nullptr);
  // extract() in two steps, with the same result: detect() reads only the
  // image and the pyramid settings (safe on any thread, beside set_n_features
  // and describe on this extractor); describe() applies the exclusion mask
  // and the budget in force when it is called.
  OrbDetection detect(const cv::Mat& image) const;
  void describe(OrbDetection&& detection, const cv::Mat& exclude, std::vector<cv::KeyPoint>& keypoints,
                cv::Mat& descriptors, ExcludedCount* count = nullptr);

  // extract() level by level, for a caller that spreads the levels over
  // threads: start() builds the pyramid; detect_level() then
  // describe_level() do one level (FAST, blur; exclusion, quadtree,
  // orientation, descriptors), and different levels may run on different
  // threads at once (each writes only its own level of the detection);
  // finish() gathers the levels in order. The same keypoints, descriptors
  // and count as extract(). count_region: ExcludedCount::region, or nullptr
  // for no count (as is a count whose region is not of the mask's size).
  OrbDetection start(const cv::Mat& image) const;
  void detect_level(OrbDetection& detection, int level) const;
  void describe_level(OrbDetection& detection, int level, const cv::Mat& exclude,
                      const cv::Mat* count_region = nullptr) const;
  void finish(OrbDetection&& detection, std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors,
              ExcludedCount* count = nullptr);

  // The keypoint budget of later extractions (nFeatures), spread over the
  // levels as at construction.
  void set_n_features(int n);

  // A corner is also dropped when an excluded pixel lies within `level_px`
  // pixels of it at its own level (a square of half-size ceil(level_px s^l)
  // level-0 pixels around its level-0 position): FAST decides on a circle of
  // radius 3 level pixels, so a corner just outside a mask, found on the
  // masked object's silhouette, moves with the object; at level 7 (s 1.2)
  // that circle spans 11 level-0 pixels. 0 (the default): only the corner's
  // own pixel is tested. std::invalid_argument below 0.
  void set_exclude_margin(int level_px);
  int exclude_margin() const { return exclude_margin_; }

  // The pyramid of the last extracted image (level 0 = the image itself).
  const std::vector<cv::Mat>& pyramid() const { return pyramid_; }

  int n_levels() const { return static_cast<int>(scale_.size()); }
  double scale_factor() const { return settings_.scale_factor; }
  const std::vector<float>& scale_factors() const { return scale_; }         // s^level
  const std::vector<float>& inv_scale_factors() const { return inv_scale_; }
  const std::vector<float>& level_sigma2() const { return sigma2_; }         // (s^level)^2
  const std::vector<float>& inv_level_sigma2() const { return inv_sigma2_; }

 private:
  // std::invalid_argument for a detection of another extractor's pyramid, a
  // level out of range (describe_level checks the exclusion mask's size).
  void check_detection(const OrbDetection& d) const;
  void check_level(const OrbDetection& d, int level) const;

  ExtractorSettings settings_;
  std::vector<float> scale_, inv_scale_, sigma2_, inv_sigma2_;
  std::vector<int> features_per_level_;
  std::vector<int> umax_;  // circular patch bounds for the intensity centroid
  int exclude_margin_ = 0;
  std::vector<cv::Mat> pyramid_;
};

}  // namespace dynaorb::features
