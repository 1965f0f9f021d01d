#include "robot/force/ArmLogs.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"
#include "io/scene/CsvTable.h"

namespace viscera::robot {

std::string Series::where(int i) const {
  return i >= 0 && i < static_cast<int>(lines.size()) && lines[i] > 0 ? source + ":" + std::to_string(lines[i]) : source;
}

namespace {

std::vector<std::string> splitCommas(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string field;
  while (std::getline(in, field, ',')) out.push_back(field);
  if (!s.empty() && s.back() == ',') out.emplace_back();
  return out;
}

// Lower case, letters and digits only: "Position_3" -> "position3".
std::string normalised(const std::string& s) {
  std::string out;
  for (char c : s)
    if (std::isalnum(static_cast<unsigned char>(c))) out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// The first line with content, for the column count and a possible header.
struct FirstLine {
  std::vector<std::string> fields;
  int line = 0;
  bool header = false;
};

FirstLine firstContentLine(const std::string& text, const std::string& source) {
  std::stringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line[start] == '#') continue;
    FirstLine f{splitCommas(line), number, false};
    std::string first = f.fields.front();
    first.erase(0, first.find_first_not_of(" \t"));
    double ignored;
    f.header = !parseNumber(first, ignored) && !(first.empty() == false && (std::isdigit(static_cast<unsigned char>(first[0])) ||
                                                                            first[0] == '-' || first[0] == '+' || first[0] == '.'));
    return f;
  }
  throw Error(source + ": no rows");
}

// Where each quantity sits among the file's columns: -1 when absent.
struct ColumnMap {
  int time = -1;
  std::vector<int> q, qd, effort;
};

// Reads one column name of a map or header; false when it names nothing we know.
bool assign(const std::string& raw, int column, int dof, ColumnMap& map, std::string& problem, bool lenient) {
  const std::string n = normalised(raw);
  if (raw == "-" || n.empty()) return true;
  if (n == "t" || n == "time" || n == "timestamp") {
    if (map.time >= 0) return problem = "time appears twice", false;
    map.time = column;
    return true;
  }
  static const std::vector<std::pair<std::string, int>> prefixes = {
      {"qd", 1}, {"velocity", 1}, {"vel", 1}, {"tau", 2}, {"effort", 2}, {"torque", 2}, {"q", 0}, {"position", 0}, {"pos", 0}};
  for (const auto& [prefix, kind] : prefixes) {
    if (n.rfind(prefix, 0) != 0 || n.size() == prefix.size()) continue;
    const std::string digits = n.substr(prefix.size());
    if (!std::all_of(digits.begin(), digits.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); }))
      continue;
    const int joint = std::stoi(digits);
    if (joint < 1) return problem = "joints are numbered from 1: " + viscera::quoted(raw), false;
    if (joint > dof) return true;  // a joint the arm model does not have (the jaw): skipped
    std::vector<int>& slot = kind == 0 ? map.q : kind == 1 ? map.qd : map.effort;
    if (slot[joint - 1] >= 0) return problem = viscera::quoted(raw) + " appears twice", false;
    slot[joint - 1] = column;
    return true;
  }
  if (lenient) return true;  // a header's other columns (the jaw, a sequence number, ...)
  problem = "unknown column " + viscera::quoted(raw) + " (t, qK, qdK, tauK or -)";
  return false;
}

// The map named by `names` (false with `problem` set when it is not one). A header is `lenient`:
// columns it names otherwise are skipped; a column map must name every column.
bool mapFromNames(const std::vector<std::string>& names, int dof, ColumnMap& map, std::string& problem, bool lenient) {
  map = ColumnMap{-1, std::vector<int>(dof, -1), std::vector<int>(dof, -1), std::vector<int>(dof, -1)};
  for (int c = 0; c < static_cast<int>(names.size()); ++c)
    if (!assign(names[c], c, dof, map, problem, lenient)) return false;
  std::string missing;
  if (map.time < 0) missing += " t";
  for (int j = 0; j < dof; ++j) {
    if (map.q[j] < 0) missing += " q" + std::to_string(j + 1);
    if (map.qd[j] < 0) missing += " qd" + std::to_string(j + 1);
    if (map.effort[j] < 0) missing += " tau" + std::to_string(j + 1);
  }
  if (!missing.empty()) return problem = "no column for" + missing, false;
  return true;
}

