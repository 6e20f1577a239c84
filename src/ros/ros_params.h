// Typed ROS parameters for the nodes: a parameter set with a value of the
// wrong type (~queue_size: "ten", ~use_labels: 1) is refused with an error
// naming it, never silently replaced by the default. (An integer is a number:
// roscpp reads 10 as 10.0.)
#pragma once

#include <ros/node_handle.h>

#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "dynaorb/io/errors.h"

namespace dynaorb::node {

template <typename T>
const char* param_type_name() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_same_v<T, int>) return "an integer";
  else if constexpr (std::is_floating_point_v<T>) return "a number";
  else if constexpr (std::is_same_v<T, std::vector<int>>) return "a list of integers";
  else if constexpr (std::is_same_v<T, std::vector<double>>) return "a list of numbers";
  else return "a string";
}

// true and `out` set when the parameter is set; false when it is not;
// InputError when it is set with a value of another type.
template <typename T>
bool read_param(const ros::NodeHandle& nh, const std::string& name, T& out) {
  if constexpr (std::is_same_v<T, int>) {
    // roscpp rounds a floating-point value to the nearest integer (12.5 ->
    // 13) without a word: refused instead unless it is whole.
    XmlRpc::XmlRpcValue raw;
    if (nh.getParam(name, raw) && raw.getType() == XmlRpc::XmlRpcValue::TypeDouble &&
        static_cast<double>(raw) != std::floor(static_cast<double>(raw)))
      throw InputError("~" + name + " must be " + param_type_name<T>());
  }
  T v;
  if (nh.getParam(name, v)) {
    out = v;
    return true;
  }
  if (nh.hasParam(name)) throw InputError("~" + name + " must be " + param_type_name<T>());
  return false;
}

// The parameter's value, or `fallback` when it is not set (see read_param).
template <typename T>
T param_or(const ros::NodeHandle& nh, const std::string& name, const T& fallback) {
  T v = fallback;
  read_param(nh, name, v);
  return v;
}

// A duration parameter (s): its value, or `fallback` when it is not set;
// InputError naming it when it is negative, NaN or infinite (`note` is
// appended to the message, e.g. " (0: no wait)").
inline double seconds_param_or(const ros::NodeHandle& nh, const std::string& name, double fallback,
                               const std::string& note = "") {
  const double v = param_or(nh, name, fallback);
  if (!(v >= 0.0) || !std::isfinite(v)) throw InputError("~" + name + " must be a finite number of seconds >= 0" + note);
  return v;
}

}  // namespace dynaorb::node
