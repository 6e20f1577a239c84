// Shared motion cues: Harris (or FAST) corners tracked by pyramidal LK
// (DS-SLAM / STDyn-SLAM's optical-flow step) and the ego-motion from the points outside
// the movable-class regions (DM-SLAM Sec. 3.2.3).
#include "dynaorb/dynamic/motion_cues.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <future>
#include <sstream>
#include <string>
#include <utility>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "dynaorb/core/stopwatch.h"
#include "dynaorb/dynamic/corner_subpix.h"
#include "dynaorb/dynamic/harris_corners.h"
#include "dynaorb/io/errors.h"
#include "file_node_options.h"
#include "../core/option_checks.h"

#include "view_geometry.h"

namespace dynaorb::dynamic {

void MotionCueOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "detector", detector);
  read_option(node, "fast_threshold", fast_threshold);
  read_option(node, "candidate_fast_threshold", candidate_fast_threshold);
  read_option(node, "max_corners", max_corners);
  read_option(node, "quality_level", quality_level);
  read_option(node, "min_distance", min_distance);
  read_option(node, "block_size", block_size);
  read_option(node, "use_harris", use_harris);
  read_option(node, "harris_k", harris_k);
  read_option(node, "max_background_corners", max_background_corners);
  read_option(node, "max_candidate_corners", max_candidate_corners);
  read_option(node, "candidate_quality_level", candidate_quality_level);
  read_option(node, "subpix_window", subpix_window);
  read_option(node, "lk_window", lk_window);
  read_option(node, "lk_levels", lk_levels);
  read_option(node, "lk_max_iterations", lk_max_iterations);
  read_option(node, "lk_epsilon", lk_epsilon);
  read_option(node, "forward_backward_max", forward_backward_max);
  read_option(node, "stereo_depth_forward_backward_max", stereo_depth_forward_backward_max);
  read_option(node, "border", border);
  read_option(node, "depth_edge_radius", depth_edge_radius);
  read_option(node, "depth_edge_max_ratio", depth_edge_max_ratio);
  read_option(node, "ransac_reprojection_px", ransac_reprojection_px);
  read_option(node, "ransac_confidence", ransac_confidence);
  read_option(node, "ransac_iterations", ransac_iterations);
  read_option(node, "min_ego_points", min_ego_points);
}

