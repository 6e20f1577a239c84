// dynaorb_node's services (map files, reset, localisation, the trajectory
// file, stats) and its shutdown: each takes the system mutex, so it runs
// between two frames (services have their own queue and thread).
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <system_error>

#include "slam_node.h"
#include "support/trajectory_files.h"

namespace dynaorb::node {

bool SlamNode::on_save_map(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res) {
  std::lock_guard<std::mutex> lk(system_mutex_);
  if (!system_) {
    res.message = "no system yet (waiting for camera_info)";
    return true;
  }
  try {
    system_->save_map(req.path);
    res.success = true;
    res.message = "saved " + req.path;
  } catch (const std::exception& e) {
    res.message = e.what();
  }
  return true;
}

bool SlamNode::on_load_map(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res) {
  std::lock_guard<std::mutex> lk(system_mutex_);
  if (!system_) {
    res.message = "no system yet (waiting for camera_info)";
    return true;
  }
  // The frames so far are written first: a loaded map restarts the
  // trajectory (a refused file keeps it, and the pass goes on).
  const size_t written = write_trajectory_locked(pass_file(), "before ~load_map");
  try {
    system_->load_map(req.path);
    if (written > 0) advance_trajectory_pass_locked();
    // The loaded map's world is the map frame (the saved map's first base pose).
    T_map_world_ = Eigen::Isometry3d::Identity();
    map_restarted_ = false;
    last_tracked_ = false;
    res.success = true;
    res.message = "loaded " + req.path + ": the next frame is relocalised in it";
  } catch (const std::exception& e) {
    res.message = e.what();
  }
  return true;
}

bool SlamNode::on_reset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::lock_guard<std::mutex> lk(system_mutex_);
  end_trajectory_pass_locked("~reset");
  if (system_) system_->reset();
  map_restarted_ = true;
  last_tracked_ = false;
  res.success = true;
  res.message = "map dropped: the next frame starts a new one";
  return true;
}

bool SlamNode::on_localization(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
  std::lock_guard<std::mutex> lk(system_mutex_);
  cfg_.system.localization_only = req.data;
  if (system_) system_->set_localization_mode(req.data);
  res.success = true;
  res.message = req.data ? "localisation only" : "mapping";
  return true;
}

bool SlamNode::on_save_trajectory(dynaorb::MapFile::Request& req, dynaorb::MapFile::Response& res) {
  std::lock_guard<std::mutex> lk(system_mutex_);
  const std::string path = req.path.empty() ? pass_file() : req.path;
  if (path.empty()) {
    res.message = "no path given and no ~trajectory_file set";
    return true;
  }
  if (!system_) {
    res.message = "no system yet (waiting for camera_info)";
    return true;
  }
  if (!req.path.empty()) {  // its folder made, as ~trajectory_file's is at start-up (a failure: the write says so)
    std::error_code ec;
    std::filesystem::create_directories(std::filesystem::absolute(req.path).parent_path(), ec);
  }
  std::string error;
  const size_t frames = write_trajectory_locked(path, "on ~save_trajectory", &error);
  res.success = frames > 0;
  res.message = !error.empty() ? error
                : frames > 0 ? std::to_string(frames) + " frames written to " + path
                             : "no frame tracked in this pass yet: " + path + " not written";
  return true;
}

std::string SlamNode::pass_file() const {
  return cfg_.node.trajectory_file.empty() ? std::string() : pass_path(cfg_.node.trajectory_file, trajectory_pass_);
}

size_t SlamNode::write_trajectory_locked(const std::string& path, const char* when, std::string* error) {
  if (path.empty() || !system_) return 0;
  try {
    const WrittenTrajectory w = write_trajectory_files(path, system_->trajectory(), system_->trajectory_segments());
    if (w.frames > 0)
      ROS_INFO("dynaorb_node: %s: trajectory of pass %d (%zu frames) written to %s%s", when, trajectory_pass_,
               w.frames, path.c_str(), w.files.size() > 1 ? " (and one file per map beside it)" : "");
    return w.frames;
  } catch (const std::exception& e) {
    ++counters_.trajectory_write_failures;
    ROS_ERROR("dynaorb_node: %s: %s", when, e.what());
    if (error) *error = e.what();
    return 0;
  }
}

