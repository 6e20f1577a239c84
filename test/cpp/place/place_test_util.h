#pragma once
// Shared by the place-recognition tests: a small vocabulary trained once on
// real ORB descriptors (EuRoC MH_05, every 25th frame), and KITTI 06 stereo
// frames through the System's own front end (ORB, stereo matching, grid)
// with their ground-truth poses. Keyframes get a map point at every keypoint
// with stereo depth, as tracking gives them.
#include <algorithm>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "../test_util.h"
#include "dynaorb/io/dataset.h"
#include "dynaorb/map/frame.h"
#include "dynaorb/map/map.h"
#include "dynaorb/tracking/frame_builder.h"
#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb::test {

struct PlaceData {
  bool ok = false;
  std::shared_ptr<const vocab::Vocabulary> vocabulary;
  std::vector<std::shared_ptr<const map::Features>> frames;  // KITTI 06, frames 0 .. kFrames-1
  Trajectory ground_truth;                                   // T_world_camera per frame
  static constexpr int kFrames = 12;
};

inline const PlaceData& place_data() {
  static const PlaceData d = [] {
    PlaceData d;
    const fs::path kitti = shared_data() / "kitti/sequences/06";
    const fs::path mh05 = shared_data() / "euroc/MH_05_difficult_head/mav0/cam0/data";
    if (!fs::is_directory(kitti) || !fs::is_directory(mh05)) return d;
    auto provider = open_dataset("kitti", kitti.string());
    const Settings settings = provider->default_settings();
    // Training images: another camera and place than the queries.
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(mh05))
      if (e.path().extension() == ".png") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    features::OrbExtractor orb(settings.extractor);
    std::vector<cv::Mat> train;
    for (size_t i = 0; i < files.size(); i += 25) {
      std::vector<cv::KeyPoint> keys;
      cv::Mat desc;
      orb.extract(cv::imread(files[i], cv::IMREAD_GRAYSCALE), cv::Mat(), keys, desc);
      train.push_back(desc);
    }
    d.vocabulary = std::make_shared<const vocab::Vocabulary>(vocab::Vocabulary::train(train, 10, 5, 3));

    const dynaorb::Frame first = provider->load(0);
    tracking::FrameBuilder builder(
        settings, map::Calibration::make(settings, Sensor::kStereo, first.image.cols, first.image.rows));
    const Trajectory gt = provider->ground_truth();
    for (int i = 0; i < PlaceData::kFrames; ++i) {
      const dynaorb::Frame f = provider->load(i);
      tracking::StageTimes t;
      d.frames.push_back(builder.stereo(f.image, f.right, cv::Mat(), t));
      d.ground_truth.push_back(gt.at(i));
    }
    d.ok = true;
    return d;
  }();
  return d;
}

#define REQUIRE_PLACE_DATA()                                                      \
  DYNAORB_REQUIRE_SHARED();                                                       \
  if (!::dynaorb::test::place_data().ok) GTEST_SKIP() << "KITTI 06 / EuRoC MH_05 not found";

// Keyframe of frame i at its ground-truth pose, with a map point at every
// keypoint that has stereo depth, added to the map (not to a database).
inline std::shared_ptr<map::KeyFrame> make_keyframe(map::Map& map, int i) {
  const PlaceData& d = place_data();
  const Eigen::Isometry3d T_cw = d.ground_truth[i].pose.inverse();
  auto kf = std::make_shared<map::KeyFrame>(map.new_keyframe_id(), i, i, d.frames[i], T_cw);
  for (int k = 0; k < kf->f().size(); ++k) {
    if (!kf->f().has_depth(k)) continue;
    auto p = std::make_shared<map::MapPoint>(map.new_point_id(), kf->unproject(k), kf.get(), kf->id);
    map.add_observation(*kf, k, p);
    p->compute_distinctive_descriptor();
    p->update_normal_and_depth();
    map.add_point(p);
  }
  kf->set_bow(map::BagOfWords::compute(*d.vocabulary, kf->f()));
  map.add_keyframe(kf);
  return kf;
}

inline map::Frame make_frame(int i, long id = 1000) {
  const PlaceData& d = place_data();
  map::Frame f(id + i, i, d.frames[i]);
  f.bow = map::BagOfWords::compute(*d.vocabulary, f.f());
  return f;
}

}  // namespace dynaorb::test
