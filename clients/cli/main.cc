// rheoctl: command-line client of rheod. Exit 0 on success; otherwise the gRPC status code
// (1..16) with "CODE: message" on stderr.
#include <CLI/CLI.hpp>

#include "rheoctl.h"

namespace rheoctl {
// Stays 1 when no command ran (the parser requires one).
int g_exit_code = 1;
}  // namespace rheoctl

int main(int argc, char** argv) {
  rheoctl::Global g;
  CLI::App app{"rheoctl: talk to a running rheod"};
  app.add_option("--server", g.server, "rheod address host:port")->capture_default_str();
  app.add_option("--timeout", g.timeout_s,
                 "deadline of each call [s] (default 5, object create 300)");
  app.add_option("--token", g.token,
                 "access token (else --token-file, $RHEO_TOKEN, or the local "
                 "daemon's admin token)");
  app.add_option("--token-file", g.token_file, "file holding the access token");
  app.add_option("--data-dir", g.data_dir,
                 "the local rheod's data directory, for its admin.token (default: rheod's)");
  app.add_option("--tls-ca", g.tls_ca, "CA certificate that signed rheod's (TLS)");
  app.add_option("--tls-cert", g.tls_cert, "this client's certificate (mutual TLS)");
  app.add_option("--tls-key", g.tls_key, "this client's private key (mutual TLS)");
  app.add_option("--tls-server-name", g.tls_server_name,
                 "the name rheod's certificate must carry (default: the --server host)");
  app.require_subcommand(1);
  rheoctl::AddStatusCommands(app, g);
  rheoctl::AddObjectCommand(app, g);
  rheoctl::AddSceneCommand(app, g);
  rheoctl::AddParamCommand(app, g);
  rheoctl::AddDeviceCommand(app, g);
  rheoctl::AddContourCommand(app, g);
  rheoctl::AddRecordCommand(app, g);
  rheoctl::AddTokenCommands(app, g);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return rheoctl::g_exit_code;
}
