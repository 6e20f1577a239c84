// DDL-SLAM's multi-view geometry (Algorithm 1) and the region growing that
// turns its dynamic points into dynamic regions.
#include "dynaorb/dynamic/ddl_stage.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <optional>

#include "file_node_options.h"
#include "view_geometry.h"

namespace dynaorb::dynamic {

void DdlOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "reference_keyframes", reference_keyframes);
  read_option(node, "min_overlap", min_overlap);
  read_option(node, "parallax_threshold_deg", parallax_threshold_deg);
  read_option(node, "parallax_marks_dynamic", parallax_marks_dynamic);
  read_option(node, "depth_threshold_m", depth_threshold_m);
  read_option(node, "max_depth_m", max_depth_m);
  read_option(node, "depth_search_radius_px", depth_search_radius_px);
  read_option(node, "border_px", border_px);
  read_option(node, "refine_pose", refine_pose);
  read_option(node, "refine_reprojection_px", refine_reprojection_px);
  read_option(node, "refine_max_shift_px", refine_max_shift_px);
  read_option(node, "refine_min_inliers", refine_min_inliers);
  read_option(node, "refine_points_per_keyframe", refine_points_per_keyframe);
  read_option(node, "vanished_points_dynamic", vanished_points_dynamic);
  read_option(node, "confirm_with_keyframes", confirm_with_keyframes);
  read_option(node, "confirm_search_radius_px", confirm_search_radius_px);
  read_option(node, "confirm_min_zncc", confirm_min_zncc);
  read_option(node, "confirm_min_std_grey", confirm_min_std_grey);
  read_option(node, "confirm_patch_radius_px", confirm_patch_radius_px);
  read_option(node, "confirm_blur_sigma_px", confirm_blur_sigma_px);
  read_option(node, "grow_max_step_inv_depth", grow_max_step_inv_depth);
  read_option(node, "grow_max_from_seed_m", grow_max_from_seed_m);
  read_option(node, "dilation_px", dilation_px);
  read_option(node, "combine_semantic", combine_semantic);
}

namespace {

bool is_depth(const cv::Mat& m, const cv::Size& size) {
  return !m.empty() && m.type() == CV_32FC1 && m.size() == size;
}

bool is_mask(const cv::Mat& m, const cv::Size& size) {
  return !m.empty() && m.type() == CV_8UC1 && m.size() == size;
}

bool mask_at(const cv::Mat& mask, const cv::Point2f& p) {
  const int x = cvRound(p.x), y = cvRound(p.y);
  if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows) return false;
  return mask.at<unsigned char>(y, x) != 0;
}

// The pose of the low-cost tracking (DDL-SLAM Fig. 2: "the camera poses are
// tracked utilizing the static part of the frame", before the multi-view
// check). source: 1 tracked, 2 ego-motion, 3 SLAM's prediction.
std::optional<Eigen::Isometry3d> current_pose(const Context& ctx, int& source) {
  if (ctx.current.T_cw) {
    source = 1;
    return ctx.current.T_cw;
  }
  // The ego-motion comes from the points outside the movable-class regions:
  // the paper's tracking on the static part. The constant-velocity
  // prediction ignores this frame's images altogether, so it comes last.
  if (ctx.ego && ctx.ego->valid && ctx.previous && ctx.previous->T_cw) {
    source = 2;
    return ctx.ego->T_cur_prev * *ctx.previous->T_cw;
  }
  if (ctx.T_cw_predicted) {
    source = 3;
    return ctx.T_cw_predicted;
  }
  source = 0;
  return std::nullopt;
}

