#pragma once
// dynaorb_node's ~trajectory_file (ROS-free, unit-tested): the System's final
// trajectory written as TUM files, one file per pass. A pass ends where the
// node's map is replaced (time going back, ~reset, ~load_map: each restarts
// the System's trajectory); its frames are written before that, and the
// next pass goes to STEM.passN.SUFFIX, as trajectory_recorder names a looped
// bag's passes.
#include <string>
#include <vector>

#include "dynaorb/system.h"

namespace dynaorb::node {

// The file of pass `pass` (1-based): the first is `file` itself, then
// STEM.pass2.SUFFIX and so on (traj.tum -> traj.pass2.tum; traj -> traj.pass2).
std::string pass_path(const std::string& file, int pass);

// The file of map `map` of a pass whose frames were tracked in several maps
// (the tracker gave a lost map up for a new one): STEM.mapK.SUFFIX.
std::string map_path(const std::string& file, int map);

struct WrittenTrajectory {
  size_t frames = 0;               // poses in `path` (0: nothing written)
  std::vector<std::string> files;  // `path`, then one per map when there are several
};

// Writes `trajectory` (System::trajectory(): the frames' final poses, the
// largest map's when there are several) to `path`, and each of `segments`
// (System::trajectory_segments()) to map_path(path, K) when there are
// several. Nothing is written for an empty trajectory. Throws InputError
// naming the file when it cannot be written.
WrittenTrajectory write_trajectory_files(const std::string& path, const Trajectory& trajectory,
                                         const std::vector<TrajectorySegment>& segments);

}  // namespace dynaorb::node
