#pragma once
// Errors for bad input: every message names the file (and line, where there is one).
#include <stdexcept>
#include <string>

namespace dynaorb {

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
  // "<file>:<line>: <problem>"; line 0 means "the file as a whole".
  InputError(const std::string& file, int line, const std::string& problem);
  const std::string& file() const { return file_; }
  int line() const { return line_; }

 private:
  std::string file_;
  int line_ = 0;
};

}  // namespace dynaorb