// t, q1..qm, qd1..qm, tau1..taum.
std::vector<std::string> standardNames(int joints) {
  std::vector<std::string> names = {"t"};
  for (const char* kind : {"q", "qd", "tau"})
    for (int j = 1; j <= joints; ++j) names.push_back(kind + std::to_string(j));
  return names;
}

void requireIncreasingTime(const Series& s) {
  for (int i = 1; i < s.samples(); ++i)
    if (!(s.t[i] > s.t[i - 1]))
      throw Error(s.where(i) + ": time " + std::to_string(s.t[i]) + " s does not increase (previous sample: " +
                  std::to_string(s.t[i - 1]) + " s)");
}

Series seriesFromCsv(const io::NumericCsv& csv, int timeColumn, const std::vector<int>& columns,
                     std::vector<std::string> names) {
  Series s;
  s.source = csv.source;
  s.names = std::move(names);
  s.lines = csv.lines;
  s.t.resize(csv.rows());
  s.values.resize(csv.rows(), static_cast<Eigen::Index>(columns.size()));
  for (int r = 0; r < csv.rows(); ++r) {
    s.t[r] = csv.at(r, timeColumn);
    for (size_t c = 0; c < columns.size(); ++c) s.values(r, static_cast<Eigen::Index>(c)) = csv.at(r, columns[c]);
  }
  requireIncreasingTime(s);
  return s;
}

// A table of fixed columns `t, names...` (wrench, Jacobian).
Series readFixed(const std::string& text, const std::string& source, const std::vector<std::string>& names) {
  std::vector<std::string> all = {"t"};
  all.insert(all.end(), names.begin(), names.end());
  const io::NumericCsv csv = io::parseNumericCsv(text, source, all);
  std::vector<int> columns(names.size());
  for (size_t i = 0; i < names.size(); ++i) columns[i] = static_cast<int>(i) + 1;
  return seriesFromCsv(csv, 0, columns, names);
}

std::vector<std::string> jacobianNames(int dof) {
  std::vector<std::string> names;
  for (int r = 1; r <= 6; ++r)
    for (int c = 1; c <= dof; ++c) names.push_back("J" + std::to_string(r) + "_" + std::to_string(c));
  return names;
}

const std::vector<std::string> kWrenchNames = {"Fx", "Fy", "Fz", "Tx", "Ty", "Tz"};

}  // namespace

JointStateLog sliceLog(const JointStateLog& log, int begin, int end) {
  if (begin < 0 || end > log.samples() || begin > end) throw Error(log.series.source + ": no samples " + std::to_string(begin) + " to " + std::to_string(end));
  JointStateLog out;
  out.dof = log.dof;
  out.series.source = log.series.source;
  out.series.names = log.series.names;
  out.series.t.assign(log.series.t.begin() + begin, log.series.t.begin() + end);
  out.series.values = log.series.values.middleRows(begin, end - begin);
  if (!log.series.lines.empty()) out.series.lines.assign(log.series.lines.begin() + begin, log.series.lines.begin() + end);
  return out;
}

JointStateLog makeJointStateLog(std::vector<double> t, const Eigen::MatrixXd& q, const Eigen::MatrixXd& qd,
                                const Eigen::MatrixXd& effort, const std::string& source) {
  const int n = static_cast<int>(q.cols());
  if (q.rows() != static_cast<Eigen::Index>(t.size()) || qd.rows() != q.rows() || effort.rows() != q.rows() ||
      qd.cols() != n || effort.cols() != n)
    throw Error("joint state log: t, q, qd and effort differ in size");
  JointStateLog log;
  log.dof = n;
  log.series.source = source;
  std::vector<std::string> names = standardNames(n);
  log.series.names.assign(names.begin() + 1, names.end());
  log.series.t = std::move(t);
  log.series.values.resize(q.rows(), 3 * n);
  log.series.values << q, qd, effort;
  requireIncreasingTime(log.series);
  return log;
}

