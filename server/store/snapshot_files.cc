#include "server/store/snapshot_files.h"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>

#include "platform/data_dir.h"

namespace sandswim {

Result<BedSnapshot> ReadStoredSnapshot(const std::string& data_dir, int64_t run_id, int idx) {
  const std::string path = DataDir(data_dir).Snapshot(run_id, idx);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return Status::IOError("run " + std::to_string(run_id) + "'s snapshot file " + path +
                           " is missing; restore DATA_DIR/snapshots from a copy of the data directory");
  }
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto snapshot = ParseBedSnapshot(text);
  if (!snapshot.ok()) return Status::Corruption(path + ": " + snapshot.status().reason());
  return snapshot;
}

int RemoveSnapshotFiles(const std::string& data_dir, int64_t run_id, const std::vector<int>& keep) {
  namespace fs = std::filesystem;
  const DataDir data(data_dir);
  const fs::path dir = data.RunSnapshots(run_id);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  std::set<std::string> kept;
  for (int idx : keep) kept.insert(fs::path(data.Snapshot(run_id, idx)).filename().string());
  int removed = 0;
  std::vector<fs::path> doomed;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (!kept.count(entry.path().filename().string())) doomed.push_back(entry.path());
  for (const fs::path& path : doomed) removed += fs::remove(path, ec) ? 1 : 0;
  if (keep.empty()) fs::remove(dir, ec);
  return removed;
}

}  // namespace sandswim
