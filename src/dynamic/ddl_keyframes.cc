// The DDL stage's reference keyframes: back-projection of their keypoints
// and the keyframe check (see ddl_keyframes.h).
#include "ddl_keyframes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace dynaorb::dynamic::ddl {

bool back_project(const KeyFrameData& kf, const view::Camera& camera, double max_depth, Reference& r) {
  if (!kf.frame || !kf.frame->T_cw || kf.keypoints.empty()) return false;
  const FrameData& f = *kf.frame;
  const bool per_point_depth = kf.depth.size() == kf.keypoints.size();
  const bool image_depth = !f.depth.empty() && f.depth.type() == CV_32FC1;
  if (!per_point_depth && !image_depth) return false;
  const bool has_mask = !f.dynamic.empty() && f.dynamic.type() == CV_8UC1;
  std::vector<cv::Point2f> px;
  std::vector<float> z;
  for (size_t i = 0; i < kf.keypoints.size(); ++i) {
    const cv::Point2f& p = kf.keypoints[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
    float d = 0.f;
    if (per_point_depth) {
      d = kf.depth[i];
    } else {
      const int x = cvRound(p.x), y = cvRound(p.y);
      if (x >= 0 && y >= 0 && x < f.depth.cols && y < f.depth.rows) d = f.depth.at<float>(y, x);
    }
    if (!view::valid_depth(d) || (max_depth > 0 && d > max_depth)) continue;
    if (has_mask && view::mask_at(f.dynamic, p)) continue;
    px.push_back(p);
    z.push_back(d);
  }
  if (px.empty()) return false;
  const std::vector<cv::Point2f> rays = camera.rays(px);
  const Eigen::Isometry3d T_wc = f.T_cw->inverse();
  r.kf = &kf;
  r.px = px;
  r.centre_w = T_wc.translation();
  r.X_w.reserve(px.size());
  for (size_t i = 0; i < px.size(); ++i)
    r.X_w.push_back(T_wc * Eigen::Vector3d(rays[i].x * z[i], rays[i].y * z[i], z[i]));
  return true;
}

float closest_depth(const cv::Mat& depth, const cv::Point& p, float z_ref, int radius) {
  const float z0 = depth.at<float>(p.y, p.x);
  if (radius <= 0) return view::valid_depth(z0) ? z0 : 0.f;
  float best = 0.f;
  float best_diff = std::numeric_limits<float>::infinity();
  for (int y = std::max(0, p.y - radius); y <= std::min(depth.rows - 1, p.y + radius); ++y) {
    const float* row = depth.ptr<float>(y);
    for (int x = std::max(0, p.x - radius); x <= std::min(depth.cols - 1, p.x + radius); ++x) {
      const float d = row[x];
      if (!view::valid_depth(d)) continue;
      const float diff = std::abs(d - z_ref);
      if (diff < best_diff) {
        best_diff = diff;
        best = d;
      }
    }
  }
  return best;
}

namespace {

// Both images are compared slightly blurred: resampling a texture finer
// than the pixels (a floor at a grazing angle) aliases differently in
// each view.
void smooth(const cv::Mat& in, cv::Mat& out, const DdlOptions& o) {
  in.convertTo(out, CV_32F);
  if (o.confirm_blur_sigma_px > 0) cv::GaussianBlur(out, out, cv::Size(), o.confirm_blur_sigma_px);
}

}  // namespace

void prepare_keyframe_maps(const FrameData& f, const DdlOptions& o, bool check, bool pyramid, KeyframeMaps& m) {
  if (pyramid && !m.pyramid_made) {
    m.pyramid_made = true;
    if (!f.grey.empty() && f.grey.type() == CV_8UC1)
      cv::buildOpticalFlowPyramid(f.grey, m.pyramid, kRefineWindow, kRefineLevels);
  }
  if (!check || m.check) return;
  m.check = true;
  if (f.depth.empty() || f.depth.type() != CV_32FC1) return;
  // The keyframe's nearest and farthest depth around where P lands: a
  // projection a pixel off a depth edge still finds P's surface (DynaSLAM's
  // code searches a window for z' likewise).
  const float far = std::numeric_limits<float>::max();
  cv::Mat depth = f.depth.clone(), depth_min, depth_max;
  cv::patchNaNs(depth, 0);
  const cv::Mat holes = depth <= 0;
  cv::Mat min_src = depth.clone();
  min_src.setTo(far, holes);
  const int r = std::max(0, o.confirm_search_radius_px);
  const cv::Mat window = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * r + 1, 2 * r + 1));
  cv::erode(min_src, depth_min, window);
  cv::dilate(depth, depth_max, window);
  const cv::Mat planes[4] = {depth, depth_min, depth_max, cv::Mat::zeros(depth.size(), CV_32FC1)};
  cv::merge(planes, 4, m.depths);
  if (o.confirm_min_zncc > -1 && !f.grey.empty() && f.grey.size() == f.depth.size() && f.grey.type() == CV_8UC1)
    smooth(f.grey, m.grey, o);
}

