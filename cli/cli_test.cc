// The real `sandswim` against a real `sandswimd` (no workers, so runs stay queued): every
// subcommand's output in table, CSV and JSON, every exit code, and the "no daemon" message. The
// daemon starts as a user's does, without being given a token: it makes one in its data
// directory (./var/data/token under the test's directory), and the CLI, run from that directory
// and told nothing, finds it there.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

namespace sandswim::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::MatchesRegex;
using ::testing::Not;
using ::testing::StartsWith;

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string Trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

fs::path MakeTempDir() {
  std::string pattern = (fs::temp_directory_path() / "sandswim-cli-test-XXXXXX").string();
  char* made = mkdtemp(pattern.data());
  if (made == nullptr) throw std::runtime_error("mkdtemp failed");
  return made;
}

// Spawns argv with stdin/stdout/stderr from/to files, in directory `cwd` when it is given; the
// environment is this process's, minus SANDSWIM_SERVER / SANDSWIM_TOKEN / NO_COLOR so the
// machine's settings do not leak in.
pid_t Spawn(const std::vector<std::string>& args, const fs::path& in, const fs::path& out, const fs::path& err,
            const fs::path& cwd = {}) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!cwd.empty()) posix_spawn_file_actions_addchdir_np(&actions, cwd.c_str());
  posix_spawn_file_actions_addopen(&actions, 0, in.c_str(), O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e) {
    std::string v = *e;
    if (v.rfind("SANDSWIM_", 0) == 0 || v.rfind("NO_COLOR=", 0) == 0) continue;
    env_strings.push_back(v);
  }
  std::vector<char*> envp;
  for (auto& v : env_strings) envp.push_back(v.data());
  envp.push_back(nullptr);
  std::vector<std::string> copy = args;
  std::vector<char*> argv;
  for (auto& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error("cannot spawn " + args[0]);
  return pid;
}

struct Outcome {
  int code = -1;
  std::string out, err;
};

class CliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(MakeTempDir());
    std::string url = StartDaemon(*dir_ / "db.sqlite", "daemon", &daemon_, {}, *dir_ / "var/data");
    if (!url.empty()) server_ = new std::string(url);
  }

  // Starts sandswimd on the SQLite file `db` (data under `data`, else <dir>/<tag>-data; logs under
  // <dir>/<tag>...) with `extra` flags; returns its URL, or "" (and a test failure) when it does
  // not start.
  static std::string StartDaemon(const fs::path& db, const std::string& tag, pid_t* pid,
                                 const std::vector<std::string>& extra = {}, fs::path data = {}) {
    fs::path log = *dir_ / (tag + ".log");
    if (data.empty()) data = *dir_ / (tag + "-data");
    std::vector<std::string> argv = {SANDSWIMD_BIN, "--listen",         "127.0.0.1:0", "--db",
                                     db.string(),   "--data",           data.string(), "--local-workers",
                                     "0",           "--engine-version", "test-engine"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    *pid = Spawn(argv, "/dev/null", log, *dir_ / (tag + ".err"));
    // Wait for the line that names the port (the daemon prints it once it listens).
    static const std::regex kListening(R"(listening on http://127\.0\.0\.1:([0-9]+))");
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (std::chrono::steady_clock::now() < deadline) {
      std::smatch m;
      std::string text = ReadAll(log);
      if (std::regex_search(text, m, kListening)) return "http://127.0.0.1:" + m[1].str();
      int status = 0;
      if (waitpid(*pid, &status, WNOHANG) == *pid) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ADD_FAILURE() << "sandswimd did not start: " << ReadAll(log) << ReadAll(*dir_ / (tag + ".err"));
    return "";
  }

  static void TearDownTestSuite() {
    if (daemon_ > 0) {
      kill(daemon_, SIGTERM);
      int status = 0;
      waitpid(daemon_, &status, 0);
    }
    std::error_code ec;
    if (dir_ != nullptr) fs::remove_all(*dir_, ec);
    delete dir_;
    delete server_;
    dir_ = nullptr;
    server_ = nullptr;
  }

  void SetUp() override { ASSERT_NE(server_, nullptr) << "no daemon"; }

  // Runs sandswim with --server pointing at the test daemon (unless `with_server` is false).
  static Outcome Sandswim(std::vector<std::string> args, const std::string& stdin_text = "", bool with_server = true) {
    static int counter = 0;
    std::string n = std::to_string(++counter);
    fs::path in = *dir_ / ("in" + n), out = *dir_ / ("out" + n), err = *dir_ / ("err" + n);
    std::ofstream(in) << stdin_text;
    std::vector<std::string> argv = {SANDSWIM_BIN};
    if (with_server) {
      argv.push_back("--server");
      argv.push_back(*server_);
    }
    argv.insert(argv.end(), args.begin(), args.end());
    pid_t pid = Spawn(argv, in, out, err, *dir_);  // where ./var/data/token is the daemon's
    int status = 0;
    waitpid(pid, &status, 0);
    Outcome o;
    o.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    o.out = ReadAll(out);
    o.err = ReadAll(err);
    return o;
  }

  static std::string WriteFile(const std::string& name, const std::string& text) {
    fs::path p = *dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }

  // Submits a fresh two-point sweep (a distinct name and Omega pair so runs are not shared
  // with other tests) and returns its id.
  static int64_t SubmitSweep(const std::string& name, double omega) {
    std::string file = WriteFile(
        name + ".json",
        json{{"name", name},
             {"scale", "smoke"},
             {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", omega}, {"duration_s", 0.3}}},
             {"axes", {{{"param", "Omega"}, {"values", {omega, -omega}}}}}}
            .dump());
    Outcome o = Sandswim({"submit", file});
    EXPECT_EQ(o.code, 0) << o.err;
    EXPECT_THAT(o.out, MatchesRegex("[0-9]+\n"));
    return std::stoll(o.out);
  }

  static fs::path* dir_;
  static std::string* server_;
  static pid_t daemon_;
};

fs::path* CliTest::dir_ = nullptr;
std::string* CliTest::server_ = nullptr;
pid_t CliTest::daemon_ = -1;

// The daemon, told nothing, made its token file (owner-only); the CLI, told nothing, found it (as
// every test here does). A wrong token file is refused with the way to the right one.
TEST_F(CliTest, FindsTheDaemonsTokenByItself) {
  const fs::path token = *dir_ / "var/data/token";
  ASSERT_TRUE(fs::exists(token));
  EXPECT_EQ(fs::status(token).permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
  Outcome o = Sandswim({"status"});
  EXPECT_EQ(o.code, 0) << o.err;
  const std::string wrong = WriteFile("wrong-token", std::string(64, 'a'));
  o = Sandswim({"--token-file", wrong, "status"});
  EXPECT_NE(o.code, 0);
  EXPECT_THAT(o.err, HasSubstr("not the daemon's token"));
  EXPECT_THAT(o.err, HasSubstr("--token-file DATA/token"));
  // The refusal names its field once (it said "Authorization: Authorization: ...").
  EXPECT_THAT(o.err, StartsWith("sandswim: Authorization: the bearer token is not the daemon's token"));
  EXPECT_THAT(o.err, Not(HasSubstr("Authorization: Authorization")));
}

TEST_F(CliTest, SubmitPrintsTheSweepIdAndStatusShowsIt) {
  int64_t id = SubmitSweep("status-sweep", 10);
  Outcome o = Sandswim({"status", std::to_string(id)});
  EXPECT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("sweep " + std::to_string(id) + " status-sweep (scale smoke)\n"));
  EXPECT_THAT(o.out, HasSubstr("runs: 2 (2 queued, 0 running, 0 done, 0 failed, 0 cancelled)"));
  EXPECT_THAT(o.out, HasSubstr("ETA unknown (the bed waits for a worker: is one running?)"));

  o = Sandswim({"status", std::to_string(id), "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  json j = json::parse(o.out);
  EXPECT_EQ(j["target"], std::to_string(id));
  EXPECT_EQ(j["counts"]["queued"], 2);
  EXPECT_EQ(j["finished"], false);
  EXPECT_TRUE(j["eta_s"].is_null());

  o = Sandswim({"status"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("ID  NAME"));
  EXPECT_THAT(o.out, HasSubstr("status-sweep"));
  o = Sandswim({"status", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  bool found = false;
  for (const auto& s : json::parse(o.out)) found = found || s["id"] == id;
  EXPECT_TRUE(found);
}

// `sandswim backup FILE` while the daemon serves: the copy is a whole database that a second daemon
// opens and serves the same sweep from; no partial file is left (and a daemon's start removes what
// one killed mid-backup left); an unwritable FILE is one clear error.
TEST_F(CliTest, BackupIsAConsistentCopyThatADaemonServes) {
  const int64_t id = SubmitSweep("backup-sweep", 7);
  const fs::path copy = *dir_ / "copy.db";
  Outcome o = Sandswim({"backup", copy.string()});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(o.out, fs::absolute(copy).string() + "\n");
  EXPECT_THAT(o.err, HasSubstr("wrote a consistent copy of the daemon's database"));
  EXPECT_THAT(o.err, HasSubstr("To restore it: stop sandswimd"));
  EXPECT_FALSE(fs::exists(copy.string() + ".part"));
  EXPECT_TRUE(fs::is_empty(*dir_ / "var/data" / "backups"));  // the daemon keeps no copy

  // The restored daemon's data directory holds what a daemon killed mid-backup leaves: its start
  // removes it.
  const fs::path stale = *dir_ / "restored-data" / "backups";
  fs::create_directories(stale);
  std::ofstream(stale / "backup-1-1.db.partial") << "half a copy";
  pid_t restored = -1;
  // With the first daemon's token, so the CLI's one token file serves both.
  const std::string url =
      StartDaemon(copy, "restored", &restored, {"--token-file", (*dir_ / "var/data/token").string()});
  ASSERT_FALSE(url.empty());
  EXPECT_TRUE(fs::is_empty(stale));
  o = Sandswim({"--server", url, "status", std::to_string(id), "--json"}, "", /*with_server=*/false);
  kill(restored, SIGTERM);
  int status = 0;
  waitpid(restored, &status, 0);
  ASSERT_EQ(o.code, 0) << o.err;
  json j = json::parse(o.out);
  EXPECT_EQ(j["counts"]["queued"], 2) << o.out;

  o = Sandswim({"backup", (*dir_ / "no-such-dir" / "copy.db").string()});
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("cannot write"));
  EXPECT_THAT(o.out, IsEmpty());
}

TEST_F(CliTest, SubmitFromStdinAndWithJson) {
  std::string sweep = R"({"name": "stdin-sweep", "scale": "smoke",
      "base": {"mode": "vibration", "A": 0.02, "f": 4, "duration_s": 0.5}})";
  Outcome o = Sandswim({"submit", "-", "--json"}, sweep);
  ASSERT_EQ(o.code, 0) << o.err;
  json reply = json::parse(o.out);
  EXPECT_EQ(reply["runs"], 1);
  EXPECT_TRUE(reply["id"].is_number_integer());
  // The same key again: the same id, nothing new.
  o = Sandswim({"submit", "-", "--idempotency-key", "k-1"}, sweep);
  ASSERT_EQ(o.code, 0) << o.err;
  Outcome again = Sandswim({"submit", "-", "--idempotency-key", "k-1"}, sweep);
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_EQ(again.out, o.out);
  EXPECT_THAT(again.err, HasSubstr("earlier identical submission"));
}

TEST_F(CliTest, RunsInTableAndJson) {
  int64_t id = SubmitSweep("runs-sweep", 20);
  Outcome o = Sandswim({"runs", "--sweep", std::to_string(id)});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("ID  STATE   PROGRESS  U_z  POINT"));
  EXPECT_THAT(o.out, HasSubstr("oscillatory A=0.03 f=3 Omega=20 T=0.3s"));

  o = Sandswim({"runs", "--sweep", std::to_string(id), "--state", "queued", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  json runs = json::parse(o.out);
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0]["state"], "queued");
  EXPECT_EQ(runs[0]["point"]["mode"], "oscillatory");
  EXPECT_EQ(runs[0]["point"]["Omega"], 20.0);
  EXPECT_EQ(runs[1]["point"]["Omega"], -20.0);

  o = Sandswim({"runs", "--limit", "1", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(json::parse(o.out).size(), 1u);
}

TEST_F(CliTest, ResultsInTableCsvAndJson) {
  int64_t id = SubmitSweep("results-sweep", 30);
  Outcome o = Sandswim({"results", std::to_string(id)});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("RUN  STATE   MODE"));
  EXPECT_THAT(o.out, HasSubstr("Δz (m)"));
  EXPECT_THAT(o.out, HasSubstr("queued  oscillatory  0.03  3           30  -"));

  o = Sandswim({"results", std::to_string(id), "--format", "csv"});
  ASSERT_EQ(o.code, 0) << o.err;
  // The CLI's CSV is the daemon's, byte for byte.
  httplib::Client http(*server_);
  http.set_bearer_token_auth(Trimmed(ReadAll(*dir_ / "var/data/token")));
  auto daemon_csv = http.Get("/api/v1/sweeps/" + std::to_string(id) + "/results?format=csv");
  ASSERT_TRUE(daemon_csv);
  EXPECT_EQ(o.out, daemon_csv->body);
  std::istringstream lines(o.out);
  std::string header, row1, row2, extra;
  std::getline(lines, header);
  std::getline(lines, row1);
  std::getline(lines, row2);
  EXPECT_FALSE(std::getline(lines, extra));
  EXPECT_EQ(
      header,
      "run_id,key,state,mode,A,f,Omega,omega,axis,duration_s,run_duration_s,replicate,bed_id,Uz_text,Uz,Uz_stderr,"
      "Uz_ci95,Uz_blocks,block_s,block_kind,window_t0,window_t1,window_end,conclusive,"
      "inconclusive_reason,trending,trend_p,trend_slope,trend_slope_se,trend_note,dz,dz_rate,z_osc_amplitude,"
      "x_osc_amplitude,x_drift,broke_surface,near_floor,stop_reason,"
      "stop_note,precision_met,sim_time_s,grains,analysis,analysed_from,engine_version,"
      "so_density_kg_m3,so_diameter_m,so_friction,so_restitution,grain_diameter_m,grain_density_kg_m3,"
      "grain_friction,grain_restitution,grain_youngs_Pa,grain_poisson");
  EXPECT_THAT(row1, MatchesRegex("[0-9]+,[0-9a-f]{64},queued,oscillatory,0.03,3.0,30.0,,,0.3,0.3,0,[0-9]+(,){32},"
                                 "2500.0,0.12,0.5,0.5,0.02,2500.0,0.45,0.9,10000000.0,0.25"));

  for (std::vector<std::string> args : {std::vector<std::string>{"--format", "json"}, {"--json"}}) {
    std::vector<std::string> argv = {"results", std::to_string(id)};
    argv.insert(argv.end(), args.begin(), args.end());
    o = Sandswim(argv);
    ASSERT_EQ(o.code, 0) << o.err;
    json rows = json::parse(o.out);
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_EQ(rows[0]["Omega"], 30.0);
    EXPECT_EQ(rows[0]["state"], "queued");
    EXPECT_TRUE(rows[0]["Uz"].is_null());
    EXPECT_EQ(rows[1]["Omega"], -30.0);
  }
}

// A sweep over several pages (2 points on 3 beds each, read 2 runs a page: the first page holds
// only the first point's runs, the second one run of each) prints the same tables as from one page.
TEST_F(CliTest, ResultsOverSeveralPagesPrintTheSameTables) {
  std::string file = WriteFile("paged.json", json{{"name", "paged"},
                                                  {"scale", "smoke"},
                                                  {"replicates", 3},
                                                  {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", 41}, {"duration_s", 0.3}}},
                                                  {"axes", {{{"param", "Omega"}, {"values", {41, -41}}}}}}
                                                 .dump());
  Outcome o = Sandswim({"submit", file});
  ASSERT_EQ(o.code, 0) << o.err;
  const std::string id = Trimmed(o.out);
  const Outcome whole = Sandswim({"results", id});
  ASSERT_EQ(whole.code, 0) << whole.err;
  EXPECT_THAT(whole.out, HasSubstr("per point, over its replicate beds"));
  const size_t first = whole.out.find("queued queued queued");
  ASSERT_NE(first, std::string::npos) << whole.out;
  EXPECT_NE(whole.out.find("queued queued queued", first + 1), std::string::npos) << "both points over 3 beds";
  setenv("SANDSWIM_RESULTS_PAGE_ROWS", "2", 1);
  const Outcome paged = Sandswim({"results", id});
  const Outcome paged_json = Sandswim({"results", id, "--json"});
  unsetenv("SANDSWIM_RESULTS_PAGE_ROWS");
  ASSERT_EQ(paged.code, 0) << paged.err;
  EXPECT_EQ(paged.out, whole.out);
  ASSERT_EQ(paged_json.code, 0) << paged_json.err;
  EXPECT_EQ(json::parse(paged_json.out).size(), 6u);
}

TEST_F(CliTest, ShowPrintsPointDeckAndLog) {
  int64_t id = SubmitSweep("show-sweep", 40);
  Outcome runs = Sandswim({"runs", "--sweep", std::to_string(id), "--json"});
  ASSERT_EQ(runs.code, 0) << runs.err;
  int64_t run = json::parse(runs.out)[0]["id"];
  Outcome o = Sandswim({"show", std::to_string(run)});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("run " + std::to_string(run) + "  queued\n"));
  EXPECT_THAT(o.out, HasSubstr("point:     oscillatory A=0.03 f=3 Omega=40 T=0.3s"));
  EXPECT_THAT(o.out, HasSubstr("--- deck ---\n# sandswim drive deck"));
  EXPECT_THAT(o.out, HasSubstr("--- log tail ---\n(no log yet)"));

  o = Sandswim({"show", std::to_string(run), "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  json j = json::parse(o.out);
  EXPECT_EQ(j["id"], run);
  EXPECT_THAT(j["deck"].get<std::string>(), HasSubstr("sandswim drive deck"));
  EXPECT_EQ(j["sweeps"], json::array({id}));
}

TEST_F(CliTest, CancelCancelsTheRunsAndWatchEnds) {
  int64_t id = SubmitSweep("cancel-sweep", 50);
  Outcome o = Sandswim({"cancel", std::to_string(id)});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(o.out,
            "sweep " + std::to_string(id) + " cancelled: 2 queued run(s) cancelled, 0 running run(s) told to stop\n");
  o = Sandswim({"runs", "--sweep", std::to_string(id), "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  for (const auto& r : json::parse(o.out)) EXPECT_EQ(r["state"], "cancelled");

  // Nothing queued or running: watch prints one plain line (piped) and exits 0.
  o = Sandswim({"watch", std::to_string(id)});
  EXPECT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(o.out, "sweep " + std::to_string(id) +
                       " cancel-sweep (scale smoke, cancelled): 0/2 done, 0 running, 0 queued, 0 failed, "
                       "2 cancelled; finished\n");
  EXPECT_EQ(o.out.find('\x1b'), std::string::npos);
}

TEST_F(CliTest, CampaignSubmitStatusResultsAndRerun) {
  Outcome o = Sandswim({"submit", "paper-58", "--scale", "smoke"});
  ASSERT_EQ(o.code, 0) << o.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_match(o.out, m, std::regex("cr:([0-9]+)\nsweeps:( [0-9]+)+\n"))) << o.out;
  const std::string cr_id = m[1].str();  // `m` points into o.out, which is reused below
  const std::string cr = "cr:" + cr_id;

  o = Sandswim({"status", cr, "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(json::parse(o.out)["counts"]["queued"], 58);

  o = Sandswim({"results", cr, "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  json rows = json::parse(o.out);
  ASSERT_EQ(rows.size(), 58u);
  EXPECT_TRUE(rows[0]["sweeps"].is_array());
  Outcome flag = Sandswim({"results", "--campaign-run", cr_id, "--json"});
  ASSERT_EQ(flag.code, 0) << flag.err;
  EXPECT_EQ(json::parse(flag.out), rows);

  // Rerun: every run is still queued, so every one is shared, none new.
  o = Sandswim({"rerun", "paper-58", "--scale", "smoke"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("cr:"));
  EXPECT_THAT(o.err, HasSubstr("58 run(s): 0 new"));
}

TEST_F(CliTest, ExitCodes) {
  Outcome o = Sandswim({"status", "999999"});
  EXPECT_EQ(o.code, 1);
  EXPECT_EQ(o.err, "sandswim: no sweep 999999\n");
  EXPECT_EQ(o.out, "");

  o = Sandswim({"show", "999999"});
  EXPECT_EQ(o.code, 1);

  o = Sandswim({"status", "cr:abc"});
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.err, HasSubstr("SWEEP: expected a sweep id (12) or a campaign run id (cr:7)"));

  // A name is a campaign: its last drift report, or why there is none.
  o = Sandswim({"status", "abc"});
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("no campaign named 'abc'"));

  o = Sandswim({"runs", "--state", "sleeping"});
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.err, HasSubstr("--state"));

  o = Sandswim({});
  EXPECT_EQ(o.code, 2);

  o = Sandswim({"results", "1", "--format", "xml"});
  EXPECT_EQ(o.code, 2);

  o = Sandswim({"submit", "no-such-file.json"});
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.err, HasSubstr("no such file: no-such-file.json"));

  // The daemon refuses a bad sweep, naming the field: an error (1), one line.
  std::string bad = WriteFile("bad.json", R"({"name": "bad", "scale": "smoke",
      "base": {"mode": "vibration", "A": -1, "f": 3, "duration_s": 1}})");
  o = Sandswim({"submit", bad});
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("A"));
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1);

  o = Sandswim({"--help"});
  EXPECT_EQ(o.code, 0);
  EXPECT_THAT(o.out, HasSubstr("submit"));
  o = Sandswim({"results", "--help"});
  EXPECT_EQ(o.code, 0);
  EXPECT_THAT(o.out, HasSubstr("Examples:"));
}

TEST_F(CliTest, NoDaemonIsOneClearLine) {
  // A port nobody listens on: bind one, note it, close it.
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  socklen_t len = sizeof addr;
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  int port = ntohs(addr.sin_port);
  close(fd);
  std::string url = "http://127.0.0.1:" + std::to_string(port);

  Outcome o = Sandswim({"--server", url, "status"}, "", /*with_server=*/false);
  EXPECT_EQ(o.code, 1);
  EXPECT_EQ(o.err, "sandswim: no daemon at " + url +
                       " (connection refused). Start one with: build/bin/sandswimd --local-workers 2\n");
  EXPECT_EQ(o.out, "");

  // SANDSWIM_SERVER is honoured the same way: version still prints the client's version.
  o = Sandswim({"version", "--server", url}, "", /*with_server=*/false);
  EXPECT_EQ(o.code, 0);
  EXPECT_THAT(o.out, StartsWith("sandswim "));
  EXPECT_THAT(o.out, HasSubstr("not reachable"));

  o = Sandswim({"--server", "ftp://x", "status"}, "", /*with_server=*/false);
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.err, HasSubstr("--server: expected http://HOST:PORT"));
}

TEST_F(CliTest, VersionShowsTheDaemon) {
  Outcome o = Sandswim({"version"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(
      o.out,
      MatchesRegex("sandswim [0-9.]+\ndaemon at http://127.0.0.1:[0-9]+: ok, engine test-engine, schema [0-9]+\n"));
  o = Sandswim({"version", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(json::parse(o.out)["server"]["engine_version"], "test-engine");
}

TEST_F(CliTest, ExpandPaper58IsOfflineAnd58Runs) {
  // No --server: expand never talks to a daemon.
  Outcome o = Sandswim({"expand", "paper-58", "--json"}, "", /*with_server=*/false);
  ASSERT_EQ(o.code, 0) << o.err;
  json runs = json::parse(o.out);
  ASSERT_EQ(runs.size(), 58u);
  int four = 0, five = 0;
  for (const auto& r : runs) {
    if (r["duration_s"] == 4.0) ++four;
    if (r["duration_s"] == 5.0) ++five;
    EXPECT_EQ(r["key"].get<std::string>().size(), 64u);
  }
  EXPECT_EQ(four, 56);
  EXPECT_EQ(five, 2);

  o = Sandswim({"expand", "paper-58", "--scale", "smoke", "--engine-version", "x"}, "", false);
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(std::count(o.out.begin(), o.out.end(), '\n'), 58);
  EXPECT_THAT(o.err, HasSubstr("58 distinct run(s); engine x"));

  // A name that is not built in is asked of the daemon; with none there, the error says what to do.
  o = Sandswim({"--server", "http://127.0.0.1:1", "expand", "no-such-campaign"}, "", false);
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("campaign \"no-such-campaign\" is not built in (builtin: paper-58"));
  EXPECT_THAT(o.err, HasSubstr("no daemon at http://127.0.0.1:1"));
  EXPECT_THAT(o.err, HasSubstr("sandswim expand mine.json"));
}

// A stored campaign is expanded from the definition the daemon holds (its current version, its
// base filled in), saying so; --cost works on it; a name the daemon does not hold either is refused
// naming both places looked in.
TEST_F(CliTest, ExpandAStoredCampaignFromTheDaemon) {
  Outcome o = Sandswim({"campaign", "put", "-"},
                       R"({"name":"cli-expand","extends":"paper-58","sweeps":["baseline"],"replicates":3,"scale":"smoke"})");
  ASSERT_EQ(o.code, 0) << o.err;
  o = Sandswim({"expand", "cli-expand", "--json", "--engine-version", "test-engine"});
  ASSERT_EQ(o.code, 0) << o.err;
  const json runs = json::parse(o.out);
  ASSERT_EQ(runs.size(), 6u);  // baseline's 2 points on 3 beds
  std::set<int> beds;
  for (const json& r : runs) beds.insert(r.value("replicate", 0));
  EXPECT_EQ(beds.size(), 3u) << o.out;
  EXPECT_THAT(o.err, HasSubstr("sandswim: campaign cli-expand version 1 (as it runs, its base filled in) from the "
                               "daemon at " + *server_));
  // The same keys the daemon plans when it runs it.
  Outcome run = Sandswim({"campaign", "run", "cli-expand"});
  ASSERT_EQ(run.code, 0) << run.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(run.out, m, std::regex("cr:[0-9]+"))) << run.out;
  Outcome results = Sandswim({"results", m[0].str(), "--json"});
  ASSERT_EQ(results.code, 0) << results.err;
  std::set<std::string> planned, daemon;
  for (const json& r : runs) planned.insert(r["key"].get<std::string>());
  for (const json& r : json::parse(results.out)) daemon.insert(r["key"].get<std::string>());
  EXPECT_EQ(planned, daemon);

  o = Sandswim({"expand", "cli-expand", "--scale", "mini", "--cost", "--engine-version", "test-engine"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, HasSubstr("mini: 6 runs on 3 bed(s)"));

  o = Sandswim({"expand", "cli-nobody"});
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("no campaign \"cli-nobody\": not built in (builtin: paper-58"));
  EXPECT_THAT(o.err, HasSubstr(") and not stored in the daemon at " + *server_));
}

TEST_F(CliTest, ExpandMatchesTheDaemonsKeys) {
  // The same engine version gives the same content keys the daemon stores.
  std::string file = WriteFile("keys.json", R"({"name": "keys", "scale": "smoke",
      "base": {"mode": "rotation", "omega": 7, "axis": "z", "duration_s": 0.4}})");
  Outcome expand = Sandswim({"expand", file, "--json", "--engine-version", "test-engine"}, "", false);
  ASSERT_EQ(expand.code, 0) << expand.err;
  Outcome submit = Sandswim({"submit", file});
  ASSERT_EQ(submit.code, 0) << submit.err;
  Outcome results = Sandswim({"results", std::to_string(std::stoll(submit.out)), "--json"});
  ASSERT_EQ(results.code, 0) << results.err;
  EXPECT_EQ(json::parse(expand.out)[0]["key"], json::parse(results.out)[0]["key"]);
}

// A user's own campaign, end to end on the real daemon: put (paper-58's baseline on three beds, from
// stdin) -> list -> show -> edit in $EDITOR (a script), a refused edit kept -> run -> rm refused while
// its runs are queued, then removed, its campaign run still readable; schedule set, listed, removed.
// Last in this file: it cancels its sweeps, whose runs other campaign tests share.
TEST_F(CliTest, OwnCampaignPutShowEditRunRm) {
  const std::string definition =
      R"({"name":"cli-own","extends":"paper-58","sweeps":["baseline"],"replicates":3,"scale":"smoke"})";
  Outcome o = Sandswim({"campaign", "put", "-"}, definition);
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("cli-own: stored as version 1 (a new campaign)\n"));
  EXPECT_THAT(o.out, HasSubstr("  plans 6 runs at smoke"));  // 2 points on 3 beds
  o = Sandswim({"campaign", "put", "-"}, definition);
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(o.out.substr(0, o.out.find('\n')), "cli-own: unchanged, still version 1");

  // A refusal names the definition's own field, once; nothing is stored.
  o = Sandswim({"campaign", "put", "-"}, R"({"name":"cli-bad","extends":"paper-58","replicates":0})");
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, StartsWith("sandswim: replicates: "));
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1);
  EXPECT_EQ(Sandswim({"campaign", "show", "cli-bad"}).code, 1);
  o = Sandswim({"campaign", "put", "-"}, R"({"name":"paper-58","replicates":3})");
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("extends"));  // how to make a copy instead

  o = Sandswim({"campaign", "list"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("NAME"));
  EXPECT_THAT(o.out, MatchesRegex("(.|\n)*\ncli-own +1  no +paper-58 +- +-\n(.|\n)*"));
  EXPECT_THAT(o.out, MatchesRegex("(.|\n)*\npaper-58 +-  yes(.|\n)*"));

  o = Sandswim({"campaign", "show", "cli-own"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("campaign cli-own, version 1\n  extends:   paper-58\n"));
  EXPECT_THAT(o.out, HasSubstr("\"replicates\": 3"));
  o = Sandswim({"campaign", "show", "cli-own", "--resolved", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  json shown = json::parse(o.out);
  EXPECT_EQ(shown["resolved"]["sweeps"].size(), 1u);
  EXPECT_FALSE(shown["resolved"].contains("extends"));

  // edit: the editor is a script; VISUAL would win over EDITOR, so it is cleared.
  const fs::path edit =
      WriteFile("edit-replicates.sh", "#!/bin/sh\nsed -i 's/\"replicates\": 3/\"replicates\": 2/' \"$1\"\n");
  const fs::path spoil =
      WriteFile("spoil-replicates.sh", "#!/bin/sh\nsed -i 's/\"replicates\": 2/\"replicates\": 0/' \"$1\"\n");
  fs::permissions(edit, fs::perms::owner_all);
  fs::permissions(spoil, fs::perms::owner_all);
  const char* visual = getenv("VISUAL");
  const std::string saved_visual = visual != nullptr ? visual : "";
  unsetenv("VISUAL");
  setenv("EDITOR", edit.c_str(), 1);
  o = Sandswim({"campaign", "edit", "cli-own"});
  EXPECT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("cli-own: stored as version 2\n"));
  EXPECT_THAT(o.out, HasSubstr("  plans 4 runs at smoke"));
  setenv("EDITOR", spoil.c_str(), 1);
  o = Sandswim({"campaign", "edit", "cli-own"}, "n\n");
  unsetenv("EDITOR");
  if (visual != nullptr) setenv("VISUAL", saved_visual.c_str(), 1);
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("sandswim: replicates: "));
  EXPECT_THAT(o.err, HasSubstr("re-open the editor to fix it? [Y/n]"));
  std::smatch kept;
  ASSERT_TRUE(std::regex_search(o.err, kept, std::regex("your text is kept in (\\S+) "))) << o.err;
  EXPECT_THAT(ReadAll(kept[1].str()), HasSubstr("\"replicates\": 0"));
  fs::remove(kept[1].str());
  o = Sandswim({"campaign", "show", "cli-own", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  shown = json::parse(o.out);
  EXPECT_EQ(shown["version"], 2);
  EXPECT_EQ(shown["definition"]["replicates"], 2);
  EXPECT_EQ(shown["versions"].size(), 2u);

  // run: the campaign run and its sweeps, as submit prints them.
  o = Sandswim({"campaign", "run", "cli-own"});
  ASSERT_EQ(o.code, 0) << o.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_match(o.out, m, std::regex("cr:([0-9]+)\nsweeps:((?: [0-9]+)+)\n"))) << o.out;
  const std::string cr = "cr:" + m[1].str();
  std::vector<std::string> sweeps;
  std::istringstream ids(m[2].str());
  for (std::string id; ids >> id;) sweeps.push_back(id);
  EXPECT_THAT(o.err, HasSubstr("4 run(s)"));
  o = Sandswim({"status", cr, "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(json::parse(o.out)["counts"]["queued"], 4);
  o = Sandswim({"campaign", "show", "cli-own"});
  EXPECT_THAT(o.out, HasSubstr("\n" + cr + " "));

  // schedule: set (stored), listed, removed.
  o = Sandswim({"schedule", "cli-own", "0 3 * * *", "--scale", "smoke"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(o.out, StartsWith("cli-own: 0 3 * * * at smoke, next due "));
  o = Sandswim({"schedule"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_THAT(
      o.out, MatchesRegex("(.|\n)*\ncli-own +0 3 \\* \\* \\* +smoke +[0-9-]+ [0-9:]+ UTC +sandswim schedule\n(.|\n)*"));
  o = Sandswim({"schedule", "cli-own", "not a cron"});
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, StartsWith("sandswim: cron: "));

  // rm: refused while its runs are queued (nothing removed), then removed once they are cancelled.
  o = Sandswim({"campaign", "rm", "cli-own"});
  EXPECT_EQ(o.code, 1);
  EXPECT_THAT(o.err, HasSubstr("campaign run " + cr.substr(3) + " "));
  EXPECT_EQ(Sandswim({"campaign", "show", "cli-own"}).code, 0);
  for (const std::string& sweep : sweeps) ASSERT_EQ(Sandswim({"cancel", sweep}).code, 0);
  o = Sandswim({"campaign", "rm", "cli-own"});
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(o.out, "removed campaign cli-own\n");
  EXPECT_THAT(o.err, HasSubstr(cr));
  EXPECT_EQ(Sandswim({"campaign", "show", "cli-own"}).code, 1);
  EXPECT_EQ(Sandswim({"status", cr}).code, 0);  // its past run stays readable
  o = Sandswim({"schedule", "--json"});
  ASSERT_EQ(o.code, 0) << o.err;
  for (const auto& s : json::parse(o.out)) EXPECT_NE(s["campaign"], "cli-own");  // its schedule went with it
}

}  // namespace
}  // namespace sandswim::cli
