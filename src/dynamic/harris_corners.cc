// Harris corners chosen as cv::goodFeaturesToTrack chooses them, with the
// response in exact integer arithmetic (include/dynaorb/dynamic/harris_corners.h).
//
// Against cv::goodFeaturesToTrack (Harris, 1000 corners, quality 0.01,
// distance 8, block 3, a 10 px border masked: the motion cues' detection),
// one thread, the fastest of 10 rounds of 30 calls on one frame: 1.47 ms
// against 4.30 on the synthetic 640x480 room, 3.40 against 9.51 on KITTI 06
// (1226x370). The corners: test_harris_corners.cc; the effect on the runs:
// docs/dynamic-frontend.md.
#include "dynaorb/dynamic/harris_corners.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace dynaorb::dynamic {
namespace {

// 45^2 box cells of (4 * 255)^2 each stay below 2^31: the sums fit int32.
constexpr int kMaxBlock = 45;

// BORDER_REFLECT_101 (n >= 2): -1 -> 1, n -> n - 2.
int reflect101(int i, int n) {
  while (i < 0 || i >= n) i = i < 0 ? -i : 2 * n - 2 - i;
  return i;
}

struct Scratch {
  std::vector<int16_t> gx, gy;         // 3x3 Sobel gradients (integers, unscaled)
  std::vector<int32_t> sxx, sxy, syy;  // their products summed along each row's box
  std::vector<int32_t> pxx, pxy, pyy;  // one row's products
  std::vector<int32_t> a, b, c;        // one row's box sums
  std::vector<double> response;
};
thread_local Scratch t_scratch;

// Sobel dx and dy of `grey` (the 3x3 kernels [-1 0 1] x [1 2 1] and their
// transpose, no scale), BORDER_REFLECT_101.
void sobel(const cv::Mat& grey, int16_t* gx, int16_t* gy) {
  const int W = grey.cols, H = grey.rows;
  for (int y = 0; y < H; ++y) {
    const uint8_t* up = grey.ptr<uint8_t>(reflect101(y - 1, H));
    const uint8_t* mid = grey.ptr<uint8_t>(y);
    const uint8_t* down = grey.ptr<uint8_t>(reflect101(y + 1, H));
    int16_t* ox = gx + static_cast<size_t>(y) * W;
    int16_t* oy = gy + static_cast<size_t>(y) * W;
    const auto at = [&](int x) {
      const int l = reflect101(x - 1, W), r = reflect101(x + 1, W);
      ox[x] = static_cast<int16_t>((up[r] - up[l]) + 2 * (mid[r] - mid[l]) + (down[r] - down[l]));
      oy[x] = static_cast<int16_t>((down[l] + 2 * down[x] + down[r]) - (up[l] + 2 * up[x] + up[r]));
    };
    at(0);
    for (int x = 1; x < W - 1; ++x) {
      ox[x] = static_cast<int16_t>((up[x + 1] - up[x - 1]) + 2 * (mid[x + 1] - mid[x - 1]) +
                                   (down[x + 1] - down[x - 1]));
      oy[x] = static_cast<int16_t>((down[x - 1] + 2 * down[x] + down[x + 1]) - (up[x - 1] + 2 * up[x] + up[x + 1]));
    }
    at(W - 1);
  }
}

// out[x] = sum of in[reflect101(x + i - lead)] over i < block, for one row.
void box_along_row(const int32_t* __restrict in, int W, int block, int lead, int32_t* __restrict out) {
  const int first = lead, last = W - block + lead;  // x in [first, last]: no reflection
  std::fill(out, out + W, 0);
  for (int i = 0; i < block; ++i) {
    const int32_t* __restrict src = in + i - lead;
    for (int x = first; x <= last; ++x) out[x] += src[x];
  }
  const auto reflected = [&](int from, int to) {  // the columns whose box leaves the row
    for (int x = from; x < to; ++x) {
      int32_t s = 0;
      for (int i = 0; i < block; ++i) s += in[reflect101(x + i - lead, W)];
      out[x] = s;
    }
  };
  reflected(0, first);
  reflected(last + 1, W);
}

// out[x] = sum of rows[j][x] over the rows.
void vertical_sum(const std::vector<const int32_t*>& rows, int W, int32_t* __restrict out) {
  if (rows.size() == 3) {
    const int32_t* __restrict r0 = rows[0];
    const int32_t* __restrict r1 = rows[1];
    const int32_t* __restrict r2 = rows[2];
    for (int x = 0; x < W; ++x) out[x] = r0[x] + r1[x] + r2[x];
    return;
  }
  std::fill(out, out + W, 0);
  for (const int32_t* row : rows) {
    const int32_t* __restrict in = row;
    for (int x = 0; x < W; ++x) out[x] += in[x];
  }
}

constexpr double kNone = -std::numeric_limits<double>::infinity();

// The largest of r[x] where m[x] is set (m null: everywhere); kNone if none.
// 16 at a time where the mask is all set or all clear there.
double masked_max(const double* __restrict r, const uint8_t* __restrict m, int W) {
  double best = kNone;
  int x = 0;
  const auto run = [&](int from, int to) {
    double b = kNone;
    for (int i = from; i < to; ++i) b = r[i] > b ? r[i] : b;
    best = b > best ? b : best;
  };
  if (!m) {
    run(0, W);
    return best;
  }
  for (; x + 16 <= W; x += 16) {
    uint64_t lo, hi;
    std::memcpy(&lo, m + x, 8);
    std::memcpy(&hi, m + x + 8, 8);
    if ((lo | hi) == 0) continue;
    const auto has_zero_byte = [](uint64_t v) {
      return ((v - 0x0101010101010101ull) & ~v & 0x8080808080808080ull) != 0;
    };
    if (!has_zero_byte(lo) && !has_zero_byte(hi)) {
      run(x, x + 16);
      continue;
    }
    for (int i = x; i < x + 16; ++i)
      if (m[i] && r[i] > best) best = r[i];
  }
  for (; x < W; ++x)
    if (m[x] && r[x] > best) best = r[x];
  return best;
}

// Whether any of r[0..8) is above t.
bool any_above(const double* __restrict r, double t) {
  int n = 0;
  for (int i = 0; i < 8; ++i) n += r[i] > t;
  return n != 0;
}

struct Candidate {
  double response;
  int index;  // y * W + x
};

}  // namespace