KeyframeEvidence::KeyframeEvidence(const cv::Mat& depth, const cv::Mat& grey,
                                   const std::vector<cv::Point2f>& rays, const std::vector<Reference>& refs,
                                   const view::Camera& camera, const DdlOptions& o)
    : depth_(depth),
      rays_(rays),
      camera_(camera),
      o_(o),
      cache_(depth.size(), CV_8UC1, cv::Scalar(0)),
      area_(depth.size(), CV_8UC1, cv::Scalar(0)),
      block_(depth.size(), CV_8UC1, cv::Scalar(0)) {
  texture_ = o.confirm_min_zncc > -1 && grey.size() == depth.size() && grey.type() == CV_8UC1;
  if (texture_) {
    smooth(grey, grey_, o_);
    // Current pixels next to a depth edge: their grey blends both sides.
    const float far = std::numeric_limits<float>::max();
    cv::Mat d = depth.clone(), d_hi, d_lo;
    cv::patchNaNs(d, 0);
    cv::Mat d_for_min = d.clone();
    d_for_min.setTo(far, d <= 0);
    const cv::Mat k3 = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
    cv::dilate(d, d_hi, k3);
    cv::erode(d_for_min, d_lo, k3);
    edge_ = (d_hi - d_lo) > o.depth_threshold_m;
  }
  const cv::Size size = depth.size();
  for (const Reference& r : refs) {
    if (!r.dense || !r.maps || r.maps->depths.empty()) continue;
    Warped wk;
    wk.ref = &r;
    // Not cleared here: warp_tile writes every pixel of a tile before any
    // of them is read (pixels are read only in tiles already resampled),
    // and most tiles are never asked about.
    wk.agree.create(size, CV_8UC1);
    wk.through.create(size, CV_8UC1);
    if (texture_ && !r.maps->grey.empty()) {
      wk.grey.create(size, CV_32FC1);
      wk.usable.create(size, CV_8UC1);
    }
    warped_.push_back(std::move(wk));
  }
  tiles_x_ = (size.width + kTile - 1) / kTile;
  tiles_y_ = (size.height + kTile - 1) / kTile;
  tile_done_.assign(static_cast<size_t>(tiles_x_) * tiles_y_, 0);
}

Seen KeyframeEvidence::operator()(int x, int y) {
  unsigned char& c = cache_.at<unsigned char>(y, x);
  if (c == 0) c = static_cast<unsigned char>(classify(x, y));
  return static_cast<Seen>(c);
}

bool KeyframeEvidence::moving_block(int x, int y) {
  if (x < 1 || y < 1 || x >= cache_.cols - 1 || y >= cache_.rows - 1) return false;
  unsigned char& b = block_.at<unsigned char>(y, x);
  if (b == 0) {
    bool all = true;
    for (int v = y - 1; v <= y + 1 && all; ++v)
      for (int u = x - 1; u <= x + 1 && all; ++u) all = (*this)(u, v) == Seen::kMoving;
    b = all ? 2 : 1;
  }
  return b == 2;
}

bool KeyframeEvidence::moving_area(int x, int y) {
  unsigned char& a = area_.at<unsigned char>(y, x);
  if (a == 0) {
    bool any = false;
    if ((*this)(x, y) == Seen::kMoving)
      for (int cy = y - 1; cy <= y + 1 && !any; ++cy)
        for (int cx = x - 1; cx <= x + 1 && !any; ++cx) any = moving_block(cx, cy);
    a = any ? 2 : 1;
  }
  return a == 2;
}

