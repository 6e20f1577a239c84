// TUM RGB-D: rgb.txt / depth.txt (`timestamp filename`), groundtruth.txt,
// colour and depth associated by nearest stamp within 0.02 s (as the
// benchmark's associate.py: greedy on |dt|, one-to-one).
#include <algorithm>
#include <opencv2/imgcodecs.hpp>

#include "dataset_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/io/text_table.h"
#include "dynaorb/io/trajectory_io.h"

namespace dynaorb {
namespace {

using io::fs::path;

struct ListEntry {
  double stamp;
  std::string file;
  int line;
};

std::vector<ListEntry> read_list(const path& list) {
  const std::string name = list.string();
  std::vector<ListEntry> entries;
  for (const io::TextRow& row : io::read_text_table(name)) {
    io::require_fields(name, row, 2, "timestamp filename");
    ListEntry e{io::parse_double(name, row, 0, "timestamp"), row.fields[1], row.line};
    if (!entries.empty() && e.stamp <= entries.back().stamp)
      throw InputError(name, row.line, "timestamps are not increasing (" + row.fields[0] +
                                           " after line " + std::to_string(entries.back().line) + ")");
    io::require_file(list.parent_path() / e.file, name, row.line);
    entries.push_back(e);
  }
  if (entries.empty()) throw InputError(name, 0, "lists no images");
  return entries;
}

// Camera tables of the TUM benchmark (as ORB-SLAM2's TUM1/2/3.yaml and config/TUM*.yaml).
Settings freiburg_settings(int n) {
  Settings s;
  CameraSettings& c = s.camera;
  c.dist = cv::Mat::zeros(1, 5, CV_64F);
  if (n == 1) {
    c.fx = 517.306408; c.fy = 516.469215; c.cx = 318.643040; c.cy = 255.313989;
    c.dist = (cv::Mat_<double>(1, 5) << 0.262383, -0.953104, -0.005358, 0.002628, 1.163314);
    c.depth_map_factor = 5000.0;
  } else if (n == 2) {
    c.fx = 520.908620; c.fy = 521.007327; c.cx = 325.141442; c.cy = 249.701764;
    c.dist = (cv::Mat_<double>(1, 5) << 0.231222, -0.784899, -0.003257, -0.000105, 0.917205);
    c.depth_map_factor = 5208.0;
  } else {
    c.fx = 535.4; c.fy = 539.2; c.cx = 320.1; c.cy = 247.6;
    c.depth_map_factor = 5000.0;
  }
  c.width = 640; c.height = 480; c.fps = 30.0; c.rgb = true;
  c.bf = 40.0; c.th_depth = 40.0;
  s.source = "<built-in TUM freiburg" + std::to_string(n) + ">";
  return s;
}

}  // namespace

std::optional<Settings> tum_settings_for_name(const std::string& name) {
  for (int n = 1; n <= 3; ++n)
    if (name.find("freiburg" + std::to_string(n)) != std::string::npos) return freiburg_settings(n);
  return std::nullopt;
}

namespace {

class TumDataset : public DataProvider {
 public:
  TumDataset(const path& root, const DatasetOptions& options) : root_(root) {
    sensor_ = io::choose_sensor(options, Sensor::kRGBD, false, true, "TUM sequence " + root.string());
    rgb_ = read_list(root / "rgb.txt");
    if (sensor_ == Sensor::kRGBD) associate(read_list(root / "depth.txt"));
    std::error_code ec;
    if (io::fs::is_regular_file(root / "groundtruth.txt", ec))
      ground_truth_ = io::read_tum((root / "groundtruth.txt").string());
  }

  std::string kind() const override { return "tum"; }
  std::string root() const override { return root_.string(); }
  Sensor sensor() const override { return sensor_; }
  size_t size() const override { return rgb_.size(); }
  double stamp(size_t i) const override { return rgb_.at(i).stamp; }

  Frame load(size_t i) const override {
    const ListEntry& e = rgb_.at(i);
    Frame f;
    f.index = i;
    f.stamp = e.stamp;
    f.image_path = (root_ / e.file).string();
    f.image = io::load_image(f.image_path, cv::IMREAD_UNCHANGED, (root_ / "rgb.txt").string(), e.line);
    if (sensor_ == Sensor::kRGBD) {
      const ListEntry& d = depth_.at(i);
      const std::string depth_path = (root_ / d.file).string();
      f.depth = io::load_image(depth_path, cv::IMREAD_ANYDEPTH, (root_ / "depth.txt").string(), d.line);
      if (f.depth.type() != CV_16UC1 && f.depth.type() != CV_32FC1)
        throw InputError(depth_path, 0, "depth image must be 16-bit or 32-bit float, one channel");
      io::require_same_size(f.image, f.image_path, f.depth, depth_path);
    }
    return f;
  }

  Settings default_settings() const override {
    if (io::has_settings_file(root_)) return Settings::load((root_ / "settings.yaml").string());
    const std::string name = root_.filename().string().empty() ? root_.parent_path().filename().string()
                                                               : root_.filename().string();
    if (std::optional<Settings> s = tum_settings_for_name(name)) return *s;
    throw InputError(root_.string(), 0,
                     "no settings.yaml here and the folder name names no freiburg1/2/3 camera: "
                     "pass a settings file (--config)");
  }

  Trajectory ground_truth() const override { return ground_truth_; }

 private:
  void associate(const std::vector<ListEntry>& depth) {
    constexpr double kMaxDt = 0.02;
    struct Candidate {
      double dt;
      size_t rgb, depth;
    };
    std::vector<Candidate> candidates;
    size_t lo = 0;
    for (size_t i = 0; i < rgb_.size(); ++i) {
      while (lo < depth.size() && depth[lo].stamp < rgb_[i].stamp - kMaxDt) ++lo;
      for (size_t j = lo; j < depth.size() && depth[j].stamp <= rgb_[i].stamp + kMaxDt; ++j)
        candidates.push_back({std::abs(depth[j].stamp - rgb_[i].stamp), i, j});
    }
    std::stable_sort(candidates.begin(), candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.dt < b.dt; });
    std::vector<long> match(rgb_.size(), -1);
    std::vector<bool> used(depth.size(), false);
    for (const Candidate& c : candidates)
      if (match[c.rgb] < 0 && !used[c.depth]) {
        match[c.rgb] = static_cast<long>(c.depth);
        used[c.depth] = true;
      }
    std::vector<ListEntry> rgb;
    for (size_t i = 0; i < rgb_.size(); ++i) {
      if (match[i] < 0) continue;
      rgb.push_back(rgb_[i]);
      depth_.push_back(depth[match[i]]);
    }
    if (rgb.size() < rgb_.size())
      warnings_.push_back(std::to_string(rgb_.size() - rgb.size()) +
                          " colour images have no depth image within 0.02 s and are skipped");
    if (rgb.empty())
      throw InputError((root_ / "depth.txt").string(), 0,
                       "no depth image lies within 0.02 s of any colour image in rgb.txt");
    rgb_ = std::move(rgb);
  }

  path root_;
  Sensor sensor_;
  std::vector<ListEntry> rgb_, depth_;
  Trajectory ground_truth_;
};

}  // namespace

std::unique_ptr<DataProvider> open_tum(const std::string& root, const DatasetOptions& options) {
  return std::make_unique<TumDataset>(root, options);
}

}  // namespace dynaorb
