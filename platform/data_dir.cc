#include "platform/data_dir.h"

#include <filesystem>

namespace sandswim {

// std::filesystem's join: one separator between the root and the name whether or not the root
// ends with one (the files are the same as those an earlier `root + "/name"` named).
std::string DataDir::Under(const std::string& name) const { return (std::filesystem::path(root_) / name).string(); }

std::string DataDir::Token() const { return Under("token"); }
std::string DataDir::Tls() const { return Under("tls"); }
std::string DataDir::Beds() const { return Under("beds"); }
std::string DataDir::BedRestart(const std::string& bed_key) const {
  return (std::filesystem::path(Beds()) / (bed_key + ".restart")).string();
}
std::string DataDir::Snapshots() const { return Under("snapshots"); }
std::string DataDir::RunSnapshots(int64_t run_id) const {
  return (std::filesystem::path(Snapshots()) / ("run-" + std::to_string(run_id))).string();
}
std::string DataDir::Snapshot(int64_t run_id, int idx) const {
  return RunSnapshots(run_id) + "/" + std::to_string(idx) + ".dump";
}
std::string DataDir::Figures() const { return Under("figures"); }
std::string DataDir::Backups() const { return Under("backups"); }
std::string DataDir::Uploads() const { return Under("uploads"); }
std::string DataDir::Worker() const { return Under("worker"); }

}  // namespace sandswim
