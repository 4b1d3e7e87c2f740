#include "daemon/store/store.h"

#include <sqlite3.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <random>

#include "common/tet_mesh_io.h"

namespace rheo::daemon {
namespace {

// RAII prepared statement.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    rc_ = sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr);
  }
  ~Stmt() { sqlite3_finalize(stmt_); }
  bool ok() const { return rc_ == SQLITE_OK; }
  sqlite3_stmt* get() { return stmt_; }
  void Text(int i, const std::string& s) {
    sqlite3_bind_text(stmt_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
  }
  void Blob(int i, const std::string& s) {
    sqlite3_bind_blob(stmt_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
  }
  void Int(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  std::string ColumnBytes(int i) {
    const void* p = sqlite3_column_blob(stmt_, i);
    int n = sqlite3_column_bytes(stmt_, i);
    return p ? std::string(static_cast<const char*>(p), static_cast<size_t>(n)) : std::string();
  }
  std::string Error() const { return sqlite3_errmsg(db_); }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  int rc_;
};

constexpr int64_t kSchemaVersion = 2;
// What the quota counts of one row, and of all of them.
#define RHEO_ROW_BYTES                                                               \
  "(length(meta) + length(sketch) + ifnull(length(background), 0) + length(mesh) + " \
  "ifnull(length(triangulation_svg), 0))"
constexpr const char* kSizeSum = "SELECT ifnull(sum" RHEO_ROW_BYTES ", 0) FROM objects";
constexpr const char* kRowSize = "SELECT " RHEO_ROW_BYTES " FROM objects WHERE id = ?";
#undef RHEO_ROW_BYTES

// The first four columns every query of an object selects: id, name, created_ms, meta.
StoredObject ReadHeader(Stmt& st) {
  StoredObject o;
  o.id = st.ColumnBytes(0);
  o.name = st.ColumnBytes(1);
  o.created_unix_ms = sqlite3_column_int64(st.get(), 2);
  o.meta = st.ColumnBytes(3);
  return o;
}

std::string Megabytes(uint64_t bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f MB", static_cast<double>(bytes) / 1e6);
  return b;
}

}  // namespace

Result<std::unique_ptr<Store>> Store::Open(const std::string& path, uint64_t quota_bytes) {
  sqlite3* db = nullptr;
  int rc =
      sqlite3_open_v2(path.c_str(), &db,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string msg = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    sqlite3_close(db);
    return Error{ErrorCode::kUnavailable, "cannot open object store " + path + ": " + msg};
  }
  sqlite3_busy_timeout(db, 2000);
  std::unique_ptr<Store> store(new Store(db));
  for (const char* sql : {
           "PRAGMA journal_mode=WAL",
           "PRAGMA synchronous=NORMAL",
           "PRAGMA foreign_keys=ON",
           "CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)",
           "CREATE TABLE IF NOT EXISTS objects ("
           " id TEXT PRIMARY KEY, name TEXT NOT NULL, created_ms INTEGER NOT NULL,"
           " meta BLOB NOT NULL, sketch BLOB NOT NULL, sketch_kind TEXT NOT NULL,"
           " background BLOB, mesh BLOB NOT NULL, triangulation_svg TEXT, request_id TEXT)",
           "CREATE INDEX IF NOT EXISTS objects_created ON objects (created_ms DESC, id)",
           // Access tokens (only their hashes) and the audit of state-changing calls.
           "CREATE TABLE IF NOT EXISTS tokens ("
           " name TEXT PRIMARY KEY, role INTEGER NOT NULL, hash TEXT NOT NULL UNIQUE,"
           " created_ms INTEGER NOT NULL, expires_ms INTEGER NOT NULL DEFAULT 0,"
           " revoked_ms INTEGER NOT NULL DEFAULT 0)",
           "CREATE TABLE IF NOT EXISTS audit ("
           " seq INTEGER PRIMARY KEY AUTOINCREMENT, at_ms INTEGER NOT NULL, token TEXT NOT NULL,"
           " method TEXT NOT NULL, target TEXT NOT NULL, code INTEGER NOT NULL,"
           " message TEXT NOT NULL)",
           "CREATE INDEX IF NOT EXISTS audit_at ON audit (at_ms DESC)",
       }) {
    if (Status s = store->Exec(sql); !s.ok()) return s.error();
  }
  // Version 2 added the client's request id (CreateObject retries find what they stored).
  int64_t version = 0;
  {
    Stmt q(db, "SELECT version FROM schema_version");
    if (!q.ok()) return Internal("object store: " + q.Error());
    if (sqlite3_step(q.get()) == SQLITE_ROW) version = sqlite3_column_int64(q.get(), 0);
  }
  if (version > kSchemaVersion)
    return Error{ErrorCode::kFailedPrecondition,
                 "object store " + path + " has schema version " + std::to_string(version) +
                     "; this rheod reads versions 1 to " + std::to_string(kSchemaVersion)};
  if (version < kSchemaVersion) {
    // One transaction: a store is either still version 1 or wholly version 2.
    const std::string upgrade =
        std::string("BEGIN IMMEDIATE;") +
        (version == 1 ? "ALTER TABLE objects ADD COLUMN request_id TEXT;" : "") +
        (version == 0 ? "INSERT INTO schema_version VALUES (2);"
                      : "UPDATE schema_version SET version = 2;") +
        "CREATE UNIQUE INDEX IF NOT EXISTS objects_request ON objects (request_id)"
        " WHERE request_id IS NOT NULL;"
        "COMMIT;";
    if (Status s = store->Exec(upgrade.c_str()); !s.ok()) {
      (void)store->Exec("ROLLBACK");
      return s.error();
    }
  }
  store->quota_bytes_ = quota_bytes;
  {
    Stmt q(db, kSizeSum);
    if (!q.ok() || sqlite3_step(q.get()) != SQLITE_ROW)
      return Internal("object store: " + q.Error());
    store->used_bytes_ = static_cast<uint64_t>(sqlite3_column_int64(q.get(), 0));
  }
  return store;
}

Store::~Store() {
  sqlite3_close(db_);
}

Status Store::Exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : "unknown error";
    sqlite3_free(err);
    return Internal(std::string("object store: ") + msg + " in: " + sql);
  }
  return Status::Ok();
}

