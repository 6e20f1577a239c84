#pragma once
// One interface over the dataset layouts users run: TUM RGB-D, KITTI odometry
// and EuRoC MAV. Providers read the index files eagerly (so bad layouts fail at
// open, naming the file and line) and images lazily, one frame at a time.
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "dynaorb/core/pose.h"
#include "dynaorb/core/sensor.h"
#include "dynaorb/io/settings.h"

namespace dynaorb {

struct Frame {
  size_t index = 0;
  double stamp = 0.0;      // seconds
  cv::Mat image;           // left / colour image as stored (8-bit grey or BGR)
  cv::Mat right;           // right image (stereo only)
  cv::Mat depth;           // depth as stored: 16UC1 (scale DepthMapFactor) or 32FC1 metres
  std::string image_path;  // for messages
};

struct DatasetOptions {
  std::optional<Sensor> sensor;  // default: the richest the dataset supports
};

class DataProvider {
 public:
  virtual ~DataProvider() = default;
  virtual std::string kind() const = 0;  // "tum" | "kitti" | "euroc"
  virtual std::string root() const = 0;
  virtual Sensor sensor() const = 0;
  virtual size_t size() const = 0;
  virtual double stamp(size_t i) const = 0;
  // Loads frame i; throws InputError naming the file when an image is missing,
  // cannot be decoded, or has a size that disagrees with its partner image.
  virtual Frame load(size_t i) const = 0;
  // Settings from the dataset's own calibration (settings.yaml in the sequence
  // root when there is one); throws InputError when none can be derived.
  virtual Settings default_settings() const = 0;
  // Ground truth poses of the left / colour camera in the world frame; empty
  // when the dataset has none.
  virtual Trajectory ground_truth() const = 0;
  // Problems found at open that were handled (e.g. unmatched stereo stamps).
  const std::vector<std::string>& warnings() const { return warnings_; }

 protected:
  std::vector<std::string> warnings_;
};

// kind: "tum", "kitti" or "euroc". KITTI's path is ROOT/sequences/NN; EuRoC's is
// the folder that holds mav0 (or mav0 itself).
std::unique_ptr<DataProvider> open_dataset(const std::string& kind, const std::string& path,
                                           const DatasetOptions& options = {});
std::unique_ptr<DataProvider> open_tum(const std::string& path, const DatasetOptions& options);
std::unique_ptr<DataProvider> open_kitti(const std::string& path, const DatasetOptions& options);
std::unique_ptr<DataProvider> open_euroc(const std::string& path, const DatasetOptions& options);

// The TUM RGB-D benchmark's camera (ORB-SLAM2's TUM1/2/3.yaml: intrinsics,
// distortion, DepthMapFactor) for a name that names freiburg1, 2 or 3 (a TUM
// sequence's folder, or TUM's own bag rgbd_dataset_freiburgN_*.bag); nullopt
// when it names none.
std::optional<Settings> tum_settings_for_name(const std::string& name);

}  // namespace dynaorb