namespace {

bool is_grey(const cv::Mat& m) { return !m.empty() && m.type() == CV_8UC1; }

bool finite(const cv::Point2f& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

bool away_from_edge(const cv::Point2f& p, const cv::Size& size, int border) {
  return finite(p) && p.x >= border && p.y >= border && p.x <= size.width - 1 - border &&
         p.y <= size.height - 1 - border;
}

using view::mask_at;

bool valid_depth(float z) { return std::isfinite(z) && z > 0.f; }

// Nearest-pixel depth: interpolating across a depth edge would invent a
// surface between foreground and background. A corner on a depth edge (an
// object's silhouette against what lies behind it) has no single depth, and
// what LK follows there is a T-junction, not a point: no depth for it.
float depth_at(const cv::Mat& depth, const cv::Point2f& p, const MotionCueOptions& o) {
  const int x = cvRound(p.x), y = cvRound(p.y);
  if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return 0.f;
  const float z = depth.at<float>(y, x);
  if (!valid_depth(z)) return 0.f;
  if (o.depth_edge_radius > 0 && o.depth_edge_max_ratio > 0) {
    const int r = o.depth_edge_radius;
    float lo = z, hi = z;
    for (int yy = std::max(0, y - r); yy <= std::min(depth.rows - 1, y + r); ++yy) {
      const float* row = depth.ptr<float>(yy);
      for (int xx = std::max(0, x - r); xx <= std::min(depth.cols - 1, x + r); ++xx)
        if (valid_depth(row[xx])) {
          lo = std::min(lo, row[xx]);
          hi = std::max(hi, row[xx]);
        }
    }
    if (hi - lo > o.depth_edge_max_ratio * z) return 0.f;
  }
  return z;
}

// DS-SLAM's cornerSubPix (half window, 20 steps, 0.03 px), corner by corner:
// chunks of corners on the worker threads give what one call over all of them
// gives.
void refine_corners(const cv::Mat& grey, std::vector<cv::Point2f>& corners, int half_window) {
  const int n = static_cast<int>(corners.size());
  constexpr int kChunk = 64;
  cv::parallel_for_(cv::Range(0, (n + kChunk - 1) / kChunk), [&](const cv::Range& r) {
    const int begin = r.start * kChunk, end = std::min(n, r.end * kChunk);
    std::vector<cv::Point2f> part(corners.begin() + begin, corners.begin() + end);
    refine_corners_subpix(grey, part, half_window, 20, 0.03);
    std::copy(part.begin(), part.end(), corners.begin() + begin);
  });
}

// At most `budget` of the corners on one side of `candidates` (outside, or
// inside with `inside`), spread over the image: a grid of about `budget`
// square cells over the side's bounding box; each round takes the next
// strongest corner of every cell (the detections return them strongest
// first) until the budget is spent. The corners on the other side all stay.
// The order of the input is kept.
std::vector<cv::Point2f> within_budget(const std::vector<cv::Point2f>& corners, const cv::Mat& candidates,
                                       const cv::Size& size, int budget, bool inside) {
  const bool have_mask = candidates.type() == CV_8UC1 && candidates.size() == size;
  if (inside && !have_mask) return corners;  // no candidates: nothing inside
  std::vector<size_t> side;
  for (size_t i = 0; i < corners.size(); ++i)
    if ((have_mask && mask_at(candidates, corners[i])) == inside) side.push_back(i);
  if (budget <= 0 || static_cast<int>(side.size()) <= budget) return corners;
  cv::Rect2f box(0, 0, static_cast<float>(size.width), static_cast<float>(size.height));
  if (inside) {
    std::vector<cv::Point2f> pts;
    for (size_t i : side) pts.push_back(corners[i]);
    box = cv::boundingRect(pts);
    box.width = std::max(box.width, 1.f);
    box.height = std::max(box.height, 1.f);
  }
  const double cell = std::max(1.0, std::sqrt(static_cast<double>(box.area()) / budget));
  const int cols = std::max(1, static_cast<int>(std::ceil(box.width / cell)));
  const int rows = std::max(1, static_cast<int>(std::ceil(box.height / cell)));
  std::vector<std::vector<size_t>> cells(static_cast<size_t>(cols) * rows);
  for (size_t i : side) {
    const int cx = std::clamp(static_cast<int>((corners[i].x - box.x) / cell), 0, cols - 1);
    const int cy = std::clamp(static_cast<int>((corners[i].y - box.y) / cell), 0, rows - 1);
    cells[static_cast<size_t>(cy) * cols + cx].push_back(i);
  }
  std::vector<unsigned char> keep(corners.size(), 1);
  for (size_t i : side) keep[i] = 0;
  int left = budget;
  for (size_t round = 0; left > 0; ++round) {
    bool any = false;
    for (const auto& c : cells) {
      if (round >= c.size()) continue;
      any = true;
      keep[c[round]] = 1;
      if (--left == 0) break;
    }
    if (!any) break;
  }
  std::vector<cv::Point2f> out;
  for (size_t i = 0; i < corners.size(); ++i)
    if (keep[i]) out.push_back(corners[i]);
  return out;
}

// cornerSubPix can pull neighbouring corners onto the same point; a point
// counted twice would count twice in every vote downstream.
std::vector<cv::Point2f> without_duplicates(const std::vector<cv::Point2f>& corners, double min_gap) {
  std::vector<cv::Point2f> out;
  out.reserve(corners.size());
  const double gap2 = min_gap * min_gap;
  for (const auto& c : corners) {
    bool dup = false;
    for (const auto& k : out) {
      const cv::Point2f d = c - k;
      if (d.x * d.x + d.y * d.y < gap2) {
        dup = true;
        break;
      }
    }
    if (!dup) out.push_back(c);
  }
  return out;
}

struct Flow {
  std::vector<cv::Point2f> to;
  std::vector<unsigned char> ok;  // found (and tracked back within fb_max, when checked)
};

int lk_window(const MotionCueOptions& o) { return std::max(o.lk_window, 3); }
int lk_levels(const MotionCueOptions& o) { return std::max(o.lk_levels, 0); }

// The LK pyramid of an image with its derivatives: what calcOpticalFlowPyrLK
// builds from the image on every call, built once for the calls that share it.
// LK reads the derivatives of the image it tracks from only: the right image
// of a stereo pair, tracked into and (with the depths' backward check) back
// from, gets them only for that check (right_pyramid; the same tracks
// either way, without a Scharr pass and its buffers per level when unused).
std::vector<cv::Mat> lk_pyramid(const cv::Mat& image, const MotionCueOptions& o, bool with_derivatives = true) {
  std::vector<cv::Mat> pyramid;
  const int w = lk_window(o);
  cv::buildOpticalFlowPyramid(image, pyramid, cv::Size(w, w), lk_levels(o), with_derivatives);
  return pyramid;
}

std::vector<cv::Mat> right_pyramid(const cv::Mat& right, const MotionCueOptions& o) {
  return lk_pyramid(right, o, o.stereo_depth_forward_backward_max > 0);
}

// Whether the cache holds the LK pyramid of `image` (the same buffer) built
// with o's window and levels.
bool holds_pyramid_of(const MotionCueCache& cache, const cv::Mat& image, const MotionCueOptions& o) {
  return !cache.image.empty() && cache.image.data == image.data && cache.image.size() == image.size() &&
         cache.window == lk_window(o) && cache.levels == lk_levels(o);
}

// LK from `a` into `b` and back (pyramids of lk_pyramid); a point is kept
// only when the backward track returns to within fb_max px of where it
// started (fb_max <= 0: not tracked back, kept when found). keep (optional):
// the caller's own test of where point i lands; a point that fails it is
// not tracked back and not kept.
Flow track_forward_backward(const std::vector<cv::Mat>& a, const std::vector<cv::Mat>& b,
                            const std::vector<cv::Point2f>& from, const MotionCueOptions& o, double fb_max,
                            const std::function<bool(size_t, const cv::Point2f&)>& keep = {}) {
  Flow f;
  f.ok.assign(from.size(), 0);
  if (from.empty()) return f;
  const int win = lk_window(o);
  const int levels = lk_levels(o);
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, std::max(o.lk_max_iterations, 1),
                              std::max(o.lk_epsilon, 0.0));
  std::vector<unsigned char> st_f, st_b;
  cv::calcOpticalFlowPyrLK(a, b, from, f.to, st_f, cv::noArray(), cv::Size(win, win), levels, crit);
  // Back only from the points the forward pass found (LK tracks each point
  // on its own: the same answer as tracking all of them back).
  std::vector<size_t> found;
  std::vector<cv::Point2f> there, back;
  for (size_t i = 0; i < from.size(); ++i)
    if (st_f[i] && finite(f.to[i]) && (!keep || keep(i, f.to[i]))) {
      found.push_back(i);
      there.push_back(f.to[i]);
    }
  if (found.empty()) return f;
  if (!(fb_max > 0)) {  // no backward check (DS-SLAM's code has none)
    for (size_t i : found) f.ok[i] = 1;
    return f;
  }
  cv::calcOpticalFlowPyrLK(b, a, there, back, st_b, cv::noArray(), cv::Size(win, win), levels, crit);
  const double fb2 = fb_max * fb_max;
  for (size_t k = 0; k < found.size(); ++k) {
    if (!st_b[k] || !finite(back[k])) continue;
    const cv::Point2f d = back[k] - from[found[k]];
    f.ok[found[k]] = d.x * d.x + d.y * d.y <= fb2;
  }
  return f;
}

std::vector<cv::Point2f> undistorted(const std::vector<cv::Point2f>& px, const map::Calibration& c) {
  if (c.dist.empty() || px.empty()) return px;
  std::vector<cv::Point2f> out;
  const cv::Matx33d K = view::camera_matrix(c);
  cv::undistortPoints(px, out, K, c.dist, cv::noArray(), K);
  return out;
}

// OpenCV's rotation vector and translation as an isometry.
// The points the pose T_cur_prev explains: in front of the camera and
// reprojected within `threshold` px (a pose is checked by what it explains,
// not by what the solver reports). None for a non-finite pose.
std::vector<int> pnp_inliers(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
                             const map::Calibration& calib, const Eigen::Isometry3d& T, double threshold) {
  std::vector<int> inliers;
  if (!T.matrix().allFinite()) return inliers;
  const double t2 = threshold * threshold;
  for (size_t k = 0; k < object.size(); ++k) {
    const Eigen::Vector3d X = T * Eigen::Vector3d(object[k].x, object[k].y, object[k].z);
    if (!(X.z() > 1e-6)) continue;
    if ((calib.project(X) - Eigen::Vector2d(image[k].x, image[k].y)).squaredNorm() <= t2)
      inliers.push_back(static_cast<int>(k));
  }
  return inliers;
}

// The strongest of `points` at least min_distance apart, at most max_count,
// picked as goodFeaturesToTrack picks its corners: the strongest first (ties
// in raster order), a point closer than min_distance to one already taken is
// skipped; the checks go through a grid of min_distance cells.
std::vector<cv::Point2f> strongest_apart(std::vector<cv::KeyPoint> points, const cv::Size& size, int max_count,
                                         double min_distance) {
  std::sort(points.begin(), points.end(), [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    if (a.response != b.response) return a.response > b.response;
    return a.pt.y != b.pt.y ? a.pt.y < b.pt.y : a.pt.x < b.pt.x;
  });
  std::vector<cv::Point2f> out;
  const int cell = std::max(1, cvRound(min_distance));
  const int cols = (size.width + cell - 1) / cell, rows = (size.height + cell - 1) / cell;
  std::vector<std::vector<cv::Point2f>> grid(static_cast<size_t>(cols) * rows);
  const double d2 = min_distance * min_distance;
  for (const cv::KeyPoint& k : points) {
    if (static_cast<int>(out.size()) >= max_count) break;
    const cv::Point2f p = k.pt;
    const int cx = std::clamp(static_cast<int>(p.x) / cell, 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y) / cell, 0, rows - 1);
    bool good = true;
    for (int y = std::max(0, cy - 1); good && y <= std::min(rows - 1, cy + 1); ++y)
      for (int x = std::max(0, cx - 1); good && x <= std::min(cols - 1, cx + 1); ++x)
        for (const cv::Point2f& q : grid[static_cast<size_t>(y) * cols + x]) {
          const float dx = p.x - q.x, dy = p.y - q.y;
          if (dx * dx + dy * dy < d2) {
            good = false;
            break;
          }
        }
    if (!good) continue;
    grid[static_cast<size_t>(cy) * cols + cx].push_back(p);
    out.push_back(p);
  }
  return out;
}