Status Store::Put(const StoredObject& o) {
  const std::string mesh = EncodeMeshBlob(o.mesh);
  const uint64_t bytes = o.meta.size() + o.sketch.size() + o.background.size() + mesh.size() +
                         o.triangulation_svg.size();
  std::lock_guard<std::mutex> lock(mutex_);
  // An object replaced under its own id gives its old bytes back.
  uint64_t replaced = 0;
  {
    Stmt q(db_, kRowSize);
    if (!q.ok()) return Internal("object store: " + q.Error());
    q.Text(1, o.id);
    if (sqlite3_step(q.get()) == SQLITE_ROW)
      replaced = static_cast<uint64_t>(sqlite3_column_int64(q.get(), 0));
  }
  if (quota_bytes_ > 0 && used_bytes_ - replaced + bytes > quota_bytes_)
    return ResourceExhausted("the object store is full: it holds " + Megabytes(used_bytes_) +
                             " of its " + Megabytes(quota_bytes_) +
                             " quota and this object takes " + Megabytes(bytes) +
                             "; delete objects you no longer need (DeleteObject) or start rheod "
                             "with a larger --store-quota");
  Stmt st(db_,
          // Replaces an object under its own id; another object's request_id is a conflict.
          "INSERT INTO objects (id, name, created_ms, meta, sketch, sketch_kind,"
          " background, mesh, triangulation_svg, request_id) VALUES (?,?,?,?,?,?,?,?,?,?)"
          " ON CONFLICT(id) DO UPDATE SET name = excluded.name, created_ms = excluded.created_ms,"
          " meta = excluded.meta, sketch = excluded.sketch, sketch_kind = excluded.sketch_kind,"
          " background = excluded.background, mesh = excluded.mesh,"
          " triangulation_svg = excluded.triangulation_svg, request_id = excluded.request_id");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Text(1, o.id);
  st.Text(2, o.name);
  st.Int(3, o.created_unix_ms);
  st.Blob(4, o.meta);
  st.Blob(5, o.sketch);
  st.Text(6, o.sketch_kind);
  st.Blob(7, o.background);
  st.Blob(8, mesh);
  st.Text(9, o.triangulation_svg);
  if (o.request_id.empty())
    sqlite3_bind_null(st.get(), 10);
  else
    st.Text(10, o.request_id);
  const int rc = sqlite3_step(st.get());
  if (rc == SQLITE_CONSTRAINT)
    return Error{ErrorCode::kAlreadyExists,
                 "another object was stored with request_id '" + o.request_id + "'"};
  if (rc != SQLITE_DONE)
    return Error{ErrorCode::kUnavailable, "object store: cannot save " + o.id + ": " + st.Error()};
  used_bytes_ = used_bytes_ - replaced + bytes;
  return Status::Ok();
}

Result<StoredObject> Store::FindByRequestId(const std::string& request_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_, "SELECT id, name, created_ms, meta FROM objects WHERE request_id = ?");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Text(1, request_id);
  const int rc = sqlite3_step(st.get());
  if (rc == SQLITE_DONE) return NotFound("no object was stored with this request_id");
  if (rc != SQLITE_ROW) return Internal("object store: " + st.Error());
  StoredObject o = ReadHeader(st);
  o.request_id = request_id;
  return o;
}

uint64_t Store::used_bytes() {
  std::lock_guard<std::mutex> lock(mutex_);
  return used_bytes_;
}

