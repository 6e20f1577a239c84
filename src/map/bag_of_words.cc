#include "dynaorb/map/bag_of_words.h"

#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb::map {

std::shared_ptr<const BagOfWords> BagOfWords::compute(const vocab::Vocabulary& vocabulary,
                                                      const Features& features, int levels_up) {
  auto b = std::make_shared<BagOfWords>();
  vocabulary.transform(features.descriptors, b->words, b->nodes, levels_up);
  return b;
}

}  // namespace dynaorb::map