// FAST corners (non-maximum suppression) of `image` at `threshold` where
// `mask` is set, at least o.min_distance apart, the strongest first.
std::vector<cv::Point2f> fast_corners(const cv::Mat& image, const cv::Mat& mask, int threshold,
                                      const MotionCueOptions& o) {
  std::vector<cv::KeyPoint> points;
  cv::FAST(image, points, threshold, true);
  points.erase(std::remove_if(points.begin(), points.end(), [&](const cv::KeyPoint& k) { return !mask_at(mask, k.pt); }),
               points.end());
  return strongest_apart(std::move(points), image.size(), std::max(o.max_corners, 1), std::max(o.min_distance, 0.0));
}

}  // namespace

std::vector<cv::Point2f> detect_corners(const cv::Mat& grey, const MotionCueOptions& o, const cv::Mat& candidates) {
  std::vector<cv::Point2f> corners;
  const int border = std::max(o.border, 0);
  if (!is_grey(grey) || grey.cols <= 2 * border + 1 || grey.rows <= 2 * border + 1) return corners;
  // Corners only where they could survive the edge rejection, so the corner
  // budget is not spent on pairs that are dropped anyway.
  cv::Mat detect_mask(grey.size(), CV_8UC1, cv::Scalar(0));
  detect_mask(cv::Rect(border, border, grey.cols - 2 * border, grey.rows - 2 * border)).setTo(255);
  const double quality = std::clamp(o.quality_level, 1e-6, 1.0);
  const bool fast = o.detector == "fast";
  // q: the Harris quality level, or the FAST threshold.
  auto detect = [&](const cv::Mat& image, const cv::Mat& mask, double q, std::vector<cv::Point2f>& out) {
    if (fast) out = fast_corners(image, mask, static_cast<int>(q), o);
    else if (o.use_harris)  // goodFeaturesToTrack's Harris corners in a third of the time (harris_corners.h)
      out = harris_corners(image, std::max(o.max_corners, 1), q, std::max(o.min_distance, 0.0), mask,
                           std::max(o.block_size, 1), o.harris_k);
    else
      cv::goodFeaturesToTrack(image, out, std::max(o.max_corners, 1), q, std::max(o.min_distance, 0.0), mask,
                              std::max(o.block_size, 1), false);
  };
  detect(grey, detect_mask, fast ? o.fast_threshold : quality, corners);
  const bool have_candidates = candidates.type() == CV_8UC1 && candidates.size() == grey.size();
  const bool own = fast ? o.candidate_fast_threshold < o.fast_threshold
                        : o.candidate_quality_level > 0 && o.candidate_quality_level < quality;
  if (have_candidates && own) {
    // The candidates' corners come from their own detection.
    const cv::Mat inside = (candidates != 0) & detect_mask;
    const cv::Rect box = cv::boundingRect(inside);
    if (box.area() > 0) {
      corners.erase(std::remove_if(corners.begin(), corners.end(),
                                   [&](const cv::Point2f& p) { return mask_at(candidates, p); }),
                    corners.end());
      std::vector<cv::Point2f> inner;
      detect(grey(box), inside(box), fast ? o.candidate_fast_threshold : o.candidate_quality_level, inner);
      const cv::Point2f origin(static_cast<float>(box.x), static_cast<float>(box.y));
      for (const cv::Point2f& p : inner) corners.push_back(p + origin);
    }
  }
  corners = within_budget(corners, candidates, grey.size(), o.max_background_corners, /*inside=*/false);
  corners = within_budget(corners, candidates, grey.size(), o.max_candidate_corners, /*inside=*/true);
  if (!corners.empty() && o.subpix_window > 0) {
    refine_corners(grey, corners, o.subpix_window);
    corners = without_duplicates(corners, std::max(1.0, o.min_distance / 2));
  }
  return corners;
}

