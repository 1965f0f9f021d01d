// Small text helpers shared by the command modules: option words and JSON strings.
#pragma once

#include <string>
#include <vector>

namespace viscera::cli {

// Words separated by blanks and/or commas ("1 2 3", "1,2,3", "1, 2, 3").
std::vector<std::string> words(const std::string& s);

// Exactly `count` finite numbers written as words (blanks and/or commas between), e.g. a box
// "xmin ymin zmin xmax ymax zmax". Throws viscera::Error naming `option` and showing `shape`.
std::vector<double> finiteNumbers(const std::string& text, const std::string& option, size_t count, const std::string& shape);

// Throws viscera::Error "PATH: OPTION: the folder F does not exist" unless the folder `path` is to
// be written in exists, and when `path` is a symbolic link or a folder; commands check this before
// doing any work, so a typo costs nothing.
void requireParentFolder(const std::string& path, const std::string& option);

// Prints notes to standard error, at most `limit` of them, then "... and N more notes" (a scene
// with thousands of ignored elements would otherwise bury the output); each note cut to 500
// characters.
void printNotes(const std::vector<std::string>& notes, size_t limit = 20);

// `s` as a quoted JSON string (nlohmann::json's escaping; invalid UTF-8 replaced).
std::string jsonString(const std::string& s);

// Throws viscera::Error "PATH: OPTION: is an input of this command (WHAT); it is not overwritten"
// when `path` names the same file as one of `inputs` (by inode: links and other spellings count).
void requireNotAnInput(const std::string& path, const std::string& option, const std::vector<std::string>& inputs);

}  // namespace viscera::cli
