#include "tests/service_fixture.h"

#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <stdexcept>
#include <thread>

#include <httplib.h>

#include "tests/engine_fixture.h"

namespace sandswim::testing {
namespace fs = std::filesystem;

ChildProcess::ChildProcess(std::vector<std::string> argv, const std::string& dir, const std::string& output_file)
    : output_path_(dir + "/" + output_file) {
  fs::create_directories(dir);
  worker::LaunchSpec spec;
  spec.argv = std::move(argv);
  spec.cwd = dir;
  spec.output_file = output_file;
  worker::ProcessLauncher launcher;
  auto started = launcher.Start(spec);
  if (!started.ok()) throw std::runtime_error("cannot start " + spec.argv[0] + ": " + started.status().ToString());
  process_ = std::move(started.value());
  pid_ = process_->pid();
}

ChildProcess::~ChildProcess() { Stop(); }

bool ChildProcess::running() { return !process_->WaitFor(0); }

void ChildProcess::Kill(int signal) {
  if (running()) ::kill(pid_, signal);
}

void ChildProcess::Stop(double grace_s) { process_->Stop(grace_s); }

std::string ChildProcess::Output() const { return ReadFile(output_path_); }

Daemon::Daemon(const std::string& dir, std::vector<std::string> extra) : dir_(dir), db_(dir + "/sandswim.db") {
  std::vector<std::string> argv = {SANDSWIMD_PATH, "--db", db_, "--data", dir + "/data", "--listen", "127.0.0.1:0",
                                   "--local-workers", "0"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  process_ = std::make_unique<ChildProcess>(argv, dir, "sandswimd.out");
  static const std::regex re(R"(listening on (http://127\.0\.0\.1:\d+))");
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  std::smatch m;
  std::string out;
  while (std::chrono::steady_clock::now() < deadline) {
    out = process_->Output();
    if (std::regex_search(out, m, re)) {
      url_ = m[1];
      return;
    }
    if (!process_->running()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  throw std::runtime_error("sandswimd did not start; it printed:\n" + out);
}

namespace {
nlohmann::json Parse(const httplib::Result& r, const std::string& what, int* status) {
  if (!r) throw std::runtime_error(what + ": " + httplib::to_string(r.error()));
  if (status) *status = r->status;
  if (r->body.empty()) return nullptr;
  return nlohmann::json::parse(r->body, nullptr, /*allow_exceptions=*/false);
}
}  // namespace

nlohmann::json Daemon::Get(const std::string& path, int* status) {
  httplib::Client c(url_);
  return Parse(c.Get(path), "GET " + path, status);
}

nlohmann::json Daemon::Post(const std::string& path, const nlohmann::json& body, int* status) {
  httplib::Client c(url_);
  return Parse(c.Post(path, body.dump(), "application/json"), "POST " + path, status);
}

nlohmann::json Daemon::WaitForSweep(int64_t sweep_id, double timeout_s) {
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  nlohmann::json s;
  while (std::chrono::steady_clock::now() < deadline) {
    s = Get("/api/v1/sweeps/" + std::to_string(sweep_id));
    if (s.is_object() && s["counts"]["queued"] == 0 && s["counts"]["running"] == 0) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  return s;
}

std::string Daemon::Sql(const std::string& query) {
  std::string out = dir_ + "/sql.out";
  std::string cmd = "sqlite3 -cmd '.timeout 10000' '" + db_ + "' \"" + query + "\" > '" + out + "' 2>&1";
  std::system(cmd.c_str());
  std::string s = ReadFile(out);
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  return s;
}

std::unique_ptr<ChildProcess> StartWorker(const Daemon& daemon, const std::string& dir, int slots,
                                          const std::vector<std::string>& extra) {
  std::vector<std::string> argv = {SANDSWIM_WORKER_PATH, "--server", daemon.url(), "--slots", std::to_string(slots),
                                   "--ranks", "1", "--workdir", dir, "--heartbeat", "1"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return std::make_unique<ChildProcess>(argv, dir, "worker.out");
}

nlohmann::json OmegaSweep(const std::string& name, const std::vector<double>& omegas, double duration, double f) {
  using nlohmann::json;
  return {{"name", name},
          {"scale", "smoke"},
          {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", f}, {"Omega", omegas.at(0)}, {"duration_s", duration}}},
          {"axes", json::array({{{"param", "Omega"}, {"values", omegas}}})},
          {"combine", "product"}};
}

}  // namespace sandswim::testing