std::vector<float> stereo_depths(const std::vector<cv::Mat>& left_pyramid, const std::vector<cv::Mat>& right_pyramid,
                                 const std::vector<cv::Point2f>& points, double bf, const MotionCueOptions& o) {
  std::vector<float> depth(points.size(), 0.f);
  // Rectified pair: the match lies on the same row, left of the corner.
  const auto on_row = [&](size_t i, const cv::Point2f& r) {
    return std::abs(r.y - points[i].y) <= 1.0 && points[i].x - r.x > 0;
  };
  const Flow stereo = track_forward_backward(left_pyramid, right_pyramid, points, o,
                                             o.stereo_depth_forward_backward_max, on_row);
  for (size_t i = 0; i < points.size(); ++i) {
    if (!stereo.ok[i]) continue;
    const cv::Point2f& r = stereo.to[i];
    const double disparity = points[i].x - r.x;
    if (std::abs(r.y - points[i].y) > 1.0 || !(disparity > 0)) continue;
    depth[i] = static_cast<float>(bf / disparity);
  }
  return depth;
}

namespace {

// A depth image (RGB-D, or a stage's stereo depth) the corners' depth is read from.
bool has_depth_image(const FrameData& f) {
  return !f.depth.empty() && f.depth.type() == CV_32FC1 && f.depth.size() == f.grey.size();
}

// What track_points does for stereo depth: a rectified right image and no
// depth image.
bool wants_stereo_depth(const FrameData& f, const map::Calibration& calib, Sensor sensor) {
  return !has_depth_image(f) && sensor == Sensor::kStereo && is_grey(f.right) && f.right.size() == f.grey.size() &&
         calib.bf > 0;
}

}  // namespace

