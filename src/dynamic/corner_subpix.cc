// cv::cornerSubPix (OpenCV 4, imgproc/cornersubpix.cpp) with the same
// floating-point operations in the same order, two or four corners at a time.
//
// The algorithm (Foerstner's corner; OpenCV's names): each step samples the
// (2w+3)^2 patch around the current estimate c by bilinear interpolation
// (getRectSubPix into float), takes central differences g of the (2w+1)^2
// window pixels q, weighted by m(q) = exp(-(x/w)^2 - (y/w)^2), and solves
//   sum m g g^T (c' - q) = 0
// for the next estimate c' from the sums a, b, c (of m g g^T) and bb1, bb2
// (of m g g^T q). It stops after max_iterations steps, on a step shorter than
// epsilon, on a singular system or when c' leaves the image; an estimate that
// ended more than w px from its start is dropped for the start.
//
// Why not cv::cornerSubPix: the motion cues refine hundreds of corners per
// frame with DS-SLAM's 21x21 window and 20 steps, about 12 steps per corner on
// average, 2.1 us per step in OpenCV's scalar loops: 16 of the 20 ms of an
// RGB-D frame's corner detection. What is the same here, bit for bit:
//  - the patch: getRectSubPix_8u32f's recurrence inside the image (each
//    row's first value from the left pixels, then t_j = a12 s[j+1] + a22
//    s'[j+1], value_j = prev + t_j, prev = (float)(t_j * (1 - a) / a)); where
//    the patch leaves the image, cv::getRectSubPix itself;
//  - the gradients as float differences, the weights from OpenCV's float
//    expressions, every product and sum in double in OpenCV's order: the
//    window's pixels are added one after the other, row by row;
//  - the step, its tests and the final fallback.
// What differs: the float parts run on 4 lanes, the double parts on 2 (SSE2)
// or 4 (AVX2, where the CPU has it), one lane per corner, so that each
// corner's sums are still one sequential chain. With no FMA contraction
// (x86-64's SSE2 baseline, as Debian builds OpenCV; the AVX2 code asks for
// no FMA; CMakeLists.txt sets -ffp-contract=off on this file) every lane
// computes what OpenCV's scalar code computes: the gtest compares positions
// bit for bit on real images, for both lane counts.
// Measured on one thread, DS-SLAM's settings (w = 10, 20 steps, 0.03 px):
// the 715 Harris corners of a `dynaorb synth` RGB-D frame 18.8 -> 8.5 ms with
// 2 lanes, 6.7 ms with 4; the 914 of a KITTI 06 frame 26.3 -> 12.0 / 9.1 ms.
#include "dynaorb/dynamic/corner_subpix.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>

#include <opencv2/core/hal/intrin.hpp>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif
#include <opencv2/imgproc.hpp>

namespace dynaorb::dynamic {

namespace {

// The window's constants and the buffers of L lanes (L corners refined side by side).
template <int L>
struct SubpixWork {
  int half = 0;
  int width = 0;   // 2 * half + 1: the window
  int side = 0;    // width + 2: the sampled patch
  int pixels = 0;  // width^2
  int stride = 0;  // a patch row in floats: whole vectors, room for loads at j + 1
  int row_pad = 0; // a window row rounded up to whole vectors
  std::vector<double> m, px, py;  // per window pixel, L times (one per lane): weight, x, y
  std::vector<float> patch[L];    // side rows of `stride`
  std::vector<float> source;      // side + 1 rows of side + 1 pixels as float (+ padding)
  std::vector<float> t;           // one patch row's t_j
  std::vector<float> gx, gy;      // per window pixel, interleaved: pixel k of lane l at L k + l
  std::vector<float> row_gx[L], row_gy[L];

  explicit SubpixWork(int w) : half(w), width(2 * w + 1), side(2 * w + 3), pixels(width * width) {
    stride = (side + 4 + 3) / 4 * 4;
    row_pad = (width + 3) / 4 * 4;
    m.resize(L * static_cast<size_t>(pixels));
    px.resize(m.size());
    py.resize(m.size());
    for (int i = 0, k = 0; i < width; ++i) {
      // OpenCV's weights, in its float expressions.
      const float y = static_cast<float>(i - half) / half;
      const float vy = std::exp(-y * y);
      for (int j = 0; j < width; ++j, ++k) {
        const float x = static_cast<float>(j - half) / half;
        const float mk = static_cast<float>(vy * std::exp(-x * x));
        for (int l = 0; l < L; ++l) {
          m[L * k + l] = mk;
          px[L * k + l] = j - half;
          py[L * k + l] = i - half;
        }
      }
    }
    for (auto& p : patch) p.assign(static_cast<size_t>(side) * stride, 0.f);
    source.assign(static_cast<size_t>(side + 1) * stride, 0.f);
    t.assign(stride + 4, 0.f);
    // Interleaved rows are stored whole vectors at a time: room for the last one's overrun.
    gx.assign(L * (static_cast<size_t>(pixels) + row_pad) + 4, 0.f);
    gy.assign(gx.size(), 0.f);
    for (int l = 0; l < L; ++l) {
      row_gx[l].assign(row_pad, 0.f);
      row_gy[l].assign(row_pad, 0.f);
    }
  }