Result<StoredObject> Store::Get(const std::string& id, bool with_mesh) {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_,
          "SELECT id, name, created_ms, meta, sketch, sketch_kind, background, mesh,"
          " triangulation_svg FROM objects WHERE id = ?");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Text(1, id);
  int rc = sqlite3_step(st.get());
  if (rc == SQLITE_DONE) return NotFound("no object with id '" + id + "'");
  if (rc != SQLITE_ROW) return Internal("object store: " + st.Error());
  StoredObject o = ReadHeader(st);
  o.sketch = st.ColumnBytes(4);
  o.sketch_kind = st.ColumnBytes(5);
  o.background = st.ColumnBytes(6);
  if (with_mesh) {
    Result<TetMesh> m = DecodeMeshBlob(st.ColumnBytes(7));
    if (!m.ok()) return Internal("object " + id + ": " + m.error().message);
    o.mesh = std::move(m).value();
  }
  o.triangulation_svg = st.ColumnBytes(8);
  return o;
}

Result<std::vector<StoredObject>> Store::List(uint32_t limit, const std::string& after,
                                              std::string* next_token) {
  std::lock_guard<std::mutex> lock(mutex_);
  // Page token: "<created_ms>:<id>" of the last object of the previous page.
  int64_t after_ms = INT64_MAX;
  std::string after_id;
  if (!after.empty()) {
    size_t colon = after.find(':');
    try {
      if (colon == std::string::npos) throw std::invalid_argument("no colon");
      after_ms = std::stoll(after.substr(0, colon));
      after_id = after.substr(colon + 1);
    } catch (const std::exception&) {
      return InvalidArgument("page_token '" + after + "' is not one this daemon issued");
    }
  }
  Stmt st(db_,
          "SELECT id, name, created_ms, meta FROM objects WHERE (created_ms < ?1) OR"
          " (created_ms = ?1 AND id > ?2) ORDER BY created_ms DESC, id ASC LIMIT ?3");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Int(1, after_ms);
  st.Text(2, after_id);
  st.Int(3, static_cast<int64_t>(limit) + 1);
  std::vector<StoredObject> out;
  int rc;
  while ((rc = sqlite3_step(st.get())) == SQLITE_ROW) {
    out.push_back(ReadHeader(st));
  }
  if (rc != SQLITE_DONE) return Internal("object store: " + st.Error());
  if (next_token) next_token->clear();
  if (out.size() > limit) {
    out.pop_back();
    if (next_token) *next_token = std::to_string(out.back().created_unix_ms) + ":" + out.back().id;
  }
  return out;
}

Status Store::Delete(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  uint64_t bytes = 0;
  {
    Stmt q(db_, kRowSize);
    if (!q.ok()) return Internal("object store: " + q.Error());
    q.Text(1, id);
    if (sqlite3_step(q.get()) == SQLITE_ROW)
      bytes = static_cast<uint64_t>(sqlite3_column_int64(q.get(), 0));
  }
  Stmt st(db_, "DELETE FROM objects WHERE id = ?");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Text(1, id);
  if (sqlite3_step(st.get()) != SQLITE_DONE) return Internal("object store: " + st.Error());
  if (sqlite3_changes(db_) == 0) return NotFound("no object with id '" + id + "'");
  used_bytes_ -= std::min(used_bytes_, bytes);
  return Status::Ok();
}

Result<uint64_t> Store::Count() {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_, "SELECT COUNT(*) FROM objects");
  if (!st.ok() || sqlite3_step(st.get()) != SQLITE_ROW)
    return Internal("object store: " + st.Error());
  return static_cast<uint64_t>(sqlite3_column_int64(st.get(), 0));
}

Status Store::PutToken(const StoredToken& t) {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_,
          "INSERT INTO tokens (name, role, hash, created_ms, expires_ms, revoked_ms)"
          " VALUES (?,?,?,?,?,?)");
  if (!st.ok()) return Internal("token store: " + st.Error());
  st.Text(1, t.name);
  st.Int(2, t.role);
  st.Text(3, t.hash);
  st.Int(4, t.created_unix_ms);
  st.Int(5, t.expires_unix_ms);
  st.Int(6, t.revoked_unix_ms);
  const int rc = sqlite3_step(st.get());
  if (rc == SQLITE_CONSTRAINT)
    return Error{ErrorCode::kAlreadyExists,
                 "a token named '" + t.name +
                     "' exists (or existed: names of revoked tokens are not reused); choose "
                     "another name"};
  if (rc != SQLITE_DONE) return Error{ErrorCode::kUnavailable, "token store: " + st.Error()};
  return Status::Ok();
}

