// Background inpainting from the previous keyframes (DDL-SLAM Sec. III-E).
//
// Forward-warping colour pixel by pixel leaves cracks wherever the current
// view is closer than the keyframe, and blurs texture. So each keyframe is
// used in two passes: its static pixels are forward-warped as depth only,
// into a z-buffer over the current dynamic pixels (each sample splatted on
// the four pixels around where it lands, as DynaSLAM's FillRGBD does); then
// every dynamic pixel with a warped depth is back-projected at that depth
// into the keyframe, and the keyframe's image is sampled there when the
// keyframe's own depth confirms it sees that surface.
#include "dynaorb/dynamic/inpainting.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <opencv2/imgproc.hpp>

#include "file_node_options.h"
#include "view_geometry.h"

namespace dynaorb::dynamic {

void InpaintOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "keyframes", keyframes);
  read_option(node, "depth_tolerance_m", depth_tolerance_m);
  read_option(node, "depth_tolerance_ratio", depth_tolerance_ratio);
  read_option(node, "max_depth_m", max_depth_m);
  read_option(node, "keyframe_mask_margin_px", keyframe_mask_margin_px);
  read_option(node, "background_behind_object", background_behind_object);
  read_option(node, "stereo_num_disparities", stereo.num_disparities);
  read_option(node, "stereo_block_size", stereo.block_size);
  read_option(node, "stereo_uniqueness_ratio", stereo.uniqueness_ratio);
  read_option(node, "stereo_speckle_window", stereo.speckle_window);
  read_option(node, "stereo_speckle_range", stereo.speckle_range);
  read_option(node, "stereo_disp12_max_diff", stereo.disp12_max_diff);
  read_option(node, "stereo_three_way", stereo.three_way);
  try {
    stereo.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("Dynamic.inpainting: ") + e.what());
  }
}

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// A keyframe the inpainting can use: pose, depth and an image of the current size.
bool usable(const KeyFrameData& kf, const cv::Size& size) {
  if (!kf.frame || !kf.frame->T_cw) return false;
  const FrameData& f = *kf.frame;
  if (f.depth.empty() || f.depth.type() != CV_32FC1 || f.depth.size() != size) return false;
  const bool grey = !f.grey.empty() && f.grey.type() == CV_8UC1 && f.grey.size() == size;
  const bool colour = !f.colour.empty() && f.colour.type() == CV_8UC3 && f.colour.size() == size;
  return grey || colour;
}

// Bilinear sample of an 8-bit image (1 or 3 channels) at q; nearest pixel
// when the 2x2 footprint touches the keyframe's dynamic mask, so moving
// objects do not bleed into the background.
template <typename T>
T sample(const cv::Mat& img, const cv::Mat& mask, const cv::Point2f& q) {
  const int x0 = static_cast<int>(std::floor(q.x)), y0 = static_cast<int>(std::floor(q.y));
  const int x1 = std::min(x0 + 1, img.cols - 1), y1 = std::min(y0 + 1, img.rows - 1);
  const bool clean = mask.at<unsigned char>(y0, x0) == 0 && mask.at<unsigned char>(y0, x1) == 0 &&
                     mask.at<unsigned char>(y1, x0) == 0 && mask.at<unsigned char>(y1, x1) == 0;
  if (!clean) return img.at<T>(cvRound(q.y), cvRound(q.x));
  const float ax = q.x - x0, ay = q.y - y0;
  const cv::Vec<float, cv::DataType<T>::channels> v =
      (1 - ax) * (1 - ay) * cv::Vec<float, cv::DataType<T>::channels>(img.at<T>(y0, x0)) +
      ax * (1 - ay) * cv::Vec<float, cv::DataType<T>::channels>(img.at<T>(y0, x1)) +
      (1 - ax) * ay * cv::Vec<float, cv::DataType<T>::channels>(img.at<T>(y1, x0)) +
      ax * ay * cv::Vec<float, cv::DataType<T>::channels>(img.at<T>(y1, x1));
  T out;
  for (int c = 0; c < cv::DataType<T>::channels; ++c) out[c] = cv::saturate_cast<unsigned char>(v[c]);
  return out;
}

}  // namespace