JointStateLog parseJointStateLog(const std::string& text, const std::string& source, int dof, const std::string& columns) {
  if (dof < 1) throw Error(source + ": a joint state log needs at least one joint");
  const FirstLine first = firstContentLine(text, source);
  const int count = static_cast<int>(first.fields.size());
  ColumnMap map;
  std::string problem;
  std::vector<std::string> fileNames;  // what the CSV reader calls each column in messages
  if (!columns.empty()) {
    fileNames = splitCommas(columns);
    for (auto& n : fileNames) n.erase(0, n.find_first_not_of(" \t")), n.erase(n.find_last_not_of(" \t") + 1);
    if (!mapFromNames(fileNames, dof, map, problem, false)) throw Error("--columns: " + problem);
    if (static_cast<int>(fileNames.size()) != count)
      throw Error(source + ":" + std::to_string(first.line) + ": " + std::to_string(count) +
                  " columns, but the column map names " + std::to_string(fileNames.size()));
  } else if (first.header && mapFromNames(first.fields, dof, map, problem, true)) {
    fileNames = first.fields;
  } else if (count == 1 + 3 * dof || (dof == 6 && count == 22)) {
    fileNames = standardNames(count == 1 + 3 * dof ? dof : 7);
    mapFromNames(fileNames, dof, map, problem, false);
  } else {
    throw Error(source + ":" + std::to_string(first.line) + ": " + std::to_string(count) + " columns; a joint state log has " +
                std::to_string(1 + 3 * dof) + " (t,q1..q" + std::to_string(dof) + ",qd1..,tau1..)" +
                (dof == 6 ? " or 22 (with the jaw)" : "") +
                (first.header && !problem.empty() ? "; its header: " + problem : "") +
                "; give the order with a column map (--columns)");
  }
  for (auto& n : fileNames)
    if (n.empty() || n == "-") n = "skipped";
  const io::NumericCsv csv = io::parseNumericCsv(text, source, fileNames);
  std::vector<int> cols;
  for (const std::vector<int>* part : {&map.q, &map.qd, &map.effort}) cols.insert(cols.end(), part->begin(), part->end());
  std::vector<std::string> names = standardNames(dof);
  JointStateLog log;
  log.dof = dof;
  log.series = seriesFromCsv(csv, map.time, cols, std::vector<std::string>(names.begin() + 1, names.end()));
  return log;
}

JointStateLog readJointStateLog(const std::string& path, int dof, const std::string& columns) {
  return parseJointStateLog(readInputFile(path, "joint state log"), path, dof, columns);
}

Series readWrenchCsv(const std::string& path) {
  const std::string text = readInputFile(path, "wrench log");
  // A force sensor's log without torques (t,Fx,Fy,Fz) reads with zero torques.
  if (firstContentLine(text, path).fields.size() == 4) {
    Series s = readFixed(text, path, {"Fx", "Fy", "Fz"});
    Eigen::MatrixXd w = Eigen::MatrixXd::Zero(s.samples(), 6);
    w.leftCols(3) = s.values;
    s.values = w;
    s.names = kWrenchNames;
    return s;
  }
  return readFixed(text, path, kWrenchNames);
}

Series readJacobianCsv(const std::string& path, int dof) {
  return readFixed(readInputFile(path, "Jacobian log"), path, jacobianNames(dof));
}

std::string formatSeries(const Series& s, int digits) {
  if (digits < 1 || digits > 17) throw Error("values are written with 1 to 17 significant digits, not " + std::to_string(digits));
  std::string out = "t";
  for (const std::string& n : s.names) out += "," + n;
  out += "\n";
  char buffer[32];
  for (int i = 0; i < s.samples(); ++i) {
    std::snprintf(buffer, sizeof buffer, "%.17g", s.t[i]);  // 17 digits: at most 24 characters
    out += buffer;
    for (Eigen::Index c = 0; c < s.values.cols(); ++c) {
      std::snprintf(buffer, sizeof buffer, ",%.*g", digits, s.values(i, c));
      out += buffer;
    }
    out += "\n";
  }
  return out;
}

void writeSeries(const std::string& path, const Series& s, int digits) { writeFileAtomic(path, formatSeries(s, digits)); }

Series wrenchSeries(std::vector<double> t, const Eigen::MatrixXd& wrench) {
  if (wrench.cols() != 6 || wrench.rows() != static_cast<Eigen::Index>(t.size()))
    throw Error("wrench series: needs 6 columns and one row per time");
  return Series{"", kWrenchNames, std::move(t), wrench, {}};
}

Series jacobianSeries(std::vector<double> t, const Eigen::MatrixXd& jacobian, int dof) {
  if (jacobian.cols() != 6 * dof || jacobian.rows() != static_cast<Eigen::Index>(t.size()))
    throw Error("Jacobian series: needs 6 x dof columns and one row per time");
  return Series{"", jacobianNames(dof), std::move(t), jacobian, {}};
}

