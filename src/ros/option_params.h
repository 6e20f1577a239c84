// The core's option structs as ROS parameters: every field of an options
// struct's option_fields list (dynaorb/core/option_fields.h) is the private
// parameter ~NS/NAME, a nested struct's fields ~NS/GROUP/NAME
// (~tracker/reloc/pnp/chi2, ~loop/ransac/chi2), by the names Python and
// `dynaorb run --tracker KEY=VALUE` use. A parameter of the wrong type is
// refused (ros_params.h), and so is one under ~NS/ that names no field (a
// misspelt option would otherwise be ignored without a word). Ranges are
// the options' own validate()'s.
#pragma once

#include <ros/node_handle.h>

#include <set>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "dynaorb/core/option_fields.h"
#include "dynaorb/io/errors.h"
#include "ros_params.h"

namespace dynaorb::node {

namespace detail {

// One field, the parameter ~ns/name: read it if set; `name` goes to `known`,
// "name=value" to `set`.
template <class T>
void read_option_field(const ros::NodeHandle& pnh, const std::string& ns, const std::string& name, T& value,
                       std::set<std::string>& known, std::vector<std::string>& set) {
  known.insert(name);
  const std::string param = ns + "/" + name;
  bool given = false;
  if constexpr (std::is_same_v<T, unsigned>) {  // seeds: an integer >= 0
    int v = 0;
    given = read_param(pnh, param, v);
    if (given && v < 0) throw InputError("~" + param + " must be an integer >= 0");
    if (given) value = static_cast<unsigned>(v);
  } else {
    static_assert(std::is_same_v<T, int> || std::is_same_v<T, double> || std::is_same_v<T, bool>,
                  "an option field of a type the ROS parameters cannot hold");
    given = read_param(pnh, param, value);
  }
  if (given) {
    std::ostringstream s;
    s << name << '=' << std::boolalpha << value;
    set.push_back(s.str());
  }
}

// The fields of `o`, named `group` + field (group: "" or "reloc/pnp/").
template <class Options>
void read_option_fields(const ros::NodeHandle& pnh, const std::string& ns, const std::string& group, Options& o,
                        std::set<std::string>& known, std::vector<std::string>& set) {
  for_each_option_field<Options>([&](const char* field, auto member) {
    auto& value = o.*member;
    using T = std::remove_reference_t<decltype(value)>;
    if constexpr (has_option_fields_v<T>)
      read_option_fields(pnh, ns, group + field + "/", value, known, set);
    else
      read_option_field(pnh, ns, group + field, value, known, set);
  });
}

}  // namespace detail

// Sets the fields of `o` given as ~ns/NAME parameters; returns "NAME=value"
// for each one set (NAME relative to ~ns, slashes between groups). Throws
// InputError for a parameter under ~ns/ that is no field (`what` names the
// options in the message: "~mapping/neighbours_stereo is not a local mapping
// option") and for a value of the wrong type.
template <class Options>
std::vector<std::string> read_option_params(const ros::NodeHandle& pnh, const std::string& ns, Options& o,
                                            const std::string& what) {
  std::set<std::string> known;
  std::vector<std::string> set;
  detail::read_option_fields(pnh, ns, "", o, known, set);
  // Every parameter the master holds under ~ns/ must be one of them.
  std::vector<std::string> names;
  pnh.getParamNames(names);
  const std::string root = pnh.resolveName(ns) + "/";
  for (const std::string& full : names) {
    if (full.compare(0, root.size(), root) != 0 || known.count(full.substr(root.size()))) continue;
    std::string list;
    for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
    throw InputError("~" + ns + "/" + full.substr(root.size()) + " is not a " + what + " option (known: " + list + ")");
  }
  return set;
}

}  // namespace dynaorb::node
