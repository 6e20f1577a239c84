#include "dynaorb/map/bag_of_words.h"

#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb::map {

std::shared_ptr<const BagOfWords> BagOfWords::compute(const vocab::Vocabulary& vocabulary,
                                                      const Features& features, int levels_up) {
  vocab::BowVector words;
  vocab::FeatureVector nodes;
  vocabulary.transform(features.descriptors, words, nodes, levels_up);
  return std::make_shared<const BagOfWords>(std::move(words), std::move(nodes));
}

}  // namespace dynaorb::map
