#pragma once
// Reading whitespace- or comma-separated text tables (rgb.txt, times.txt, data.csv,
// poses) with the file and line kept for error messages.
#include <string>
#include <vector>

namespace dynaorb::io {

struct TextRow {
  int line = 0;                     // 1-based line number in the file
  std::vector<std::string> fields;  // split on whitespace (and commas when csv)
};

// Reads every non-blank line that does not start with '#'. Throws InputError when
// the file cannot be opened.
std::vector<TextRow> read_text_table(const std::string& path, bool csv = false);

// Parses a field as a double / integer; throws InputError "<path>:<line>: ..." otherwise.
double parse_double(const std::string& path, const TextRow& row, size_t index, const char* what);
long long parse_int64(const std::string& path, const TextRow& row, size_t index, const char* what);

// Throws InputError when the row has fewer than n fields.
void require_fields(const std::string& path, const TextRow& row, size_t n, const char* layout);

}  // namespace dynaorb::io
