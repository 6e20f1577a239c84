// The built-in stages, by the names presets use.
#include "stage_registry.h"

#include "dynaorb/dynamic/ddl_stage.h"
#include "dynaorb/dynamic/dm_stage.h"
#include "dynaorb/dynamic/li_stage.h"
#include "dynaorb/dynamic/semantic_stage.h"
#include "dynaorb/dynamic/stdyn_stage.h"

namespace dynaorb::dynamic {

namespace {

// A factory for a stage whose options struct has read(const cv::FileNode&).
template <class StageT, class OptionsT>
StageFactory factory() {
  return [](const cv::FileNode& node) -> std::unique_ptr<Stage> {
    OptionsT o;
    o.read(node);
    return std::make_unique<StageT>(o);
  };
}

}  // namespace

std::map<std::string, StageFactory> builtin_stages() {
  return {
      {"semantic", factory<SemanticStage, SemanticOptions>()},  // the semantic prior (all papers)
      {"dm", factory<DmStage, DmOptions>()},                    // DM-SLAM Sec. 3.2
      {"stdyn", factory<StdynStage, StdynOptions>()},           // STDyn-SLAM Sec. III-A/B
      {"ddl", factory<DdlStage, DdlOptions>()},                 // DDL-SLAM Sec. III-C
      {"li", factory<LiStage, LiOptions>()},                    // Li et al. 2021
  };
}

}  // namespace dynaorb::dynamic
