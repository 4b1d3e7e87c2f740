// Subcommands of the offline `rheo` tool. Each registers itself on the app and sets the exit code
// through the returned callback; errors go to stderr with a non-zero exit.
#pragma once

#include <CLI/CLI.hpp>

namespace rheo::tools {

/// Exit code of the subcommand that ran (0 ok, 1 bad input, 2 internal error).
extern int g_exit_code;

void AddContourCommand(CLI::App& app);   // cmd_contour.cc
void AddMeshCommand(CLI::App& app);      // cmd_mesh.cc
void AddSimulateCommand(CLI::App& app);  // cmd_simulate.cc
void AddReplayCommand(CLI::App& app);    // cmd_replay.cc

}  // namespace rheo::tools