Series interpolate(const Series& s, const std::vector<double>& times) {
  if (s.samples() == 0) throw Error(s.source + ": no samples");
  Series out{s.source, s.names, times, Eigen::MatrixXd(static_cast<Eigen::Index>(times.size()), s.values.cols()), {}};
  constexpr double slack = 1e-9;  // s: rounding of uniformTimes' end point
  for (size_t i = 0; i < times.size(); ++i) {
    const double t = times[i];
    if (t < s.t.front() - slack || t > s.t.back() + slack)
      throw Error(s.source + ": covers " + std::to_string(s.t.front()) + " to " + std::to_string(s.t.back()) +
                  " s, not " + std::to_string(t) + " s");
    const Eigen::Index row = static_cast<Eigen::Index>(i);
    if (s.samples() == 1) {
      out.values.row(row) = s.values.row(0);
      continue;
    }
    const auto after = std::upper_bound(s.t.begin(), s.t.end(), t) - s.t.begin();
    const size_t k = static_cast<size_t>(std::clamp<std::ptrdiff_t>(after - 1, 0, s.samples() - 2));
    const double w = std::clamp((t - s.t[k]) / (s.t[k + 1] - s.t[k]), 0.0, 1.0);
    out.values.row(row) = (1 - w) * s.values.row(static_cast<Eigen::Index>(k)) + w * s.values.row(static_cast<Eigen::Index>(k + 1));
  }
  return out;
}

std::vector<double> uniformTimes(double start, double end, double rate) {
  if (!(rate > 0) || !(end >= start)) throw Error("resampling: needs a positive rate and end >= start");
  const auto count = static_cast<long long>(std::floor((end - start) * rate + 1e-6)) + 1;
  std::vector<double> t(static_cast<size_t>(count));
  // The last time may pass `end` by rounding: it is held at `end`, which every log spanning
  // [start, end] covers.
  for (long long i = 0; i < count; ++i) t[static_cast<size_t>(i)] = std::min(end, start + static_cast<double>(i) / rate);
  return t;
}

Series averageAt(const Series& s, const std::vector<double>& times, double period) {
  if (s.samples() == 0) throw Error(s.source + ": no samples");
  if (!(period > 0)) throw Error("resampling: the period must be positive");
  Series out{s.source, s.names, times, Eigen::MatrixXd(static_cast<Eigen::Index>(times.size()), s.values.cols()), {}};
  const double half = 0.5 * period;
  size_t lo = 0;
  for (size_t i = 0; i < times.size(); ++i) {
    if (i > 0 && times[i] < times[i - 1]) lo = 0;
    while (lo < s.t.size() && s.t[lo] < times[i] - half) ++lo;
    size_t hi = lo;
    Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(s.values.cols());
    while (hi < s.t.size() && s.t[hi] < times[i] + half) sum += s.values.row(static_cast<Eigen::Index>(hi++));
    if (hi > lo) {
      out.values.row(static_cast<Eigen::Index>(i)) = sum / static_cast<double>(hi - lo);
    } else {  // a gap in the log longer than the period: interpolate across it
      out.values.row(static_cast<Eigen::Index>(i)) = interpolate(s, {times[i]}).values.row(0);
    }
  }
  return out;
}

Series resample(const Series& s, double rate, bool average) {
  if (s.samples() == 0) throw Error(s.source + ": no samples");
  const std::vector<double> times = uniformTimes(s.t.front(), s.t.back(), rate);
  return average ? averageAt(s, times, 1 / rate) : interpolate(s, times);
}

JointStateLog resample(const JointStateLog& log, double rate, bool average) {
  return JointStateLog{log.dof, resample(log.series, rate, average)};
}

std::pair<double, double> overlap(const Series& a, const Series& b) {
  if (a.samples() == 0 || b.samples() == 0) throw Error("logs without samples do not overlap");
  const double start = std::max(a.t.front(), b.t.front()), end = std::min(a.t.back(), b.t.back());
  if (!(end >= start))
    throw Error(a.source + " (" + std::to_string(a.t.front()) + " to " + std::to_string(a.t.back()) + " s) and " + b.source +
                " (" + std::to_string(b.t.front()) + " to " + std::to_string(b.t.back()) + " s) share no time");
  return {start, end};
}

}  // namespace viscera::robot
