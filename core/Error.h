// Errors for bad input (with the scene location when there is one) and the process exit codes.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace viscera {

// Exit codes of the `viscera` command line.
enum ExitCode : int { kExitOk = 0, kExitInternal = 1, kExitInvalidInput = 2, kExitDiverged = 3 };

// Where something came from: a file and, when known, a 1-based line and column.
struct SourceLoc {
  std::string file;
  int line = 0;
  int col = 0;

  // "file:line:col" (parts that are unknown are left out).
  std::string str() const;
  bool known() const { return !file.empty(); }
};

// Invalid input: a scene, mesh, trajectory or option that cannot be used. The message reads
// "file:line:col: Component.attribute: what is wrong" when a location is known.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
  Error(const SourceLoc& where, const std::string& what)
      : std::runtime_error(where.known() ? where.str() + ": " + what : what), where_(where) {}
  const SourceLoc& where() const { return where_; }

 private:
  SourceLoc where_;
};

// A piece of input quoted for an error message: at most 40 characters (then "..."), bytes that
// are not printable ASCII shown as '?', so binary garbage stays out of terminals.
std::string quoted(std::string_view text);

}  // namespace viscera
