// FakeClient: an in-memory DaemonClient for tests (the header of cli_tests only). Sweeps, runs and
// campaign runs are plain JSON the test sets; unknown ids answer kNotFound like the daemon.
#ifndef SANDSWIM_CLI_FAKE_CLIENT_TEST_UTIL_H_
#define SANDSWIM_CLI_FAKE_CLIENT_TEST_UTIL_H_

#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cli/client.h"

namespace sandswim::cli {

class FakeClient : public DaemonClient {
 public:
  std::map<int64_t, nlohmann::json> sweeps;
  std::map<int64_t, nlohmann::json> campaign_runs;
  std::map<int64_t, nlohmann::json> claims;       // GET /campaign-runs/{id}/claims, by campaign run id
  nlohmann::json runs = nlohmann::json::array();  // every run; ListRuns filters by state
  nlohmann::json cost_model;                      // GET /api/v1/cost-model; null: Unavailable
  std::string url = "http://fake";
  // Campaigns: each as GET /api/v1/campaigns/{name} answers it ({name, version, builtin, definition,
  // resolved, extends, schedule, versions, runs}); PutCampaign stores into it as the daemon would.
  std::map<std::string, nlohmann::json> campaigns;
  std::map<std::pair<std::string, int64_t>, nlohmann::json> versions;  // GET ?version=N of a past version
  std::map<std::string, nlohmann::json> campaign_run_lists;            // GET /campaign-runs?campaign=NAME
  std::vector<Status> put_refusals;                                    // PutCampaign answers these first, one a call
  std::vector<std::pair<std::string, nlohmann::json>> puts;            // every PutCampaign: name, definition
  Status delete_refusal;                                               // DeleteCampaign answers it when set
  std::vector<std::string> deleted;
  std::vector<std::pair<std::string, nlohmann::json>> run_requests;  // every RunCampaign: name, body
  nlohmann::json run_reply = {{"campaign_run_id", 7}, {"ids", {3, 4}}, {"runs", 2}, {"runs_new", 2}};
  Status schedule_refusal;  // PutSchedule answers it when set
  bool serves_board = true;  // Live() answers (else NotFound, as a daemon from before the board)
  std::vector<Status> live_refusals;  // Live() answers these first, one a call
  // Live() hands its board to this first (a test's stale or odd board).
  std::function<void(nlohmann::json&)> edit_board;
  int live_calls = 0;
  Status runs_refusal;  // ListRuns answers it when set
  int route_calls = 0;  // GetSweep, GetCampaignRun and ListRuns: the target's own routes
  // Live, GetSweep, GetCampaignRun, ListRuns and GetRun answer it when set: a daemon that cannot
  // be reached (restarting), every route alike.
  Status down;

  // Called as the client is destroyed (at the end of RunCli), so a test can keep what it recorded.
  std::function<void(const FakeClient&)> on_close;

  FakeClient() = default;
  FakeClient(const FakeClient&) = default;
  ~FakeClient() override {
    if (on_close) on_close(*this);
  }

  const std::string& base_url() const override { return url; }
  Result<nlohmann::json> Healthz() override { return nlohmann::json{{"status", "ok"}}; }
  Result<nlohmann::json> CostModel() override {
    if (cost_model.is_null()) return Status::Unavailable("no daemon");
    return cost_model;
  }
  Result<nlohmann::json> Submit(const nlohmann::json&, const std::string&) override {
    return Status::Unavailable("FakeClient takes no submissions");
  }
  Result<nlohmann::json> ListSweeps() override {
    nlohmann::json all = nlohmann::json::array();
    for (const auto& [id, s] : sweeps) all.push_back(s);
    return all;
  }
  Result<nlohmann::json> GetSweep(int64_t id) override {
    ++route_calls;
    if (!down.ok()) return down;
    auto it = sweeps.find(id);
    if (it == sweeps.end()) return Status::NotFound("no sweep " + std::to_string(id));
    return it->second;
  }
  Result<nlohmann::json> SweepResults(int64_t id) override {
    return nlohmann::json{{"id", id}, {"results", nlohmann::json::array()}};
  }
  Result<nlohmann::json> CancelSweep(int64_t id) override { return GetSweep(id); }
  // By state and by sweep: a run is in the sweeps its "sweeps" names (none without it), as
  // GET /api/v1/runs?sweep= finds it through the daemon's sweep membership.
  Result<nlohmann::json> ListRuns(const RunQuery& query) override {
    ++route_calls;
    if (!down.ok()) return down;
    if (!runs_refusal.ok()) return runs_refusal;
    nlohmann::json out = nlohmann::json::array();
    for (const auto& r : runs) {
      if (query.state && r.value("state", "") != *query.state) continue;
      if (query.sweep && !InSweep(r, *query.sweep)) continue;
      out.push_back(r);
    }
    return out;
  }
  static bool InSweep(const nlohmann::json& run, int64_t sweep) {
    for (const auto& id : run.value("sweeps", nlohmann::json::array())) {
      if (id == sweep) return true;
    }
    return false;
  }
  Result<nlohmann::json> GetRun(int64_t id) override {
    if (!down.ok()) return down;
    for (const auto& r : runs) {
      if (r.value("id", int64_t{0}) == id) return r;
    }
    return Status::NotFound("no run " + std::to_string(id));
  }
  Result<nlohmann::json> GetCampaignRun(int64_t id) override {
    ++route_calls;
    if (!down.ok()) return down;
    auto it = campaign_runs.find(id);
    if (it == campaign_runs.end()) return Status::NotFound("no campaign run " + std::to_string(id));
    return it->second;
  }
  Result<nlohmann::json> CampaignRunResults(int64_t id) override {
    return nlohmann::json{{"id", id}, {"results", nlohmann::json::array()}};
  }
  // The progress board as the daemon builds it from the sweeps, campaign runs and runs above
  // (server/dashboard/live_feed.h): each running run as it is, with the "sweeps" it names (a run
  // without them makes a board from before running runs named their sweeps).
  Result<nlohmann::json> Live() override {
    ++live_calls;
    if (!down.ok()) return down;
    if (!serves_board) return Status::NotFound("no route GET /api/v1/live");
    if (!live_refusals.empty()) {
      Status refusal = live_refusals.front();
      live_refusals.erase(live_refusals.begin());
      return refusal;
    }
    nlohmann::json board = {{"sweeps", nlohmann::json::array()},
                            {"campaign_runs", nlohmann::json::array()},
                            {"running", nlohmann::json::array()}};
    for (const auto& [id, s] : sweeps) {
      nlohmann::json j = s;
      j["id"] = id;
      board["sweeps"].push_back(j);
    }
    for (const auto& [id, c] : campaign_runs) {
      nlohmann::json j = c;
      j["id"] = id;
      board["campaign_runs"].push_back(j);
    }
    for (const auto& r : runs) {
      if (r.value("state", "") == "running") board["running"].push_back(r);
    }
    if (edit_board) edit_board(board);
    return board;
  }
  Result<nlohmann::json> CampaignRunClaims(int64_t id) override {
    auto it = claims.find(id);
    if (it == claims.end()) return Status::NotFound("no campaign run " + std::to_string(id));
    return it->second;
  }