void MotionCueOptions::validate() const {
  const dynaorb::detail::OptionChecks c("Dynamic.motion_cues");
  if (detector != "harris" && detector != "fast") c.fail("detector", detector, "harris or fast");
  c.between("fast_threshold", fast_threshold, 0, 255, false);  // FAST's intensity difference
  c.between("candidate_fast_threshold", candidate_fast_threshold, 0, 255, false);
  c.at_least("max_corners", max_corners, 1);
  c.between("quality_level", quality_level, 0, 1, true);
  if (!(min_distance >= 0)) c.fail("min_distance", min_distance, ">= 0");  // a double: NaN and -0.5 refused
  c.at_least("block_size", block_size, 1);
  if (use_harris) c.between("harris_k", harris_k, 0, 1, false);
  c.at_least("max_background_corners", max_background_corners, 0);
  c.at_least("max_candidate_corners", max_candidate_corners, 0);
  if (std::isnan(candidate_quality_level) || candidate_quality_level >= quality_level)
    c.fail("candidate_quality_level", candidate_quality_level, "in (0, quality_level) to be used, or <= 0 (off)");
  c.at_least("subpix_window", subpix_window, 0);
  c.at_least("lk_window", lk_window, 3);
  c.at_least("lk_levels", lk_levels, 0);
  c.at_least("lk_max_iterations", lk_max_iterations, 1);
  c.positive("lk_epsilon", lk_epsilon);
  for (const auto& [key, value] : {std::pair<const char*, double>{"forward_backward_max", forward_backward_max},
                                   {"stereo_depth_forward_backward_max", stereo_depth_forward_backward_max}})
    if (std::isnan(value)) c.fail(key, value, "a number of pixels (<= 0: no backward check)");
  c.at_least("border", border, 0);
  c.at_least("depth_edge_radius", depth_edge_radius, 0);
  if (!(depth_edge_max_ratio >= 0) || std::isinf(depth_edge_max_ratio))
    c.fail("depth_edge_max_ratio", depth_edge_max_ratio, "a finite ratio >= 0 (0: no depth-edge check)");
  if (!(ransac_reprojection_px > 0) || std::isinf(ransac_reprojection_px))
    c.fail("ransac_reprojection_px", ransac_reprojection_px, "a finite number of pixels > 0");
  c.between("ransac_confidence", ransac_confidence, 0, 1, false);
  c.at_least("ransac_iterations", ransac_iterations, 1);
  if (!(min_ego_points >= 8)) c.fail("min_ego_points", min_ego_points, ">= 8 (the fundamental matrix's 8 points)");
}

