#pragma once
// The stereo scene of the Li stage tests: synthetic_scene.h's room seen by a
// stereo camera walking forward (one 20 Hz frame at ~1 m/s, turning
// slightly), with one textured fronto-parallel box (a "person", VOC 15)
// walking left at 1.2 m/s between the two frames.
#include <memory>

#include "dynaorb/dynamic/stage.h"
#include "synthetic_scene.h"

namespace dynaorb::test::li {

using namespace dynaorb::test::synth;

inline const Eigen::Isometry3d& camera_motion() {
  static const Eigen::Isometry3d m = make_motion(0.2, 0.6, 0.1, {0.03, -0.01, 0.05});
  return m;
}

constexpr int kMoverIndex = 4;  // room() has four quads

struct StereoPair {
  std::shared_ptr<dynamic::FrameData> prev, cur;
  RenderedView prev_view, cur_view;
};

inline StereoPair render_stereo_pair(const map::Calibration& calib) {
  auto mover = [](const Eigen::Vector3d& c) { return facing_quad(c, 0.3, 0.6, 160, 77, 15); };
  std::vector<TexturedQuad> prev_scene = room(), cur_scene = room();
  prev_scene.push_back(mover({-0.10, 0.25, 1.8}));
  cur_scene.push_back(mover({-0.16, 0.25, 1.8}));
  // The right camera sits baseline metres along +x of the left one.
  Eigen::Isometry3d T_rl = Eigen::Isometry3d::Identity();
  T_rl.translation() = Eigen::Vector3d(-calib.baseline, 0, 0);
  StereoPair p;
  p.prev = std::make_shared<dynamic::FrameData>();
  p.cur = std::make_shared<dynamic::FrameData>();
  p.prev->id = 0;
  p.cur->id = 1;
  p.prev_view = render(prev_scene, Eigen::Isometry3d::Identity(), calib);
  p.prev->grey = p.prev_view.grey;
  p.prev->right = render(prev_scene, T_rl, calib).grey;
  p.cur_view = render(cur_scene, camera_motion(), calib);
  p.cur->grey = p.cur_view.grey;
  p.cur->right = render(cur_scene, T_rl * camera_motion(), calib).grey;
  return p;
}

}  // namespace dynaorb::test::li
