#pragma once
// The reference keyframes as DDL-SLAM's multi-view stage (ddl_stage.h) uses
// them: their keypoints back-projected to world points (Algorithm 1), the
// keyframe check that says whether a current pixel's surface was seen
// static by them, and the pose refinement against their points. Internal to
// src/dynamic.
#include <Eigen/Geometry>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "dynaorb/dynamic/ddl_stage.h"
#include "view_geometry.h"

namespace dynaorb::dynamic::ddl {

// A keyframe's images as the keyframe check reads them. They depend on the
// keyframe and the options only, so the stage prepares them once per
// keyframe and keeps them while the keyframe is remembered.
struct KeyframeMaps {
  // CV_32FC4 per pixel: the depth (NaN -> 0); the least valid depth in the
  // (2r+1)^2 window, r = confirm_search_radius_px (FLT_MAX where the window
  // holds none); the greatest depth in the window (0 where none); 0. One
  // pixel's three in one cache line: the keyframe check reads them together
  // at scattered pixels.
  cv::Mat depths;
  cv::Mat grey;       // CV_32FC1 smoothed grey; empty without a usable grey image or texture test
  bool check = false;  // depths and grey are made
  // The keyframe grey's LK pyramid (with derivatives) for refine_pose; empty
  // when not made or without a usable grey image.
  std::vector<cv::Mat> pyramid;
  bool pyramid_made = false;
};

// refine_pose's Lucas-Kanade window and pyramid levels above the image.
// Two levels (neither paper prescribes LK here): LK starts where the given
// pose projects a point and a shift beyond refine_max_shift_px (30 px) is
// dropped anyway; a 21x21 window two octaves up follows about 10 px x 4 =
// 40 px. A third level (as before) cost a quarter more LK time and gave
// the same masks on `dynaorb synth --movers 3` seed 0 (ddl and full).
inline const cv::Size kRefineWindow(21, 21);
constexpr int kRefineLevels = 2;

// Makes what `m` lacks of the check images (check) and the LK pyramid
// (pyramid) for frame `f`. Without a depth image the check images stay empty.
void prepare_keyframe_maps(const FrameData& f, const DdlOptions& o, bool check, bool pyramid, KeyframeMaps& m);

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
  std::shared_ptr<const KeyframeMaps> maps;  // set for dense keyframes before the keyframe check
};

// The keyframe's static keypoints with depth, back-projected (Algorithm 1
// line 6, "corresponding 3D point X"). Keypoints inside the keyframe's own
// dynamic mask are skipped: SLAM extracts none there, and a point on a
// moving object says nothing about the current frame. Fills kf, px,
// centre_w and X_w; false when nothing is left.
bool back_project(const KeyFrameData& kf, const view::Camera& camera, double max_depth, Reference& r);

// z' of Algorithm 1: the current depth at x'. With a search window (ours,
// after DynaSLAM's code): the depth in the window closest to z_proj, so a
// projection that misses a depth edge by a pixel or two still finds X's
// surface; 0 when the window holds no depth at all.
float closest_depth(const cv::Mat& depth, const cv::Point& p, float z_ref, int radius);

// What the reference keyframes say about each current pixel's surface P
// (its depth back-projected with the current pose): DdlOptions'
// confirm_with_keyframes. Every keyframe is resampled into the current view
// through P (its depth and grey where P would appear in it), so a static P
// gives back its own depth and texture. The resampling is done tile by tile
// where a pixel is first asked about (remap's output at a pixel depends on
// that pixel's map values only, so a tile gives what the whole image would).
enum class Seen : unsigned char {
  kUnknown = 0,  // not asked yet (the cache's empty value)
  kStatic,   // some keyframe saw P there: depth and texture agree
  kMoving,   // some keyframe saw through P's place, or other texture at P's depth
  kNothing,  // no keyframe saw P's place (occluded, out of view, no depth)
};

class KeyframeEvidence {
 public:
  // depth, grey: the current frame's; rays: of every current pixel; refs:
  // the reference keyframes with T_kc (and maps, for the dense ones) set.
  // All must outlive the object.
  KeyframeEvidence(const cv::Mat& depth, const cv::Mat& grey, const std::vector<cv::Point2f>& rays,
                   const std::vector<Reference>& refs, const view::Camera& camera, const DdlOptions& o);

  Seen operator()(int x, int y);

  // Moving, and part of a 3x3 block of moving pixels (a morphological
  // opening): depth edges of a real sensor do not sit exactly where the
  // colour edges are, and leave lines of "moving" a pixel or two wide along
  // static silhouettes; moving objects are areas. Cached per pixel, as are
  // the blocks: region growing asks about each neighbour of the region,
  // most of them several times.
  bool moving_area(int x, int y);

 private:
  struct Warped {
    const Reference* ref = nullptr;
    cv::Mat agree;    // CV_8UC1: the keyframe's depth there matches P's within tau_d
                      //   (1; 2: and its window lies on one surface)
    cv::Mat through;  // CV_8UC1: the keyframe saw beyond P's place
    cv::Mat grey;     // CV_32FC1: the keyframe's (smoothed) grey where P lands, empty without texture
    cv::Mat usable;   // CV_8UC1 (with grey): agree == 2 and no current depth edge, the texture test's pixels
  };
  static constexpr int kTile = 32;  // px, square
  static constexpr int kTextureLanes = 2;

  // Resamples every keyframe on the tiles that hold the rectangle (clipped to the image).
  void warp_tiles(const cv::Rect& r);
  void warp_tile(Warped& wk, const cv::Rect& tile);
  Seen classify(int x, int y);
  // Whether one of the kTextureLanes keyframes `wks` agrees in texture at
  // (x, y): texture_agrees of each in one pass over the patch (each
  // keyframe's sums taken in the same order, so each answer is
  // texture_agrees's).
  bool texture_agrees_lanes(const Warped* const* wks, int x, int y) const;
  // The 3x3 block centred on (x, y) lies in the image and all of it is moving.
  bool moving_block(int x, int y);
  bool texture_agrees(const Warped& wk, int x, int y) const;

  const cv::Mat& depth_;
  const std::vector<cv::Point2f>& rays_;
  const view::Camera& camera_;
  const DdlOptions& o_;
  bool texture_ = false;
  cv::Mat grey_;
  cv::Mat edge_;
  std::vector<Warped> warped_;
  int tiles_x_ = 0, tiles_y_ = 0;
  std::vector<unsigned char> tile_done_;
  cv::Mat cache_;
  cv::Mat area_;   // CV_8UC1 moving_area: 0 not asked yet, 1 no, 2 yes
  cv::Mat block_;  // CV_8UC1 moving_block, the same code
};

// Ours: the pose DDL-SLAM checks with comes from its low-cost tracking,
// ORB-SLAM2's tracking against the map restricted to the static part, which
// the ego-motion or the constant-velocity prediction only approximate; the
// keyframe check compares textures pixel by pixel and needs the pose to a
// pixel. So the reference keyframes' points (X, with depth) are followed from
// their keyframe image into the current one by pyramidal Lucas-Kanade,
// starting where the given pose projects them, and the pose is re-estimated
// from them by PnP RANSAC (points on moving objects are its outliers).
// Returns the refined T_cw, or nothing (the given pose stays); fills the
// refine_* and pose_correction_* report values.
std::optional<Eigen::Isometry3d> refine_pose(const std::vector<Reference>& refs, const cv::Mat& grey,
                                             const map::Calibration& calib, const Eigen::Isometry3d& T_cw,
                                             const DdlOptions& o, StageReport& report);

}  // namespace dynaorb::dynamic::ddl
