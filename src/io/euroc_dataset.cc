// EuRoC MAV: mav0/cam0|cam1/{data.csv,data/<ns>.png,sensor.yaml}; ground truth
// mav0/state_groundtruth_estimate0/data.csv is the body (IMU) pose, turned into
// cam0 poses through cam0's T_BS. Images are distorted (radtan): stereo
// settings carry a rectification computed from both sensor.yaml files.
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "dataset_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/io/text_table.h"

namespace dynaorb {
namespace {

using io::fs::path;

struct CameraInfo {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  cv::Mat dist;  // k1 k2 p1 p2
  int width = 0, height = 0;
  double rate_hz = 20.0;
  Pose T_BS = Pose::Identity();
};

std::vector<double> numbers(const cv::FileNode& node, const std::string& file, const std::string& key,
                            size_t n) {
  if (node.empty() || !node.isSeq()) throw InputError(file, 0, "missing key '" + key + "'");
  std::vector<double> v;
  for (const cv::FileNode& item : node) {
    if (!item.isReal() && !item.isInt()) throw InputError(file, 0, "key '" + key + "' must hold numbers");
    v.push_back(static_cast<double>(item));
  }
  if (v.size() != n)
    throw InputError(file, 0, "key '" + key + "' must hold " + std::to_string(n) + " numbers, has " +
                                  std::to_string(v.size()));
  return v;
}

CameraInfo read_sensor_yaml(const path& yaml) {
  const std::string file = yaml.string();
  std::error_code ec;
  if (!io::fs::is_regular_file(yaml, ec)) throw InputError(file, 0, "missing camera calibration file");
  // OpenCV needs the "%YAML:1.0" directive, which some EuRoC files lack.
  std::ifstream in(file);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (text.rfind("%YAML", 0) != 0) text = "%YAML:1.0\n" + text;
  cv::FileStorage fs;
  try {
    fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    throw InputError(file, 0, "not a valid YAML file (" + e.msg + ")");
  }
  if (!fs.isOpened()) throw InputError(file, 0, "not a valid YAML file");
  CameraInfo c;
  auto k = numbers(fs["intrinsics"], file, "intrinsics", 4);
  c.fx = k[0]; c.fy = k[1]; c.cx = k[2]; c.cy = k[3];
  auto d = numbers(fs["distortion_coefficients"], file, "distortion_coefficients", 4);
  c.dist = (cv::Mat_<double>(1, 4) << d[0], d[1], d[2], d[3]);
  auto r = numbers(fs["resolution"], file, "resolution", 2);
  c.width = static_cast<int>(r[0]);
  c.height = static_cast<int>(r[1]);
  if (!fs["rate_hz"].empty()) c.rate_hz = static_cast<double>(fs["rate_hz"]);
  cv::FileNode tbs = fs["T_BS"];
  if (tbs.empty()) throw InputError(file, 0, "missing key 'T_BS'");
  auto t = numbers(tbs["data"], file, "T_BS.data", 16);
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = t[i];
  c.T_BS.matrix() = m;
  const std::string model = fs["distortion_model"].empty() ? "" : fs["distortion_model"].string();
  if (!model.empty() && model != "radial-tangential")
    throw InputError(file, 0, "distortion_model '" + model + "' is not supported (radial-tangential only)");
  return c;
}

struct Entry {
  long long ns;
  std::string file;
  int line;
};

// Rows of cam/data.csv. Files are checked by require_images() for the rows in
// use: EuRoC clips may list cam1 images beyond the last cam0 image.
std::vector<Entry> read_camera_csv(const path& cam) {
  const std::string csv = (cam / "data.csv").string();
  std::vector<Entry> entries;
  for (const io::TextRow& row : io::read_text_table(csv, true)) {
    io::require_fields(csv, row, 2, "#timestamp [ns],filename");
    Entry e{io::parse_int64(csv, row, 0, "timestamp [ns]"), row.fields[1], row.line};
    if (!entries.empty() && e.ns <= entries.back().ns)
      throw InputError(csv, row.line, "timestamps are not increasing");
    entries.push_back(e);
  }
  if (entries.empty()) throw InputError(csv, 0, "lists no images");
  return entries;
}

void require_images(const path& cam, const std::vector<Entry>& entries) {
  const std::string csv = (cam / "data.csv").string();
  for (const Entry& e : entries) io::require_file(cam / "data" / e.file, csv, e.line);
}

class EurocDataset : public DataProvider {
 public:
  EurocDataset(const path& mav0, const DatasetOptions& options) : mav0_(mav0) {
    std::error_code ec;
    const bool has_cam1 = io::fs::is_regular_file(mav0 / "cam1" / "data.csv", ec);
    sensor_ = io::choose_sensor(options, has_cam1 ? Sensor::kStereo : Sensor::kMono, has_cam1, false,
                                "EuRoC sequence " + mav0.string());
    cam0_ = read_sensor_yaml(mav0 / "cam0" / "sensor.yaml");
    left_ = read_camera_csv(mav0 / "cam0");
    if (sensor_ == Sensor::kStereo) {
      cam1_ = read_sensor_yaml(mav0 / "cam1" / "sensor.yaml");
      std::map<long long, Entry> right;
      for (const Entry& e : read_camera_csv(mav0 / "cam1")) right.emplace(e.ns, e);
      std::vector<Entry> left;
      for (const Entry& e : left_) {
        auto it = right.find(e.ns);
        if (it == right.end()) continue;
        left.push_back(e);
        right_.push_back(it->second);
      }
      if (left.size() < left_.size())
        warnings_.push_back(std::to_string(left_.size() - left.size()) +
                            " cam0 images have no cam1 image with the same stamp and are skipped");
      if (left.empty()) throw InputError((mav0 / "cam1" / "data.csv").string(), 0, "no stamp matches cam0");
      left_ = std::move(left);
      require_images(mav0 / "cam1", right_);
    }
    require_images(mav0 / "cam0", left_);
    read_ground_truth();
  }

