#include "dynaorb/io/text_table.h"

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "dynaorb/io/errors.h"

namespace dynaorb::io {

std::vector<TextRow> read_text_table(const std::string& path, bool csv) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open file");
  std::vector<TextRow> rows;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    if (csv) {
      for (char& c : line)
        if (c == ',') c = ' ';
    }
    TextRow row;
    row.line = number;
    std::istringstream fields(line);
    std::string field;
    while (fields >> field) row.fields.push_back(field);
    rows.push_back(std::move(row));
  }
  return rows;
}

void require_fields(const std::string& path, const TextRow& row, size_t n, const char* layout) {
  if (row.fields.size() < n)
    throw InputError(path, row.line,
                     "expected " + std::to_string(n) + " fields (" + layout + "), found " +
                         std::to_string(row.fields.size()));
}

double parse_double(const std::string& path, const TextRow& row, size_t index, const char* what) {
  const std::string& s = row.fields.at(index);
  char* end = nullptr;
  errno = 0;
  double v = std::strtod(s.c_str(), &end);
  if (end == s.c_str() || *end != '\0' || errno == ERANGE)
    throw InputError(path, row.line, std::string("cannot read ") + what + " from '" + s + "'");
  return v;
}

long long parse_int64(const std::string& path, const TextRow& row, size_t index, const char* what) {
  const std::string& s = row.fields.at(index);
  char* end = nullptr;
  errno = 0;
  long long v = std::strtoll(s.c_str(), &end, 10);
  if (end == s.c_str() || *end != '\0' || errno == ERANGE)
    throw InputError(path, row.line, std::string("cannot read ") + what + " from '" + s + "'");
  return v;
}

}  // namespace dynaorb::io