InpaintResult inpaint_background(const FrameData& current, const std::vector<KeyFrameData>& keyframes,
                                 const map::Calibration& calib, const InpaintOptions& o) {
  InpaintResult r;
  if (current.grey.empty() || current.grey.type() != CV_8UC1) {
    r.values["skipped_bad_input"] = 1;
    return r;
  }
  const cv::Size size = current.grey.size();
  const int w = size.width, h = size.height;
  r.grey = current.grey.clone();
  if (!current.colour.empty() && current.colour.type() == CV_8UC3 && current.colour.size() == size)
    r.colour = current.colour.clone();
  const bool has_depth =
      !current.depth.empty() && current.depth.type() == CV_32FC1 && current.depth.size() == size;
  if (has_depth)
    r.depth = current.depth.clone();
  else
    r.depth = cv::Mat(size, CV_32FC1, cv::Scalar(0));
  r.filled = cv::Mat(size, CV_8UC1, cv::Scalar(0));
  if (current.dynamic.empty()) {
    r.values["nothing_to_fill"] = 1;
    return r;
  }
  if (current.dynamic.type() != CV_8UC1 || current.dynamic.size() != size) {
    r.values["skipped_bad_input"] = 1;
    return r;
  }
  const cv::Mat target = current.dynamic != 0;
  r.target_pixels = cv::countNonZero(target);
  if (r.target_pixels == 0) {
    r.values["nothing_to_fill"] = 1;
    return r;
  }
  // The moving object is removed whatever happens next: what is not filled stays empty.
  r.grey.setTo(0, target);
  if (!r.colour.empty()) r.colour.setTo(cv::Scalar::all(0), target);
  r.depth.setTo(0, target);
  if (!current.T_cw) {
    r.values["skipped_no_pose"] = 1;
    return r;
  }

  // The last o.keyframes usable keyframes, newest first.
  std::vector<const KeyFrameData*> used;
  int unusable = 0;
  for (auto it = keyframes.rbegin(); it != keyframes.rend(); ++it) {
    if (o.keyframes > 0 && static_cast<int>(used.size()) >= o.keyframes) break;
    if (it->frame && current.id >= 0 && it->frame->id == current.id) continue;
    if (!usable(*it, size)) {
      ++unusable;
      continue;
    }
    used.push_back(&*it);
  }
  r.values["keyframes_without_pose_or_depth"] = unusable;
  if (used.empty()) {
    r.values["skipped_no_keyframes"] = 1;
    return r;
  }
  r.keyframes_used = static_cast<int>(used.size());

  const auto tolerance = [&](double z) { return std::max(o.depth_tolerance_m, o.depth_tolerance_ratio * z); };

  // Rays of the target pixels of the current view; rays of every keyframe
  // pixel (one grid: all keyframes share the camera).
  std::vector<cv::Point> target_px;
  cv::findNonZero(target, target_px);
  std::vector<cv::Point2f> target_pf(target_px.begin(), target_px.end());
  const view::Camera camera(calib);
  const std::vector<cv::Point2f> target_rays = camera.rays(target_pf);
  const std::vector<cv::Point2f> grid_rays = camera.image_rays(w, h);

  cv::Mat best_z(size, CV_32FC1, cv::Scalar(kInf));
  cv::Mat zk(size, CV_32FC1);
  const Eigen::Isometry3d& T_cw = *current.T_cw;
  std::vector<Eigen::Vector3d> pts;
  std::vector<size_t> pts_pixel;
  for (const KeyFrameData* kf : used) {
    const FrameData& f = *kf->frame;
    const Eigen::Isometry3d T_ck = T_cw * f.T_cw->inverse();
    const Eigen::Isometry3d T_kc = T_ck.inverse();
    cv::Mat kf_mask;
    if (!f.dynamic.empty() && f.dynamic.type() == CV_8UC1 && f.dynamic.size() == size) {
      kf_mask = f.dynamic != 0;
      // A keyframe without a previous frame (the first, the first after a
      // reset) could not check its movable-class regions for motion: they
      // may be a mover, so they are no background source.
      if (!f.motion_checked && !f.candidates.empty() && f.candidates.size() == size)
        kf_mask |= f.candidates != 0;
      if (o.keyframe_mask_margin_px > 0) {
        const int m = o.keyframe_mask_margin_px;
        cv::dilate(kf_mask, kf_mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * m + 1, 2 * m + 1)));
      }
    } else {
      kf_mask = cv::Mat(size, CV_8UC1, cv::Scalar(0));
    }

    // Pass 1: the keyframe's static surface, as depth, into the current view.
    pts.clear();
    for (int v = 0; v < h; ++v) {
      const float* drow = f.depth.ptr<float>(v);
      const unsigned char* mrow = kf_mask.ptr<unsigned char>(v);
      for (int u = 0; u < w; ++u) {
        const float d = drow[u];
        if (!view::valid_depth(d) || mrow[u] || (o.max_depth_m > 0 && d > o.max_depth_m)) continue;
        const cv::Point2f& ray = grid_rays[static_cast<size_t>(v) * w + u];
        pts.push_back(T_ck * Eigen::Vector3d(ray.x * d, ray.y * d, d));
      }
    }
    const std::vector<cv::Point2f> landed = camera.project(pts);
    zk.setTo(kInf);
    for (size_t i = 0; i < pts.size(); ++i) {
      const cv::Point2f& p = landed[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
      const float z = static_cast<float>(pts[i].z());
      const int x0 = static_cast<int>(std::floor(p.x)), y0 = static_cast<int>(std::floor(p.y));
      for (int y = y0; y <= y0 + 1; ++y)
        for (int x = x0; x <= x0 + 1; ++x) {
          if (x < 0 || y < 0 || x >= w || y >= h || !target.at<unsigned char>(y, x)) continue;
          float& zb = zk.at<float>(y, x);
          zb = std::min(zb, z);
        }
    }

    // Pass 2: each target pixel the keyframe reaches with a nearer surface
    // than the newer keyframes gave (by more than the tolerance), read back
    // from the keyframe at that depth.
    pts.clear();
    pts_pixel.clear();
    for (size_t i = 0; i < target_px.size(); ++i) {
      const cv::Point& t = target_px[i];
      const float z = zk.at<float>(t);
      if (!std::isfinite(z)) continue;
      const float zb = best_z.at<float>(t);
      if (std::isfinite(zb) && z >= zb - tolerance(zb)) continue;
      // The background lies behind the object that hides it; a keyframe
      // sample at the object's own depth is the object, missed by that
      // keyframe's mask.
      if (o.background_behind_object && has_depth) {
        const float zc = current.depth.at<float>(t);
        if (view::valid_depth(zc) && z <= zc + tolerance(zc)) continue;
      }
      const cv::Point2f& ray = target_rays[i];
      pts.push_back(T_kc * Eigen::Vector3d(ray.x * z, ray.y * z, z));
      pts_pixel.push_back(i);
    }
    const std::vector<cv::Point2f> in_kf = camera.project(pts);
    const bool kf_colour = !f.colour.empty() && f.colour.type() == CV_8UC3 && f.colour.size() == size;
    const bool kf_grey = !f.grey.empty() && f.grey.type() == CV_8UC1 && f.grey.size() == size;
    for (size_t j = 0; j < pts.size(); ++j) {
      const cv::Point2f& q = in_kf[j];
      if (!view::inside(q, size)) continue;
      const cv::Point qi(cvRound(q.x), cvRound(q.y));
      if (kf_mask.at<unsigned char>(qi)) continue;
      const float dk = f.depth.at<float>(qi);
      const double zq = pts[j].z();
      if (!view::valid_depth(dk) || std::abs(dk - zq) > tolerance(zq)) continue;  // hidden in the keyframe
      const cv::Point& t = target_px[pts_pixel[j]];
      const float z = zk.at<float>(t);
      best_z.at<float>(t) = z;
      r.depth.at<float>(t) = z;
      r.filled.at<unsigned char>(t) = 255;
      cv::Vec3b bgr;
      if (kf_colour) {
        bgr = sample<cv::Vec3b>(f.colour, kf_mask, q);
      } else {
        const unsigned char g = sample<cv::Vec<unsigned char, 1>>(f.grey, kf_mask, q)[0];
        bgr = cv::Vec3b(g, g, g);
      }
      if (kf_grey) {
        r.grey.at<unsigned char>(t) = sample<cv::Vec<unsigned char, 1>>(f.grey, kf_mask, q)[0];
      } else {
        r.grey.at<unsigned char>(t) =
            cv::saturate_cast<unsigned char>(0.114 * bgr[0] + 0.587 * bgr[1] + 0.299 * bgr[2]);
      }
      if (!r.colour.empty()) r.colour.at<cv::Vec3b>(t) = bgr;
    }
  }
  r.filled_pixels = cv::countNonZero(r.filled);
  r.filled_fraction = static_cast<double>(r.filled_pixels) / r.target_pixels;
  r.values["filled_fraction"] = r.filled_fraction;
  return r;
}

}  // namespace dynaorb::dynamic