void KeyframeEvidence::warp_tiles(const cv::Rect& r) {
  const cv::Rect c = r & cv::Rect(0, 0, depth_.cols, depth_.rows);
  if (c.empty()) return;
  for (int ty = c.y / kTile; ty <= (c.y + c.height - 1) / kTile; ++ty)
    for (int tx = c.x / kTile; tx <= (c.x + c.width - 1) / kTile; ++tx) {
      unsigned char& done = tile_done_[static_cast<size_t>(ty) * tiles_x_ + tx];
      if (done) continue;
      done = 1;
      const cv::Rect tile = cv::Rect(tx * kTile, ty * kTile, kTile, kTile) & cv::Rect(0, 0, depth_.cols, depth_.rows);
      for (Warped& wk : warped_) warp_tile(wk, tile);
    }
}

// The keyframe resampled through the current pixels' surfaces in `tile`:
// where its depth agrees, where it sees beyond, and its grey.
void KeyframeEvidence::warp_tile(Warped& wk, const cv::Rect& tile) {
  const Reference& ref = *wk.ref;
  const KeyframeMaps& km = *ref.maps;
  const int w = depth_.cols;
  const cv::Size ksize = km.depths.size();
  cv::Mat map_x(tile.size(), CV_32FC1, cv::Scalar(-1)), map_y(tile.size(), CV_32FC1, cv::Scalar(-1));
  cv::Mat z_k(tile.size(), CV_32FC1, cv::Scalar(0));
  for (int j = 0; j < tile.height; ++j) {
    const int y = tile.y + j;
    const float* d = depth_.ptr<float>(y);
    float* mx = map_x.ptr<float>(j);
    float* my = map_y.ptr<float>(j);
    float* zk = z_k.ptr<float>(j);
    for (int i = 0; i < tile.width; ++i) {
      const int x = tile.x + i;
      if (!view::valid_depth(d[x])) continue;
      const cv::Point2f& ray = rays_[static_cast<size_t>(y) * w + x];
      const Eigen::Vector3d P_k = ref.T_kc * Eigen::Vector3d(ray.x * d[x], ray.y * d[x], d[x]);
      const cv::Point2f q = camera_.project(P_k);
      if (!view::inside(q, ksize)) continue;
      mx[i] = q.x;
      my[i] = q.y;
      zk[i] = static_cast<float>(P_k.z());
    }
  }
  const float far = std::numeric_limits<float>::max();
  const float tau = static_cast<float>(o_.depth_threshold_m);
  for (int j = 0; j < tile.height; ++j) {
    const float* mx = map_x.ptr<float>(j);
    const float* my = map_y.ptr<float>(j);
    const float* zk = z_k.ptr<float>(j);
    unsigned char* a = wk.agree.ptr<unsigned char>(tile.y + j) + tile.x;
    unsigned char* t = wk.through.ptr<unsigned char>(tile.y + j) + tile.x;
    std::fill(a, a + tile.width, 0);
    std::fill(t, t + tile.width, 0);
    for (int i = 0; i < tile.width; ++i) {
      if (zk[i] <= 0.f) continue;
      // The keyframe's depths at the nearest pixel, as cv::remap with
      // INTER_NEAREST reads them (coordinates rounded by cvRound, 0 outside;
      // a pixel with zk > 0 was projected inside).
      const int qx = cvRound(mx[i]), qy = cvRound(my[i]);
      if (qx < 0 || qy < 0 || qx >= ksize.width || qy >= ksize.height) continue;
      const cv::Vec4f& dk = km.depths.at<cv::Vec4f>(qy, qx);
      const float dn = dk[0], dl = dk[1], dh = dk[2];
      if (dh <= 0.f) continue;
      const auto near = [&](float v) { return v > 0.f && v < far && std::abs(v - zk[i]) <= tau; };
      // 2: the keyframe's window lies on one surface, so its grey there is
      // that surface's and not blended with a neighbour across a depth edge.
      if (near(dn) || near(dl) || near(dh)) a[i] = dh - dl <= tau ? 2 : 1;
      else if (dl > zk[i] + tau && dl < far) t[i] = 1;
    }
  }
  if (!wk.grey.empty()) {
    cv::Mat out = wk.grey(tile);  // remap writes into the tile: same size and type
    cv::remap(km.grey, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    for (int j = 0; j < tile.height; ++j) {
      const unsigned char* a = wk.agree.ptr<unsigned char>(tile.y + j) + tile.x;
      const unsigned char* e = edge_.ptr<unsigned char>(tile.y + j) + tile.x;
      unsigned char* ok = wk.usable.ptr<unsigned char>(tile.y + j) + tile.x;
      for (int i = 0; i < tile.width; ++i) ok[i] = a[i] == 2 && !e[i];
    }
  }
}

Seen KeyframeEvidence::classify(int x, int y) {
  // The texture test reads the keyframes around (x, y).
  const int pr = std::max(0, o_.confirm_patch_radius_px);
  warp_tiles(cv::Rect(x - pr, y - pr, 2 * pr + 1, 2 * pr + 1));

  // Static when some keyframe agrees in depth and, where it has a grey, in
  // texture; else moving when some keyframe saw through P's place or
  // disagreed in texture. The answer does not depend on which keyframe is
  // asked first, so the texture tests run two at a time (almost every
  // pixel asked about is moving, where all of them run: 95 % on `dynaorb
  // synth --movers 3` seed 0).
  bool moving = false;
  const Warped* textured[kTextureLanes];
  int n = 0;
  for (const Warped& wk : warped_) {
    if (wk.through.at<unsigned char>(y, x)) {
      moving = true;
      continue;
    }
    if (!wk.agree.at<unsigned char>(y, x)) continue;
    if (wk.grey.empty()) return Seen::kStatic;
    moving = true;
    textured[n++] = &wk;
    if (n == kTextureLanes) {
      if (texture_agrees_lanes(textured, x, y)) return Seen::kStatic;
      n = 0;
    }
  }
  for (int i = 0; i < n; ++i)
    if (texture_agrees(*textured[i], x, y)) return Seen::kStatic;
  return moving ? Seen::kMoving : Seen::kNothing;
}

namespace {

// The texture test's decision from its sums over the n patch pixels taken
// (see texture_agrees).
bool texture_decision(double sk, double sc, double skk, double scc, double skc, int n, int pr, const DdlOptions& o) {
  if (4 * n < (2 * pr + 1) * (2 * pr + 1)) return true;
  const double vk = skk - sk * sk / n, vc = scc - sc * sc / n, ckc = skc - sk * sc / n;
  const double min_var = o.confirm_min_std_grey * o.confirm_min_std_grey * n;
  // A flat patch in both images: no texture to compare.
  if (vk < min_var && vc < min_var) return true;
  if (vk < min_var || vc < min_var) return false;
  return ckc / std::sqrt(vk * vc) >= o.confirm_min_zncc;
}

}  // namespace

// Zero-mean normalised cross-correlation over the patch pixels on P's own
// surface (current depth within tau_d of P's) whose depth the keyframe
// confirms, away from depth edges in either image; fewer than a quarter
// of the patch, or flat in both images: depth alone decides. Flat in one
// image only: the texture changed.
bool KeyframeEvidence::texture_agrees(const Warped& wk, int x, int y) const {
  const int pr = std::max(0, o_.confirm_patch_radius_px);
  const float z0 = depth_.at<float>(y, x);
  const float tau = static_cast<float>(o_.depth_threshold_m);
  double sk = 0, sc = 0, skk = 0, scc = 0, skc = 0;
  int n = 0;
  for (int v = std::max(0, y - pr); v <= std::min(depth_.rows - 1, y + pr); ++v) {
    const float* d = depth_.ptr<float>(v);
    const unsigned char* ok = wk.usable.ptr<unsigned char>(v);
    const float* gk = wk.grey.ptr<float>(v);
    const float* gc = grey_.ptr<float>(v);
    // Branch-free: a pixel left out adds exact zeros, so the sums are those
    // of the pixels taken, in the same order.
    for (int u = std::max(0, x - pr); u <= std::min(depth_.cols - 1, x + pr); ++u) {
      const bool use = ok[u] && !(std::abs(d[u] - z0) > tau);
      const float k = use ? gk[u] : 0.f, c = use ? gc[u] : 0.f;
      sk += k;
      sc += c;
      skk += k * k;
      scc += c * c;
      skc += k * c;
      n += use;
    }
  }
  return texture_decision(sk, sc, skk, scc, skc, n, pr, o_);
}

// texture_agrees for up to kTextureLanes keyframes in one pass: each lane
// adds its own keyframe's terms in texture_agrees's order (exact zeros for
// the pixels it leaves out), so its sums are bit for bit texture_agrees's;
// the lanes are independent chains of additions, which the processor (and
// the compiler's vector units) run side by side.
bool KeyframeEvidence::texture_agrees_lanes(const Warped* const* wks, int x, int y) const {
  constexpr int L = kTextureLanes;
  const int pr = std::max(0, o_.confirm_patch_radius_px);
  const float z0 = depth_.at<float>(y, x);
  const float tau = static_cast<float>(o_.depth_threshold_m);
  alignas(16) double sk[L], sc[L], skk[L], scc[L], skc[L];
  int n[L] = {};
  const int u0 = std::max(0, x - pr), u1 = std::min(depth_.cols - 1, x + pr);
#if defined(__SSE2__)
  static_assert(L == 2, "one SSE register of doubles per term");
  // Both lanes in one register per term: float products (mulps is mulss
  // lane by lane), widened to double exactly (cvtps2pd) and added lane by
  // lane (addpd), in the scalar loop's order.
  __m128d ak = _mm_setzero_pd(), ac = ak, akk = ak, acc = ak, akc = ak;
#else
  for (int l = 0; l < L; ++l) sk[l] = sc[l] = skk[l] = scc[l] = skc[l] = 0;
#endif
  for (int v = std::max(0, y - pr); v <= std::min(depth_.rows - 1, y + pr); ++v) {
    const float* d = depth_.ptr<float>(v);
    const float* gc = grey_.ptr<float>(v);
    const unsigned char* ok[L];
    const float* gk[L];
    for (int l = 0; l < L; ++l) {
      ok[l] = wks[l]->usable.ptr<unsigned char>(v);
      gk[l] = wks[l]->grey.ptr<float>(v);
    }
    for (int u = u0; u <= u1; ++u) {
      const bool near = !(std::abs(d[u] - z0) > tau);
      const bool use0 = ok[0][u] && near, use1 = ok[1][u] && near;
      n[0] += use0;
      n[1] += use1;
      const float k0 = use0 ? gk[0][u] : 0.f, k1 = use1 ? gk[1][u] : 0.f;
      const float c0 = use0 ? gc[u] : 0.f, c1 = use1 ? gc[u] : 0.f;
#if defined(__SSE2__)
      const __m128 k = _mm_setr_ps(k0, k1, 0.f, 0.f), c = _mm_setr_ps(c0, c1, 0.f, 0.f);
      ak = _mm_add_pd(ak, _mm_cvtps_pd(k));
      ac = _mm_add_pd(ac, _mm_cvtps_pd(c));
      akk = _mm_add_pd(akk, _mm_cvtps_pd(_mm_mul_ps(k, k)));
      acc = _mm_add_pd(acc, _mm_cvtps_pd(_mm_mul_ps(c, c)));
      akc = _mm_add_pd(akc, _mm_cvtps_pd(_mm_mul_ps(k, c)));
#else
      sk[0] += k0;
      sk[1] += k1;
      sc[0] += c0;
      sc[1] += c1;
      skk[0] += k0 * k0;
      skk[1] += k1 * k1;
      scc[0] += c0 * c0;
      scc[1] += c1 * c1;
      skc[0] += k0 * c0;
      skc[1] += k1 * c1;
#endif
    }
  }
#if defined(__SSE2__)
  _mm_store_pd(sk, ak);
  _mm_store_pd(sc, ac);
  _mm_store_pd(skk, akk);
  _mm_store_pd(scc, acc);
  _mm_store_pd(skc, akc);
#endif
  for (int l = 0; l < L; ++l)
    if (texture_decision(sk[l], sc[l], skk[l], scc[l], skc[l], n[l], pr, o_)) return true;
  return false;
}

}  // namespace dynaorb::dynamic::ddl
