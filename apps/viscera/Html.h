// Reports as HTML pages: the Markdown the commands write (headings, paragraphs, lists, pipe
// tables, **bold**, `code`), turned into a self-contained page a browser opens.
#pragma once

#include <string>

namespace viscera {

// The page for `markdown`, titled `title`; `image`, when given, is shown after the first section
// (a file name beside the page).
std::string markdownPage(const std::string& title, const std::string& markdown, const std::string& image = "");

}  // namespace viscera
