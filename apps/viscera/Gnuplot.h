// Plots through gnuplot (Debian's gnuplot-nox): the commands write a .gp script beside their data
// and run it, so that a user can restyle and re-plot without re-running the study.
#pragma once

#include <filesystem>
#include <string>

namespace viscera {

// Runs gnuplot on `script` (a file in `dir`, run from `dir`) with the variable `outfile` set to a
// temporary name, then renames the image to `image`: the PNG is either complete or absent.
// Throws viscera::Error naming the script when gnuplot is missing or fails.
void plotWithGnuplot(const std::filesystem::path& dir, const std::string& script, const std::string& image);

}  // namespace viscera
