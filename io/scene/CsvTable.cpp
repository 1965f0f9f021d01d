#include "core/Files.h"
#include "io/scene/CsvTable.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <string_view>

#include "core/Error.h"
#include "core/Text.h"

namespace viscera::io {
namespace {

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && isBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && isBlank(s.back())) s.remove_suffix(1);
  return s;
}

bool looksNumeric(std::string_view first) {
  double ignored;
  if (parseNumber(first, ignored)) return true;
  const char c = first.empty() ? '\0' : first.front();
  return std::isdigit(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.';
}

struct Field {
  std::string_view text;
  int col;  // 1-based column of the field's first character in the line
};

void splitFields(std::string_view line, std::vector<Field>& fields) {
  fields.clear();
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    const size_t stop = comma == std::string_view::npos ? line.size() : comma;
    const std::string_view raw = line.substr(start, stop - start);
    size_t lead = 0;
    while (lead < raw.size() && isBlank(raw[lead])) ++lead;
    fields.push_back({trim(raw), static_cast<int>(start + lead) + 1});
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) {
    if (!s.empty()) s += ',';
    s += n;
  }
  return s;
}

}  // namespace

NumericCsv parseNumericCsv(const std::string& raw, const std::string& source,
                           const std::vector<std::string>& columnNames) {
  const std::string text = plainText(raw);
  NumericCsv table;
  table.source = source;
  table.columns = static_cast<int>(columnNames.size());
  std::vector<Field> fields;
  bool firstContent = true;
  size_t pos = 0;
  for (int lineNo = 1; pos < text.size(); ++lineNo) {
    size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    const std::string_view line = trim(std::string_view(text).substr(pos, eol - pos));
    pos = eol + 1;
    if (line.empty() || line.front() == '#') continue;
    splitFields(line, fields);
    if (firstContent) {
      firstContent = false;
      if (!looksNumeric(fields[0].text)) {
        for (const Field& f : fields) table.header.emplace_back(f.text);
        continue;
      }
    }
    if (static_cast<int>(fields.size()) != table.columns)
      throw Error(SourceLoc{source, lineNo}, "expected " + std::to_string(table.columns) + " columns (" +
                                                 joined(columnNames) + "), got " + std::to_string(fields.size()));
    for (int c = 0; c < table.columns; ++c) {
      double v;
      const std::string column = "column '" + columnNames[c] + "'";
      if (!parseNumber(fields[c].text, v))
        throw Error(SourceLoc{source, lineNo, fields[c].col}, column + ": " + quoted(fields[c].text) + " is not a number");
      if (!std::isfinite(v))
        throw Error(SourceLoc{source, lineNo, fields[c].col}, column + " is not finite (" + quoted(fields[c].text) + ")");
      table.values.push_back(v);
    }
    table.lines.push_back(lineNo);
  }
  if (table.lines.empty()) throw Error(SourceLoc{source}, "no rows (expected " + joined(columnNames) + ")");
  return table;
}

NumericCsv readNumericCsv(const std::string& path, const std::vector<std::string>& columnNames) {
  return parseNumericCsv(readInputFile(path), path, columnNames);
}

}  // namespace viscera::io
