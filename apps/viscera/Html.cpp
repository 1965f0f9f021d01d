#include "apps/viscera/Html.h"

#include <sstream>
#include <vector>

namespace viscera {

namespace {

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// **bold** and `code` within a line (escaped first).
std::string inlineMarkup(const std::string& text) {
  const std::string s = escape(text);
  std::string out;
  bool bold = false, code = false;
  for (size_t i = 0; i < s.size(); ++i) {
    if (!code && s.compare(i, 2, "**") == 0) {
      out += bold ? "</strong>" : "<strong>";
      bold = !bold;
      ++i;
    } else if (s[i] == '`') {
      out += code ? "</code>" : "<code>";
      code = !code;
    } else {
      out += s[i];
    }
  }
  if (code) out += "</code>";
  if (bold) out += "</strong>";
  return out;
}

std::vector<std::string> cells(const std::string& row) {
  std::vector<std::string> out;
  std::string cur;
  for (size_t i = 1; i < row.size(); ++i) {
    if (row[i] == '|') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += row[i];
    }
  }
  for (auto& c : out) {
    const auto b = c.find_first_not_of(' '), e = c.find_last_not_of(' ');
    c = b == std::string::npos ? "" : c.substr(b, e - b + 1);
  }
  return out;
}

}  // namespace

std::string markdownPage(const std::string& title, const std::string& markdown, const std::string& image) {
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>" << escape(title) << "</title>\n"
    << "<style>body{font-family:sans-serif;max-width:70em;margin:2em auto;line-height:1.4}"
       "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:.2em .6em;text-align:left}"
       "th{background:#eee}code{background:#f4f4f4;padding:0 .2em}img{max-width:100%}</style>\n</head><body>\n";
  std::istringstream in(markdown);
  std::string line;
  std::vector<std::string> table;
  std::string para;
  bool list = false, imageShown = image.empty();
  int headings = 0;
  auto flushPara = [&] {
    if (!para.empty()) h << "<p>" << inlineMarkup(para) << "</p>\n";
    para.clear();
  };
  auto flushTable = [&] {
    if (table.empty()) return;
    h << "<table>\n";
    for (size_t r = 0; r < table.size(); ++r) {
      if (r == 1) continue;  // the |---| row
      h << "<tr>";
      for (const auto& c : cells(table[r])) h << (r == 0 ? "<th>" : "<td>") << inlineMarkup(c) << (r == 0 ? "</th>" : "</td>");
      h << "</tr>\n";
    }
    h << "</table>\n";
    table.clear();
  };
  auto flushList = [&] {
    if (list) h << "</ul>\n";
    list = false;
  };
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '|') {
      flushPara();
      flushList();
      table.push_back(line);
      continue;
    }
    flushTable();
    if (line.empty()) {
      flushPara();
      flushList();
    } else if (line[0] == '#') {
      flushPara();
      flushList();
      size_t level = line.find_first_not_of('#');
      if (++headings == 3 && !imageShown) {
        h << "<p><img src=\"" << escape(image) << "\" alt=\"plots\"></p>\n";
        imageShown = true;
      }
      h << "<h" << level << ">" << inlineMarkup(line.substr(level + 1)) << "</h" << level << ">\n";
    } else if (line.rfind("![", 0) == 0 && line.find("](") != std::string::npos && line.back() == ')') {
      // An image on a line of its own: ![alt](file).
      flushPara();
      flushList();
      const size_t mid = line.find("](");
      h << "<p><img src=\"" << escape(line.substr(mid + 2, line.size() - mid - 3)) << "\" alt=\""
        << escape(line.substr(2, mid - 2)) << "\"></p>\n";
    } else if (line.rfind("- ", 0) == 0) {
      flushPara();
      if (!list) h << "<ul>\n";
      list = true;
      h << "<li>" << inlineMarkup(line.substr(2)) << "</li>\n";
    } else {
      para += (para.empty() ? "" : " ") + line;
    }
  }
  flushPara();
  flushTable();
  flushList();
  if (!imageShown) h << "<p><img src=\"" << escape(image) << "\" alt=\"plots\"></p>\n";
  h << "</body></html>\n";
  return h.str();
}

}  // namespace viscera
