// Label propagation: old labels moved by optical flow onto later frames of a
// textured scene whose camera pans and whose object walks, against the
// object's true place; and LiveLabels' choice of labels per frame.
#include <gtest/gtest.h>

#include <limits>
#include <vector>
#include <opencv2/imgproc.hpp>

#include "dynaorb/dynamic/label_propagation.h"
#include "dynaorb/io/errors.h"

namespace dynaorb::dynamic {
namespace {

constexpr int kPerson = 15;  // PASCAL VOC

// A frame of the scene: a textured background (noise at three scales, as
// real surfaces have structure at several) seen from a camera panned by
// `pan` pixels, and a textured 90x140 object with its left edge at object_x.
cv::Mat texture(cv::RNG& rng, cv::Size size) {
  cv::Mat sum = cv::Mat::zeros(size, CV_32FC1);
  for (double sigma : {3.0, 8.0, 20.0}) {
    cv::Mat n(size, CV_32FC1);
    rng.fill(n, cv::RNG::UNIFORM, 0.0, 1.0);
    cv::GaussianBlur(n, n, cv::Size(0, 0), sigma);
    cv::Scalar mean, sd;
    cv::meanStdDev(n, mean, sd);
    sum += (n - mean[0]) / sd[0];
  }
  cv::Mat out;
  cv::normalize(sum, out, 0, 255, cv::NORM_MINMAX, CV_8UC1);
  return out;
}

struct Scene {
  cv::Mat background, object;
  Scene() {
    cv::RNG rng(7);
    background = texture(rng, cv::Size(900, 360));
    object = texture(rng, cv::Size(90, 140));
  }
  static cv::Rect box(int object_x) { return {object_x, 100, 90, 140}; }
  cv::Mat grey(int pan, int object_x) const {
    cv::Mat g = background(cv::Rect(pan, 0, 640, 360)).clone();
    object.copyTo(g(box(object_x)));
    return g;
  }
  static cv::Mat labels(int object_x) {
    cv::Mat l = cv::Mat::zeros(360, 640, CV_8UC1);
    l(box(object_x)).setTo(kPerson);
    return l;
  }
};

double iou(const cv::Mat& labels, const cv::Mat& truth) {
  const cv::Mat a = labels == kPerson, b = truth == kPerson;
  return cv::countNonZero(a & b) / static_cast<double>(cv::countNonZero(a | b));
}

// One frame of a 10 Hz camera: the camera pans 4 px (the scene moves left),
// the object walks 8 px to the right in the image.
TEST(LabelPropagator, MovesLabelsWithTheirObject) {
  const Scene scene;
  for (const double scale : {0.5, 1.0}) {
    LabelPropagator propagator(scale);
    const int x0 = 200;
    const cv::Mat labels0 = Scene::labels(x0);
    double ms = -1;
    const cv::Mat moved = propagator.warp(labels0, scene.grey(0, x0), scene.grey(4, x0 + 8), &ms);
    const cv::Mat truth = Scene::labels(x0 + 8);
    EXPECT_GT(ms, 0);
    ASSERT_EQ(moved.type(), CV_8UC1);
    const double stale = iou(labels0, truth), propagated = iou(moved, truth);
    EXPECT_LT(stale, 0.84);
    EXPECT_GT(propagated, 0.9) << "scale " << scale << ", stale " << stale;
    // Only labels that exist are moved: no new classes appear.
    EXPECT_EQ(cv::countNonZero((moved != 0) & (moved != kPerson)), 0);
  }
  // 16-bit labels are sampled the same way.
  LabelPropagator propagator;
  cv::Mat labels16;
  Scene::labels(300).convertTo(labels16, CV_16U);
  labels16.setTo(1000, labels16 == kPerson);
  const cv::Mat moved = propagator.warp(labels16, scene.grey(0, 300), scene.grey(4, 308));
  ASSERT_EQ(moved.type(), CV_16UC1);
  cv::Mat as_person = cv::Mat::zeros(moved.size(), CV_8UC1);
  as_person.setTo(kPerson, moved == 1000);
  EXPECT_GT(iou(as_person, Scene::labels(308)), 0.9);
}

TEST(LabelPropagator, BackgroundOnlyNeedsNoFlow) {
  const Scene scene;
  LabelPropagator propagator;
  double ms = -1;
  const cv::Mat moved =
      propagator.warp(cv::Mat::zeros(360, 640, CV_8UC1), scene.grey(0, 100), scene.grey(30, 100), &ms);
  EXPECT_EQ(ms, 0);
  EXPECT_EQ(cv::countNonZero(moved), 0);
}

TEST(LabelPropagator, RefusesBadInput) {
  const Scene scene;
  LabelPropagator propagator;
  const cv::Mat g = scene.grey(0, 100);
  EXPECT_THROW(propagator.warp(Scene::labels(100), g, g(cv::Rect(0, 0, 320, 180)).clone()), InputError);
  EXPECT_THROW(propagator.warp(cv::Mat::zeros(360, 640, CV_32FC1), g, g), InputError);
  cv::Mat colour;
  cv::cvtColor(g, colour, cv::COLOR_GRAY2BGR);
  EXPECT_THROW(propagator.warp(Scene::labels(100), colour, g), InputError);
  EXPECT_THROW(LabelPropagator(0.0), InputError);
  EXPECT_THROW(LabelPropagator(1.5), InputError);
  LabelPropagationOptions o;
  o.max_age_s = -1;
  EXPECT_THROW(LiveLabels{o}, InputError);
  // A live stream's bad input: non-finite stamps, a colour frame, labels of a float type.
  LiveLabels live;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(live.add_labels(nan, Scene::labels(100)), InputError);
  EXPECT_THROW(live.add_labels(0.0, cv::Mat::zeros(360, 640, CV_32FC1)), InputError);
  EXPECT_THROW(live.labels_for(std::numeric_limits<double>::infinity(), g), InputError);
  EXPECT_THROW(live.labels_for(0.0, colour), InputError);
  // ... and the stream goes on: the next good frame gets an answer.
  EXPECT_EQ(live.labels_for(0.1, g).source, FrameLabels::Source::kNone);
}

// A live camera at 10 Hz: the object walks 8 px and the camera pans 4 px a
// frame; the network's labels of frame k arrive while frame k + 3 is tracked.
TEST(LiveLabels, NewestLabelsMovedToEachFrame) {
  const Scene scene;
  LabelPropagationOptions o;
  o.max_age_s = 0.55;  // the oldest labels used are 0.5 s old
  LiveLabels live(o);
  auto x_of = [](int k) { return 150 + 8 * k; };
  for (int k = 0; k < 12; ++k) {
    const double stamp = 0.1 * k;
    if (k >= 3 && k % 3 == 0) live.add_labels(0.1 * (k - 3), Scene::labels(x_of(k - 3)));
    const FrameLabels l = live.labels_for(stamp, scene.grey(4 * k, x_of(k)));
    if (k < 3) {
      EXPECT_EQ(l.source, FrameLabels::Source::kNone) << k;
      EXPECT_TRUE(l.labels.empty());
      EXPECT_EQ(l.age_s, -1);
      continue;
    }
    ASSERT_EQ(l.source, FrameLabels::Source::kPropagated) << k;
    // Frames 3, 6, 9 take a new result of 3 frames before; the frames between the same one, older.
    const int source = k - 3 - k % 3;
    EXPECT_NEAR(l.age_s, 0.1 * (k - source), 1e-9) << k;
    EXPECT_GT(l.propagate_ms, 0);
    const cv::Mat truth = Scene::labels(x_of(k));
    const double stale = iou(Scene::labels(x_of(source)), truth);
    // Measured: 0.72 / 0.65 / 0.59 at 3 / 4 / 5 frames against 0.58 / 0.48 / 0.39.
    EXPECT_GT(iou(l.labels, truth), stale + 0.1) << "frame " << k;
  }
  // One flow across the 5 frames from frame 0 to frame 5 (what LiveLabels
  // does not do): worse than the stale labels (0.30 against 0.39).
  LabelPropagator direct;
  const double across = iou(direct.warp(Scene::labels(x_of(0)), scene.grey(0, x_of(0)), scene.grey(20, x_of(5))),
                            Scene::labels(x_of(5)));
  EXPECT_LT(across, iou(Scene::labels(x_of(0)), Scene::labels(x_of(5))));
  EXPECT_EQ(live.count(FrameLabels::Source::kPropagated), 9);
  EXPECT_EQ(live.count(FrameLabels::Source::kNone), 3);
}

TEST(LiveLabels, FreshAsIsStaleAndReset) {
  const Scene scene;
  LabelPropagationOptions o;
  o.max_age_s = 0.25;
  LiveLabels live(o);
  // Labels of the frame itself: fresh, age 0.
  live.add_labels(1.0, Scene::labels(100));
  FrameLabels l = live.labels_for(1.0, scene.grey(0, 100));
  EXPECT_EQ(l.source, FrameLabels::Source::kFresh);
  EXPECT_EQ(l.age_s, 0);
  EXPECT_EQ(l.propagate_ms, 0);
  // Labels of an image the node never saw (dropped before tracking): as they are.
  live.add_labels(1.05, Scene::labels(108));
  l = live.labels_for(1.1, scene.grey(4, 116));
  EXPECT_EQ(l.source, FrameLabels::Source::kAsIs);
  EXPECT_NEAR(l.age_s, 0.05, 1e-9);
  EXPECT_EQ(cv::countNonZero(l.labels != Scene::labels(108)), 0);
  // ... so on the next frame too, while they are young enough ...
  l = live.labels_for(1.2, scene.grey(8, 124));
  EXPECT_EQ(l.source, FrameLabels::Source::kAsIs);
  EXPECT_NEAR(l.age_s, 0.15, 1e-9);
  // ... and dropped once older than max_age_s.
  l = live.labels_for(1.35, scene.grey(12, 132));
  EXPECT_EQ(l.source, FrameLabels::Source::kStale);
  EXPECT_TRUE(l.labels.empty());
  // Labels only of a later image (a frame tracked late): as they are, negative age.
  live.add_labels(1.5, Scene::labels(150));
  l = live.labels_for(1.45, scene.grey(16, 146));
  EXPECT_EQ(l.source, FrameLabels::Source::kAsIs);
  EXPECT_NEAR(l.age_s, -0.05, 1e-9);
  // Another image size: the old labels are not used.
  l = live.labels_for(1.5, cv::Mat(180, 320, CV_8UC1, cv::Scalar(9)));
  EXPECT_TRUE(l.labels.empty());
  live.clear();
  l = live.labels_for(2.0, scene.grey(0, 100));
  EXPECT_EQ(l.source, FrameLabels::Source::kNone);
}

// Time going back (a bag played again): the labels kept of the time before
// are the newest, so the capped store drops the new time's labels first;
// forget_after clears the way.
TEST(LiveLabels, TimeGoingBackForgetsTheLabelsOfTheTimeBefore) {
  const Scene scene;
  LabelPropagationOptions o;
  o.frames_kept = 4;
  for (const bool forget : {false, true}) {
    LiveLabels live(o);
    for (int k = 0; k < 4; ++k) {
      const double t = 10.0 + 0.1 * k;
      live.labels_for(t, scene.grey(4 * k, 100 + 8 * k));
      live.add_labels(t, Scene::labels(100 + 8 * k));
    }
    if (forget) live.forget_after(1.0);  // the node: the stamp of the first frame or label that went back
    live.add_labels(1.0, Scene::labels(140));
    const FrameLabels l = live.labels_for(1.0, scene.grey(0, 140));
    if (!forget) {
      // The new labels were dropped as the oldest; those kept are 9 s away: stale.
      EXPECT_EQ(l.source, FrameLabels::Source::kStale);
      EXPECT_TRUE(l.labels.empty());
      continue;
    }
    EXPECT_EQ(l.source, FrameLabels::Source::kFresh);
    EXPECT_EQ(cv::countNonZero(l.labels != Scene::labels(140)), 0);
    // Labels of the new time from then on: moved onto the next frame.
    const FrameLabels next = live.labels_for(1.1, scene.grey(4, 148));
    EXPECT_EQ(next.source, FrameLabels::Source::kPropagated);
    EXPECT_GT(iou(next.labels, Scene::labels(148)), 0.8);
    // A stamp that is no time: refused, nothing forgotten.
    EXPECT_THROW(live.forget_after(std::numeric_limits<double>::quiet_NaN()), InputError);
    EXPECT_EQ(live.labels_for(1.1, scene.grey(4, 148)).source, FrameLabels::Source::kPropagated);
  }
}

TEST(LiveLabels, WithoutPropagationLabelsStayAsTheyAre) {
  const Scene scene;
  LabelPropagationOptions o;
  o.propagate = false;
  LiveLabels live(o);
  live.labels_for(0.0, scene.grey(0, 100));
  live.add_labels(0.0, Scene::labels(100));
  const FrameLabels l = live.labels_for(0.1, scene.grey(4, 108));
  EXPECT_EQ(l.source, FrameLabels::Source::kAsIs);
  EXPECT_EQ(cv::countNonZero(l.labels != Scene::labels(100)), 0);
  EXPECT_EQ(l.propagate_ms, 0);
}

TEST(KeepClasses, OtherIdsBecomeBackground) {
  cv::Mat l8 = (cv::Mat_<unsigned char>(1, 5) << 0, 15, 18, 7, 15);
  cv::Mat kept = keep_classes(l8, {15, 7, 300});
  EXPECT_EQ(cv::countNonZero(kept != (cv::Mat_<unsigned char>(1, 5) << 0, 15, 0, 7, 15)), 0);
  cv::Mat l16 = (cv::Mat_<unsigned short>(1, 4) << 0, 1000, 18, 24);
  kept = keep_classes(l16, {1000, 24});
  ASSERT_EQ(kept.type(), CV_16UC1);
  EXPECT_EQ(cv::countNonZero(kept != (cv::Mat_<unsigned short>(1, 4) << 0, 1000, 0, 24)), 0);
  EXPECT_EQ(keep_classes(l8, {}).data, l8.data);  // no ids: as they are
  EXPECT_THROW(keep_classes(l8, {-1}), InputError);
  EXPECT_THROW(keep_classes(l8, {70000}), InputError);
  EXPECT_THROW(keep_classes(cv::Mat(2, 2, CV_32FC1), {15}), InputError);
  LabelPropagationOptions o;
  o.classes = {15, -3};
  EXPECT_THROW(LiveLabels{o}, InputError);
}

// A label image whose only labelled class is not carried (EuRoC V1's "sofa"
// under the PASCAL network) is background: no flow; a carried class is moved
// and nothing else comes with it.
TEST(LiveLabels, OnlyTheCarriedClassesAreMoved) {
  const Scene scene;
  constexpr int kSofa = 18;
  LabelPropagationOptions o;
  o.classes = {kPerson};
  LiveLabels live(o);
  cv::Mat sofa = Scene::labels(100);
  sofa.setTo(kSofa, sofa == 0);  // the person on a sofa filling the rest of the image
  live.labels_for(0.0, scene.grey(0, 100));
  live.add_labels(0.0, sofa);
  FrameLabels l = live.labels_for(0.1, scene.grey(4, 108));
  ASSERT_EQ(l.source, FrameLabels::Source::kPropagated);
  EXPECT_GT(l.propagate_ms, 0);
  EXPECT_EQ(cv::countNonZero(l.labels == kSofa), 0);
  EXPECT_GT(iou(l.labels, Scene::labels(108)), iou(Scene::labels(100), Scene::labels(108)));
  // Only sofa: background, no flow.
  cv::Mat only_sofa(360, 640, CV_8UC1, cv::Scalar(kSofa));
  live.add_labels(0.1, only_sofa);
  l = live.labels_for(0.2, scene.grey(8, 116));
  ASSERT_EQ(l.source, FrameLabels::Source::kPropagated);
  EXPECT_EQ(l.propagate_ms, 0);
  EXPECT_EQ(cv::countNonZero(l.labels), 0);
  // A label set announced later: the images kept are reduced to it.
  LiveLabels all;  // carries every class until told otherwise
  all.labels_for(0.0, scene.grey(0, 100));
  all.add_labels(0.0, sofa);
  all.set_classes({kSofa});
  l = all.labels_for(0.1, scene.grey(4, 108));
  EXPECT_EQ(cv::countNonZero(l.labels == kPerson), 0);
  EXPECT_GT(cv::countNonZero(l.labels == kSofa), 0);
  EXPECT_THROW(all.set_classes({-1}), InputError);
}

// The whole-image chain, written out: backward DIS flows at half size
// between consecutive frames, displacements chained by bilinear sampling,
// labels sampled at nearest neighbour through the displacement resized to
// full size. LiveLabels follows the chain only over the pixels that can reach
// a label; its labels must be the same.
cv::Mat whole_image_chain(const cv::Mat& labels, const std::vector<cv::Mat>& greys) {
  auto dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_ULTRAFAST);
  auto half = [](const cv::Mat& g) {
    cv::Mat s;
    cv::resize(g, s, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    return s;
  };
  std::vector<cv::Mat> flows;  // flows[j]: frame j + 1 -> frame j
  for (size_t j = 1; j < greys.size(); ++j) {
    cv::Mat f;
    dis->calc(half(greys[j]), half(greys[j - 1]), f);
    flows.push_back(f);
  }
  cv::Mat disp = flows.back().clone();
  for (int j = static_cast<int>(flows.size()) - 2; j >= 0; --j) {
    cv::Mat mx(disp.size(), CV_32FC1), my(disp.size(), CV_32FC1), step;
    for (int y = 0; y < disp.rows; ++y)
      for (int x = 0; x < disp.cols; ++x) {
        mx.at<float>(y, x) = x + disp.at<cv::Vec2f>(y, x)[0];
        my.at<float>(y, x) = y + disp.at<cv::Vec2f>(y, x)[1];
      }
    cv::remap(flows[j], step, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(1e6, 1e6));
    disp += step;
  }
  cv::Mat full;
  cv::resize(disp, full, labels.size(), 0, 0, cv::INTER_LINEAR);
  const float sx = static_cast<float>(static_cast<double>(labels.cols) / disp.cols);
  const float sy = static_cast<float>(static_cast<double>(labels.rows) / disp.rows);
  cv::Mat map(labels.size(), CV_32FC2), out;
  for (int y = 0; y < map.rows; ++y)
    for (int x = 0; x < map.cols; ++x) {
      const cv::Vec2f d = full.at<cv::Vec2f>(y, x);
      map.at<cv::Vec2f>(y, x) = cv::Vec2f(static_cast<float>(x) + d[0] * sx, static_cast<float>(y) + d[1] * sy);
    }
  cv::remap(labels, out, map, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

TEST(LiveLabels, ChainOverThePixelsThatReachALabelOnly) {
  const Scene scene;
  for (int speed : {8, 30}) {  // px a frame; 30: the object outruns the flow (IoU 0.56 to 0.21)
    auto x_of = [speed](int k) { return 100 + speed * k; };
    std::vector<cv::Mat> greys;
    for (int k = 0; k < 5; ++k) greys.push_back(scene.grey(4 * k, x_of(k)));
    for (int k = 1; k < 5; ++k) {
      // The labels of frame 0 arrive at frame k: a chain of k flows.
      LiveLabels live;
      for (int i = 0; i < k; ++i) live.labels_for(0.1 * i, greys[i]);
      live.add_labels(0.0, Scene::labels(x_of(0)));
      const FrameLabels l = live.labels_for(0.1 * k, greys[k]);
      ASSERT_EQ(l.source, FrameLabels::Source::kPropagated);
      const cv::Mat expected =
          whole_image_chain(Scene::labels(x_of(0)), std::vector<cv::Mat>(greys.begin(), greys.begin() + k + 1));
      EXPECT_GT(cv::countNonZero(expected), 0);
      EXPECT_EQ(cv::countNonZero(l.labels != expected), 0) << "speed " << speed << ", frame " << k;
    }
  }
}

}  // namespace
}  // namespace dynaorb::dynamic
