// rheo: offline tool over the pure libraries (no daemon needed).
#include <iostream>

#include "commands.h"

namespace rheo::tools {
int g_exit_code = 0;
}

int main(int argc, char** argv) {
  CLI::App app{"rheo: sketch -> contour -> solid -> simulation, and session replay, offline"};
  app.require_subcommand(1);
#ifdef RHEO_HAVE_SKETCH
  rheo::tools::AddContourCommand(app);
#endif
#ifdef RHEO_HAVE_MESH
  rheo::tools::AddMeshCommand(app);
#endif
#ifdef RHEO_HAVE_SIM
  rheo::tools::AddSimulateCommand(app);
#endif
#ifdef RHEO_HAVE_REPLAY
  rheo::tools::AddReplayCommand(app);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return rheo::tools::g_exit_code;
}