// One reference keyframe: its keypoints as world points, where they fall in
// the current image, and what the keyframe check needs.
struct Reference {
  const KeyFrameData* kf = nullptr;
  int order = 0;  // position in ctx.keyframes (newest last)
  Eigen::Vector3d centre_w;
  Eigen::Isometry3d T_kc;  // current camera -> keyframe camera
  std::vector<cv::Point2f> px;       // the keypoints kept, in the keyframe's image
  std::vector<Eigen::Vector3d> X_w;
  std::vector<Eigen::Vector3d> X_c;  // in the current camera
  std::vector<cv::Point2f> proj;     // raw current pixels (NaN: not in front / out of reach)
  int in_view = 0;
  double overlap = 0;
  bool dense = false;  // depth image of the current size, usable by the keyframe check
};

// The keyframe's static keypoints with depth, back-projected (Algorithm 1
// line 6, "corresponding 3D point X"). Keypoints inside the keyframe's own
// dynamic mask are skipped: SLAM extracts none there, and a point on a
// moving object says nothing about the current frame.
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
    if (has_mask && mask_at(f.dynamic, p)) continue;
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

// z' of Algorithm 1: the current depth at x'. With a search window (ours,
// after DynaSLAM's code): the depth in the window closest to z_proj, so a
// projection that misses a depth edge by a pixel or two still finds X's
// surface; 0 when the window holds no depth at all.
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

// What the reference keyframes say about each current pixel's surface P
// (its depth back-projected with the current pose): DdlOptions'
// confirm_with_keyframes. Every keyframe is resampled into the current view
// through P (its depth and grey where P would appear in it), so a static P
// gives back its own depth and texture.
enum class Seen : unsigned char {
  kUnknown = 0,
  kStatic,   // some keyframe saw P there: depth and texture agree
  kMoving,   // some keyframe saw through P's place, or other texture at P's depth
  kNothing,  // no keyframe saw P's place (occluded, out of view, no depth)
};