void detect_corners_ahead(const FrameData& frame, const map::Calibration& calib, Sensor sensor,
                          const MotionCueOptions& o, MotionCueCache& cache) {
  cache.corners_image = std::move(cache.next_corners_image);
  cache.corners = std::move(cache.next_corners);
  const cv::Mat grey = frame.grey;
  const cv::Mat candidates = frame.candidates;  // shares the buffer: the semantic stage makes a new one per frame
  const cv::Mat right = wants_stereo_depth(frame, calib, sensor) ? frame.right : cv::Mat();
  const double bf = calib.bf;
  cache.next_corners_image = grey;
  // The frame's own track_points call (when it ran first) left its LK
  // pyramid in the cache: the stereo depths start from it instead of
  // building it again. Only read from here on, by both threads.
  std::vector<cv::Mat> left_pyramid;
  if (!right.empty() && holds_pyramid_of(cache, grey, o)) left_pyramid = cache.pyramid;
  // The job owns copies of what it reads (cv::Mat headers share the buffers).
  auto task = std::make_shared<std::packaged_task<AheadCorners()>>([grey, candidates, right, left_pyramid, bf, o] {
    AheadCorners a;
    auto t0 = Clock::now();
    a.corners = detect_corners(grey, o, candidates);
    a.corners_ms = ms_since(t0);
    if (!right.empty() && !a.corners.empty()) {
      t0 = Clock::now();
      a.right_depth = stereo_depths(left_pyramid.empty() ? lk_pyramid(grey, o) : left_pyramid, right_pyramid(right, o),
                                    a.corners, bf, o);
      a.stereo_ms = ms_since(t0);
    }
    return a;
  });
  cache.next_corners = task->get_future().share();
  cache.ahead->post([task] { (*task)(); });  // what it throws reaches next_corners
}

