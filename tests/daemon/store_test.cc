#include "daemon/store/store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <set>

namespace rheo::daemon {
namespace {

class StoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (std::filesystem::temp_directory_path() / "rheo-store-XXXXXX").string();
    dir_ = mkdtemp(tmpl.data());
    path_ = dir_ + "/objects.db";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  static StoredObject Sample(const std::string& id, int64_t ms) {
    StoredObject o;
    o.id = id;
    o.name = "bean " + id;
    o.created_unix_ms = ms;
    o.meta = std::string("\x0a\x03", 2) + "abc";
    o.sketch = "{\"width\":1}";
    o.sketch_kind = "strokes";
    o.background = std::string(1000, '\xff');
    o.mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1.5}};
    o.mesh.tets = {{0, 1, 2, 3}};
    o.mesh.surface = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    o.triangulation_svg = "<svg/>";
    return o;
  }

  std::string dir_, path_;
};

TEST_F(StoreTest, PutGetSurvivesReopen) {
  {
    auto s = Store::Open(path_);
    ASSERT_TRUE(s.ok()) << s.error().message;
    ASSERT_TRUE((*s)->Put(Sample("a", 1)).ok());
  }
  auto s = Store::Open(path_);
  ASSERT_TRUE(s.ok());
  auto o = (*s)->Get("a");
  ASSERT_TRUE(o.ok()) << o.error().message;
  StoredObject want = Sample("a", 1);
  EXPECT_EQ(o->name, want.name);
  EXPECT_EQ(o->meta, want.meta);
  EXPECT_EQ(o->background, want.background);
  EXPECT_EQ(o->mesh.positions, want.mesh.positions);
  EXPECT_EQ(o->mesh.tets, want.mesh.tets);
  EXPECT_EQ(o->mesh.surface, want.mesh.surface);
  EXPECT_EQ(o->triangulation_svg, "<svg/>");
  EXPECT_EQ(*(*s)->Count(), 1u);
}

TEST_F(StoreTest, ListPagesNewestFirstWithoutRepeats) {
  auto s = Store::Open(path_);
  ASSERT_TRUE(s.ok());
  for (int i = 0; i < 25; ++i) ASSERT_TRUE((*s)->Put(Sample("id" + std::to_string(i), i / 3)).ok());
  std::set<std::string> seen;
  std::string token;
  int64_t last_ms = INT64_MAX;
  int pages = 0;
  do {
    std::string next;
    auto page = (*s)->List(4, token, &next);
    ASSERT_TRUE(page.ok()) << page.error().message;
    for (auto& o : *page) {
      EXPECT_TRUE(seen.insert(o.id).second) << o.id << " repeated";
      EXPECT_LE(o.created_unix_ms, last_ms);
      last_ms = o.created_unix_ms;
      EXPECT_TRUE(o.mesh.positions.empty()) << "listing does not load meshes";
    }
    token = next;
    ++pages;
  } while (!token.empty());
  EXPECT_EQ(seen.size(), 25u);
  EXPECT_EQ(pages, 7);
  EXPECT_EQ((*s)->List(4, "garbage", nullptr).error().code, ErrorCode::kInvalidArgument);
}

TEST_F(StoreTest, DeleteAndMissingIdsAreNotFound) {
  auto s = Store::Open(path_);
  ASSERT_TRUE(s.ok());
  ASSERT_TRUE((*s)->Put(Sample("x", 5)).ok());
  EXPECT_TRUE((*s)->Delete("x").ok());
  auto g = (*s)->Get("x");
  ASSERT_FALSE(g.ok());
  EXPECT_EQ(g.error().code, ErrorCode::kNotFound);
  EXPECT_NE(g.error().message.find("'x'"), std::string::npos);
  EXPECT_EQ((*s)->Delete("x").error().code, ErrorCode::kNotFound);
}

TEST_F(StoreTest, UnopenablePathIsAClearError) {
  auto s = Store::Open(dir_ + "/no/such/dir/objects.db");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("cannot open object store"), std::string::npos);
}

// The audit keeps its newest rows, in order; 0 keeps everything.
TEST_F(StoreTest, TheAuditKeepsItsNewestRows) {
  auto s = Store::Open(path_);
  ASSERT_TRUE(s.ok()) << s.error().message;
  (*s)->set_audit_keep(50);
  for (int i = 0; i < 1000; ++i) {
    AuditRow r;
    r.at_unix_ms = 1000 + i;
    r.token_name = "admin";
    r.method = "SetParameters";
    r.target = "1";
    r.message = "change " + std::to_string(i);
    ASSERT_TRUE((*s)->AppendAudit(r).ok());
  }
  auto rows = (*s)->ListAudit(0, 100000);
  ASSERT_TRUE(rows.ok()) << rows.error().message;
  EXPECT_GE(rows->size(), 50u);
  EXPECT_LE(rows->size(), 55u);
  for (size_t k = 0; k < rows->size(); ++k)
    EXPECT_EQ((*rows)[k].message, "change " + std::to_string(999 - k));
  (*s)->set_audit_keep(0);
  for (int i = 0; i < 100; ++i) {
    AuditRow r;
    r.at_unix_ms = 5000 + i;
    ASSERT_TRUE((*s)->AppendAudit(r).ok());
  }
  EXPECT_EQ((*s)->ListAudit(0, 100000)->size(), rows->size() + 100);
}