class KeyframeEvidence {
 public:
  KeyframeEvidence(const cv::Mat& depth, const cv::Mat& grey, const std::vector<cv::Point2f>& rays,
                   const std::vector<Reference>& refs, const view::Camera& camera, const DdlOptions& o)
      : depth_(depth), o_(o), cache_(depth.size(), CV_8UC1, cv::Scalar(0)) {
    texture_ = o.confirm_min_zncc > -1 && grey.size() == depth.size() && grey.type() == CV_8UC1;
    if (texture_) {
      smooth(grey, grey_);
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
    for (const Reference& r : refs)
      if (r.dense) warp(*r.kf->frame, r.T_kc, rays, camera);
  }

  Seen operator()(int x, int y) {
    unsigned char& c = cache_.at<unsigned char>(y, x);
    if (c == 0) c = static_cast<unsigned char>(classify(x, y));
    return static_cast<Seen>(c);
  }

  // Moving, and part of a 3x3 block of moving pixels (a morphological
  // opening): depth edges of a real sensor do not sit exactly where the
  // colour edges are, and leave lines of "moving" a pixel or two wide along
  // static silhouettes; moving objects are areas.
  bool moving_area(int x, int y) {
    if ((*this)(x, y) != Seen::kMoving) return false;
    const int w = cache_.cols, h = cache_.rows;
    for (int cy = y - 1; cy <= y + 1; ++cy)
      for (int cx = x - 1; cx <= x + 1; ++cx) {
        bool all = true;
        for (int v = cy - 1; v <= cy + 1 && all; ++v)
          for (int u = cx - 1; u <= cx + 1 && all; ++u)
            all = u >= 0 && v >= 0 && u < w && v < h && (*this)(u, v) == Seen::kMoving;
        if (all) return true;
      }
    return false;
  }

 private:
  struct Warped {
    cv::Mat agree;    // CV_8UC1: the keyframe's depth there matches P's within tau_d (1; 2: away from its depth edges)
    cv::Mat through;  // CV_8UC1: the keyframe saw beyond P's place
    cv::Mat grey;     // CV_32FC1: the keyframe's (smoothed) grey where P lands, empty without texture
  };

  // Both images are compared slightly blurred: resampling a texture finer
  // than the pixels (a floor at a grazing angle) aliases differently in
  // each view.
  void smooth(const cv::Mat& in, cv::Mat& out) const {
    in.convertTo(out, CV_32F);
    if (o_.confirm_blur_sigma_px > 0) cv::GaussianBlur(out, out, cv::Size(), o_.confirm_blur_sigma_px);
  }

  void warp(const FrameData& f, const Eigen::Isometry3d& T_kc, const std::vector<cv::Point2f>& rays,
            const view::Camera& camera) {
    const cv::Size size = depth_.size();
    const int w = size.width, h = size.height;
    cv::Mat map_x(size, CV_32FC1, cv::Scalar(-1)), map_y(size, CV_32FC1, cv::Scalar(-1));
    cv::Mat z_k(size, CV_32FC1, cv::Scalar(0));
    for (int y = 0; y < h; ++y) {
      const float* d = depth_.ptr<float>(y);
      float* mx = map_x.ptr<float>(y);
      float* my = map_y.ptr<float>(y);
      float* zk = z_k.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        if (!view::valid_depth(d[x])) continue;
        const cv::Point2f& ray = rays[static_cast<size_t>(y) * w + x];
        const Eigen::Vector3d P_k = T_kc * Eigen::Vector3d(ray.x * d[x], ray.y * d[x], d[x]);
        const cv::Point2f q = camera.project(P_k);
        if (!view::inside(q, f.depth.size())) continue;
        mx[x] = q.x;
        my[x] = q.y;
        zk[x] = static_cast<float>(P_k.z());
      }
    }
    // The keyframe's nearest and farthest depth around where P lands: a
    // projection a pixel off a depth edge still finds P's surface (DynaSLAM's
    // code searches a window for z' likewise).
    const float far = std::numeric_limits<float>::max();
    cv::Mat kd;
    f.depth.copyTo(kd);
    cv::patchNaNs(kd, 0);
    const cv::Mat holes = kd <= 0;
    cv::Mat kd_min_src = kd.clone();
    kd_min_src.setTo(far, holes);
    const int r = std::max(0, o_.confirm_search_radius_px);
    const cv::Mat window = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * r + 1, 2 * r + 1));
    cv::Mat kmin, kmax, d_near, d_min, d_max;
    cv::erode(kd_min_src, kmin, window);
    cv::dilate(kd, kmax, window);
    cv::remap(kd, d_near, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::remap(kmin, d_min, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::remap(kmax, d_max, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
    Warped wk;
    wk.agree = cv::Mat(size, CV_8UC1, cv::Scalar(0));
    wk.through = cv::Mat(size, CV_8UC1, cv::Scalar(0));
    const float tau = static_cast<float>(o_.depth_threshold_m);
    for (int y = 0; y < h; ++y) {
      const float* zk = z_k.ptr<float>(y);
      const float* dn = d_near.ptr<float>(y);
      const float* dl = d_min.ptr<float>(y);
      const float* dh = d_max.ptr<float>(y);
      unsigned char* a = wk.agree.ptr<unsigned char>(y);
      unsigned char* t = wk.through.ptr<unsigned char>(y);
      for (int x = 0; x < w; ++x) {
        if (zk[x] <= 0.f || dh[x] <= 0.f) continue;
        const auto near = [&](float v) { return v > 0.f && v < far && std::abs(v - zk[x]) <= tau; };
        // 2: the keyframe's window lies on one surface, so its grey there is
        // that surface's and not blended with a neighbour across a depth edge.
        if (near(dn[x]) || near(dl[x]) || near(dh[x])) a[x] = dh[x] - dl[x] <= tau ? 2 : 1;
        else if (dl[x] > zk[x] + tau && dl[x] < far) t[x] = 1;
      }
    }
    if (texture_ && !f.grey.empty() && f.grey.size() == f.depth.size() && f.grey.type() == CV_8UC1) {
      cv::Mat kf_grey;
      smooth(f.grey, kf_grey);
      cv::remap(kf_grey, wk.grey, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    }
    warped_.push_back(std::move(wk));
  }

  Seen classify(int x, int y) const {
    bool moving = false;
    for (const Warped& wk : warped_) {
      if (wk.through.at<unsigned char>(y, x)) {
        moving = true;
        continue;
      }
      if (!wk.agree.at<unsigned char>(y, x)) continue;
      if (wk.grey.empty() || texture_agrees(wk, x, y)) return Seen::kStatic;
      moving = true;
    }
    return moving ? Seen::kMoving : Seen::kNothing;
  }

  // Zero-mean normalised cross-correlation over the patch pixels on P's own
  // surface (current depth within tau_d of P's) whose depth the keyframe
  // confirms, away from depth edges in either image; fewer than a quarter
  // of the patch, or flat in both images: depth alone decides. Flat in one
  // image only: the texture changed.
  bool texture_agrees(const Warped& wk, int x, int y) const {
    const int pr = std::max(0, o_.confirm_patch_radius_px);
    const float z0 = depth_.at<float>(y, x);
    const float tau = static_cast<float>(o_.depth_threshold_m);
    double sk = 0, sc = 0, skk = 0, scc = 0, skc = 0;
    int n = 0;
    for (int v = std::max(0, y - pr); v <= std::min(depth_.rows - 1, y + pr); ++v) {
      const float* d = depth_.ptr<float>(v);
      const unsigned char* a = wk.agree.ptr<unsigned char>(v);
      const float* gk = wk.grey.ptr<float>(v);
      const float* gc = grey_.ptr<float>(v);
      const unsigned char* e = edge_.ptr<unsigned char>(v);
      for (int u = std::max(0, x - pr); u <= std::min(depth_.cols - 1, x + pr); ++u) {
        if (a[u] != 2 || e[u] || std::abs(d[u] - z0) > tau) continue;
        sk += gk[u];
        sc += gc[u];
        skk += gk[u] * gk[u];
        scc += gc[u] * gc[u];
        skc += gk[u] * gc[u];
        ++n;
      }
    }
    if (4 * n < (2 * pr + 1) * (2 * pr + 1)) return true;
    const double vk = skk - sk * sk / n, vc = scc - sc * sc / n, ckc = skc - sk * sc / n;
    const double min_var = o_.confirm_min_std_grey * o_.confirm_min_std_grey * n;
    // A flat patch in both images: no texture to compare.
    if (vk < min_var && vc < min_var) return true;
    if (vk < min_var || vc < min_var) return false;
    return ckc / std::sqrt(vk * vc) >= o_.confirm_min_zncc;
  }

  const cv::Mat& depth_;
  const DdlOptions& o_;
  bool texture_ = false;
  cv::Mat grey_;
  cv::Mat edge_;
  std::vector<Warped> warped_;
  cv::Mat cache_;
};

// Ours: the pose DDL-SLAM checks with comes from its low-cost tracking,
// ORB-SLAM2's tracking against the map restricted to the static part, which
// the ego-motion or the constant-velocity prediction only approximate; the
// keyframe check compares textures pixel by pixel and needs the pose to a
// pixel. So the reference keyframes' points (X, with depth) are followed from
// their keyframe image into the current one by pyramidal Lucas-Kanade,
// starting where the given pose projects them, and the pose is re-estimated
// from them by PnP RANSAC (points on moving objects are its outliers).
std::optional<Eigen::Isometry3d> refine_pose(const std::vector<Reference>& refs, const cv::Mat& grey,
                                             const map::Calibration& calib, const Eigen::Isometry3d& T_cw,
                                             const DdlOptions& o, StageReport& report) {
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  const cv::Size size = grey.size();
  const cv::Size window(21, 21);
  constexpr int kLevels = 3;
  std::vector<cv::Mat> pyramid;  // the current image's, built once for all keyframes
  cv::buildOpticalFlowPyramid(grey, pyramid, window, kLevels);
  for (const Reference& r : refs) {
    const cv::Mat& kf_grey = r.kf->frame->grey;
    if (kf_grey.empty() || kf_grey.type() != CV_8UC1 || kf_grey.size() != size) continue;
    std::vector<cv::Point2f> from, to;
    std::vector<size_t> idx;
    // A few hundred points fix a pose; more only cost time.
    const size_t stride = std::max<size_t>(1, r.px.size() / std::max(1, o.refine_points_per_keyframe));
    for (size_t i = 0; i < r.px.size(); i += stride) {
      if (!view::inside(r.proj[i], size, o.border_px)) continue;
      from.push_back(r.px[i]);
      to.push_back(r.proj[i]);
      idx.push_back(i);
    }
    if (from.empty()) continue;
    std::vector<unsigned char> ok;
    std::vector<float> err;
    cv::calcOpticalFlowPyrLK(kf_grey, pyramid, from, to, ok, err, window, kLevels,
                             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    for (size_t j = 0; j < from.size(); ++j) {
      if (!ok[j] || !view::inside(to[j], size)) continue;
      if (cv::norm(to[j] - r.proj[idx[j]]) > o.refine_max_shift_px) continue;
      const Eigen::Vector3d& X = r.X_w[idx[j]];
      object.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()), static_cast<float>(X.z()));
      image.push_back(to[j]);
    }
  }
  report.values["refine_points"] = static_cast<double>(object.size());
  if (static_cast<int>(object.size()) < o.refine_min_inliers) return std::nullopt;
  cv::Mat R;
  cv::eigen2cv(Eigen::Matrix3d(T_cw.linear()), R);
  cv::Mat rvec, tvec;
  cv::Rodrigues(R, rvec);
  cv::eigen2cv(Eigen::Vector3d(T_cw.translation()), tvec);
  const cv::Mat dist = calib.dist.empty() ? cv::Mat() : calib.dist;
  std::vector<int> inliers;
  const bool solved = cv::solvePnPRansac(object, image, calib.K, dist, rvec, tvec, true, 200,
                                         static_cast<float>(o.refine_reprojection_px), 0.99, inliers,
                                         cv::SOLVEPNP_ITERATIVE);
  if (!solved) return std::nullopt;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d Re;
  Eigen::Vector3d te;
  cv::cv2eigen(R, Re);
  cv::cv2eigen(tvec, te);
  Eigen::Isometry3d refined = Eigen::Isometry3d::Identity();
  refined.linear() = Re;
  refined.translation() = te;
  if (!refined.matrix().allFinite()) return std::nullopt;
  // The refined pose must explain more of the points than the given one
  // (RANSAC's final fit can drift, and on a frame full of movers a
  // consensus of moving points can win); points behind the camera count
  // against it.
  const view::Camera camera(calib);
  const auto explained = [&](const Eigen::Isometry3d& T, double threshold) {
    int n = 0;
    for (size_t i = 0; i < object.size(); ++i) {
      const cv::Point2f q = camera.project(T * Eigen::Vector3d(object[i].x, object[i].y, object[i].z));
      if (std::isfinite(q.x) && cv::norm(q - image[i]) <= threshold) ++n;
    }
    return n;
  };
  const int n_refined = explained(refined, o.refine_reprojection_px);
  report.values["refine_inliers"] = n_refined;
  if (n_refined < o.refine_min_inliers) return std::nullopt;
  // Compared at half the threshold, and by a clear margin (5 %): a pose
  // that is right puts the static points within a fraction of a pixel, a
  // compromise with moving ones does not, and a given pose that is already
  // right is kept.
  const int n_close = explained(refined, 0.5 * o.refine_reprojection_px);
  const int n_given = explained(T_cw, 0.5 * o.refine_reprojection_px);
  report.values["refine_close"] = n_close;
  report.values["refine_close_given_pose"] = n_given;
  if (n_close <= n_given + std::max(5, n_given / 20)) return std::nullopt;
  const Eigen::Isometry3d D = refined * T_cw.inverse();
  report.values["pose_correction_m"] = D.translation().norm();
  report.values["pose_correction_deg"] = Eigen::AngleAxisd(D.linear()).angle() * 180.0 / M_PI;
  return refined;
}

}  // namespace