std::vector<TrackedPoint> track_points(const FrameData& prev, const FrameData& cur,
                                       const map::Calibration& calib, Sensor sensor,
                                       const MotionCueOptions& o, MotionCueCache* cache) {
  std::vector<TrackedPoint> out;
  if (cache) cache->ms.clear();
  if (!is_grey(prev.grey) || !is_grey(cur.grey) || prev.grey.size() != cur.grey.size()) return out;
  const cv::Size size = prev.grey.size();
  const int border = std::max(o.border, 0);
  if (size.width <= 2 * border + 1 || size.height <= 2 * border + 1) return out;

  try {
    auto t0 = Clock::now();
    // The previous image's corners are in the cache's current slot, or in its
    // next one when this image's own have not been posted yet.
    const auto slot = [&](const cv::Mat& image, const std::shared_future<AheadCorners>& f) {
      return f.valid() && image.data == prev.grey.data && image.size() == size;
    };
    const std::shared_future<AheadCorners>* found =
        !cache ? nullptr
        : slot(cache->corners_image, cache->corners)           ? &cache->corners
        : slot(cache->next_corners_image, cache->next_corners) ? &cache->next_corners
                                                                : nullptr;
    const bool ahead = found != nullptr;
    AheadCorners detected;
    if (ahead) detected = found->get();
    else detected.corners = detect_corners(prev.grey, o, prev.candidates);
    const std::vector<cv::Point2f>& corners = detected.corners;
    if (corners.empty()) return out;
    if (cache) {
      cache->ms["corners"] = ms_since(t0);
      if (ahead) cache->ms["corners_ahead"] = detected.corners_ms;
    }

    t0 = Clock::now();
    const std::vector<cv::Mat> prev_pyramid =
        cache && holds_pyramid_of(*cache, prev.grey, o) ? cache->pyramid : lk_pyramid(prev.grey, o);
    std::vector<cv::Mat> cur_pyramid = lk_pyramid(cur.grey, o);
    if (cache) {
      cache->image = cur.grey;
      cache->pyramid = cur_pyramid;
      cache->window = lk_window(o);
      cache->levels = lk_levels(o);
      cache->ms["pyramids"] = ms_since(t0);
    }

    t0 = Clock::now();
    const auto inside = [&](size_t, const cv::Point2f& p) { return away_from_edge(p, size, border); };
    const Flow flow = track_forward_backward(prev_pyramid, cur_pyramid, corners, o, o.forward_backward_max, inside);
    std::vector<cv::Point2f> kept_prev, kept_cur;
    std::vector<size_t> kept_corner;
    for (size_t i = 0; i < corners.size(); ++i) {
      if (!flow.ok[i]) continue;
      if (!away_from_edge(corners[i], size, border) || !away_from_edge(flow.to[i], size, border)) continue;
      kept_prev.push_back(corners[i]);
      kept_cur.push_back(flow.to[i]);
      kept_corner.push_back(i);
    }
    if (cache) cache->ms["flow"] = ms_since(t0);
    out.resize(kept_prev.size());
    for (size_t i = 0; i < out.size(); ++i) {
      out[i].prev = kept_prev[i];
      out[i].cur = kept_cur[i];
      out[i].in_candidate = mask_at(prev.candidates, kept_prev[i]) || mask_at(cur.candidates, kept_cur[i]);
    }

    if (has_depth_image(prev)) {
      for (auto& p : out) p.prev_depth = depth_at(prev.depth, p.prev, o);
    } else if (wants_stereo_depth(prev, calib, sensor)) {
      if (detected.right_depth.size() == corners.size()) {
        // Found with the corners, ahead.
        for (size_t i = 0; i < out.size(); ++i) out[i].prev_depth = detected.right_depth[kept_corner[i]];
        if (cache) cache->ms["stereo_ahead"] = detected.stereo_ms;
      } else {
        t0 = Clock::now();
        const std::vector<float> depth = stereo_depths(prev_pyramid, right_pyramid(prev.right, o), kept_prev, calib.bf, o);
        if (cache) cache->ms["stereo"] = ms_since(t0);
        for (size_t i = 0; i < out.size(); ++i) out[i].prev_depth = depth[i];
      }
    }
  } catch (const cv::Exception&) {
    // OpenCV rejects what it cannot process (odd sizes, options out of range):
    // no cues for this frame rather than a crash.
    return {};
  }
  return out;
}