namespace {
StoredToken ReadToken(Stmt& st) {
  StoredToken t;
  t.name = st.ColumnBytes(0);
  t.role = static_cast<int>(sqlite3_column_int64(st.get(), 1));
  t.hash = st.ColumnBytes(2);
  t.created_unix_ms = sqlite3_column_int64(st.get(), 3);
  t.expires_unix_ms = sqlite3_column_int64(st.get(), 4);
  t.revoked_unix_ms = sqlite3_column_int64(st.get(), 5);
  return t;
}
constexpr const char* kTokenColumns =
    "SELECT name, role, hash, created_ms, expires_ms, revoked_ms FROM tokens";
}  // namespace

Result<std::vector<StoredToken>> Store::ListTokens() {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_, (std::string(kTokenColumns) + " ORDER BY created_ms, name").c_str());
  if (!st.ok()) return Internal("token store: " + st.Error());
  std::vector<StoredToken> out;
  int rc;
  while ((rc = sqlite3_step(st.get())) == SQLITE_ROW) out.push_back(ReadToken(st));
  if (rc != SQLITE_DONE) return Internal("token store: " + st.Error());
  return out;
}

Result<StoredToken> Store::RevokeToken(const std::string& name, int64_t at_unix_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  StoredToken t;
  {
    Stmt q(db_, (std::string(kTokenColumns) + " WHERE name = ?").c_str());
    if (!q.ok()) return Internal("token store: " + q.Error());
    q.Text(1, name);
    const int rc = sqlite3_step(q.get());
    if (rc == SQLITE_DONE)
      return NotFound("no token named '" + name + "' (rheoctl token list shows them)");
    if (rc != SQLITE_ROW) return Internal("token store: " + q.Error());
    t = ReadToken(q);
  }
  if (t.revoked_unix_ms != 0) return FailedPrecondition("token '" + name + "' is already revoked");
  Stmt st(db_, "UPDATE tokens SET revoked_ms = ? WHERE name = ?");
  if (!st.ok()) return Internal("token store: " + st.Error());
  st.Int(1, at_unix_ms);
  st.Text(2, name);
  if (sqlite3_step(st.get()) != SQLITE_DONE)
    return Error{ErrorCode::kUnavailable, "token store: " + st.Error()};
  t.revoked_unix_ms = at_unix_ms;
  return t;
}

Status Store::AppendAudit(const AuditRow& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_,
          "INSERT INTO audit (at_ms, token, method, target, code, message) VALUES (?,?,?,?,?,?)");
  if (!st.ok()) return Internal("audit: " + st.Error());
  st.Int(1, r.at_unix_ms);
  st.Text(2, r.token_name);
  st.Text(3, r.method);
  st.Text(4, r.target);
  st.Int(5, r.code);
  st.Text(6, r.message);
  if (sqlite3_step(st.get()) != SQLITE_DONE)
    return Error{ErrorCode::kUnavailable, "audit: " + st.Error()};
  if (audit_keep_ == 0) return Status::Ok();
  // The rows older than the newest audit_keep_ (seq is the rowid: a range on the primary key,
  // usually the one row that fell out).
  Stmt prune(db_, "DELETE FROM audit WHERE seq <= ?");
  if (!prune.ok()) return Internal("audit: " + prune.Error());
  prune.Int(1, sqlite3_last_insert_rowid(db_) - static_cast<int64_t>(audit_keep_));
  if (sqlite3_step(prune.get()) != SQLITE_DONE)
    return Error{ErrorCode::kUnavailable, "audit: pruning the oldest rows: " + prune.Error()};
  return Status::Ok();
}

void Store::set_audit_keep(uint64_t rows) {
  std::lock_guard<std::mutex> lock(mutex_);
  audit_keep_ = rows;
}

Result<std::vector<AuditRow>> Store::ListAudit(int64_t since_unix_ms, uint32_t limit) {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_,
          "SELECT at_ms, token, method, target, code, message FROM audit WHERE at_ms >= ?"
          " ORDER BY seq DESC LIMIT ?");
  if (!st.ok()) return Internal("audit: " + st.Error());
  st.Int(1, since_unix_ms);
  st.Int(2, limit);
  std::vector<AuditRow> out;
  int rc;
  while ((rc = sqlite3_step(st.get())) == SQLITE_ROW) {
    AuditRow r;
    r.at_unix_ms = sqlite3_column_int64(st.get(), 0);
    r.token_name = st.ColumnBytes(1);
    r.method = st.ColumnBytes(2);
    r.target = st.ColumnBytes(3);
    r.code = static_cast<int>(sqlite3_column_int64(st.get(), 4));
    r.message = st.ColumnBytes(5);
    out.push_back(std::move(r));
  }
  if (rc != SQLITE_DONE) return Internal("audit: " + st.Error());
  return out;
}

std::string Store::NewId() {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  char buf[32];
  std::snprintf(buf, sizeof buf, "obj-%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

}  // namespace rheo::daemon
