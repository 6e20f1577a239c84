// ORB extraction as described in ORB-SLAM (Mur-Artal, Montiel, Tardos, T-RO 2015,
// Sec. III-A) and ORB-SLAM2 (Mur-Artal, Tardos, T-RO 2017), on top of ORB
// (Rublee et al., ICCV 2011):
//  1. a scale pyramid, level i = level 0 scaled by 1/s^i;
//  2. per level, FAST corners over a grid of ~30x30 px cells, with a lower
//     threshold where a cell found nothing (so low-texture areas still count);
//  3. corners on the exclusion mask are dropped, then a quadtree keeps the
//     level's share of the budget spread over the image;
//  4. orientation by the intensity centroid of a circular patch (r = 15);
//  5. rotated BRIEF on the Gaussian-blurred level with OpenCV's learned pattern.
#include "dynaorb/features/orb_extractor.h"

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "orb_pattern.h"
#include "quadtree.h"

namespace dynaorb::features {

namespace {

constexpr int kPatchSize = 31;
constexpr int kHalfPatchSize = 15;
constexpr int kEdgeThreshold = 19;  // keypoints stay this far from the level's border
constexpr int kFastMargin = 3;      // FAST's circle radius
constexpr int kCellSize = 30;
constexpr int kDescriptorBytes = 32;

// Per-thread buffers reused across calls (left and right images, or the
// levels of one image, are often extracted on two threads).
struct Scratch {
  std::vector<cv::KeyPoint> cell_kps;
  std::vector<unsigned char> cell_found;
  std::vector<int> keep;
  detail::QuadtreeScratch quadtree;
};
thread_local Scratch t_scratch;

// Intensity centroid orientation (Rosin; ORB Sec. 3.2): m10, m01 over the disc
// of radius 15 around the keypoint, rows bounded by umax; angle of (m10, m01).
float ic_angle(const cv::Mat& img, int x, int y, const std::vector<int>& umax) {
  const uchar* center = img.ptr<uchar>(y) + x;
  const int step = static_cast<int>(img.step1());
  int m01 = 0, m10 = 0;
  for (int u = -kHalfPatchSize; u <= kHalfPatchSize; ++u) m10 += u * center[u];
  for (int v = 1; v <= kHalfPatchSize; ++v) {
    // Rows +v and -v together.
    int v_sum = 0;
    const int d = umax[v];
    const uchar* up = center + v * step;
    const uchar* down = center - v * step;
    for (int u = -d; u <= d; ++u) {
      const int p = up[u], m = down[u];
      v_sum += p - m;
      m10 += u * (p + m);
    }
    m01 += v * v_sum;
  }
  float a = cv::fastAtan2(static_cast<float>(m01), static_cast<float>(m10));
  if (a >= 360.f) a -= 360.f;
  return a;
}

// The pattern's 512 points as floats, x and y apart (p1 of pair i at 2i, p2
// at 2i + 1), for the rotation below.
struct PatternPoints {
  alignas(16) float x[2 * detail::kOrbPatternPairs];
  alignas(16) float y[2 * detail::kOrbPatternPairs];
  PatternPoints() {
    for (int i = 0; i < 2 * detail::kOrbPatternPairs; ++i) {
      x[i] = detail::kOrbBitPattern31[2 * i];
      y[i] = detail::kOrbBitPattern31[2 * i + 1];
    }
  }
};
const PatternPoints kPatternPoints;

// Steered BRIEF: each of the 256 point pairs is rotated by the keypoint angle
// and the blurred intensities compared (bit = I(p1) < I(p2)). The arithmetic
// follows OpenCV's ORB so that the bits are identical: in float,
// x' = round(x a - y b), y' = round(x b + y a), rounding half to even (cvRound).
// The 512 offsets are computed first, four at a time with SSE2 where there is
// SSE2 (the same IEEE operations in the same order, so the same bits), then
// the bytes are compared.
void describe_keypoint(const cv::Mat& blurred, int x, int y, float angle_deg, uchar* desc) {
  const float angle = angle_deg * static_cast<float>(CV_PI / 180.f);
  const float a = static_cast<float>(std::cos(angle)), b = static_cast<float>(std::sin(angle));
  const uchar* center = blurred.ptr<uchar>(y) + x;
  const int step = static_cast<int>(blurred.step1());
  constexpr int kPoints = 2 * detail::kOrbPatternPairs;
  alignas(16) int offset[kPoints];
  const PatternPoints& pp = kPatternPoints;
#if defined(__SSE2__)
  const __m128 va = _mm_set1_ps(a), vb = _mm_set1_ps(b);
  const __m128i vstep = _mm_set1_epi32(step);
  for (int i = 0; i < kPoints; i += 4) {
    const __m128 px = _mm_load_ps(pp.x + i), py = _mm_load_ps(pp.y + i);
    const __m128i ix = _mm_cvtps_epi32(_mm_sub_ps(_mm_mul_ps(px, va), _mm_mul_ps(py, vb)));
    const __m128i iy = _mm_cvtps_epi32(_mm_add_ps(_mm_mul_ps(px, vb), _mm_mul_ps(py, va)));
    // iy * step in 32 bits with SSE2 only: products of the even and odd lanes.
    const __m128i even = _mm_mul_epu32(iy, vstep);
    const __m128i odd = _mm_mul_epu32(_mm_srli_epi64(iy, 32), _mm_srli_epi64(vstep, 32));
    const __m128i prod = _mm_unpacklo_epi32(_mm_shuffle_epi32(even, _MM_SHUFFLE(0, 0, 2, 0)),
                                            _mm_shuffle_epi32(odd, _MM_SHUFFLE(0, 0, 2, 0)));
    _mm_store_si128(reinterpret_cast<__m128i*>(offset + i), _mm_add_epi32(prod, ix));
  }
#else
  for (int i = 0; i < kPoints; ++i) {
    const float fx = pp.x[i] * a - pp.y[i] * b, fy = pp.x[i] * b + pp.y[i] * a;
    offset[i] = cvRound(fy) * step + cvRound(fx);
  }
#endif
  const int* o = offset;
  for (int i = 0; i < kDescriptorBytes; ++i) {
    int val = 0;
    for (int bit = 0; bit < 8; ++bit, o += 2) val |= (center[o[0]] < center[o[1]]) << bit;
    desc[i] = static_cast<uchar>(val);
  }
}

}  // namespace

OrbExtractor::OrbExtractor(const ExtractorSettings& settings) : settings_(settings) {
  const ExtractorSettings& s = settings_;
  if (s.n_features < 1) throw std::invalid_argument("OrbExtractor: n_features must be >= 1");
  if (s.n_levels < 1) throw std::invalid_argument("OrbExtractor: n_levels must be >= 1");
  if (!(s.scale_factor > 1.0))
    throw std::invalid_argument("OrbExtractor: scale_factor must be > 1, got " +
                                std::to_string(s.scale_factor));
  if (s.ini_th_fast < 1 || s.min_th_fast < 1)
    throw std::invalid_argument("OrbExtractor: FAST thresholds must be >= 1");

  const int L = s.n_levels;
  scale_.resize(L);
  inv_scale_.resize(L);
  sigma2_.resize(L);
  inv_sigma2_.resize(L);
  for (int i = 0; i < L; ++i) {
    const double sc = std::pow(s.scale_factor, i);
    scale_[i] = static_cast<float>(sc);
    inv_scale_[i] = static_cast<float>(1.0 / sc);
    sigma2_[i] = static_cast<float>(sc * sc);
    inv_sigma2_[i] = static_cast<float>(1.0 / (sc * sc));
  }

  set_n_features(s.n_features);

  // umax[v]: half width of the circular patch at row v, made symmetric under
  // transposition so that the disc is the same in x and y.
  umax_.resize(kHalfPatchSize + 1);
  const int vmax = cvFloor(kHalfPatchSize * std::sqrt(2.f) / 2 + 1);
  const int vmin = cvCeil(kHalfPatchSize * std::sqrt(2.f) / 2);
  const double hp2 = kHalfPatchSize * kHalfPatchSize;
  for (int v = 0; v <= vmax; ++v) umax_[v] = cvRound(std::sqrt(hp2 - v * v));
  for (int v = kHalfPatchSize, v0 = 0; v >= vmin; --v) {
    while (umax_[v0] == umax_[v0 + 1]) ++v0;
    umax_[v] = v0;
    ++v0;
  }
}

void OrbExtractor::set_n_features(int n) {
  if (n < 1) throw std::invalid_argument("OrbExtractor: n_features must be >= 1");
  settings_.n_features = n;
  // Budget per level: a geometric series with ratio 1/s (the area of a level
  // shrinks with s^2, ORB-SLAM2 uses 1/s), summing to n_features; the last
  // level gets the remainder.
  const int L = settings_.n_levels;
  features_per_level_.resize(L);
  const double f = 1.0 / settings_.scale_factor;
  double per_level = n * (1 - f) / (1 - std::pow(f, L));
  int sum = 0;
  for (int i = 0; i < L - 1; ++i) {
    features_per_level_[i] = cvRound(per_level);
    sum += features_per_level_[i];
    per_level *= f;
  }
  features_per_level_[L - 1] = std::max(n - sum, 0);
}

namespace {
void check_image(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("OrbExtractor::extract: image is empty");
  if (image.type() != CV_8UC1)
    throw std::invalid_argument("OrbExtractor::extract: image must be CV_8UC1 (grayscale), got "
                                "type " + std::to_string(image.type()));
}

void check_exclude(const cv::Mat& exclude, const cv::Size& image_size) {
  if (!exclude.empty() && (exclude.type() != CV_8UC1 || exclude.size() != image_size))
    throw std::invalid_argument("OrbExtractor::extract: exclude mask must be empty or CV_8UC1 "
                                "of the image size");
}

// Whether `m` (CV_8UC1) is non-zero anywhere in the square of half-size r
// around (u, v), clipped to the image.
bool near_excluded(const cv::Mat& m, int u, int v, int r) {
  const int x0 = std::max(u - r, 0), x1 = std::min(u + r, m.cols - 1);
  const int y0 = std::max(v - r, 0), y1 = std::min(v + r, m.rows - 1);
  if (x1 < x0) return false;
  for (int y = y0; y <= y1; ++y) {
    const uchar* row = m.ptr<uchar>(y);
    if (std::any_of(row + x0, row + x1 + 1, [](uchar p) { return p != 0; })) return true;
  }
  return false;
}

// The FAST area of a level: [b, max_x) x [b, max_y), b = EDGE_THRESHOLD - 3,
// so corners lie at least EDGE_THRESHOLD px inside the level (room for the
// 31x31 rotated patch); det_w x det_h pixels can hold a corner.
struct LevelArea {
  int b, max_x, max_y, det_w, det_h;
  explicit LevelArea(const cv::Mat& img)
      : b(kEdgeThreshold - kFastMargin), max_x(img.cols - b), max_y(img.rows - b),
        det_w(max_x - b - 2 * kFastMargin), det_h(max_y - b - 2 * kFastMargin) {}
  bool usable() const { return det_w >= 1 && det_h >= 1; }
};
}  // namespace

void OrbExtractor::extract(const cv::Mat& image, const cv::Mat& exclude,
                           std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors, ExcludedCount* count) {
  check_image(image);
  check_exclude(exclude, image.size());
  describe(detect(image), exclude, keypoints, descriptors, count);
}

OrbDetection OrbExtractor::detect(const cv::Mat& image) const {
  OrbDetection d = start(image);
  for (int level = 0; level < n_levels(); ++level) detect_level(d, level);
  return d;
}

void OrbExtractor::describe(OrbDetection&& d, const cv::Mat& exclude, std::vector<cv::KeyPoint>& keypoints,
                            cv::Mat& descriptors, ExcludedCount* count) {
  // describe_level checks the detection, the mask and the count's region;
  // finish sets the count (0 where the region cannot be counted).
  const cv::Mat* region = count ? &count->region : nullptr;
  for (int level = 0; level < n_levels(); ++level) describe_level(d, level, exclude, region);
  finish(std::move(d), keypoints, descriptors, count);
}

OrbDetection OrbExtractor::start(const cv::Mat& image) const {
  check_image(image);
  // 1. Pyramid. Each level is resized from the previous one (bilinear), as
  // ORB-SLAM2 does, to the size of level 0 divided by s^i. Fresh buffers every
  // call: pyramids handed out earlier stay valid.
  const int L = n_levels();
  OrbDetection d;
  d.pyramid.assign(L, cv::Mat());
  d.blurred.assign(L, cv::Mat());
  d.corners.assign(L, {});
  d.kept.assign(L, {});
  d.descriptors.assign(L, cv::Mat());
  d.excluded_corners.assign(L, 0);
  d.excluded_keypoints.assign(L, 0);
  d.pyramid[0] = image.clone();
  for (int i = 1; i < L; ++i) {
    const cv::Size sz(cvRound(image.cols * inv_scale_[i]), cvRound(image.rows * inv_scale_[i]));
    if (sz.width < 1 || sz.height < 1) {
      d.pyramid[i] = cv::Mat(std::max(sz.height, 1), std::max(sz.width, 1), CV_8UC1, cv::Scalar(0));
      continue;
    }
    cv::resize(d.pyramid[i - 1], d.pyramid[i], sz, 0, 0, cv::INTER_LINEAR);
  }
  return d;
}

void OrbExtractor::detect_level(OrbDetection& d, int level) const {
  check_level(d, level);
  Scratch& s = t_scratch;
  const cv::Mat& img = d.pyramid[level];
  const LevelArea a(img);
  if (!a.usable()) return;
  const int b = a.b, max_x = a.max_x, max_y = a.max_y;

  // 2. FAST with the initial threshold over the whole detection area, then
  // binned in ~30x30 cells; cells with no corner are searched again with the
  // minimum threshold (ORB-SLAM's per-cell iniThFAST/minThFAST rule).
  std::vector<cv::KeyPoint>& cand = d.corners[level];
  cand.clear();
  cv::FAST(img(cv::Rect(b, b, max_x - b, max_y - b)), cand, settings_.ini_th_fast, true);
  const int n_cols = std::max(1, a.det_w / kCellSize), n_rows = std::max(1, a.det_h / kCellSize);
  const int cell_w = (a.det_w + n_cols - 1) / n_cols, cell_h = (a.det_h + n_rows - 1) / n_rows;
  const int x0 = b + kFastMargin, y0 = b + kFastMargin;  // first detectable pixel
  s.cell_found.assign(static_cast<size_t>(n_cols) * n_rows, 0);
  for (cv::KeyPoint& k : cand) {
    k.pt.x += b;
    k.pt.y += b;
    const int cx = std::min(n_cols - 1, (cvRound(k.pt.x) - x0) / cell_w);
    const int cy = std::min(n_rows - 1, (cvRound(k.pt.y) - y0) / cell_h);
    s.cell_found[cy * n_cols + cx] = 1;
  }
  for (int cy = 0; cy < n_rows; ++cy) {
    for (int cx = 0; cx < n_cols; ++cx) {
      if (s.cell_found[cy * n_cols + cx]) continue;
      // Cell [xa, xe) x [ya, ye) of detectable pixels, plus FAST's margin.
      const int xa = x0 + cx * cell_w, xe = std::min(xa + cell_w, max_x - kFastMargin);
      const int ya = y0 + cy * cell_h, ye = std::min(ya + cell_h, max_y - kFastMargin);
      if (xe <= xa || ye <= ya) continue;
      const cv::Rect r(xa - kFastMargin, ya - kFastMargin, xe - xa + 2 * kFastMargin,
                       ye - ya + 2 * kFastMargin);
      s.cell_kps.clear();
      cv::FAST(img(r), s.cell_kps, settings_.min_th_fast, true);
      for (cv::KeyPoint& k : s.cell_kps) {
        k.pt.x += r.x;
        k.pt.y += r.y;
        cand.push_back(k);
      }
    }
  }
  // The descriptors' image: the level blurred by a 7x7 Gaussian (sigma 2).
  cv::GaussianBlur(img, d.blurred[level], cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
}

void OrbExtractor::describe_level(OrbDetection& d, int level, const cv::Mat& exclude,
                                  const cv::Mat* count_region) const {
  check_level(d, level);
  check_exclude(exclude, d.pyramid[0].size());
  if (count_region && (exclude.empty() || count_region->type() != CV_8UC1 || count_region->size() != exclude.size()))
    count_region = nullptr;
  Scratch& s = t_scratch;
  std::vector<cv::KeyPoint>& out = d.kept[level];
  out.clear();
  d.descriptors[level].release();
  d.excluded_corners[level] = d.excluded_keypoints[level] = 0;
  const cv::Mat& img = d.pyramid[level];
  const LevelArea a(img);
  if (!a.usable() || features_per_level_[level] == 0) return;
  const int b = a.b, max_x = a.max_x, max_y = a.max_y;
  std::vector<cv::KeyPoint>& cand = d.corners[level];

  // 3a. Drop the corners whose level-0 position is excluded, or that have an
  // excluded pixel within exclude_margin_ level pixels (set_exclude_margin).
  const float sc = scale_[level];
  if (!exclude.empty()) {
    auto at = [&](const cv::Mat& m, const cv::KeyPoint& k) {
      const int u = std::clamp(cvRound(k.pt.x * sc), 0, m.cols - 1);
      const int v = std::clamp(cvRound(k.pt.y * sc), 0, m.rows - 1);
      return m.at<uchar>(v, u) != 0;
    };
    const int r = exclude_margin_ > 0 ? static_cast<int>(std::ceil(exclude_margin_ * sc - 1e-4f)) : 0;
    // With a margin the square holds the corner's own pixel too.
    auto excluded = [&](const cv::KeyPoint& k) {
      return r == 0 ? at(exclude, k) : near_excluded(exclude, cvRound(k.pt.x * sc), cvRound(k.pt.y * sc), r);
    };
    if (count_region) {
      int dropped = 0;
      for (const cv::KeyPoint& k : cand) dropped += excluded(k) && at(*count_region, k);
      d.excluded_corners[level] = dropped;
      if (dropped > 0) {
        // What the level would have kept without the exclusion.
        detail::distribute_quadtree(cand, static_cast<float>(b), static_cast<float>(max_x),
                                    static_cast<float>(b), static_cast<float>(max_y),
                                    features_per_level_[level], s.quadtree, s.keep);
        for (int idx : s.keep) d.excluded_keypoints[level] += at(*count_region, cand[idx]);
      }
    }
    cand.erase(std::remove_if(cand.begin(), cand.end(), excluded), cand.end());
  }

  // 3b. Quadtree distribution over the FAST area.
  detail::distribute_quadtree(cand, static_cast<float>(b), static_cast<float>(max_x),
                              static_cast<float>(b), static_cast<float>(max_y),
                              features_per_level_[level], s.quadtree, s.keep);

  // 4. Orientation on the (unblurred) level image.
  const float size = kPatchSize * sc;
  out.reserve(s.keep.size());
  for (int idx : s.keep) {
    cv::KeyPoint k = cand[idx];
    k.octave = level;
    k.size = size;
    k.angle = ic_angle(img, cvRound(k.pt.x), cvRound(k.pt.y), umax_);
    out.push_back(k);
  }

  // 5. Descriptors on the blurred level.
  cv::Mat& desc = d.descriptors[level];
  desc = cv::Mat(static_cast<int>(out.size()), kDescriptorBytes, CV_8U);
  for (size_t i = 0; i < out.size(); ++i)
    describe_keypoint(d.blurred[level], cvRound(out[i].pt.x), cvRound(out[i].pt.y), out[i].angle,
                      desc.ptr<uchar>(static_cast<int>(i)));
}

void OrbExtractor::finish(OrbDetection&& d, std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors,
                          ExcludedCount* count) {
  check_detection(d);
  const int L = n_levels();
  if (count) {
    count->corners = count->keypoints = 0;
    for (int level = 0; level < L; ++level) {
      count->corners += d.excluded_corners[level];
      count->keypoints += d.excluded_keypoints[level];
    }
  }
  // The levels in order, the keypoints in level-0 coordinates.
  int total = 0;
  for (int level = 0; level < L; ++level) total += static_cast<int>(d.kept[level].size());
  keypoints.clear();
  keypoints.reserve(total);
  descriptors = cv::Mat(total, kDescriptorBytes, CV_8U);
  int row = 0;
  for (int level = 0; level < L; ++level) {
    const std::vector<cv::KeyPoint>& kps = d.kept[level];
    if (kps.empty()) continue;
    const float sc = scale_[level];
    d.descriptors[level].copyTo(descriptors.rowRange(row, row + static_cast<int>(kps.size())));
    row += static_cast<int>(kps.size());
    for (const cv::KeyPoint& k : kps) {
      cv::KeyPoint k0 = k;
      k0.pt *= sc;
      keypoints.push_back(k0);
    }
  }
  pyramid_ = std::move(d.pyramid);
}

void OrbExtractor::set_exclude_margin(int level_px) {
  if (level_px < 0)
    throw std::invalid_argument("OrbExtractor: exclude margin must be >= 0 level pixels, got " +
                                std::to_string(level_px));
  exclude_margin_ = level_px;
}

void OrbExtractor::check_detection(const OrbDetection& d) const {
  const size_t L = static_cast<size_t>(n_levels());
  if (d.pyramid.size() != L || d.blurred.size() != L || d.corners.size() != L || d.kept.size() != L ||
      d.descriptors.size() != L || d.excluded_corners.size() != L || d.excluded_keypoints.size() != L ||
      d.pyramid[0].empty())
    throw std::invalid_argument("OrbExtractor::describe: the detection is not one of this extractor's");
}

void OrbExtractor::check_level(const OrbDetection& d, int level) const {
  check_detection(d);
  if (level < 0 || level >= n_levels())
    throw std::invalid_argument("OrbExtractor: level " + std::to_string(level) + " is not one of the " +
                                std::to_string(n_levels()) + " pyramid levels");
}

}  // namespace dynaorb::features
