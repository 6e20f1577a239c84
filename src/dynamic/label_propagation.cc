#include "dynaorb/dynamic/label_propagation.h"

#include <algorithm>
#include <cmath>
#include <vector>
#include <opencv2/imgproc.hpp>
#include <string>

#include "dynaorb/core/stopwatch.h"
#include "dynaorb/io/errors.h"

namespace dynaorb::dynamic {

namespace {

constexpr double kSameStamp = 1e-6;  // s: stamps round-trip through ROS messages (sec + nsec)
constexpr float kOutside = 1e6f;     // a displacement that leaves every image: background
constexpr int kPad = 2;              // flow-size pixels around a region the chain may reach
constexpr double kWholeShare = 0.4;  // labels boxed over more of the image: followed over all of it

std::string size_text(const cv::Mat& m) { return std::to_string(m.cols) + "x" + std::to_string(m.rows); }

bool is_labels(const cv::Mat& m) {
  return !m.empty() && m.channels() == 1 && (m.depth() == CV_8U || m.depth() == CV_16U);
}

bool is_grey(const cv::Mat& m) { return !m.empty() && m.type() == CV_8UC1; }

void check_scale(double scale) {
  if (!(scale > 0 && scale <= 1))
    throw InputError("label propagation: flow_scale " + std::to_string(scale) + " is not in (0, 1]");
}

cv::Ptr<cv::DISOpticalFlow> make_dis() { return cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_ULTRAFAST); }

cv::Mat small_of(const cv::Mat& grey, double scale) {
  if (scale >= 1) return grey.clone();
  cv::Mat s;
  cv::resize(grey, s, cv::Size(), scale, scale, cv::INTER_AREA);
  return s;
}

// map = pixel grid (from `origin`, less `of`: positions in another image's
// coordinates) + displacement (both CV_32F, disp CV_32FC2).
void grid_plus(const cv::Mat& disp, cv::Point origin, cv::Point of, cv::Mat& map_x, cv::Mat& map_y) {
  map_x.create(disp.size(), CV_32FC1);
  map_y.create(disp.size(), CV_32FC1);
  for (int y = 0; y < disp.rows; ++y) {
    const cv::Vec2f* d = disp.ptr<cv::Vec2f>(y);
    float* mx = map_x.ptr<float>(y);
    float* my = map_y.ptr<float>(y);
    const float gy = static_cast<float>(origin.y + y - of.y);
    for (int x = 0; x < disp.cols; ++x) {
      mx[x] = static_cast<float>(origin.x + x - of.x) + d[x][0];
      my[x] = gy + d[x][1];
    }
  }
}

// disp(p) += field(p + disp(p)): one more step back along the chain. disp
// covers the flow image's rectangle `at`, field the rectangle `field_at`; a
// position outside field_at can reach no labelled pixel (or came from
// outside the image): it leaves for good.
void follow(cv::Mat& disp, const cv::Rect& at, const cv::Mat& field, const cv::Rect& field_at, LabelScratch& scratch) {
  grid_plus(disp, at.tl(), field_at.tl(), scratch.small_x, scratch.small_y);
  cv::remap(field, scratch.step, scratch.small_x, scratch.small_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(kOutside, kOutside));
  disp += scratch.step;
}

// The pixels of a flow's image (the whole flow image) that land within
// `target` (a rectangle of the earlier image): their bounding box, widened
// by kPad for the bilinear steps between pixels, or an empty rectangle. Only
// those pixels can carry a label of target onward, so the chain is followed
// over that box, not over the whole image. (OpenCV's vectorised add and
// inRange: a loop over the pixels took as long as the follow it saves.)
cv::Rect landing_box(const cv::Mat& flow, const cv::Rect& target, LabelScratch& scratch) {
  if (target.area() == 0) return {};
  if (scratch.grid.size() != flow.size()) {
    scratch.grid.create(flow.size(), CV_32FC2);
    for (int y = 0; y < flow.rows; ++y) {
      cv::Vec2f* g = scratch.grid.ptr<cv::Vec2f>(y);
      for (int x = 0; x < flow.cols; ++x) g[x] = cv::Vec2f(static_cast<float>(x), static_cast<float>(y));
    }
  }
  cv::add(scratch.grid, flow, scratch.landed);
  const double pad = kPad;
  cv::inRange(scratch.landed, cv::Scalar(target.x - pad, target.y - pad),
              cv::Scalar(target.br().x - 1 + pad, target.br().y - 1 + pad), scratch.landing);
  const cv::Rect box = cv::boundingRect(scratch.landing);
  if (box.area() == 0) return {};
  return cv::Rect(box.x - kPad, box.y - kPad, box.width + 2 * kPad, box.height + 2 * kPad) &
         cv::Rect(0, 0, flow.cols, flow.rows);
}

// The bounding box of the labelled (non-zero) pixels; empty for background only.
cv::Rect labelled_box(const cv::Mat& labels) { return cv::boundingRect(labels != 0); }

// The full-size rectangle a flow-size rectangle covers (the whole image for
// the whole flow image).
cv::Rect full_rect(const cv::Rect& w, cv::Size small, cv::Size full) {
  const double sx = static_cast<double>(full.width) / small.width;
  const double sy = static_cast<double>(full.height) / small.height;
  const int x0 = static_cast<int>(std::lround(w.x * sx)), y0 = static_cast<int>(std::lround(w.y * sy));
  const int x1 = static_cast<int>(std::lround(w.br().x * sx)), y1 = static_cast<int>(std::lround(w.br().y * sy));
  return cv::Rect(x0, y0, x1 - x0, y1 - y0) & cv::Rect(0, 0, full.width, full.height);
}

// The labels at p + disp(p), disp at flow resolution over the rectangle w
// of the flow image (small: its size), bilinear between its samples
// (cv::resize's INTER_LINEAR), labels at full size. Only the pixels that can
// land on a labelled one are sampled: those within the largest displacement
// of the labelled pixels' bounding box (the rest are background); on a frame
// with one person that is a fraction of the image, where resampling the
// whole image cost 3 ms at 752x480.
cv::Mat sample_labels(const cv::Mat& labels, const cv::Rect& box, const cv::Mat& disp, const cv::Rect& w,
                      cv::Size small, LabelScratch& scratch) {
  cv::Mat out = cv::Mat::zeros(labels.size(), labels.type());
  if (box.area() == 0) return out;
  const double sx = static_cast<double>(labels.cols) / small.width;
  const double sy = static_cast<double>(labels.rows) / small.height;
  // The largest displacement at full size (positions that left for good aside).
  float reach = 0;
  for (int y = 0; y < disp.rows; ++y) {
    const cv::Vec2f* d = disp.ptr<cv::Vec2f>(y);
    for (int x = 0; x < disp.cols; ++x) {
      const float dx = std::abs(d[x][0]), dy = std::abs(d[x][1]);
      if (dx < kOutside / 2 && dy < kOutside / 2) reach = std::max(reach, std::max(dx, dy));
    }
  }
  reach *= static_cast<float>(std::max(sx, sy));
  const int r = static_cast<int>(std::ceil(reach)) + 2;
  const cv::Rect covered = full_rect(w, small, labels.size());
  const cv::Rect roi = cv::Rect(box.x - r, box.y - r, box.width + 2 * r, box.height + 2 * r) & covered;
  if (roi.area() == 0) return out;
  // The displacement at full size over w (OpenCV's vectorised
  // resize: per pixel over the ROI, the same bilinear weights took longer
  // than the whole image's resize), then where each ROI pixel's label comes from.
  cv::resize(disp, scratch.full_disp, covered.size(), 0, 0, cv::INTER_LINEAR);
  scratch.map.create(roi.size(), CV_32FC2);
  const float fx = static_cast<float>(sx), fy = static_cast<float>(sy);
  for (int j = 0; j < roi.height; ++j) {
    const float* d = scratch.full_disp.ptr<float>(roi.y - covered.y + j) + 2 * (roi.x - covered.x);
    float* m = scratch.map.ptr<float>(j);
    const float y = static_cast<float>(roi.y + j);
    for (int i = 0; i < roi.width; ++i) {
      m[2 * i] = static_cast<float>(roi.x + i) + d[2 * i] * fx;
      m[2 * i + 1] = y + d[2 * i + 1] * fy;
    }
  }
  cv::Mat out_roi = out(roi);
  cv::remap(labels, out_roi, scratch.map, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

cv::Mat sample_labels(const cv::Mat& labels, const cv::Rect& box, const cv::Mat& disp_small, LabelScratch& scratch) {
  return sample_labels(labels, box, disp_small, cv::Rect(0, 0, disp_small.cols, disp_small.rows), disp_small.size(),
                       scratch);
}

}  // namespace

void LabelPropagationOptions::validate() const {
  check_scale(flow_scale);
  check_label_ids(classes, "label propagation: classes");
  if (!(max_age_s >= 0) || std::isinf(max_age_s))
    throw InputError("label propagation: max_age_s must be a finite number of seconds >= 0");
  if (frames_kept < 1) throw InputError("label propagation: frames_kept must be at least 1");
}

void check_label_ids(const std::vector<int>& ids, const std::string& what) {
  for (int id : ids)
    if (id < 0 || id > 65535) throw InputError(what + ": " + std::to_string(id) + " is not a label id (0-65535)");
}

const char* to_string(FrameLabels::Source source) {
  switch (source) {
    case FrameLabels::Source::kFresh: return "fresh";
    case FrameLabels::Source::kPropagated: return "propagated";
    case FrameLabels::Source::kAsIs: return "as_is";
    case FrameLabels::Source::kStale: return "stale";
    case FrameLabels::Source::kNone: break;
  }
  return "none";
}

cv::Mat keep_classes(const cv::Mat& labels, const std::vector<int>& ids) {
  if (!is_labels(labels)) throw InputError("label propagation: labels must be one 8- or 16-bit channel");
  if (ids.empty()) return labels;
  check_label_ids(ids, "label propagation: classes");
  if (labels.depth() == CV_8U) {
    cv::Mat table(1, 256, CV_8UC1, cv::Scalar(0));
    for (int id : ids)
      if (id < 256) table.at<unsigned char>(id) = static_cast<unsigned char>(id);
    cv::Mat out;
    cv::LUT(labels, table, out);
    return out;
  }
  std::vector<unsigned char> keep(65536, 0);
  for (int id : ids) keep[static_cast<size_t>(id)] = 1;
  cv::Mat out(labels.size(), labels.type());
  for (int y = 0; y < labels.rows; ++y) {
    const unsigned short* in = labels.ptr<unsigned short>(y);
    unsigned short* o = out.ptr<unsigned short>(y);
    for (int x = 0; x < labels.cols; ++x) o[x] = keep[in[x]] ? in[x] : 0;
  }
  return out;
}

// ---------------------------------------------------------------- one pair

LabelPropagator::LabelPropagator(double flow_scale) : scale_(flow_scale) {
  check_scale(flow_scale);
  dis_ = make_dis();
}

cv::Mat LabelPropagator::warp(const cv::Mat& labels, const cv::Mat& src_grey, const cv::Mat& dst_grey, double* ms) {
  if (ms) *ms = 0;
  if (!is_labels(labels)) throw InputError("label propagation: labels must be one 8- or 16-bit channel");
  if (!is_grey(src_grey) || !is_grey(dst_grey))
    throw InputError("label propagation: the images must be 8-bit grey");
  if (labels.size() != src_grey.size() || src_grey.size() != dst_grey.size())
    throw InputError("label propagation needs equal sizes: labels " + size_text(labels) + ", source " +
                     size_text(src_grey) + ", destination " + size_text(dst_grey));
  const cv::Rect box = labelled_box(labels);
  if (box.area() == 0) return labels.clone();
  const auto t0 = Clock::now();
  cv::Mat flow;
  dis_->calc(small_of(dst_grey, scale_), small_of(src_grey, scale_), flow);
  cv::Mat out = sample_labels(labels, box, flow, scratch_);
  if (ms) *ms = ms_since(t0);
  return out;
}

// ---------------------------------------------------------------- live frames

LiveLabels::LiveLabels(const LabelPropagationOptions& options) : o_(options) {
  o_.validate();
  dis_ = make_dis();
}

void LiveLabels::add_labels(double stamp, const cv::Mat& labels) {
  if (!std::isfinite(stamp)) throw InputError("label propagation: a label image's stamp is not finite");
  if (!is_labels(labels)) throw InputError("label propagation: labels must be one 8- or 16-bit channel");
  // A copy either way: the caller may reuse its buffer.
  const cv::Mat own = o_.classes.empty() ? labels.clone() : keep_classes(labels, o_.classes);
  labels_[stamp] = {own, labelled_box(own)};
  while (static_cast<int>(labels_.size()) > o_.frames_kept) labels_.erase(labels_.begin());
}

void LiveLabels::set_classes(const std::vector<int>& ids) {
  check_label_ids(ids, "label propagation: classes");
  o_.classes = ids;
  for (auto& [stamp, image] : labels_) {
    image.labels = keep_classes(image.labels, ids);
    image.box = labelled_box(image.labels);
  }
}

void LiveLabels::clear() {
  labels_.clear();
  frames_.clear();
  have_disp_ = false;
}

void LiveLabels::forget_after(double stamp) {
  if (!std::isfinite(stamp)) throw InputError("label propagation: forget_after's stamp is not finite");
  labels_.erase(labels_.upper_bound(stamp), labels_.end());
  const size_t before = frames_.size();
  while (!frames_.empty() && frames_.back().stamp > stamp) frames_.pop_back();
  if (frames_.size() != before) have_disp_ = false;  // the chained flow ended at a frame now gone
}

int LiveLabels::frame_index(double stamp) const {
  for (int i = static_cast<int>(frames_.size()) - 1; i >= 0; --i)
    if (std::abs(frames_[i].stamp - stamp) <= kSameStamp) return i;
  return -1;
}

void LiveLabels::prune(double stamp) {
  const double oldest = stamp - o_.max_age_s - kSameStamp;
  while (!frames_.empty() && (frames_.front().stamp < oldest || static_cast<int>(frames_.size()) > o_.frames_kept))
    frames_.pop_front();
  // Label images too old for any later frame, but the newest of them (a
  // later frame falls back on nothing older anyway).
  while (labels_.size() > 1 && std::next(labels_.begin())->first < oldest) labels_.erase(labels_.begin());
}

const cv::Mat& LiveLabels::flow_to_previous(int j) {
  Frame& f = frames_[j];
  if (f.flow_to_previous.empty()) dis_->calc(f.small, frames_[j - 1].small, f.flow_to_previous);
  return f.flow_to_previous;
}

cv::Mat LiveLabels::carry(const LabelImage& labels, int from) {
  const int last = static_cast<int>(frames_.size()) - 1;
  const cv::Mat& small = frames_[last].small;
  const cv::Rect whole(0, 0, small.cols, small.rows);
  const double source = frames_[from].stamp;
  if (have_disp_ && std::abs(disp_source_ - source) <= kSameStamp &&
      std::abs(disp_frame_ - frames_[last - 1].stamp) <= kSameStamp && last - 1 >= from) {
    // The same labels as the last frame's: one more step, this frame's flow
    // then the chain so far, over the pixels that land where it was followed.
    const cv::Mat& flow = flow_to_previous(last);
    const cv::Rect r = disp_at_ == whole ? whole : landing_box(flow, disp_at_, scratch_);
    cv::Mat disp = flow(r).clone();
    if (r.area() > 0) follow(disp, r, disp_, disp_at_, scratch_);
    disp_ = disp;
    disp_at_ = r;
  } else {
    // The labelled box (flow size), then back from the source, frame by
    // frame, the pixels that land in the region before: the chain is followed
    // only over the last one (the whole image's pixels elsewhere reach no
    // label; the same labels as over the whole image, gtest). KITTI 06 with
    // the network's labels 3 frames old: 2.4 -> 1.4 ms a frame standalone.
    const cv::Size full = frames_[last].size;
    const double sx = static_cast<double>(small.cols) / full.width, sy = static_cast<double>(small.rows) / full.height;
    const cv::Rect& b = labels.box;
    const int x0 = static_cast<int>(std::floor(b.x * sx)), y0 = static_cast<int>(std::floor(b.y * sy));
    cv::Rect r = cv::Rect(x0, y0, static_cast<int>(std::ceil(b.br().x * sx)) - x0,
                          static_cast<int>(std::ceil(b.br().y * sy)) - y0) & whole;
    // (Labels over much of the image reach most of it: no box to find.)
    if (r.area() > kWholeShare * whole.area()) r = whole;
    for (int j = from + 1; j <= last && r.area() > 0 && r != whole; ++j)
      r = landing_box(flow_to_previous(j), r, scratch_);
    disp_ = flow_to_previous(last)(r).clone();  // the first step from the pixel grid: the flow itself
    if (r.area() > 0)
      for (int j = last - 1; j > from; --j) follow(disp_, r, flow_to_previous(j), whole, scratch_);
    disp_at_ = r;
  }
  disp_source_ = source;
  disp_frame_ = frames_[last].stamp;
  have_disp_ = true;
  if (disp_at_.area() == 0) return cv::Mat::zeros(frames_[last].size, labels.labels.type());
  return sample_labels(labels.labels, labels.box, disp_, disp_at_, small.size(), scratch_);
}

FrameLabels LiveLabels::labels_for(double stamp, const cv::Mat& grey) {
  if (!std::isfinite(stamp)) throw InputError("label propagation: a frame's stamp is not finite");
  if (!is_grey(grey)) throw InputError("label propagation: the frame's image must be 8-bit grey");
  // A camera restarted (stamps went back) or another image size: the frames kept are no chain to this one.
  if (!frames_.empty() && (stamp < frames_.back().stamp - kSameStamp || frames_.back().size != grey.size())) {
    frames_.clear();
    have_disp_ = false;
  }
  if (frames_.empty() || std::abs(frames_.back().stamp - stamp) > kSameStamp)
    frames_.push_back({stamp, small_of(grey, o_.flow_scale), grey.size(), cv::Mat()});
  prune(stamp);

  FrameLabels out;
  // The newest label image not later than the frame, and the one after it.
  auto after = labels_.upper_bound(stamp + kSameStamp);
  auto newest = after;
  const bool have_newest = newest != labels_.begin();
  if (have_newest) --newest;
  if (have_newest && stamp - newest->first <= o_.max_age_s + kSameStamp &&
      newest->second.labels.size() == grey.size()) {
    const double age = stamp - newest->first;
    const int from = frame_index(newest->first);
    out.age_s = std::max(0.0, age);
    if (age <= kSameStamp) {
      out.source = FrameLabels::Source::kFresh;
      out.labels = newest->second.labels;
    } else if (!o_.propagate || from < 0) {
      // Not moved, or its image was not seen here (dropped before tracking): as it is.
      out.source = FrameLabels::Source::kAsIs;
      out.labels = newest->second.labels;
    } else {
      out.source = FrameLabels::Source::kPropagated;
      if (newest->second.box.area() == 0) {
        out.labels = newest->second.labels;  // only background: any flow keeps it so
      } else {
        const auto t0 = Clock::now();
        out.labels = carry(newest->second, from);
        out.propagate_ms = ms_since(t0);
      }
    }
  } else if (after != labels_.end() && after->first - stamp <= o_.max_age_s &&
             after->second.labels.size() == grey.size()) {
    // Only labels of a later image (this frame tracked late): as they are.
    out.source = FrameLabels::Source::kAsIs;
    out.labels = after->second.labels;
    out.age_s = stamp - after->first;
  } else {
    out.source = labels_.empty() ? FrameLabels::Source::kNone : FrameLabels::Source::kStale;
  }
  ++counts_[static_cast<int>(out.source)];
  return out;
}

}  // namespace dynaorb::dynamic