  // getRectSubPix(grey, Size(side, side), c, patch, CV_32F) into lane l's patch.
  void sample(const cv::Mat& grey, const cv::Point2f& c, int l) {
    float* dst = patch[l].data();
    cv::Point2f center = c;
    center.x -= (side - 1) * 0.5f;
    center.y -= (side - 1) * 0.5f;
    const int ix = cvFloor(center.x), iy = cvFloor(center.y);
    if (!(0 <= ix && ix + side < grey.cols && 0 <= iy && iy + side < grey.rows)) {
      cv::Mat sub;
      cv::getRectSubPix(grey, cv::Size(side, side), c, sub, CV_32F);
      for (int r = 0; r < side; ++r) std::memcpy(dst + static_cast<size_t>(r) * stride, sub.ptr<float>(r), side * sizeof(float));
      return;
    }
    float a = center.x - ix;
    const float b = center.y - iy;
    a = std::max(a, 0.0001f);
    const float a12 = a * (1.f - b), a22 = a * b, b1 = 1.f - b, b2 = b;
    const double s = (1. - a) / a;
    // The side + 1 source rows of side + 1 pixels, as float (exact).
    for (int r = 0; r <= side; ++r) {
      const unsigned char* src = grey.ptr<unsigned char>(iy + r) + ix;
      float* f = &source[static_cast<size_t>(r) * stride];
      int j = 0;
      for (; j + 4 <= side + 1; j += 4)
        cv::v_store(f + j, cv::v_cvt_f32(cv::v_reinterpret_as_s32(cv::v_load_expand_q(src + j))));
      for (; j <= side; ++j) f[j] = src[j];
    }
    const cv::v_float32x4 va12 = cv::v_setall_f32(a12), va22 = cv::v_setall_f32(a22);
    const cv::v_float64x2 vs = cv::v_setall_f64(s);
    float* tj = t.data();
    for (int r = 0; r < side; ++r) {
      const float* s0 = &source[static_cast<size_t>(r) * stride];
      const float* s1 = s0 + stride;
      float* d = dst + static_cast<size_t>(r) * stride;
      // t_j = a12 * s0[j + 1] + a22 * s1[j + 1]
      for (int j = 0; j < side; j += 4)
        cv::v_store(tj + j, va12 * cv::v_load(s0 + j + 1) + va22 * cv::v_load(s1 + j + 1));
      d[0] = (1 - a) * (b1 * s0[0] + b2 * s1[0]) + tj[0];
      // d_j = (float)(t_{j-1} * s) + t_j for j >= 1
      for (int j = 1; j < side; j += 4) {
        const cv::v_float32x4 tp = cv::v_load(tj + j - 1);
        const cv::v_float32x4 prev = cv::v_cvt_f32(cv::v_cvt_f64(tp) * vs, cv::v_cvt_f64_high(tp) * vs);
        cv::v_store(d + j, prev + cv::v_load(tj + j));
      }
    }
  }

  // The lanes' gradients of window row i (OpenCV's float differences), interleaved.
  void gradient_row(int i) {
    for (int l = 0; l < L; ++l) {
      const float* p = patch[l].data();
      const float* up = p + static_cast<size_t>(i) * stride + 1;
      const float* mid = p + static_cast<size_t>(i + 1) * stride;
      const float* down = p + static_cast<size_t>(i + 2) * stride + 1;
      for (int j = 0; j < width; j += 4) {
        cv::v_store(row_gx[l].data() + j, cv::v_load(mid + j + 2) - cv::v_load(mid + j));
        cv::v_store(row_gy[l].data() + j, cv::v_load(down + j) - cv::v_load(up + j));
      }
    }
    interleave(row_gx, gx.data() + L * static_cast<size_t>(i) * width);
    interleave(row_gy, gy.data() + L * static_cast<size_t>(i) * width);
  }

