#pragma once
// Range checks for a module's options (a dynamic stage's, local mapping's,
// loop closing's): each failure is an InputError naming the section, the key,
// its value and the rule ("Dynamic.dm option 'epipolar_threshold_px' is nan;
// it must be a finite number > 0").
#include <cmath>
#include <sstream>
#include <string>

#include "dynaorb/io/errors.h"

namespace dynaorb::detail {

class OptionChecks {
 public:
  explicit OptionChecks(std::string section) : section_(std::move(section)) {}

  [[noreturn]] void fail(const std::string& key, double value, const std::string& rule) const {
    std::ostringstream v;
    v << value;
    throw InputError(section_ + " option '" + key + "' is " + v.str() + "; it must be " + rule);
  }
  [[noreturn]] void fail(const std::string& key, const std::string& value, const std::string& rule) const {
    throw InputError(section_ + " option '" + key + "' is '" + value + "'; it must be " + rule);
  }
  // A count (or a whole number of pixels) >= min.
  void at_least(const std::string& key, int value, int min) const {
    if (value < min) fail(key, value, ">= " + std::to_string(min));
  }
  void positive(const std::string& key, double value) const {
    if (!(value > 0) || std::isinf(value)) fail(key, value, "a finite number > 0");
  }
  void non_negative(const std::string& key, double value, const std::string& zero_means) const {
    if (!(value >= 0) || std::isinf(value)) fail(key, value, "a finite number >= 0 (0: " + zero_means + ")");
  }
  // lo < value < hi, or lo < value <= hi with closed_hi.
  void between(const std::string& key, double value, double lo, double hi, bool closed_hi) const {
    if (!(value > lo && (closed_hi ? value <= hi : value < hi))) {
      std::ostringstream r;
      r << "in (" << lo << ", " << hi << (closed_hi ? "]" : ")");
      fail(key, value, r.str());
    }
  }
  void finite(const std::string& key, double value, const std::string& rule) const {
    if (!std::isfinite(value)) fail(key, value, rule);
  }

 private:
  std::string section_;
};

}  // namespace dynaorb::detail