TEST(StoreIds, AreUnique) {
  std::set<std::string> ids;
  for (int i = 0; i < 1000; ++i) ids.insert(Store::NewId());
  EXPECT_EQ(ids.size(), 1000u);
}

TEST_F(StoreTest, RequestIdsFindTheirObjectAndAreUnique) {
  auto s = Store::Open(path_);
  ASSERT_TRUE(s.ok()) << s.error().message;
  StoredObject a = Sample("a", 1);
  a.request_id = "client-7f3a";
  ASSERT_TRUE((*s)->Put(a).ok());
  ASSERT_TRUE((*s)->Put(Sample("b", 2)).ok());  // no request id: many may have none
  ASSERT_TRUE((*s)->Put(Sample("c", 3)).ok());
  auto found = (*s)->FindByRequestId("client-7f3a");
  ASSERT_TRUE(found.ok()) << found.error().message;
  EXPECT_EQ(found->id, "a");
  EXPECT_EQ((*s)->FindByRequestId("other").error().code, ErrorCode::kNotFound);
  StoredObject d = Sample("d", 4);
  d.request_id = "client-7f3a";
  Status dup = (*s)->Put(d);
  EXPECT_EQ(dup.error().code, ErrorCode::kAlreadyExists) << dup.error().message;
  EXPECT_EQ(*(*s)->Count(), 3u);
}

TEST_F(StoreTest, QuotaRefusesWhatWouldNotFitAndKeepsWhatIsStored) {
  const uint64_t one = [&] {
    auto s = Store::Open(dir_ + "/measure.db");
    EXPECT_TRUE(s.ok());
    EXPECT_TRUE((*s)->Put(Sample("x", 1)).ok());
    return (*s)->used_bytes();
  }();
  ASSERT_GT(one, 1000u);  // the 1000-byte background and the rest
  auto s = Store::Open(path_, 2 * one + one / 2);
  ASSERT_TRUE(s.ok());
  ASSERT_TRUE((*s)->Put(Sample("a", 1)).ok());
  ASSERT_TRUE((*s)->Put(Sample("b", 2)).ok());
  Status full = (*s)->Put(Sample("c", 3));
  ASSERT_EQ(full.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(full.error().message.find("quota"), std::string::npos) << full.error().message;
  EXPECT_NE(full.error().message.find("--store-quota"), std::string::npos);
  EXPECT_EQ(*(*s)->Count(), 2u);
  EXPECT_TRUE((*s)->Get("a").ok());
  // Replacing an object under its own id counts its old bytes back; deleting frees them.
  EXPECT_TRUE((*s)->Put(Sample("b", 2)).ok());
  ASSERT_TRUE((*s)->Delete("a").ok());
  EXPECT_EQ((*s)->used_bytes(), one);
  EXPECT_TRUE((*s)->Put(Sample("c", 3)).ok());
  // The count survives a reopen (it is summed from the rows).
  s->reset();
  auto again = Store::Open(path_, 2 * one + one / 2);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ((*again)->used_bytes(), 2 * one);
}

TEST_F(StoreTest, AVersionOneStoreIsUpgradedInPlaceKeepingItsObjects) {
  {
    // The version 1 schema, as earlier rheod releases wrote it, with one object.
    auto s = Store::Open(path_);
    ASSERT_TRUE(s.ok());
    ASSERT_TRUE((*s)->Put(Sample("old", 1)).ok());
  }
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path_.c_str(), &db), SQLITE_OK);
    for (const char* sql :
         {"DROP INDEX objects_request", "ALTER TABLE objects DROP COLUMN request_id",
          "UPDATE schema_version SET version = 1"})
      ASSERT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK)
          << sql << ": " << sqlite3_errmsg(db);
    sqlite3_close(db);
  }
  auto s = Store::Open(path_);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_TRUE((*s)->Get("old").ok());
  StoredObject n = Sample("new", 2);
  n.request_id = "r1";
  ASSERT_TRUE((*s)->Put(n).ok());
  EXPECT_EQ((*s)->FindByRequestId("r1")->id, "new");
}

}  // namespace
}  // namespace rheo::daemon