void SlamNode::end_trajectory_pass_locked(const char* why) {
  // As the poses are now: waiting here for local mapping (or a global BA)
  // to finish would hold up the frames of the new map.
  if (write_trajectory_locked(pass_file(), why) > 0) advance_trajectory_pass_locked();
}

void SlamNode::advance_trajectory_pass_locked() {
  ++counters_.trajectory_passes;
  ++trajectory_pass_;
}

void SlamNode::finish() {
  std::lock_guard<std::mutex> lk(system_mutex_);
  if (pass_file().empty() || !system_) return;
  // Written as the poses are, then again once local mapping has mapped the
  // keyframes queued and a global BA has finished: a node stopped for good
  // during that wait (roslaunch escalates to SIGTERM) still leaves a file.
  if (write_trajectory_locked(pass_file(), "at shutdown") == 0) return;
  // rosout is gone by now: on stderr, so that a wait for a long global BA
  // does not look like a hang.
  std::fprintf(stderr,
               "dynaorb_node: finishing local mapping and loop closing (a running global BA may take a while); "
               "the trajectory as it is now is already in %s\n",
               pass_file().c_str());
  system_->wait_for_mapping();
  const size_t frames = write_trajectory_locked(pass_file(), "at shutdown, mapping done");
  if (frames > 0) {
    ++counters_.trajectory_passes;
    // rosout is gone by now.
    std::fprintf(stderr, "dynaorb_node: trajectory (%zu frames) written to %s\n", frames, pass_file().c_str());
  }
}

bool SlamNode::on_stats(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  res.success = true;
  res.message = stats_json();
  return true;
}

std::string SlamNode::stats_json() const {
  const NodeCounters& c = counters_;
  std::ostringstream out;
  out << "{\"frames_in\": " << c.frames_in.load() << ", \"unreadable\": " << c.unreadable.load()
      << ", \"waiting_for_camera_info\": " << c.waiting_for_camera_info.load()
      << ", \"labels_in\": " << c.labels_in.load() << ", \"labels_unreadable\": " << c.labels_unreadable.load()
      << ", \"labels_used\": " << c.labels_used.load() << ", \"labels_missing\": " << c.labels_missing.load()
      << ", \"labels_stale\": " << c.labels_stale.load() << ", \"labels_propagated\": " << c.labels_propagated.load()
      << ", \"labels_as_is\": " << c.labels_as_is.load()
      << ", \"label_propagation_ms_total\": " << c.label_propagation_us.load() / 1000.0
      << ", \"skipped_before_labels\": " << c.skipped_before_labels.load()
      << ", \"first_labels_timed_out\": " << c.first_labels_timed_out.load() << ", \"tf_failures\": " << c.tf_failures.load()
      << ", \"clouds\": " << c.clouds.load() << ", \"cloud_failures\": " << c.cloud_failures.load()
      << ", \"inpainted_clouds\": " << c.inpainted_clouds.load()
      << ", \"unchecked_clouds\": " << c.unchecked_clouds.load() << ", \"time_jumps\": " << c.time_jumps.load()
      << ", \"trajectory_passes\": " << c.trajectory_passes.load()
      << ", \"trajectory_write_failures\": " << c.trajectory_write_failures.load();
  std::lock_guard<std::mutex> lk(system_mutex_);
  if (system_) {
    const SystemCounters& s = system_->counters();
    const MapSummary m = system_->map_summary();
    out << ", \"frames\": " << s.frames << ", \"tracked\": " << s.tracked << ", \"lost\": " << s.lost
        << ", \"rejected\": " << s.rejected << ", \"masks_dropped\": " << s.masks_dropped
        << ", \"relocalizations\": " << s.relocalizations << ", \"loops_closed\": " << s.loops_closed
        << ", \"dynamic_all_frames\": " << s.dynamic_all_frames
        << ", \"dynamic_stage_failures\": " << s.dynamic_stage_failures
        << ", \"unchecked_kept\": " << s.unchecked_kept
        << ", \"keyframes\": " << m.keyframes << ", \"map_points\": " << m.points;
  }
  // The movable label ids in use: the filter's with a preset, else those masked.
  const std::vector<int> ids = system_ && system_->dynamic_filter_enabled() ? system_->movable_classes()
                                                                           : cfg_.node.movable_ids;
  out << ", \"movable_classes\": [";
  for (size_t i = 0; i < ids.size(); ++i) out << (i ? ", " : "") << ids[i];
  out << "]";
  out << "}";
  return out.str();
}

}  // namespace dynaorb::node