  Result<nlohmann::json> ListCampaigns() override {
    nlohmann::json all = nlohmann::json::array();
    for (const auto& [name, c] : campaigns) {
      all.push_back({{"name", name},
                     {"version", c.value("version", 0)},
                     {"builtin", c.value("builtin", false)},
                     {"extends", c.value("extends", nlohmann::json())},
                     {"schedule", c.value("schedule", nlohmann::json())}});
    }
    return all;
  }
  Result<nlohmann::json> ListCampaignRuns(const std::string& name, int64_t limit) override {
    nlohmann::json runs = nlohmann::json::array();
    auto it = campaign_run_lists.find(name);
    if (it == campaign_run_lists.end()) return runs;
    for (const auto& r : it->second) {
      if (static_cast<int64_t>(runs.size()) < limit) runs.push_back(r);
    }
    return runs;
  }
  Result<nlohmann::json> GetCampaign(const std::string& name, int64_t version) override {
    auto it = campaigns.find(name);
    if (it == campaigns.end()) return Status(StatusCode::kNotFound, "no campaign '" + name + "'", "name");
    if (version > 0 && it->second.value("version", 0) != version) {
      auto old = versions.find({name, version});
      if (old == versions.end()) {
        return Status(StatusCode::kNotFound, "no version " + std::to_string(version), "version");
      }
      return old->second;
    }
    return it->second;
  }
  Result<nlohmann::json> PutCampaign(const std::string& name, const nlohmann::json& definition) override {
    puts.emplace_back(name, definition);
    if (!put_refusals.empty()) {
      Status refusal = put_refusals.front();
      put_refusals.erase(put_refusals.begin());
      return refusal;
    }
    nlohmann::json& c = campaigns[name];
    if (c.is_null()) c = nlohmann::json::object();
    if (c.value("builtin", false)) return Status(StatusCode::kConflict, "built-in", "name");
    const bool unchanged = c.contains("definition") && c["definition"] == definition;
    if (!unchanged) {
      c["name"] = name;
      c["version"] = c.value("version", 0) + 1;
      c["builtin"] = false;
      c["definition"] = definition;
      c["resolved"] = definition;
      c["extends"] = definition.value("extends", nlohmann::json());
      if (!c.contains("schedule")) c["schedule"] = nullptr;
    }
    return nlohmann::json{{"name", name},
                          {"version", c["version"]},
                          {"created", c["version"] == 1 && !unchanged},
                          {"unchanged", unchanged},
                          {"notes", nlohmann::json::array()},
                          {"planned_runs", {{"smoke", 2}, {"mini", 2}, {"paper", 2}}}};
  }
  Status DeleteCampaign(const std::string& name) override {
    if (!delete_refusal.ok()) return delete_refusal;
    if (campaigns.erase(name) == 0) return Status(StatusCode::kNotFound, "no campaign '" + name + "'", "name");
    deleted.push_back(name);
    return Status::Ok();
  }
  Result<nlohmann::json> RunCampaign(const std::string& name, const nlohmann::json& body) override {
    run_requests.emplace_back(name, body);
    if (!campaigns.count(name)) return Status(StatusCode::kNotFound, "no campaign '" + name + "'", "name");
    return run_reply;
  }
  Result<nlohmann::json> PutSchedule(const std::string& name, const nlohmann::json& body) override {
    if (!schedule_refusal.ok()) return schedule_refusal;
    auto it = campaigns.find(name);
    if (it == campaigns.end()) return Status(StatusCode::kNotFound, "no campaign '" + name + "'", "name");
    nlohmann::json schedule = {{"cron", body["cron"]}, {"scale", body.value("scale", "paper")}, {"next_due", 1.8e9}};
    it->second["schedule"] = schedule;
    schedule["campaign"] = name;
    return schedule;
  }
  Status DeleteSchedule(const std::string& name) override {
    auto it = campaigns.find(name);
    if (it == campaigns.end() || it->second.value("schedule", nlohmann::json()).is_null()) {
      return Status(StatusCode::kNotFound, "'" + name + "' has no schedule", "schedule");
    }
    it->second["schedule"] = nullptr;
    return Status::Ok();
  }
};

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_FAKE_CLIENT_TEST_UTIL_H_
