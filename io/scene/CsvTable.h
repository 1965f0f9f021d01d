// Numeric CSV tables: comma-separated rows of a fixed number of finite numbers, with an optional
// header line, blank lines and '#' comments skipped, and errors that name file:line:column.
// The common reader of the robot logs (joint trajectories, velocity and capture tables).
#pragma once

#include <string>
#include <vector>

namespace viscera::io {

struct NumericCsv {
  std::string source;               // file name used in messages
  std::vector<std::string> header;  // the header's fields, empty when the file has none
  int columns = 0;
  std::vector<double> values;       // rows x columns, row-major
  std::vector<int> lines;           // 1-based line of each row

  int rows() const { return static_cast<int>(lines.size()); }
  const double* row(int r) const { return values.data() + static_cast<size_t>(r) * columns; }
  double at(int r, int c) const { return values[static_cast<size_t>(r) * columns + c]; }
};

// Parses `text`. `columnNames` fixes the column count and names the columns in messages
// ("column 'q3': "x" is not a number"). The first content line is a header when its first field
// does not start like a number. Throws viscera::Error "source:line:col: ..." for a wrong column
// count, a field that is not a number, NaN or Inf, and "source: no rows" for a table without data.
NumericCsv parseNumericCsv(const std::string& text, const std::string& source,
                           const std::vector<std::string>& columnNames);
// Reads the file at `path` (an Error naming it when it cannot be read) and parses it.
NumericCsv readNumericCsv(const std::string& path, const std::vector<std::string>& columnNames);


}  // namespace viscera::io
