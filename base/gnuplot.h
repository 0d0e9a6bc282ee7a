#pragma once
// Drawing a plot with gnuplot (a Debian package the Makefile installs; optional at run time): the
// one place that runs it, so every command that plots reports a missing gnuplot the same way (the
// command line to run later) and a failing one with its command. Not real-time safe.

#include <string>
#include <string_view>

namespace felt::report {

/// How RunGnuplot ended.
enum class GnuplotOutcome {
  kDrawn,         ///< gnuplot ran and exited 0
  kNotInstalled,  ///< no `gnuplot` on PATH: the command was printed for the user to run later
  kFailed,        ///< gnuplot exited non-zero (its own message is on stderr)
};

/// True when a `gnuplot` executable is on PATH.
bool GnuplotInstalled();

/// Runs the shell command `command` (a gnuplot call) when gnuplot is installed; otherwise prints
/// "gnuplot not found; to draw the plot run:" and the command on stdout. On success prints "wrote
/// <png>"; on failure prints "<who>: gnuplot failed: <command>" on stderr.
GnuplotOutcome RunGnuplot(std::string_view who, const std::string& command, std::string_view png);

/// `text` as one single-quoted POSIX shell word (' becomes '\'').
std::string ShellQuoted(std::string_view text);

/// `text` as a single-quoted gnuplot string literal (a ' inside is doubled, gnuplot's escape).
std::string GnuplotQuoted(std::string_view text);

}  // namespace felt::report
