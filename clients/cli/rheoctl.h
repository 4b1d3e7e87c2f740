// rheoctl: what the commands share (the connection, deadlines, errors, JSON, sketch files) and the
// commands themselves, one file per noun. Each Add*Command registers its subcommands on the app;
// the one that runs sets g_exit_code: 0 on success, otherwise the gRPC status code (1..16) with
// "CODE: message" on stderr (3 for bad input found before any call).
#pragma once

#include <google/protobuf/message.h>
#include <google/protobuf/repeated_ptr_field.h>
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

#include "rheo/v1/device.pb.h"
#include "rheo/v1/objects.pb.h"

namespace rheoctl {

struct Global {
  std::string server = "127.0.0.1:50051";
  double timeout_s = 0.0;  // 0: 5 s for quick calls, 300 s for object creation
  // The access token: --token, else --token-file, else $RHEO_TOKEN, else the local daemon's
  // admin token (DATA_DIR/admin.token, DATA_DIR from --data-dir or rheod's default).
  std::string token;
  std::string token_file;
  std::string data_dir;
  // TLS: the CA that signed rheod's certificate; a client certificate for mutual TLS.
  std::string tls_ca, tls_cert, tls_key, tls_server_name;
};

/// Exit code of the subcommand that ran.
extern int g_exit_code;

/// "CODE: message" on stderr; the exit code for `s` (1 when it is OK).
int Fail(const grpc::Status& s);

/// `m` as JSON with the proto field names; one line unless `pretty`.
std::string ToJson(const google::protobuf::Message& m, bool pretty);

std::shared_ptr<grpc::Channel> Connect(const Global& g);

void SetDeadline(grpc::ClientContext& ctx, const Global& g, double default_s = 5.0);

// One unary call with the command's deadline (default_s unless --timeout is given).
template <typename Service, typename Method, typename Request, typename Response>
grpc::Status Unary(const Global& g, Method method, const Request& request, Response* response,
                   double default_s = 5.0) {
  auto stub = Service::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g, default_s);
  return ((*stub).*method)(&ctx, request, response);
}

/// The serial line's counters (lost, reconnect attempts, reconnects; while away, for how long and
/// the backoff), a line of `rheoctl status` and `rheoctl device status`.
void PrintLineCounters(const rheo::v1::DeviceCounters& c);

/// A sketch file: stroke JSON, a contour JSON ({"contour": [[x, y], ...]}) or a PNG/JPEG picture.
/// False (with a message) when it cannot be read.
bool LoadSketch(const std::string& path, rheo::v1::Sketch* sketch);

/// "name=value" pairs into Parameter messages; false (with a message) on a malformed pair.
bool ParseAssignments(const std::vector<std::string>& items,
                      google::protobuf::RepeatedPtrField<rheo::v1::Parameter>* out);

// Registration order is the order of `rheoctl --help`.
void AddStatusCommands(CLI::App& app, const Global& g);  // cmd_status.cc: status, watch, health
void AddObjectCommand(CLI::App& app, const Global& g);   // cmd_object.cc
void AddSceneCommand(CLI::App& app, const Global& g);    // cmd_scene.cc
void AddParamCommand(CLI::App& app, const Global& g);    // cmd_param.cc
void AddDeviceCommand(CLI::App& app, const Global& g);   // cmd_device.cc
void AddContourCommand(CLI::App& app, const Global& g);  // cmd_contour.cc
void AddRecordCommand(CLI::App& app, const Global& g);   // cmd_record.cc
void AddTokenCommands(CLI::App& app, const Global& g);   // cmd_token.cc: token, audit, whoami

}  // namespace rheoctl