  std::string kind() const override { return "euroc"; }
  std::string root() const override { return mav0_.string(); }
  Sensor sensor() const override { return sensor_; }
  size_t size() const override { return left_.size(); }
  double stamp(size_t i) const override { return static_cast<double>(left_.at(i).ns) * 1e-9; }

  Frame load(size_t i) const override {
    Frame f;
    f.index = i;
    f.stamp = stamp(i);
    const Entry& l = left_.at(i);
    f.image_path = (mav0_ / "cam0" / "data" / l.file).string();
    f.image = io::load_image(f.image_path, cv::IMREAD_UNCHANGED, (mav0_ / "cam0" / "data.csv").string(), l.line);
    if (sensor_ == Sensor::kStereo) {
      const Entry& r = right_.at(i);
      const std::string right = (mav0_ / "cam1" / "data" / r.file).string();
      f.right = io::load_image(right, cv::IMREAD_UNCHANGED, (mav0_ / "cam1" / "data.csv").string(), r.line);
      io::require_same_size(f.image, f.image_path, f.right, right);
    }
    return f;
  }

  Settings default_settings() const override {
    if (io::has_settings_file(mav0_)) return Settings::load((mav0_ / "settings.yaml").string());
    Settings s;
    s.source = (mav0_ / "cam0" / "sensor.yaml").string();
    CameraSettings& c = s.camera;
    c.fps = cam0_.rate_hz;
    c.width = cam0_.width;
    c.height = cam0_.height;
    c.rgb = true;
    if (sensor_ == Sensor::kMono) {
      c.fx = cam0_.fx; c.fy = cam0_.fy; c.cx = cam0_.cx; c.cy = cam0_.cy;
      c.dist = cam0_.dist.clone();
      return s;
    }
    // Stereo: rectify both cameras to a common image plane (zero disparity at infinity).
    const cv::Size size(cam0_.width, cam0_.height);
    const cv::Mat K0 = (cv::Mat_<double>(3, 3) << cam0_.fx, 0, cam0_.cx, 0, cam0_.fy, cam0_.cy, 0, 0, 1);
    const cv::Mat K1 = (cv::Mat_<double>(3, 3) << cam1_.fx, 0, cam1_.cx, 0, cam1_.fy, cam1_.cy, 0, 0, 1);
    const Pose T_c1_c0 = cam1_.T_BS.inverse() * cam0_.T_BS;
    cv::Mat R(3, 3, CV_64F), T(3, 1, CV_64F);
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) R.at<double>(r, k) = T_c1_c0.linear()(r, k);
      T.at<double>(r) = T_c1_c0.translation()(r);
    }
    StereoRectification& q = s.rectification;
    cv::Mat Q;
    cv::stereoRectify(K0, cam0_.dist, K1, cam1_.dist, size, R, T, q.R_l, q.R_r, q.P_l, q.P_r, Q,
                      cv::CALIB_ZERO_DISPARITY, 0.0);
    q.width = size.width;
    q.height = size.height;
    q.K_l = K0; q.D_l = cam0_.dist.clone(); q.K_r = K1; q.D_r = cam1_.dist.clone();
    c.fx = q.P_l.at<double>(0, 0); c.fy = q.P_l.at<double>(1, 1);
    c.cx = q.P_l.at<double>(0, 2); c.cy = q.P_l.at<double>(1, 2);
    c.dist = cv::Mat::zeros(1, 4, CV_64F);
    c.bf = -q.P_r.at<double>(0, 3);
    c.th_depth = 35.0;
    s.extractor.n_features = 1200;
    return s;
  }

