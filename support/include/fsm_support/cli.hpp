#pragma once
// The command lines of fsm-build, fsm-demo, fsm-viewer and fsm-indent: CLI11 with one set of
// conventions. `--help` and `--version` print to standard output and exit 0; a usage error prints
// CLI11's message and a pointer to --help on standard error and exits 2 (1 stays for bad input,
// which the programs report as fsm::Error naming file, part and reason).

#include <CLI/CLI.hpp>
#include <cmath>
#include <exception>
#include <string>

#include "fsm/version.hpp"

namespace fsm::support {

/// Adds `--version` ("NAME VERSION") to `app`.
inline void add_version_flag(CLI::App& app) {
  app.set_version_flag("--version", app.get_name() + " " + fsm::version,
                       "print the version and exit");
}

/// A check for options that need a finite number greater than zero (with a readable message).
inline CLI::Validator positive_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        try {
          std::size_t used = 0;
          const double v = std::stod(text, &used);
          if (used == text.size() && v > 0 && std::isfinite(v)) return {};
        } catch (const std::exception&) {
        }
        return "needs a positive number, got '" + text + "'";
      },
      "POSITIVE");
}

/// Parses the command line: -1 to go on, else the exit status to return (0 after --help or
/// --version, 2 after a usage error).
inline int parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
    return -1;
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
}

}  // namespace fsm::support
