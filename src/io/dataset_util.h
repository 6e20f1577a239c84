#pragma once
// Helpers shared by the dataset providers (private to src/io).
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "dynaorb/core/sensor.h"
#include "dynaorb/io/dataset.h"

namespace dynaorb::io {

namespace fs = std::filesystem;

// Reads an image; throws InputError naming the image and where it was listed
// ("<list>:<line>") when it is missing or cannot be decoded.
cv::Mat load_image(const fs::path& file, int imread_flags, const std::string& listed_in, int line);

// Throws InputError "<list>:<line>: missing image <file>" when the file does not exist.
void require_file(const fs::path& file, const std::string& listed_in, int line);

// Throws InputError naming both files when their sizes differ.
void require_same_size(const cv::Mat& a, const std::string& a_path, const cv::Mat& b,
                       const std::string& b_path);

// The requested sensor if the dataset supports it, else InputError.
Sensor choose_sensor(const DatasetOptions& options, Sensor richest, bool allow_stereo,
                     bool allow_rgbd, const std::string& what);

// settings.yaml in the sequence folder, when present, overrides derived settings.
bool has_settings_file(const fs::path& root);

}  // namespace dynaorb::io