  // out[L j + l] = rows[l][j].
  void interleave(const std::vector<float> (&rows)[L], float* out) const {
    for (int j = 0; j < row_pad; j += 4) {
      if constexpr (L == 2) {
        cv::v_float32x4 lo, hi;
        cv::v_zip(cv::v_load(rows[0].data() + j), cv::v_load(rows[1].data() + j), lo, hi);
        cv::v_store(out + 2 * j, lo);
        cv::v_store(out + 2 * j + 4, hi);
      } else {
        static_assert(L == 4, "2 or 4 lanes");
        cv::v_float32x4 b0, b1, b2, b3;
        cv::v_transpose4x4(cv::v_load(rows[0].data() + j), cv::v_load(rows[1].data() + j),
                           cv::v_load(rows[2].data() + j), cv::v_load(rows[3].data() + j), b0, b1, b2, b3);
        cv::v_store(out + 4 * j, b0);
        cv::v_store(out + 4 * j + 4, b1);
        cv::v_store(out + 4 * j + 8, b2);
        cv::v_store(out + 4 * j + 12, b3);
      }
    }
  }
};

// OpenCV's sums of two lanes, each added pixel after pixel: out[l] = a, b, c, bb1, bb2.
void sums(const SubpixWork<2>& w, double out[2][5]) {
  cv::v_float64x2 A = cv::v_setzero_f64(), B = A, C = A, BB1 = A, BB2 = A;
  const auto pixel = [&](const cv::v_float64x2& tgx, const cv::v_float64x2& tgy, int k) {
    const cv::v_float64x2 m = cv::v_load(&w.m[2 * k]);
    const cv::v_float64x2 px = cv::v_load(&w.px[2 * k]), py = cv::v_load(&w.py[2 * k]);
    const cv::v_float64x2 gxx = tgx * tgx * m, gxy = tgx * tgy * m, gyy = tgy * tgy * m;
    A = A + gxx;
    B = B + gxy;
    C = C + gyy;
    BB1 = BB1 + (gxx * px + gxy * py);
    BB2 = BB2 + (gxy * px + gyy * py);
  };
  int k = 0;
  for (; k + 2 <= w.pixels; k += 2) {
    const cv::v_float32x4 fx = cv::v_load(&w.gx[2 * k]), fy = cv::v_load(&w.gy[2 * k]);
    pixel(cv::v_cvt_f64(fx), cv::v_cvt_f64(fy), k);
    pixel(cv::v_cvt_f64_high(fx), cv::v_cvt_f64_high(fy), k + 1);
  }
  if (k < w.pixels) {
    const cv::v_float32x4 fx = cv::v_load(&w.gx[2 * k]), fy = cv::v_load(&w.gy[2 * k]);
    pixel(cv::v_cvt_f64(fx), cv::v_cvt_f64(fy), k);
  }
  double v[5][2];
  cv::v_store(v[0], A);
  cv::v_store(v[1], B);
  cv::v_store(v[2], C);
  cv::v_store(v[3], BB1);
  cv::v_store(v[4], BB2);
  for (int l = 0; l < 2; ++l)
    for (int q = 0; q < 5; ++q) out[l][q] = v[q][l];
}

#if defined(__x86_64__) && defined(__GNUC__)
// The same with four lanes in AVX registers (AVX2 CPUs; no FMA).
__attribute__((target("avx2"))) void sums(const SubpixWork<4>& w, double out[4][5]) {
  __m256d A = _mm256_setzero_pd(), B = A, C = A, BB1 = A, BB2 = A;
  for (int k = 0; k < w.pixels; ++k) {
    const __m256d tgx = _mm256_cvtps_pd(_mm_loadu_ps(&w.gx[4 * k]));
    const __m256d tgy = _mm256_cvtps_pd(_mm_loadu_ps(&w.gy[4 * k]));
    const __m256d m = _mm256_loadu_pd(&w.m[4 * k]);
    const __m256d px = _mm256_loadu_pd(&w.px[4 * k]), py = _mm256_loadu_pd(&w.py[4 * k]);
    const __m256d gxx = _mm256_mul_pd(_mm256_mul_pd(tgx, tgx), m);
    const __m256d gxy = _mm256_mul_pd(_mm256_mul_pd(tgx, tgy), m);
    const __m256d gyy = _mm256_mul_pd(_mm256_mul_pd(tgy, tgy), m);
    A = _mm256_add_pd(A, gxx);
    B = _mm256_add_pd(B, gxy);
    C = _mm256_add_pd(C, gyy);
    BB1 = _mm256_add_pd(BB1, _mm256_add_pd(_mm256_mul_pd(gxx, px), _mm256_mul_pd(gxy, py)));
    BB2 = _mm256_add_pd(BB2, _mm256_add_pd(_mm256_mul_pd(gxy, px), _mm256_mul_pd(gyy, py)));
  }
  alignas(32) double v[5][4];
  _mm256_store_pd(v[0], A);
  _mm256_store_pd(v[1], B);
  _mm256_store_pd(v[2], C);
  _mm256_store_pd(v[3], BB1);
  _mm256_store_pd(v[4], BB2);
  for (int l = 0; l < 4; ++l)
    for (int q = 0; q < 5; ++q) out[l][q] = v[q][l];
}

bool cpu_has_avx2() {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  return avx2;
}
#else
bool cpu_has_avx2() { return false; }
void sums(const SubpixWork<4>&, double[4][5]) {}  // never called
#endif

// One corner's refinement in progress.
struct Lane {
  int index = -1;  // into the corners; -1: idle
  cv::Point2f start, c;
  int iter = 0;
};

template <int L>
void refine(const cv::Mat& grey, std::vector<cv::Point2f>& corners, int half_window, int iterations, double eps) {
  SubpixWork<L> work(half_window);
  Lane lanes[L];
  size_t next = 0;
  const auto take = [&](Lane& lane) {
    lane.index = -1;
    if (next >= corners.size()) return;
    lane.index = static_cast<int>(next++);
    lane.start = lane.c = corners[lane.index];
    lane.iter = 0;
  };
  const auto finish = [&](Lane& lane) {
    cv::Point2f c = lane.c;
    if (std::fabs(c.x - lane.start.x) > half_window || std::fabs(c.y - lane.start.y) > half_window) c = lane.start;
    corners[lane.index] = c;
    take(lane);
  };
  for (Lane& lane : lanes) take(lane);
  double s[L][5];
  while (std::any_of(lanes, lanes + L, [](const Lane& lane) { return lane.index >= 0; })) {
    for (int l = 0; l < L; ++l)
      if (lanes[l].index >= 0) work.sample(grey, lanes[l].c, l);
    for (int i = 0; i < work.width; ++i) work.gradient_row(i);
    sums(work, s);
    for (int l = 0; l < L; ++l) {
      Lane& lane = lanes[l];
      if (lane.index < 0) continue;
      const double a = s[l][0], b = s[l][1], c = s[l][2], bb1 = s[l][3], bb2 = s[l][4];
      const double det = a * c - b * b;
      if (std::fabs(det) <= DBL_EPSILON * DBL_EPSILON) {
        finish(lane);
        continue;
      }
      const double scale = 1.0 / det;
      cv::Point2f next_c;
      next_c.x = static_cast<float>(lane.c.x + c * scale * bb1 - b * scale * bb2);
      next_c.y = static_cast<float>(lane.c.y - b * scale * bb1 + a * scale * bb2);
      const double err = (next_c.x - lane.c.x) * (next_c.x - lane.c.x) + (next_c.y - lane.c.y) * (next_c.y - lane.c.y);
      lane.c = next_c;
      if (lane.c.x < 0 || lane.c.x >= grey.cols || lane.c.y < 0 || lane.c.y >= grey.rows) {
        finish(lane);
        continue;
      }
      if (!(++lane.iter < iterations && err > eps)) finish(lane);
    }
  }
}

}  // namespace

namespace detail {

int subpix_lanes_available() { return cpu_has_avx2() ? 4 : 2; }

void refine_corners_subpix_lanes(const cv::Mat& grey, std::vector<cv::Point2f>& corners, int half_window,
                                 int max_iterations, double epsilon, int lanes) {
  if (corners.empty()) return;
  CV_Assert(half_window > 0);
  CV_Assert(grey.type() == CV_8UC1);
  CV_Assert(grey.cols >= half_window * 2 + 5 && grey.rows >= half_window * 2 + 5);
  CV_Assert(lanes == 2 || (lanes == 4 && cpu_has_avx2()));
  const int iterations = std::min(std::max(max_iterations, 1), 100);  // OpenCV's MAX_ITERS
  double eps = std::max(epsilon, 0.);
  eps *= eps;
  const cv::Rect image(0, 0, grey.cols, grey.rows);
  for (const cv::Point2f& p : corners) CV_Assert(image.contains(p));
  if (lanes == 4)
    refine<4>(grey, corners, half_window, iterations, eps);
  else
    refine<2>(grey, corners, half_window, iterations, eps);
}

}  // namespace detail

void refine_corners_subpix(const cv::Mat& grey, std::vector<cv::Point2f>& corners, int half_window,
                           int max_iterations, double epsilon) {
  detail::refine_corners_subpix_lanes(grey, corners, half_window, max_iterations, epsilon,
                                      detail::subpix_lanes_available());
}

}  // namespace dynaorb::dynamic