cv::Mat ddl_grow_regions(const cv::Mat& depth, const std::vector<cv::Point>& seeds, const DdlOptions& o,
                         const std::function<bool(int, int)>& blocked) {
  cv::Mat region(depth.size(), CV_8UC1, cv::Scalar(0));
  if (depth.empty() || depth.type() != CV_32FC1) return region;
  const int w = depth.cols, h = depth.rows;
  std::vector<int> queue;
  const double step = o.grow_max_step_inv_depth;
  const double band = o.grow_max_from_seed_m;
  for (const cv::Point& s : seeds) {
    if (s.x < 0 || s.y < 0 || s.x >= w || s.y >= h) continue;
    if (region.at<unsigned char>(s) != 0) continue;
    const float zs = depth.at<float>(s);
    if (!view::valid_depth(zs)) continue;
    queue.clear();
    queue.push_back(s.y * w + s.x);
    region.at<unsigned char>(s) = 255;
    for (size_t head = 0; head < queue.size(); ++head) {
      const int x = queue[head] % w, y = queue[head] / w;
      const float zp = depth.at<float>(y, x);
      const int nx[4] = {x - 1, x + 1, x, x};
      const int ny[4] = {y, y, y - 1, y + 1};
      for (int k = 0; k < 4; ++k) {
        if (nx[k] < 0 || ny[k] < 0 || nx[k] >= w || ny[k] >= h) continue;
        unsigned char& m = region.at<unsigned char>(ny[k], nx[k]);
        if (m != 0) continue;
        const float zq = depth.at<float>(ny[k], nx[k]);
        if (!view::valid_depth(zq)) continue;
        if (std::abs(1.0 / zq - 1.0 / zp) > step) continue;
        if (band > 0 && std::abs(zq - zs) > band) continue;
        if (blocked && blocked(nx[k], ny[k])) continue;
        m = 255;
        queue.push_back(ny[k] * w + nx[k]);
      }
    }
  }
  return region;
}

