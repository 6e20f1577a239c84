#pragma once
// Shared by the map bookkeeping tests: keyframe features without images.
#include <memory>

#include "dynaorb/map/features.h"

namespace dynaorb::test {

// n level-0 keypoints spread over a 640x480 image (fx 500, bf 40, ThDepth 3.2 m, 8
// levels at 1.2), zero descriptors, no depth; the grid built.
inline std::shared_ptr<const map::Features> synthetic_features(int n) {
  auto c = std::make_shared<map::Calibration>();
  c->fx = c->fy = 500;
  c->cx = 320;
  c->cy = 240;
  c->inv_fx = c->inv_fy = 1.0 / 500;
  c->max_x = 640;
  c->max_y = 480;
  c->bf = 40;
  c->th_depth = 3.2;
  c->scale = map::ScalePyramid::make(8, 1.2);
  auto f = std::make_shared<map::Features>();
  f->calib = c;
  for (int i = 0; i < n; ++i) f->keys.emplace_back(float(10 + (i * 37) % 600), float(10 + (i * 53) % 460), 31.f, 0.f, 1.f, 0);
  f->keys_un = f->keys;
  f->descriptors = cv::Mat::zeros(n, 32, CV_8U);
  f->u_right.assign(n, -1);
  f->depth.assign(n, -1);
  f->build_grid();
  return f;
}

}  // namespace dynaorb::test