  // cam0 poses in the world; note that with stereo rectification the tracked
  // frame is the rectified left camera, rotated by LEFT.R from cam0.
  Trajectory ground_truth() const override { return ground_truth_; }

 private:
  void read_ground_truth() {
    const path gt = mav0_ / "state_groundtruth_estimate0" / "data.csv";
    std::error_code ec;
    if (!io::fs::is_regular_file(gt, ec)) return;
    const std::string file = gt.string();
    for (const io::TextRow& row : io::read_text_table(file, true)) {
      io::require_fields(file, row, 8, "timestamp, p xyz, q wxyz");
      const long long ns = io::parse_int64(file, row, 0, "timestamp [ns]");
      double v[7];
      for (int k = 0; k < 7; ++k) v[k] = io::parse_double(file, row, k + 1, "pose element");
      const double t = static_cast<double>(ns) * 1e-9;
      if (!ground_truth_.empty() && t <= ground_truth_.back().stamp)
        throw InputError(file, row.line, "timestamps are not increasing");
      const Pose T_w_b = pose_from_tq({v[0], v[1], v[2]}, Eigen::Quaterniond(v[3], v[4], v[5], v[6]));
      ground_truth_.push_back({t, T_w_b * cam0_.T_BS});
    }
  }

  path mav0_;
  Sensor sensor_;
  CameraInfo cam0_, cam1_;
  std::vector<Entry> left_, right_;
  Trajectory ground_truth_;
};

}  // namespace

std::unique_ptr<DataProvider> open_euroc(const std::string& root, const DatasetOptions& options) {
  path p(root);
  if (p.filename().empty()) p = p.parent_path();
  std::error_code ec;
  if (p.filename() != "mav0" && io::fs::is_directory(p / "mav0", ec)) p /= "mav0";
  if (!io::fs::is_directory(p / "cam0", ec))
    throw InputError(p.string(), 0, "not a EuRoC sequence: no mav0/cam0 folder");
  return std::make_unique<EurocDataset>(p, options);
}

}  // namespace dynaorb