void DdlStage::process(Context& ctx, StageReport& report) {
  report.values["tau_alpha_deg"] = o_.parallax_threshold_deg;
  report.values["tau_d_m"] = o_.depth_threshold_m;
  FrameData& cur = ctx.current;
  if (!ctx.calib || cur.grey.empty()) {
    report.values["skipped_bad_input"] = 1;
    return;
  }
  const map::Calibration& calib = *ctx.calib;
  const cv::Size size = cur.grey.size();
  if (cur.depth.empty()) {
    // Stereo without a disparity stage before this one, or RGB-D without depth.
    report.values["skipped_no_depth"] = 1;
    return;
  }
  if (!is_depth(cur.depth, size)) {
    report.values["skipped_bad_input"] = 1;
    return;
  }
  if (ctx.dynamic.empty()) ctx.dynamic = cv::Mat(size, CV_8UC1, cv::Scalar(0));
  if (!is_mask(ctx.dynamic, size)) {
    report.values["skipped_bad_input"] = 1;
    return;
  }

  // The semantic half of the combined mask does not depend on the geometry:
  // it is applied even when the geometric check cannot run.
  const bool semantic = o_.combine_semantic && is_mask(cur.candidates, size);
  const auto combine = [&](const cv::Mat& geometric) {
    double semantic_pixels = 0;
    if (semantic) {
      cv::bitwise_or(ctx.dynamic, cur.candidates, ctx.dynamic);
      semantic_pixels = cv::countNonZero(cur.candidates);
    }
    report.values["semantic_pixels"] = semantic_pixels;
    if (!geometric.empty()) cv::bitwise_or(ctx.dynamic, geometric, ctx.dynamic);
    cv::Mat both = geometric.empty() ? cv::Mat(size, CV_8UC1, cv::Scalar(0)) : geometric.clone();
    if (semantic) cv::bitwise_or(both, cur.candidates, both);
    report.values["combined_pixels"] = cv::countNonZero(both);
  };

  int source = 0;
  std::optional<Eigen::Isometry3d> T_cw = current_pose(ctx, source);
  report.values["pose_source"] = source;
  if (!T_cw) {
    report.values["skipped_no_pose"] = 1;
    combine(cv::Mat());
    return;
  }
  if (!ctx.keyframes || ctx.keyframes->empty()) {
    report.values["skipped_no_keyframes"] = 1;
    combine(cv::Mat());
    return;
  }

  // GetRefFrames: overlap = the share of a keyframe's points that land in
  // the current image in front of the camera.
  const view::Camera camera(calib);
  Eigen::Isometry3d T_wc = T_cw->inverse();
  std::vector<Reference> refs;
  for (size_t k = 0; k < ctx.keyframes->size(); ++k) {
    const KeyFrameData& kf = (*ctx.keyframes)[k];
    if (kf.frame && kf.frame->id == cur.id && cur.id >= 0) continue;
    Reference r;
    if (!back_project(kf, camera, o_.max_depth_m, r)) continue;
    r.order = static_cast<int>(k);
    r.T_kc = *kf.frame->T_cw * T_wc;
    r.dense = is_depth(kf.frame->depth, size);
    r.X_c.reserve(r.X_w.size());
    for (const Eigen::Vector3d& X : r.X_w) r.X_c.push_back(*T_cw * X);
    r.proj = camera.project(r.X_c);
    for (const cv::Point2f& p : r.proj)
      if (view::inside(p, size, o_.border_px)) ++r.in_view;
    r.overlap = static_cast<double>(r.in_view) / static_cast<double>(r.X_w.size());
    if (r.in_view > 0 && r.overlap >= o_.min_overlap) refs.push_back(std::move(r));
  }
  if (refs.empty()) {
    report.values["skipped_no_keyframes"] = 1;
    combine(cv::Mat());
    return;
  }
  std::stable_sort(refs.begin(), refs.end(), [](const Reference& a, const Reference& b) {
    return a.overlap != b.overlap ? a.overlap > b.overlap : a.order > b.order;
  });
  if (o_.reference_keyframes > 0 && static_cast<int>(refs.size()) > o_.reference_keyframes)
    refs.resize(static_cast<size_t>(o_.reference_keyframes));
  report.values["keyframes_used"] = static_cast<double>(refs.size());

  report.values["pose_refined"] = 0;
  if (o_.refine_pose) {
    std::optional<Eigen::Isometry3d> refined;
    try {
      refined = refine_pose(refs, cur.grey, calib, *T_cw, o_, report);
    } catch (const cv::Exception&) {
      report.values["refine_failed"] = 1;  // degenerate point sets: keep the given pose
    }
    if (refined) {
      T_cw = refined;
      T_wc = T_cw->inverse();
      for (Reference& r : refs) {
        r.T_kc = *r.kf->frame->T_cw * T_wc;
        for (size_t i = 0; i < r.X_w.size(); ++i) r.X_c[i] = *T_cw * r.X_w[i];
        r.proj = camera.project(r.X_c);
      }
      report.values["pose_refined"] = 1;
    }
  }

  if (o_.confirm_with_keyframes && (rays_calib_ != ctx.calib || rays_size_ != size)) {
    rays_ = camera.image_rays(size.width, size.height);
    rays_calib_ = ctx.calib;
    rays_size_ = size;
  }
  // Built at the first dynamic point that needs it.
  std::optional<KeyframeEvidence> keyframe_evidence;
  const auto evidence = [&](int x, int y) {
    if (!keyframe_evidence) keyframe_evidence.emplace(cur.depth, cur.grey, rays_, refs, camera, o_);
    return (*keyframe_evidence)(x, y);
  };

  const double cos_tau_alpha = std::cos(o_.parallax_threshold_deg * M_PI / 180.0);
  int projected = 0, parallax_rejected = 0, no_depth = 0, vanished = 0, seen_static_rejected = 0,
      vanished_rejected = 0;
  std::vector<cv::Point> seeds;
  for (const Reference& r : refs) {
    for (size_t i = 0; i < r.X_w.size(); ++i) {
      const cv::Point2f& p = r.proj[i];
      if (!view::inside(p, size, o_.border_px)) continue;
      const double z_proj = r.X_c[i].z();
      if (o_.max_depth_m > 0 && z_proj > o_.max_depth_m) continue;
      ++projected;
      const cv::Point q(cvRound(p.x), cvRound(p.y));
      // alpha = angle xXx': between the rays from X to both camera centres.
      const Eigen::Vector3d a = r.centre_w - r.X_w[i], b = T_wc.translation() - r.X_w[i];
      const double na = a.norm(), nb = b.norm();
      if (na > 0 && nb > 0 && a.dot(b) / (na * nb) < cos_tau_alpha) {
        ++parallax_rejected;
        if (o_.parallax_marks_dynamic) {
          report.dynamic_points.push_back(p);
          seeds.push_back(q);
        }
        continue;
      }
      const float z_meas = closest_depth(cur.depth, q, static_cast<float>(z_proj), o_.depth_search_radius_px);
      if (z_meas <= 0.f) {
        ++no_depth;
        continue;
      }
      const double dz = z_proj - z_meas;  // Algorithm 1 line 11: Delta d = d_p - d_x'
      const bool covered = dz > o_.depth_threshold_m;
      const bool gone = o_.vanished_points_dynamic && -dz > o_.depth_threshold_m;
      if ((covered || gone) && o_.confirm_with_keyframes) {
        const Seen seen = evidence(q.x, q.y);
        if (seen == Seen::kStatic) {
          ++seen_static_rejected;
          report.static_points.push_back(p);
          continue;
        }
        // X is gone, but what the current frame shows at x' may be
        // background it had hidden (always unseen by the keyframes, or
        // static): only a pixel with motion evidence of its own is dynamic.
        if (!covered && !keyframe_evidence->moving_area(q.x, q.y)) {
          ++vanished_rejected;
          continue;
        }
      }
      if (covered || gone) {
        if (gone) ++vanished;
        report.dynamic_points.push_back(p);
        seeds.push_back(q);
      } else {
        report.static_points.push_back(p);
      }
    }
  }
  report.values["projected"] = projected;
  report.values["parallax_rejected"] = parallax_rejected;
  report.values["no_depth"] = no_depth;
  report.values["vanished"] = vanished;
  report.values["seen_static_rejected"] = seen_static_rejected;
  report.values["vanished_rejected"] = vanished_rejected;
  report.values["dynamic"] = static_cast<double>(report.dynamic_points.size());
  report.values["static"] = static_cast<double>(report.static_points.size());

  // Growing needs evidence of motion at every pixel it takes: seen static
  // stops it, and so does a place no keyframe saw (background that was
  // always hidden continues the floor's depth as much as the object does).
  std::function<bool(int, int)> blocked;
  if (o_.confirm_with_keyframes) {
    blocked = [&](int x, int y) {
      evidence(x, y);  // builds the evidence on first use
      return !keyframe_evidence->moving_area(x, y);
    };
  }
  cv::Mat region = ddl_grow_regions(cur.depth, seeds, o_, blocked);
  report.values["region_pixels"] = cv::countNonZero(region);
  if (o_.dilation_px > 0 && !seeds.empty()) {
    const int d = o_.dilation_px;
    cv::dilate(region, region, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * d + 1, 2 * d + 1)));
  }
  cv::Mat labels;
  report.regions = seeds.empty() ? 0 : cv::connectedComponents(region, labels, 8, CV_32S) - 1;
  combine(region);
}

}  // namespace dynaorb::dynamic
