// FakeClient: an in-memory DaemonClient for tests (the header of cli_tests only). Sweeps, runs and
// campaign runs are plain JSON the test sets; unknown ids answer kNotFound like the daemon.
#ifndef SANDSWIM_CLI_FAKE_CLIENT_TEST_UTIL_H_
#define SANDSWIM_CLI_FAKE_CLIENT_TEST_UTIL_H_

#include <map>
#include <string>

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
    auto it = sweeps.find(id);
    if (it == sweeps.end()) return Status::NotFound("no sweep " + std::to_string(id));
    return it->second;
  }
  Result<nlohmann::json> SweepResults(int64_t id) override {
    return nlohmann::json{{"id", id}, {"results", nlohmann::json::array()}};
  }
  Result<nlohmann::json> CancelSweep(int64_t id) override { return GetSweep(id); }
  Result<nlohmann::json> ListRuns(const RunQuery& query) override {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& r : runs) {
      if (query.state && r.value("state", "") != *query.state) continue;
      out.push_back(r);
    }
    return out;
  }
  Result<nlohmann::json> GetRun(int64_t id) override {
    for (const auto& r : runs) {
      if (r.value("id", int64_t{0}) == id) return r;
    }
    return Status::NotFound("no run " + std::to_string(id));
  }
  Result<nlohmann::json> GetCampaignRun(int64_t id) override {
    auto it = campaign_runs.find(id);
    if (it == campaign_runs.end()) return Status::NotFound("no campaign run " + std::to_string(id));
    return it->second;
  }
  Result<nlohmann::json> CampaignRunResults(int64_t id) override {
    return nlohmann::json{{"id", id}, {"results", nlohmann::json::array()}};
  }
  Result<nlohmann::json> CampaignRunClaims(int64_t id) override {
    auto it = claims.find(id);
    if (it == claims.end()) return Status::NotFound("no campaign run " + std::to_string(id));
    return it->second;
  }
};

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_FAKE_CLIENT_TEST_UTIL_H_
