#pragma once
// Reading one option of a stage's options struct from a cv::FileNode: a
// missing key keeps the default, a key of the wrong type is an InputError
// naming it (never a silent 0 from cv::FileNode's conversions).
#include <opencv2/core.hpp>
#include <string>

#include "dynaorb/io/errors.h"

namespace dynaorb::dynamic::detail {

inline bool has_key(const cv::FileNode& node, const char* key) {
  if (node.empty() || !node.isMap()) return false;
  const cv::FileNode n = node[key];
  return !n.empty() && !n.isNone();
}

inline std::string key_name(const cv::FileNode& node, const char* key) {
  const std::string parent = node.name();
  return parent.empty() ? std::string(key) : parent + "." + key;
}

inline void read_option(const cv::FileNode& node, const char* key, double& value) {
  if (!has_key(node, key)) return;
  const cv::FileNode n = node[key];
  if (!n.isReal() && !n.isInt()) throw InputError("option '" + key_name(node, key) + "' must be a number");
  value = static_cast<double>(n);
}

inline void read_option(const cv::FileNode& node, const char* key, int& value) {
  if (!has_key(node, key)) return;
  const cv::FileNode n = node[key];
  if (!n.isInt()) throw InputError("option '" + key_name(node, key) + "' must be an integer");
  value = static_cast<int>(n);
}

// YAML true/false come through OpenCV as strings; 0/1 as integers.
inline void read_option(const cv::FileNode& node, const char* key, bool& value) {
  if (!has_key(node, key)) return;
  const cv::FileNode n = node[key];
  if (n.isInt()) {
    value = static_cast<int>(n) != 0;
    return;
  }
  if (n.isString()) {
    const std::string s = static_cast<std::string>(n);
    if (s == "true" || s == "True" || s == "TRUE") {
      value = true;
      return;
    }
    if (s == "false" || s == "False" || s == "FALSE") {
      value = false;
      return;
    }
  }
  throw InputError("option '" + key_name(node, key) + "' must be true/false or 0/1");
}

inline void read_option(const cv::FileNode& node, const char* key, std::string& value) {
  if (!has_key(node, key)) return;
  const cv::FileNode n = node[key];
  if (!n.isString()) throw InputError("option '" + key_name(node, key) + "' must be a string");
  value = static_cast<std::string>(n);
}

}  // namespace dynaorb::dynamic::detail
