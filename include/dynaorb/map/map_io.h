#pragma once
// Saving a Map to a versioned binary file and loading it back (ORB-SLAM2's
// map save/load, as in its forks; ORB-SLAM3's Atlas serialisation).
//
// File layout (little-endian, as written by this machine):
//   "DYNAOMAP"            8 bytes magic
//   u32 version           kMapFormatVersion
//   u64 payload_bytes     length of what follows the header
//   u64 checksum          FNV-1a 64 of the payload
//   payload:
//     sensor, the calibration summary (image size, fx fy cx cy, bf, th_depth,
//     distortion, ORB pyramid), the map's next keyframe / point ids,
//     every keyframe (id, frame id, stamp, T_cw, spanning-tree parent,
//     not_erase, features: keypoints as detected and undistorted,
//     descriptors, u_right, depth),
//     every map point (id, first keyframe, position, reference keyframe,
//     descriptor, normal, distance range, visible / found counters,
//     observations as (keyframe id, keypoint index)),
//     from version 2: the loop closer's loop edges, as pairs of keyframe ids
//     (the essential graph's loop constraints; version 1 files have none and
//     still load).
// Only what is in the map is written: culled keyframes and erased or fused
// points are gone. The covisibility graph is not stored: loading rebuilds it
// from the observations (UpdateConnections on every keyframe, by id), then
// restores the saved spanning-tree parents. The keyframes' grids are rebuilt;
// with a vocabulary their bags of words too, and they enter the database.
//
// Every problem with a file (missing, truncated, not a map, another format
// version, checksum mismatch, inconsistent content, another sensor or
// calibration) is an InputError naming the file, and the map is left as it
// was: the whole file is parsed and checked before the map is replaced.
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>

#include "dynaorb/map/calibration.h"
#include "dynaorb/map/map.h"

namespace dynaorb::place {
class KeyFrameDatabase;
}
namespace dynaorb::vocab {
class Vocabulary;
}

namespace dynaorb::map {

inline constexpr char kMapMagic[8] = {'D', 'Y', 'N', 'A', 'O', 'M', 'A', 'P'};
inline constexpr std::uint32_t kMapFormatVersion = 2;        // what save_map writes
inline constexpr std::uint32_t kMapFormatOldestVersion = 1;  // the oldest load_map reads

// Keyframe id -> the keyframes a loop closure joined it to (both directions).
using LoopEdges = std::map<long, std::set<long>>;

// What a map file was made with, from its header and first payload fields.
struct MapFileInfo {
  std::uint32_t version = 0;
  Sensor sensor = Sensor::kStereo;
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0, bf = 0, th_depth = 0;
  std::vector<double> dist;
  int n_levels = 0;
  double scale_factor = 0;
  long keyframes = 0, points = 0;
  std::uint64_t file_bytes = 0;
};

// Writes the map (the caller holds map.mutex()). calib: the calibration of
// the map's keyframes; loop_edges: the loop closer's (edges naming a keyframe
// no longer in the map are left out). Throws InputError when the file cannot
// be written.
void save_map(const std::string& path, const Map& map, const Calibration& calib, Sensor sensor,
              const LoopEdges& loop_edges = {});

// Reads and checks the header and the calibration summary only.
MapFileInfo read_map_info(const std::string& path);

// Empty when the file's sensor and calibration match these, else why not
// (a sentence naming the first difference).
std::string calibration_mismatch(const MapFileInfo& info, const Calibration& calib, Sensor sensor);

struct LoadOptions {
  const vocab::Vocabulary* vocabulary = nullptr;  // bags of words for the keyframes
  place::KeyFrameDatabase* database = nullptr;    // keyframes indexed (needs vocabulary)
  int covisibility_min_weight = 15;               // as KeyFrame::update_connections
  LoopEdges* loop_edges = nullptr;                // filled with the file's loop edges (set only on success)
};

// Replaces the map's content with the file's (the caller holds map.mutex()).
// The keyframes' features share `calib`, which must match the file's
// summary (InputError otherwise, the map untouched).
MapFileInfo load_map(const std::string& path, Map& map, const std::shared_ptr<const Calibration>& calib,
                     Sensor sensor, const LoadOptions& options = {});

}  // namespace dynaorb::map
