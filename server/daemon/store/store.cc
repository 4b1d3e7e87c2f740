#include "daemon/store/store.h"

#include <sqlite3.h>

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

}  // namespace

Result<std::unique_ptr<Store>> Store::Open(const std::string& path) {
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
           " background BLOB, mesh BLOB NOT NULL, triangulation_svg TEXT)",
           "CREATE INDEX IF NOT EXISTS objects_created ON objects (created_ms DESC, id)",
       }) {
    if (Status s = store->Exec(sql); !s.ok()) return s.error();
  }
  {
    Stmt q(db, "SELECT version FROM schema_version");
    if (!q.ok()) return Internal("object store: " + q.Error());
    if (sqlite3_step(q.get()) == SQLITE_ROW) {
      int64_t v = sqlite3_column_int64(q.get(), 0);
      if (v != 1)
        return Error{ErrorCode::kFailedPrecondition,
                     "object store " + path + " has schema version " + std::to_string(v) +
                         "; this rheod reads version 1"};
    } else if (Status s = store->Exec("INSERT INTO schema_version VALUES (1)"); !s.ok()) {
      return s.error();
    }
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
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_,
          "INSERT OR REPLACE INTO objects (id, name, created_ms, meta, sketch, sketch_kind,"
          " background, mesh, triangulation_svg) VALUES (?,?,?,?,?,?,?,?,?)");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Text(1, o.id);
  st.Text(2, o.name);
  st.Int(3, o.created_unix_ms);
  st.Blob(4, o.meta);
  st.Blob(5, o.sketch);
  st.Text(6, o.sketch_kind);
  st.Blob(7, o.background);
  st.Blob(8, EncodeMeshBlob(o.mesh));
  st.Text(9, o.triangulation_svg);
  if (sqlite3_step(st.get()) != SQLITE_DONE)
    return Error{ErrorCode::kUnavailable, "object store: cannot save " + o.id + ": " + st.Error()};
  return Status::Ok();
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
  StoredObject o;
  o.id = st.ColumnBytes(0);
  o.name = st.ColumnBytes(1);
  o.created_unix_ms = sqlite3_column_int64(st.get(), 2);
  o.meta = st.ColumnBytes(3);
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
    StoredObject o;
    o.id = st.ColumnBytes(0);
    o.name = st.ColumnBytes(1);
    o.created_unix_ms = sqlite3_column_int64(st.get(), 2);
    o.meta = st.ColumnBytes(3);
    out.push_back(std::move(o));
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
  Stmt st(db_, "DELETE FROM objects WHERE id = ?");
  if (!st.ok()) return Internal("object store: " + st.Error());
  st.Text(1, id);
  if (sqlite3_step(st.get()) != SQLITE_DONE) return Internal("object store: " + st.Error());
  if (sqlite3_changes(db_) == 0) return NotFound("no object with id '" + id + "'");
  return Status::Ok();
}

Result<uint64_t> Store::Count() {
  std::lock_guard<std::mutex> lock(mutex_);
  Stmt st(db_, "SELECT COUNT(*) FROM objects");
  if (!st.ok() || sqlite3_step(st.get()) != SQLITE_ROW)
    return Internal("object store: " + st.Error());
  return static_cast<uint64_t>(sqlite3_column_int64(st.get(), 0));
}

std::string Store::NewId() {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  char buf[32];
  std::snprintf(buf, sizeof buf, "obj-%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

}  // namespace rheo::daemon
