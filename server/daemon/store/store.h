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

  /// A fresh random id, e.g. "obj-3f9a0c2e71b4d855".
  static std::string NewId();

 private:
  explicit Store(sqlite3* db) : db_(db) {}
  Status Exec(const char* sql);

  std::mutex mutex_;
  sqlite3* db_;
  uint64_t quota_bytes_ = 0;
  uint64_t used_bytes_ = 0;  // under mutex_
};

}  // namespace rheo::daemon
