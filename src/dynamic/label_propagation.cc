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

// map = pixel grid + displacement (both CV_32F, disp CV_32FC2).
void grid_plus(const cv::Mat& disp, cv::Mat& map_x, cv::Mat& map_y) {
  map_x.create(disp.size(), CV_32FC1);
  map_y.create(disp.size(), CV_32FC1);
  for (int y = 0; y < disp.rows; ++y) {
    const cv::Vec2f* d = disp.ptr<cv::Vec2f>(y);
    float* mx = map_x.ptr<float>(y);
    float* my = map_y.ptr<float>(y);
    for (int x = 0; x < disp.cols; ++x) {
      mx[x] = static_cast<float>(x) + d[x][0];
      my[x] = static_cast<float>(y) + d[x][1];
    }
  }
}

// disp(p) += flow(p + disp(p)): one more step back along the chain. A
// position outside the flow's image came from outside: it leaves for good.
void follow(cv::Mat& disp, const cv::Mat& flow, LabelScratch& scratch) {
  grid_plus(disp, scratch.small_x, scratch.small_y);
  cv::remap(flow, scratch.step, scratch.small_x, scratch.small_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(kOutside, kOutside));
  disp += scratch.step;
}

// The bounding box of the labelled (non-zero) pixels; empty for background only.
cv::Rect labelled_box(const cv::Mat& labels) { return cv::boundingRect(labels != 0); }

// The labels at p + disp(p), disp at flow resolution (bilinear between its
// samples: cv::resize's INTER_LINEAR), labels at full size. Only the pixels
// that can land on a labelled one are sampled: those within the largest
// displacement of the labelled pixels' bounding box (the rest are
// background); on a frame with one person that is a fraction of the image,
// where resampling the whole image cost 3 ms at 752x480.
cv::Mat sample_labels(const cv::Mat& labels, const cv::Rect& box, const cv::Mat& disp_small, LabelScratch& scratch) {
  cv::Mat out = cv::Mat::zeros(labels.size(), labels.type());
  if (box.area() == 0) return out;
  const double sx = static_cast<double>(labels.cols) / disp_small.cols;
  const double sy = static_cast<double>(labels.rows) / disp_small.rows;
  // The largest displacement at full size (positions that left the image aside).
  float reach = 0;
  for (int y = 0; y < disp_small.rows; ++y) {
    const cv::Vec2f* d = disp_small.ptr<cv::Vec2f>(y);
    for (int x = 0; x < disp_small.cols; ++x) {
      const float dx = std::abs(d[x][0]), dy = std::abs(d[x][1]);
      if (dx < kOutside / 2 && dy < kOutside / 2) reach = std::max(reach, std::max(dx, dy));
    }
  }
  reach *= static_cast<float>(std::max(sx, sy));
  const int r = static_cast<int>(std::ceil(reach)) + 2;
  const cv::Rect roi = cv::Rect(box.x - r, box.y - r, box.width + 2 * r, box.height + 2 * r) &
                       cv::Rect(0, 0, labels.cols, labels.rows);
  if (roi.area() == 0) return out;
  // The displacement at full size (OpenCV's vectorised resize: per pixel
  // over the ROI, the same bilinear weights took longer than the whole
  // image's resize), then where each ROI pixel's label comes from.
  cv::resize(disp_small, scratch.full_disp, labels.size(), 0, 0, cv::INTER_LINEAR);
  scratch.map.create(roi.size(), CV_32FC2);
  const float fx = static_cast<float>(sx), fy = static_cast<float>(sy);
  for (int j = 0; j < roi.height; ++j) {
    const float* d = scratch.full_disp.ptr<float>(roi.y + j) + 2 * roi.x;
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

void check_ids(const std::vector<int>& ids) {
  for (int id : ids)
    if (id < 0 || id > 65535)
      throw InputError("label propagation: class id " + std::to_string(id) + " is not a label id (0-65535)");
}

}  // namespace

void LabelPropagationOptions::validate() const {
  check_scale(flow_scale);
  check_ids(classes);
  if (!(max_age_s >= 0) || std::isinf(max_age_s))
    throw InputError("label propagation: max_age_s must be a finite number of seconds >= 0");
  if (frames_kept < 1) throw InputError("label propagation: frames_kept must be at least 1");
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
  check_ids(ids);
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
  check_ids(ids);
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
  const double source = frames_[from].stamp;
  if (have_disp_ && std::abs(disp_source_ - source) <= kSameStamp &&
      std::abs(disp_frame_ - frames_[last - 1].stamp) <= kSameStamp && last - 1 >= from) {
    // The same labels as the last frame's: one more step, this frame's flow then the chain so far.
    cv::Mat disp = flow_to_previous(last).clone();
    follow(disp, disp_, scratch_);
    disp_ = disp;
  } else {
    disp_ = flow_to_previous(last).clone();  // the first step from the pixel grid: the flow itself
    for (int j = last - 1; j > from; --j) follow(disp_, flow_to_previous(j), scratch_);
  }
  disp_source_ = source;
  disp_frame_ = frames_[last].stamp;
  have_disp_ = true;
  return sample_labels(labels.labels, labels.box, disp_, scratch_);
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
