// Subcommands of the offline `rheo` tool. Each registers itself on the app and sets the exit code
// through the returned callback; errors go to stderr with a non-zero exit.
#pragma once

#include <CLI/CLI.hpp>
#include <cstddef>
#include <exception>
#include <string>

namespace rheo::tools {

/// Exit code of the subcommand that ran (0 ok, 1 bad input, 2 internal error).
extern int g_exit_code;

void AddContourCommand(CLI::App& app);   // cmd_contour.cc
void AddMeshCommand(CLI::App& app);      // cmd_mesh.cc
void AddSimulateCommand(CLI::App& app);  // cmd_simulate.cc
void AddReplayCommand(CLI::App& app);    // cmd_replay.cc

/// A `--set name=number` argument: false when it is not one.
inline bool ParseSetting(const std::string& s, std::string* name, double* value) {
  const size_t eq = s.find('=');
  if (eq == std::string::npos || eq == 0) return false;
  try {
    size_t used = 0;
    *value = std::stod(s.substr(eq + 1), &used);
    if (used != s.size() - eq - 1) return false;
  } catch (const std::exception&) {
    return false;
  }
  *name = s.substr(0, eq);
  return true;
}

}  // namespace rheo::tools
