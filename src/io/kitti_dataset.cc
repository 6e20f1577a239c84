// KITTI odometry: ROOT/sequences/NN/{image_0,image_1,times.txt,calib.txt},
// ground truth ROOT/poses/NN.txt (left camera at frame i in frame 0).
#include <cstdio>
#include <opencv2/imgcodecs.hpp>

#include "dataset_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/io/text_table.h"
#include "dynaorb/io/trajectory_io.h"

namespace dynaorb {
namespace {

using io::fs::path;

std::string image_name(size_t i) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%06zu.png", i);
  return buf;
}

class KittiDataset : public DataProvider {
 public:
  KittiDataset(const path& seq, const DatasetOptions& options) : seq_(seq) {
    sensor_ = io::choose_sensor(options, Sensor::kStereo, true, false, "KITTI sequence " + seq.string());
    const std::string times = (seq / "times.txt").string();
    for (const io::TextRow& row : io::read_text_table(times)) {
      double t = io::parse_double(times, row, 0, "timestamp");
      if (!stamps_.empty() && t <= stamps_.back())
        throw InputError(times, row.line, "timestamps are not increasing");
      const size_t i = stamps_.size();
      io::require_file(seq / "image_0" / image_name(i), times, row.line);
      if (sensor_ == Sensor::kStereo) io::require_file(seq / "image_1" / image_name(i), times, row.line);
      stamps_.push_back(t);
      lines_.push_back(row.line);
    }
    if (stamps_.empty()) throw InputError(times, 0, "lists no frames");
    const path poses = seq.parent_path().parent_path() / "poses" / (seq.filename().string() + ".txt");
    std::error_code ec;
    if (io::fs::is_regular_file(poses, ec)) {
      ground_truth_ = io::read_kitti(poses.string(), {});
      if (ground_truth_.size() > stamps_.size())
        warnings_.push_back(poses.string() + " has more poses than frames; extra poses ignored");
      ground_truth_.resize(std::min(ground_truth_.size(), stamps_.size()));
      for (size_t k = 0; k < ground_truth_.size(); ++k) ground_truth_[k].stamp = stamps_[k];
    }
  }

  std::string kind() const override { return "kitti"; }
  std::string root() const override { return seq_.string(); }
  Sensor sensor() const override { return sensor_; }
  size_t size() const override { return stamps_.size(); }
  double stamp(size_t i) const override { return stamps_.at(i); }

  Frame load(size_t i) const override {
    Frame f;
    f.index = i;
    f.stamp = stamps_.at(i);
    const std::string times = (seq_ / "times.txt").string();
    f.image_path = (seq_ / "image_0" / image_name(i)).string();
    f.image = io::load_image(f.image_path, cv::IMREAD_UNCHANGED, times, lines_[i]);
    if (sensor_ == Sensor::kStereo) {
      const std::string right = (seq_ / "image_1" / image_name(i)).string();
      f.right = io::load_image(right, cv::IMREAD_UNCHANGED, times, lines_[i]);
      io::require_same_size(f.image, f.image_path, f.right, right);
    }
    return f;
  }

  Settings default_settings() const override {
    if (io::has_settings_file(seq_)) return Settings::load((seq_ / "settings.yaml").string());
    const std::string calib = (seq_ / "calib.txt").string();
    Eigen::Matrix<double, 3, 4> P0, P1;
    bool have0 = false, have1 = false;
    for (const io::TextRow& row : io::read_text_table(calib)) {
      if (row.fields.empty() || (row.fields[0] != "P0:" && row.fields[0] != "P1:")) continue;
      io::require_fields(calib, row, 13, "Pn: 12 numbers");
      Eigen::Matrix<double, 3, 4>& P = row.fields[0] == "P0:" ? P0 : P1;
      for (int k = 0; k < 12; ++k) P(k / 4, k % 4) = io::parse_double(calib, row, k + 1, "projection element");
      (row.fields[0] == "P0:" ? have0 : have1) = true;
    }
    if (!have0) throw InputError(calib, 0, "missing key 'P0:'");
    if (!have1 && sensor_ == Sensor::kStereo) throw InputError(calib, 0, "missing key 'P1:'");
    Settings s;
    s.source = calib;
    CameraSettings& c = s.camera;
    c.fx = P0(0, 0); c.fy = P0(1, 1); c.cx = P0(0, 2); c.cy = P0(1, 2);
    if (have1) c.bf = -(P1(0, 3) - P0(0, 3));
    c.th_depth = 35.0;  // ORB-SLAM2's KITTI settings
    c.fps = 10.0;
    c.rgb = true;
    const cv::Mat first = load(0).image;
    c.width = first.cols;
    c.height = first.rows;
    s.extractor.n_features = 2000;
    return s;
  }

  Trajectory ground_truth() const override { return ground_truth_; }

 private:
  path seq_;
  Sensor sensor_;
  std::vector<double> stamps_;
  std::vector<int> lines_;
  Trajectory ground_truth_;
};

}  // namespace

std::unique_ptr<DataProvider> open_kitti(const std::string& seq, const DatasetOptions& options) {
  path p(seq);
  if (p.filename().empty()) p = p.parent_path();
  return std::make_unique<KittiDataset>(p, options);
}

}  // namespace dynaorb