EgoMotion estimate_ego_motion(const std::vector<TrackedPoint>& points, const map::Calibration& calib,
                              Sensor sensor, const MotionCueOptions& o, bool with_F) {
  EgoMotion e;
  e.F = cv::Matx33d::zeros();
  e.inlier.assign(points.size(), 0);
  if (!(calib.fx > 0) || !(calib.fy > 0) || !std::isfinite(calib.cx) || !std::isfinite(calib.cy)) return e;

  // DM-SLAM Sec. 3.2.3: the points in the potentially dynamic regions are
  // assumed dynamic and left out of the ego-motion.
  std::vector<int> idx;
  std::vector<cv::Point2f> prev_px, cur_px;
  for (size_t i = 0; i < points.size(); ++i) {
    const TrackedPoint& p = points[i];
    if (p.in_candidate || !finite(p.prev) || !finite(p.cur)) continue;
    idx.push_back(static_cast<int>(i));
    prev_px.push_back(p.prev);
    cur_px.push_back(p.cur);
  }
  const int min_points = std::max(o.min_ego_points, 8);  // 8: the fundamental matrix needs them
  if (static_cast<int>(idx.size()) < min_points) return e;

  std::vector<unsigned char> pnp_inlier(points.size(), 0), f_inlier(points.size(), 0);
  bool pose_ok = false;
  int pose_inliers = 0, f_inliers = 0;
  try {
    const std::vector<cv::Point2f> prev_u = undistorted(prev_px, calib);
    const std::vector<cv::Point2f> cur_u = undistorted(cur_px, calib);

    if (sensor != Sensor::kMono) {
      std::vector<cv::Point3f> object;
      std::vector<cv::Point2f> image;
      std::vector<int> which;
      for (size_t k = 0; k < idx.size(); ++k) {
        const float z = points[idx[k]].prev_depth;
        if (!std::isfinite(z) || z <= 0.f) continue;
        const Eigen::Vector3d X = calib.unproject(prev_u[k].x, prev_u[k].y, z);
        object.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()), static_cast<float>(X.z()));
        image.push_back(cur_u[k]);
        which.push_back(idx[k]);
      }
      if (static_cast<int>(object.size()) >= min_points) {
        std::vector<int> inl;
        const float threshold = static_cast<float>(o.ransac_reprojection_px);
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        const bool ok = view::pnp_ransac_refined(object, image, calib, std::max(o.ransac_iterations, 1), threshold,
                                                 std::clamp(o.ransac_confidence, 0.0, 1.0), min_points, inl, T);
        if (ok) inl = pnp_inliers(object, image, calib, T, threshold);
        if (ok && static_cast<int>(inl.size()) >= min_points) {
          e.T_cur_prev = T;
          for (int k : inl) pnp_inlier[which[k]] = 1;
          pose_inliers = static_cast<int>(inl.size());
          pose_ok = true;
        }
      }
    }

    // USAC_ACCURATE (GC-RANSAC with local optimisation) rather than plain
    // FM_RANSAC: on rendered views with the movable regions left out, FM_RANSAC's
    // F was off by 1.4 px (90th percentile of true correspondences) in the
    // image areas the static points do not cover, and the epipolar test of
    // DM-SLAM's monocular case then flagged a parked car; USAC's was off by 0.1 px.
    std::vector<unsigned char> mask;
    const cv::Mat F = with_F || sensor == Sensor::kMono
                          ? cv::findFundamentalMat(prev_u, cur_u, cv::USAC_ACCURATE, o.ransac_reprojection_px,
                                                   std::clamp(o.ransac_confidence, 0.0, 1.0),
                                                   std::max(o.ransac_iterations, 1), mask)
                          : cv::Mat();
    // The 7-point fallback can return up to three stacked solutions: only a
    // single 3x3 answer is an estimate.
    if (F.rows == 3 && F.cols == 3 && cv::checkRange(F) && mask.size() == idx.size()) {
      for (size_t k = 0; k < idx.size(); ++k)
        if (mask[k]) {
          f_inlier[idx[k]] = 1;
          ++f_inliers;
        }
      if (f_inliers >= min_points) {
        cv::Mat F64;
        F.convertTo(F64, CV_64F);
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) e.F(r, c) = F64.at<double>(r, c);
        e.has_F = true;
      }
    }
  } catch (const cv::Exception&) {
    // A RANSAC that OpenCV refuses (degenerate configuration) is no estimate.
  }

  if (sensor == Sensor::kMono) {
    e.valid = e.has_F;
    if (e.valid) {
      e.inlier = f_inlier;
      e.inliers = f_inliers;
    }
  } else {
    e.valid = pose_ok;
    if (e.valid) {
      e.inlier = pnp_inlier;
      e.inliers = pose_inliers;
    }
  }
  if (!e.has_F) e.F = cv::Matx33d::zeros();
  return e;
}

}  // namespace dynaorb::dynamic
