#include "dynaorb/dynamic/li_epipolar.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/video/tracking.hpp>

#include "../features/quadtree.h"
#include "dynaorb/core/stopwatch.h"
#include "view_geometry.h"

namespace dynaorb::dynamic {

namespace {

constexpr int kFastRadius = 3;  // FAST's Bresenham circle

bool finite(const cv::Point2f& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

bool inside(const cv::Point2f& p, const cv::Size& size, int border) {
  return finite(p) && p.x >= border && p.y >= border && p.x <= size.width - 1 - border &&
         p.y <= size.height - 1 - border;
}

}  // namespace

std::vector<cv::Point2f> li_quadtree_fast(const cv::Mat& grey, const LiOptions& o) {
  std::vector<cv::Point2f> out;
  if (grey.empty() || grey.type() != CV_8UC1) return out;
  const int b = std::max(o.border_px, kFastRadius);
  const int x0 = b, y0 = b, x1 = grey.cols - b, y1 = grey.rows - b;
  if (x1 - x0 < 8 || y1 - y0 < 8) return out;

  // Step 1: FAST in square regions, so that weakly textured squares still
  // contribute ("extract excess features from each square region"). One pass
  // over the whole area at fast_threshold gives every square's corners at
  // once; a square that got none is searched again at fast_min_threshold.
  std::vector<cv::KeyPoint> all, cell;
  const cv::Rect area(x0 - kFastRadius, y0 - kFastRadius, x1 - x0 + 2 * kFastRadius, y1 - y0 + 2 * kFastRadius);
  cv::FAST(grey(area), cell, o.fast_threshold, true);
  const int cell_px = o.fast_cell_px;
  const int ncx = (x1 - x0 + cell_px - 1) / cell_px, ncy = (y1 - y0 + cell_px - 1) / cell_px;
  std::vector<int> per_cell(static_cast<size_t>(ncx) * ncy, 0);
  for (cv::KeyPoint& k : cell) {
    k.pt.x += static_cast<float>(area.x);
    k.pt.y += static_cast<float>(area.y);
    if (k.pt.x < x0 || k.pt.y < y0 || k.pt.x >= x1 || k.pt.y >= y1) continue;
    ++per_cell[static_cast<int>((k.pt.y - y0) / cell_px) * ncx + static_cast<int>((k.pt.x - x0) / cell_px)];
    all.push_back(k);
  }
  if (o.fast_min_threshold < o.fast_threshold) {
    for (int j = 0; j < ncy; ++j) {
      for (int i = 0; i < ncx; ++i) {
        if (per_cell[j * ncx + i] > 0) continue;
        const int cx = x0 + i * cell_px, cy = y0 + j * cell_px;
        const int ex = std::min(cx + cell_px, x1), ey = std::min(cy + cell_px, y1);
        // The detector needs its circle around every candidate: pad the view.
        const cv::Rect view(cx - kFastRadius, cy - kFastRadius, ex - cx + 2 * kFastRadius,
                            ey - cy + 2 * kFastRadius);
        cv::FAST(grey(view), cell, o.fast_min_threshold, true);
        for (cv::KeyPoint& k : cell) {
          k.pt.x += static_cast<float>(view.x);
          k.pt.y += static_cast<float>(view.y);
          if (k.pt.x >= cx && k.pt.x < ex && k.pt.y >= cy && k.pt.y < ey) all.push_back(k);
        }
      }
    }
  }

  // Steps 2-4: the quadtree of ORB-SLAM, which the paper describes, keeps the
  // strongest corner of each of ~N non-empty nodes.
  thread_local features::detail::QuadtreeScratch scratch;
  std::vector<int> keep;
  features::detail::distribute_quadtree(all, static_cast<float>(x0), static_cast<float>(x1),
                                        static_cast<float>(y0), static_cast<float>(y1), o.n_points,
                                        scratch, keep);
  out.reserve(keep.size());
  for (int k : keep) out.push_back(all[k].pt);
  return out;
}

float li_disparity_at(const cv::Mat& disparity, const cv::Point2f& p, int radius) {
  if (disparity.empty() || disparity.type() != CV_32FC1 || !finite(p)) return 0.f;
  const int x = cvRound(p.x), y = cvRound(p.y);
  if (x < 0 || y < 0 || x >= disparity.cols || y >= disparity.rows) return 0.f;
  const float d = disparity.at<float>(y, x);
  if (d > 0.f) return d;
  std::vector<float> valid;
  for (int v = std::max(0, y - radius); v <= std::min(disparity.rows - 1, y + radius); ++v)
    for (int u = std::max(0, x - radius); u <= std::min(disparity.cols - 1, x + radius); ++u)
      if (disparity.at<float>(v, u) > 0.f) valid.push_back(disparity.at<float>(v, u));
  if (valid.empty()) return 0.f;
  std::nth_element(valid.begin(), valid.begin() + valid.size() / 2, valid.end());
  return valid[valid.size() / 2];
}

LiEpipolarResult li_epipolar_check(const cv::Mat& prev_grey, const cv::Mat& cur_grey,
                                   const cv::Mat& disparity, const map::Calibration& calib,
                                   const LiOptions& o, const cv::Mat& prev_dynamic) {
  LiEpipolarResult r;
  auto t0 = Clock::now();
  const std::vector<cv::Point2f> corners = li_quadtree_fast(prev_grey, o);
  r.corners = static_cast<int>(corners.size());
  r.corners_ms = ms_since(t0);

  t0 = Clock::now();
  std::vector<cv::Point2f> next;
  std::vector<unsigned char> status;
  std::vector<float> err;
  if (!corners.empty() && cur_grey.size() == prev_grey.size() && cur_grey.type() == CV_8UC1) {
    const cv::Size win(o.lk_window, o.lk_window);
    const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
    cv::calcOpticalFlowPyrLK(prev_grey, cur_grey, corners, next, status, err, win, o.lk_levels, crit);
    std::vector<unsigned char> back_ok(corners.size(), 1);
    if (o.lk_forward_backward_max > 0) {
      std::vector<cv::Point2f> back;
      std::vector<unsigned char> st_b;
      cv::calcOpticalFlowPyrLK(cur_grey, prev_grey, next, back, st_b, err, win, o.lk_levels, crit);
      for (size_t i = 0; i < corners.size(); ++i)
        back_ok[i] = st_b[i] && cv::norm(back[i] - corners[i]) <= o.lk_forward_backward_max;
    }
    for (size_t i = 0; i < corners.size(); ++i) {
      if (!status[i] || !back_ok[i] || !inside(next[i], cur_grey.size(), o.border_px)) continue;
      LiTrack t;
      t.prev = corners[i];
      t.cur = next[i];
      t.disparity = li_disparity_at(disparity, t.cur, o.disparity_patch_radius);
      r.tracks.push_back(t);
    }
  }
  r.flow_ms = ms_since(t0);

  t0 = Clock::now();
  if (static_cast<int>(r.tracks.size()) < o.min_points) {
    r.failure = "too_few_points";
    r.fmatrix_ms = ms_since(t0);
    return r;
  }
  std::vector<cv::Point2f> p, q;
  p.reserve(r.tracks.size());
  q.reserve(r.tracks.size());
  for (const LiTrack& t : r.tracks) {
    p.push_back(t.prev);
    q.push_back(t.cur);
  }
  if (!calib.dist.empty() && !calib.K.empty()) {
    cv::undistortPoints(std::vector<cv::Point2f>(p), p, calib.K, calib.dist, cv::noArray(), calib.K);
    cv::undistortPoints(std::vector<cv::Point2f>(q), q, calib.K, calib.dist, cv::noArray(), calib.K);
  }
  // The pairs F is fitted to: all, or those starting outside the previous
  // frame's dynamic mask (when enough are left).
  std::vector<cv::Point2f> fit_p, fit_q;
  if (o.f_exclude_previous_dynamic && prev_dynamic.size() == prev_grey.size()) {
    for (size_t i = 0; i < r.tracks.size(); ++i) {
      if (view::mask_at(prev_dynamic, r.tracks[i].prev)) continue;
      fit_p.push_back(p[i]);
      fit_q.push_back(q[i]);
    }
    r.f_excluded = static_cast<int>(p.size() - fit_p.size());
    if (static_cast<int>(fit_p.size()) < o.min_points) fit_p.clear();
  }
  const bool subset = !fit_p.empty() && fit_p.size() < p.size();
  r.f_fitted = static_cast<int>(subset ? fit_p.size() : p.size());
  std::vector<unsigned char> inlier;
  cv::Mat F;
  try {
    F = cv::findFundamentalMat(subset ? fit_p : p, subset ? fit_q : q, cv::FM_RANSAC, o.f_ransac_threshold_px,
                               o.f_ransac_confidence, o.f_ransac_iterations, inlier);
  } catch (const cv::Exception&) {
    F.release();
  }
  if (F.rows != 3 || F.cols != 3 || !cv::checkRange(F)) {
    r.failure = "f_failed";
    r.fmatrix_ms = ms_since(t0);
    return r;
  }
  r.has_F = true;
  r.F = cv::Matx33d(F.ptr<double>());
  for (unsigned char m : inlier) r.f_inliers += m ? 1 : 0;

  for (size_t i = 0; i < r.tracks.size(); ++i) {
    LiTrack& t = r.tracks[i];
    t.prev_u = p[i];
    t.cur_u = q[i];
    if (!(t.disparity > 0.f)) continue;
    // Eq. 1: the epipolar line of the previous point in the current image.
    const cv::Vec3d l = r.F * cv::Vec3d(p[i].x, p[i].y, 1.0);
    const double n = std::hypot(l[0], l[1]);
    if (!(n > 0)) continue;
    t.distance = std::abs(l[0] * q[i].x + l[1] * q[i].y + l[2]) / n;  // eq. 2
    t.threshold = o.alpha_epi + o.beta_epi * t.disparity;              // eq. 3
    t.dynamic = t.distance > t.threshold;
    ++r.judged;
    r.dynamic += t.dynamic ? 1 : 0;
  }
  r.fmatrix_ms = ms_since(t0);
  return r;
}

}  // namespace dynaorb::dynamic
