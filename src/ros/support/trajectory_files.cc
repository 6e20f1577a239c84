#include "support/trajectory_files.h"

#include <filesystem>
#include <system_error>

#include "dynaorb/io/errors.h"
#include "dynaorb/io/trajectory_io.h"

namespace dynaorb::node {

namespace {

// STEM + infix + SUFFIX of `file` (the suffix is the file name's last extension).
std::string with_infix(const std::string& file, const std::string& infix) {
  const std::filesystem::path p(file);
  return (p.parent_path() / (p.stem().string() + infix + p.extension().string())).string();
}

// Written beside the file, then renamed over it: a node stopped while it
// writes (a second write at shutdown) leaves the old file or the new one.
void write_replacing(const std::string& path, const Trajectory& poses) {
  const std::string part = path + ".part";
  io::write_tum(part, poses);
  std::error_code ec;
  std::filesystem::rename(part, path, ec);
  if (ec) throw InputError(path + ": cannot replace the trajectory file (" + ec.message() + ")");
}

}  // namespace

std::string pass_path(const std::string& file, int pass) {
  return pass <= 1 ? file : with_infix(file, ".pass" + std::to_string(pass));
}

std::string map_path(const std::string& file, int map) { return with_infix(file, ".map" + std::to_string(map)); }

WrittenTrajectory write_trajectory_files(const std::string& path, const Trajectory& trajectory,
                                         const std::vector<TrajectorySegment>& segments) {
  WrittenTrajectory out;
  if (trajectory.empty()) return out;
  write_replacing(path, trajectory);
  out.frames = trajectory.size();
  out.files.push_back(path);
  if (segments.size() > 1) {
    for (const TrajectorySegment& s : segments) {
      const std::string file = map_path(path, s.map);
      write_replacing(file, s.poses);
      out.files.push_back(file);
    }
  }
  return out;
}

}  // namespace dynaorb::node
