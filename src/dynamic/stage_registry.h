#pragma once
// The stages the filter knows from the start (stage_registry.cc includes them all).
#include <map>
#include <string>

#include "dynaorb/dynamic/dynamic_filter.h"

namespace dynaorb::dynamic {

std::map<std::string, StageFactory> builtin_stages();

}  // namespace dynaorb::dynamic
