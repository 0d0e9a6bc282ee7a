#include "base/gnuplot.h"

#include <cstdio>
#include <cstdlib>

namespace felt::report {

bool GnuplotInstalled() { return std::system("command -v gnuplot > /dev/null 2>&1") == 0; }

GnuplotOutcome RunGnuplot(std::string_view who, const std::string& command, std::string_view png) {
  if (!GnuplotInstalled()) {
    std::printf("gnuplot not found; to draw the plot run:\n  %s\n", command.c_str());
    return GnuplotOutcome::kNotInstalled;
  }
  if (std::system(command.c_str()) != 0) {
    std::fprintf(stderr, "%.*s: gnuplot failed: %s\n", static_cast<int>(who.size()), who.data(),
                 command.c_str());
    return GnuplotOutcome::kFailed;
  }
  std::printf("wrote %.*s\n", static_cast<int>(png.size()), png.data());
  return GnuplotOutcome::kDrawn;
}

std::string ShellQuoted(std::string_view text) {
  std::string out = "'";
  for (const char c : text) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  out += '\'';
  return out;
}

std::string GnuplotQuoted(std::string_view text) {
  std::string out = "'";
  for (const char c : text) {
    out += c;
    if (c == '\'') out += '\'';
  }
  out += '\'';
  return out;
}

}  // namespace felt::report
