// TempStore (tests only): a real Store on a new SQLite file in a directory of its own under /tmp,
// the one way the server's tests make a temporary store. It reads like the std::unique_ptr<Store>
// it replaces (store_->db(), *store_, store_.get(), store_.reset()) and adds Reopen(), the same
// file opened again as a daemon restart does, and Renew(), an empty directory and a new store.
// The destructor closes the store and removes the directory with everything in it (DATA files a
// test kept there too).
//
// Ownership: owns the Store and the directory; whatever holds a Store* (a LeaseQueue) must be
// destroyed or reset before the TempStore goes and before Reopen(), Renew() or reset().
// Thread safety: as Store; Reopen(), Renew() and reset() only while nothing else uses the store.
#ifndef SANDSWIM_SERVER_STORE_TEMP_STORE_TEST_UTIL_H_
#define SANDSWIM_SERVER_STORE_TEMP_STORE_TEST_UTIL_H_

#include <stdlib.h>

#include <filesystem>
#include <memory>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "server/store/store.h"

namespace sandswim::testing {

class TempStore {
 public:
  // A new directory /tmp/sandswim-<tag>-XXXXXX and the store at `file` below it (its parent
  // directories made by Store::Open), opened unless `open` is false (a test of opening opens it
  // with Reopen()); a failure to make or open either fails the test.
  explicit TempStore(const std::string& tag, const std::string& file = "sandswim.db", bool open = true) {
    std::string pattern = (std::filesystem::temp_directory_path() / ("sandswim-" + tag + "-XXXXXX")).string();
    const char* made = mkdtemp(pattern.data());
    EXPECT_NE(made, nullptr) << "cannot make a directory like " << pattern;
    if (made != nullptr) dir_ = made;
    path_ = (dir_ / file).string();
    if (open) Reopen();
  }
  ~TempStore() {
    store_.reset();
    if (!dir_.empty()) {
      std::error_code ignored;
      std::filesystem::remove_all(dir_, ignored);
    }
  }
  TempStore(const TempStore&) = delete;
  TempStore& operator=(const TempStore&) = delete;

  // Closes the store (when open) and opens its file again; false (and a test failure) when it
  // does not open.
  bool Reopen() {
    store_.reset();
    if (dir_.empty()) return false;
    Result<std::unique_ptr<Store>> s = Store::Open(path_);
    EXPECT_TRUE(s.ok()) << s.status().ToString();
    if (!s.ok()) return false;
    store_ = std::move(s).value();
    return true;
  }
  // Closes the store, empties the directory (the store's file and whatever a test kept there) and
  // opens a new, empty store at the same path; false (and a test failure) when it does not open.
  bool Renew() {
    store_.reset();
    if (dir_.empty()) return false;
    std::error_code error;
    for (const auto& entry : std::filesystem::directory_iterator(dir_, error)) {
      std::filesystem::remove_all(entry.path(), error);
      EXPECT_FALSE(error) << "cannot remove " << entry.path() << ": " << error.message();
    }
    return Reopen();
  }
  // Closes the store; the file stays until the TempStore goes.
  void reset() { store_.reset(); }

  Store* get() const { return store_.get(); }
  Store* operator->() const { return store_.get(); }
  Store& operator*() const { return *store_; }
  explicit operator bool() const { return store_ != nullptr; }

  const std::filesystem::path& dir() const { return dir_; }
  const std::string& path() const { return path_; }

 private:
  std::filesystem::path dir_;
  std::string path_;
  std::unique_ptr<Store> store_;
};

}  // namespace sandswim::testing

#endif  // SANDSWIM_SERVER_STORE_TEMP_STORE_TEST_UTIL_H_