std::vector<cv::Point2f> harris_corners(const cv::Mat& grey, int max_corners, double quality_level,
                                        double min_distance, const cv::Mat& mask, int block_size, double k) {
  CV_Assert(grey.type() == CV_8UC1);
  CV_Assert(quality_level > 0 && min_distance >= 0 && max_corners >= 0);
  CV_Assert(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == grey.size()));
  const int W = grey.cols, H = grey.rows;
  // OpenCV's filters read past a submatrix's edge into its parent image;
  // this reflects at the image's own edge: those, and what the rules above
  // do not cover, go to OpenCV.
  if (grey.isSubmatrix() || W < 3 || H < 3 || block_size < 1 || block_size > kMaxBlock || block_size > W ||
      block_size > H) {
    std::vector<cv::Point2f> out;
    cv::goodFeaturesToTrack(grey, out, max_corners, quality_level, min_distance, mask, block_size, true, k);
    return out;
  }

  Scratch& s = t_scratch;
  const size_t n = static_cast<size_t>(W) * H;
  s.gx.resize(n);
  s.gy.resize(n);
  s.sxx.resize(n);
  s.sxy.resize(n);
  s.syy.resize(n);
  s.response.resize(n);
  for (auto* v : {&s.pxx, &s.pxy, &s.pyy, &s.a, &s.b, &s.c}) v->resize(W);
  sobel(grey, s.gx.data(), s.gy.data());

  // The box is anchored at its centre (OpenCV's Point(-1, -1)): block / 2
  // cells before the pixel.
  const int lead = block_size / 2;
  for (int y = 0; y < H; ++y) {
    const int16_t* gx = s.gx.data() + static_cast<size_t>(y) * W;
    const int16_t* gy = s.gy.data() + static_cast<size_t>(y) * W;
    for (int x = 0; x < W; ++x) {
      s.pxx[x] = gx[x] * gx[x];
      s.pxy[x] = gx[x] * gy[x];
      s.pyy[x] = gy[x] * gy[x];
    }
    const size_t row = static_cast<size_t>(y) * W;
    box_along_row(s.pxx.data(), W, block_size, lead, s.sxx.data() + row);
    box_along_row(s.pxy.data(), W, block_size, lead, s.sxy.data() + row);
    box_along_row(s.pyy.data(), W, block_size, lead, s.syy.data() + row);
  }

  // Down the columns, then the response: A C - B^2 and (A + C)^2 are exact in
  // double (A, C < 2^24 for block 3; below 2^31 always, their products below
  // 2^53 for block 3 and within a rounding of it beyond).
  double max_response = kNone;  // inside the mask
  std::vector<const int32_t*> xx(block_size), xy(block_size), yy(block_size);
  for (int y = 0; y < H; ++y) {
    for (int j = 0; j < block_size; ++j) {
      const size_t row = static_cast<size_t>(reflect101(y + j - lead, H)) * W;
      xx[j] = s.sxx.data() + row;
      xy[j] = s.sxy.data() + row;
      yy[j] = s.syy.data() + row;
    }
    int32_t* __restrict a = s.a.data();
    int32_t* __restrict b = s.b.data();
    int32_t* __restrict c = s.c.data();
    vertical_sum(xx, W, a);
    vertical_sum(xy, W, b);
    vertical_sum(yy, W, c);
    double* __restrict r = s.response.data() + static_cast<size_t>(y) * W;
    for (int x = 0; x < W; ++x) {
      const double A = a[x], B = b[x], C = c[x];
      r[x] = (A * C - B * B) - k * ((A + C) * (A + C));
    }
    max_response = std::max(max_response, masked_max(r, mask.empty() ? nullptr : mask.ptr<uint8_t>(y), W));
  }
  if (max_response == kNone) max_response = 0;  // nothing inside the mask (cv::minMaxLoc's 0)

  // Thresholded to zero at quality_level of the largest response inside the
  // mask (cv::threshold THRESH_TOZERO), then the 3x3 local maxima (cv::dilate)
  // off the outer ring, inside the mask.
  const double threshold = max_response * quality_level;
  const auto kept = [&](double v) { return v > threshold ? v : 0.0; };
  std::vector<Candidate> candidates;
  for (int y = 1; y < H - 1; ++y) {
    const double* r = s.response.data() + static_cast<size_t>(y) * W;
    const uint8_t* m = mask.empty() ? nullptr : mask.ptr<uint8_t>(y);
    for (int x = 1; x < W - 1; ++x) {
      if ((x & 7) == 0 && x + 8 < W && !any_above(r + x, threshold)) {
        x += 7;  // none of the 8 from x on is above the threshold
        continue;
      }
      if (!(r[x] > threshold) || (m && !m[x])) continue;
      const double v = r[x];
      if (v == 0) continue;  // goodFeaturesToTrack's val != 0 (a threshold below 0)
      bool peak = true;
      for (int dy = -1; dy <= 1 && peak; ++dy) {
        const double* q = r + static_cast<ptrdiff_t>(dy) * W;
        for (int dx = -1; dx <= 1; ++dx)
          if (kept(q[x + dx]) > v) {
            peak = false;
            break;
          }
      }
      if (peak) candidates.push_back({v, y * W + x});
    }
  }
  // Strongest first; equal ones in goodFeaturesToTrack's order (its pointer
  // comparison: the later raster position first).
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& p, const Candidate& q) {
    return p.response > q.response || (p.response == q.response && p.index > q.index);
  });

  std::vector<cv::Point2f> corners;
  const auto full = [&] { return max_corners > 0 && static_cast<int>(corners.size()) == max_corners; };
  if (min_distance >= 1) {
    // goodFeaturesToTrack's grid of min_distance cells: a corner is kept
    // unless one already kept in its cell or the 8 around lies nearer.
    const int cell = cvRound(min_distance);
    const int grid_w = (W + cell - 1) / cell, grid_h = (H + cell - 1) / cell;
    std::vector<std::vector<cv::Point2f>> grid(static_cast<size_t>(grid_w) * grid_h);
    const double d2 = min_distance * min_distance;
    for (const Candidate& c : candidates) {
      const int y = c.index / W, x = c.index % W;
      const int cx = x / cell, cy = y / cell;
      bool good = true;
      for (int yy = std::max(0, cy - 1); yy <= std::min(grid_h - 1, cy + 1) && good; ++yy)
        for (int xx = std::max(0, cx - 1); xx <= std::min(grid_w - 1, cx + 1) && good; ++xx)
          for (const cv::Point2f& p : grid[static_cast<size_t>(yy) * grid_w + xx]) {
            const float ddx = static_cast<float>(x) - p.x, ddy = static_cast<float>(y) - p.y;
            if (ddx * ddx + ddy * ddy < d2) {
              good = false;
              break;
            }
          }
      if (!good) continue;
      const cv::Point2f p(static_cast<float>(x), static_cast<float>(y));
      grid[static_cast<size_t>(cy) * grid_w + cx].push_back(p);
      corners.push_back(p);
      if (full()) break;
    }
  } else {
    for (const Candidate& c : candidates) {
      corners.emplace_back(static_cast<float>(c.index % W), static_cast<float>(c.index / W));
      if (full()) break;
    }
  }
  return corners;
}

}  // namespace dynaorb::dynamic
