// Durable storage of objects (sketch, options, reports, mesh) in an embedded SQLite database.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"

struct sqlite3;

namespace rheo::daemon {

/// One stored object. `meta` is the serialized rheo.v1.Object (reports, options, bounds), so the
/// schema does not change with every API field; the bulky parts have their own columns.
struct StoredObject {
  std::string id;
  std::string name;
  int64_t created_unix_ms = 0;
  std::string meta;               // serialized rheo.v1.Object
  std::string sketch;             // the sketch as uploaded (JSON, PNG or JPEG bytes)
  std::string sketch_kind;        // "strokes", "image", "contour"
  std::string background;         // optional background photo bytes
  TetMesh mesh;                   // the tetrahedral rest shape [m]
  std::string triangulation_svg;  // 2D triangulation coloured by class
  std::string request_id;         // the client's CreateObject request id ("" when none)
};

/// An access token as stored: its SHA-256 (hex), never the token.
struct StoredToken {
  std::string name;
  int role = 0;  // rheo.v1.Role
  std::string hash;
  int64_t created_unix_ms = 0;
  int64_t expires_unix_ms = 0;  // 0: never
  int64_t revoked_unix_ms = 0;  // 0: not revoked
};

/// One state-changing call, as the audit keeps it.
struct AuditRow {
  int64_t at_unix_ms = 0;
  std::string token_name;
  std::string method;
  std::string target;
  int code = 0;
  std::string message;
};

/// Thread-safe (one connection behind a mutex; never used from the real-time loop). Every write
/// is one transaction, so a crash leaves either the old or the new object, never half of one.
class Store {
 public:
  /// Opens or creates `path` (WAL journal); a version 1 store is upgraded in place. Errors name
  /// the file and SQLite's reason. `quota_bytes` bounds what the objects may take in all
  /// (sketch, background, mesh, reports); 0 = no bound.
  static Result<std::unique_ptr<Store>> Open(const std::string& path, uint64_t quota_bytes = 0);
  ~Store();

  /// RESOURCE_EXHAUSTED when the object would take the store past its quota (nothing stored is
  /// touched); ALREADY_EXISTS when another object has its request_id.
  Status Put(const StoredObject& object);
  /// The object a CreateObject with `request_id` stored, without mesh and sketch bytes.
  Result<StoredObject> FindByRequestId(const std::string& request_id);
  /// Bytes the stored objects take (as the quota counts them).
  uint64_t used_bytes();
  uint64_t quota_bytes() const { return quota_bytes_; }
  /// NOT_FOUND names the id.
  Result<StoredObject> Get(const std::string& id, bool with_mesh = true);
  /// Objects by creation time (newest first), without their mesh and sketch bytes.
  /// `after` is an opaque page token ("" for the first page).
  Result<std::vector<StoredObject>> List(uint32_t limit, const std::string& after,
                                         std::string* next_token);
  Status Delete(const std::string& id);
  Result<uint64_t> Count();

  /// ALREADY_EXISTS when a token has this name (revoked ones included: names are not reused,
  /// so the audit stays unambiguous).
  Status PutToken(const StoredToken& token);
  Result<std::vector<StoredToken>> ListTokens();
  /// Marks the token revoked at `at_unix_ms`; NOT_FOUND names it; FAILED_PRECONDITION when it
  /// already was.
  Result<StoredToken> RevokeToken(const std::string& name, int64_t at_unix_ms);

  /// Appends the row, then drops all but the newest audit_keep rows: a daemon taking parameter
  /// changes at 10 Hz writes 864,000 rows a day.
  Status AppendAudit(const AuditRow& row);
  /// How many audit rows are kept (0 = all). Default kDefaultAuditKeep.
  void set_audit_keep(uint64_t rows);
  static constexpr uint64_t kDefaultAuditKeep = 100'000;
  /// Newest first, at or after `since_unix_ms`.
  Result<std::vector<AuditRow>> ListAudit(int64_t since_unix_ms, uint32_t limit);

  /// A fresh random id, e.g. "obj-3f9a0c2e71b4d855".
  static std::string NewId();

 private:
  explicit Store(sqlite3* db) : db_(db) {}
  Status Exec(const char* sql);

  std::mutex mutex_;
  sqlite3* db_;
  uint64_t quota_bytes_ = 0;
  uint64_t used_bytes_ = 0;                  // under mutex_
  uint64_t audit_keep_ = kDefaultAuditKeep;  // under mutex_
};

}  // namespace rheo::daemon
