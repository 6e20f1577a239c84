#include "dynaorb/io/errors.h"

namespace dynaorb {

namespace {
std::string format(const std::string& file, int line, const std::string& problem) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + problem;
  return file + ": " + problem;
}
}  // namespace

InputError::InputError(const std::string& file, int line, const std::string& problem)
    : std::runtime_error(format(file, line, problem)), file_(file), line_(line) {}

}  // namespace dynaorb
