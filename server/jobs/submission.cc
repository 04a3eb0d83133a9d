#include "server/jobs/submission.h"

#include <algorithm>
#include <map>
#include <utility>

#include "core/adaptive.h"
#include "core/keys.h"
#include "core/scale.h"
#include "server/store/campaigns.h"
#include "server/store/job_table.h"
#include "server/store/rounds.h"
#include "server/store/submission_table.h"

namespace sandswim {
namespace {

nlohmann::json SweepToJson(const SweepSpec& s) {
  nlohmann::json axes = nlohmann::json::array();
  for (const SweepAxis& a : s.axes) axes.push_back({{"param", a.param}, {"values", a.values}});
  nlohmann::json j{{"name", s.name},
                   {"scale", s.scale},
                   {"base", PointToJson(s.base)},
                   {"axes", axes},
                   {"combine", s.combine == Combine::kZip ? "zip" : "product"}};
  if (s.precision) j["precision"] = PrecisionToJson(*s.precision);
  if (s.replicates) j["replicates"] = *s.replicates;
  if (s.snapshots) j["snapshots"] = *s.snapshots;
  if (s.numerics) j["numerics"] = NumericsToJson(*s.numerics);
  return j;
}

Status CheckIdempotencyKey(const std::string& key) {
  if (key.empty() || key.size() > 200) {
    return Status::InvalidArgument("Idempotency-Key", "must be 1 to 200 characters");
  }
  for (char c : key) {
    if (c < 0x21 || c > 0x7e) {
      return Status::InvalidArgument("Idempotency-Key", "must be printable ASCII without spaces");
    }
  }
  return Status::Ok();
}

Result<SubmitResult> ResultFromJson(const std::string& text) {
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object()) return Status::Corruption("stored submission response does not parse");
  SubmitResult r;
  try {
    r.sweep_ids = j.at("ids").get<std::vector<int64_t>>();
    if (j.contains("campaign_run_id")) r.campaign_run_id = j.at("campaign_run_id").get<int64_t>();
    r.runs = j.value("runs", int64_t{0});
    r.runs_new = j.value("runs_new", int64_t{0});
    r.runs_reused = j.value("runs_reused", int64_t{0});
    r.runs_requeued = j.value("runs_requeued", int64_t{0});
    r.runs_shared = j.value("runs_shared", int64_t{0});
    r.runs_failed_bed = j.value("runs_failed_bed", int64_t{0});
  } catch (const nlohmann::json::exception& e) {
    return Status::Corruption(std::string("stored submission response: ") + e.what());
  }
  return r;
}

}  // namespace

void to_json(nlohmann::json& j, const SubmitResult& r) {
  j = nlohmann::json{{"ids", r.sweep_ids},
                     {"replayed", r.replayed},
                     {"runs", r.runs},
                     {"runs_new", r.runs_new},
                     {"runs_reused", r.runs_reused},
                     {"runs_requeued", r.runs_requeued},
                     {"runs_shared", r.runs_shared},
                     {"runs_failed_bed", r.runs_failed_bed}};
  if (!r.sweep_ids.empty()) j["id"] = r.sweep_ids.front();
  if (r.campaign_run_id) j["campaign_run_id"] = *r.campaign_run_id;
}

Result<SubmitRequest> ParseSubmitRequest(const nlohmann::json& body) {
  if (!body.is_object()) return Status::InvalidArgument("", "the body must be a JSON object");
  SubmitRequest req;
  nlohmann::json rest = body;
  if (auto it = rest.find("force"); it != rest.end()) {
    if (!it->is_boolean()) return Status::InvalidArgument("force", "must be true or false");
    req.force = it->get<bool>();
    rest.erase(it);
  }
  if (rest.contains("campaign")) {
    for (const auto& [k, v] : rest.items()) {
      if (k != "campaign" && k != "scale") {
        return Status::InvalidArgument(k,
                                       "unknown field in a campaign submission "
                                       "(allowed: campaign, scale, force)");
      }
    }
    if (!rest["campaign"].is_string() || rest["campaign"].get<std::string>().empty()) {
      return Status::InvalidArgument("campaign", "must be a campaign name");
    }
    req.campaign = rest["campaign"].get<std::string>();
    if (rest.contains("scale")) {
      if (!rest["scale"].is_string() || FindScale(rest["scale"].get<std::string>()) == nullptr) {
        return Status::InvalidArgument("scale", "must be one of paper, mini, smoke");
      }
      req.scale = rest["scale"].get<std::string>();
    }
    return req;
  }
  if (rest.contains("sweeps")) {
    if (rest.size() != 1) {
      for (const auto& [k, v] : rest.items()) {
        if (k != "sweeps") {
          return Status::InvalidArgument(k, "unknown field (allowed: sweeps, force)");
        }
      }
    }
    const nlohmann::json& arr = rest["sweeps"];
    if (!arr.is_array() || arr.empty()) {
      return Status::InvalidArgument("sweeps", "must be a non-empty array of sweeps");
    }
    for (size_t i = 0; i < arr.size(); ++i) {
      Result<SweepSpec> s = ParseSweep(arr[i]);
      if (!s.ok()) return s.status().WithFieldPrefix("sweeps[" + std::to_string(i) + "]");
      req.sweeps.push_back(std::move(s).value());
    }
    return req;
  }
  Result<SweepSpec> s = ParseSweep(rest);
  if (!s.ok()) return s.status();
  req.sweeps.push_back(std::move(s).value());
  return req;
}

namespace {

// What can be refused before anything is planned: the request's shape.
Status CheckRequest(const SubmitRequest& req) {
  if (req.sweeps.empty() == !req.campaign.has_value()) {
    return Status::InvalidArgument("sweeps", "give either sweeps or a campaign, not both or none");
  }
  if (req.trigger != "manual" && req.trigger != "schedule") {
    return Status::InvalidArgument("trigger", "must be manual or schedule");
  }
  if (req.trigger == "schedule" && (!req.campaign || !req.due_time)) {
    return Status::InvalidArgument("due_time", "a scheduled submission is a campaign with a due time");
  }
  if (req.idempotency_key) SANDSWIM_RETURN_IF_ERROR(CheckIdempotencyKey(*req.idempotency_key));
  return Status::Ok();
}

// The request, normalised and hashed: one idempotency key must always come with one request.
std::string Fingerprint(const SubmitRequest& req, const std::vector<SweepSpec>& sweeps,
                        const std::string& campaign_scale) {
  nlohmann::json fingerprint_json{{"force", req.force}, {"trigger", req.trigger}};
  if (req.campaign) {
    fingerprint_json["campaign"] = *req.campaign;
    fingerprint_json["scale"] = campaign_scale;
  } else {
    nlohmann::json arr = nlohmann::json::array();
    for (const SweepSpec& s : sweeps) arr.push_back(SweepToJson(s));
    fingerprint_json["sweeps"] = arr;
  }
  if (req.due_time) fingerprint_json["due_time"] = *req.due_time;
  return Sha256Hex(fingerprint_json.dump());
}

// The answer an earlier submission gave when this one repeats it (the same idempotency key, or
// the same scheduled slot); kConflict for a key used before with a different request.
Result<std::optional<SubmitResult>> Replayed(Transaction& t, const SubmitRequest& req, const std::string& fingerprint) {
  using Out = std::optional<SubmitResult>;
  if (req.idempotency_key) {
    Result<std::optional<submissions::StoredSubmission>> stored =
        submissions::FindByIdempotencyKey(t, *req.idempotency_key);
    if (!stored.ok()) return stored.status();
    if (*stored) {
      if ((*stored)->fingerprint != fingerprint) {
        return Status(StatusCode::kConflict, "this Idempotency-Key was used with a different request",
                      "Idempotency-Key");
      }
      Result<SubmitResult> prior = ResultFromJson((*stored)->response);
      if (!prior.ok()) return prior.status();
      prior->replayed = true;
      return Out(std::move(prior).value());
    }
  }
  if (req.trigger == "schedule") {
    Result<std::optional<std::string>> response = submissions::ScheduledRunResponse(t, *req.campaign, *req.due_time);
    if (!response.ok()) return response.status();
    if (*response) {
      Result<SubmitResult> prior = ResultFromJson(**response);
      if (!prior.ok()) return prior.status();
      prior->replayed = true;
      return Out(std::move(prior).value());
    }
  }
  return Out();
}

// The campaign run's row, with the definition it runs: the campaign's version (0: built-in), its
// resolved definition and that definition's SHA-256, so that its claims, report and drift read
// what ran whatever the campaign becomes.
Result<int64_t> InsertCampaignRun(Transaction& t, const SubmitRequest& req, const CatalogueEntry& campaign,
                                  const std::string& campaign_scale, double now) {
  submissions::NewCampaignRun row{*req.campaign,      campaign_scale,
                                  req.trigger,         req.due_time,
                                  campaign.version,    campaign.definition.dump(),
                                  DefinitionSha256(campaign.definition)};
  Result<int64_t> inserted = submissions::InsertCampaignRun(t, row, now);
  if (!inserted.ok()) return inserted.status();
  const int64_t id = *inserted;
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, "campaign_run.created", "campaign_run/" + std::to_string(id),
                                   {{"campaign", *req.campaign},
                                    {"trigger", req.trigger},
                                    {"campaign_version", campaign.version}}));
  return id;
}

// The sweeps' rows, in request order.
Result<std::vector<int64_t>> InsertSweeps(Transaction& t, const std::vector<SweepSpec>& sweeps,
                                          std::optional<int64_t> campaign_run_id, int64_t submission_id, bool force,
                                          double now) {
  std::vector<int64_t> ids(sweeps.size());
  for (size_t i = 0; i < sweeps.size(); ++i) {
    submissions::NewSweep row{sweeps[i].name, sweeps[i].scale, SweepToJson(sweeps[i]).dump(), campaign_run_id,
                              submission_id,  force};
    Result<int64_t> id = submissions::InsertSweep(t, row, now);
    if (!id.ok()) return id.status();
    ids[i] = *id;
  }
  return ids;
}

// A bed row as a submission finds it: its id, and why it failed for good (its runs fail at once).
struct SubmittedBed {
  int64_t id = 0;
  std::optional<std::string> failed_for_good;
};

// A scale's replicate bed: one per key. A failed one is given another chance, unless it failed
// for a reason preparing it again cannot change: a bed that missed the kinetic-energy criterion
// (not_equilibrated) comes out the same from the same deck and engine (both in its key).
Result<SubmittedBed> UpsertBed(Transaction& t, const std::string& scale, const PlannedBed& bed,
                               const std::string& engine_version, double now) {
  // engine_version: what the run keys on this bed were made with, so a deck rendered again
  // at lease time can be checked against its run's key (the bed key covers it too).
  SANDSWIM_RETURN_IF_ERROR(submissions::InsertBedIfNew(t, scale, bed, engine_version, now));
  Result<submissions::BedByKey> row = submissions::FindBed(t, bed.key);
  if (!row.ok()) return row.status();
  const int64_t bed_id = row->id;
  if (row->state == JobState::kFailed && row->last_error_kind == "not_equilibrated") {
    return SubmittedBed{bed_id, "bed " + std::to_string(bed_id) + " (" + scale + ", replicate " +
                                    std::to_string(bed.replicate) + ") failed for good: " + row->last_error +
                                    " Preparing it again would give the same bed, so it is not retried. "
                                    "Other replicates (\"replicates\") pour beds from other seeds."};
  }
  if (row->state == JobState::kFailed) {
    SANDSWIM_RETURN_IF_ERROR(submissions::RequeueFailedBed(t, bed_id));
    SANDSWIM_RETURN_IF_ERROR(t.Event(now, "bed.requeued", "bed/" + std::to_string(bed_id)));
  }
  return SubmittedBed{bed_id, std::nullopt};
}

// A run whose key exists already: re-queued when it failed, was cancelled or is forced again;
// else reused (done) or shared (queued, running). Counted in `out`.
Status ReuseRun(Transaction& t, int64_t run_id, JobState state, bool force, double now, SubmitResult& out) {
  const bool requeue =
      state == JobState::kFailed || state == JobState::kCancelled || (state == JobState::kDone && force);
  if (!requeue) {
    ++(state == JobState::kDone ? out.runs_reused : out.runs_shared);
    return Status::Ok();
  }
  // The old result row (if any) stays until the new completion replaces it.
  SANDSWIM_RETURN_IF_ERROR(submissions::RequeueRun(t, run_id, now));
  SANDSWIM_RETURN_IF_ERROR(
      t.Event(now, "run.requeued", "run/" + std::to_string(run_id), {{"from", state}, {"force", force}}));
  ++out.runs_requeued;
  return Status::Ok();
}

// A scale's runs (inserted, or reused by key) and their sweeps' membership, in plan order.
// `next_position` is each sweep's next membership position.
Status WriteRuns(Transaction& t, const ScalePlan& g, const std::vector<int64_t>& bed_ids,
                 const std::map<std::string, int64_t>& id_by_name, bool force, double now,
                 std::map<int64_t, int64_t>& next_position, SubmitResult& out) {
  submissions::RunRows rows(t);  // its statements prepared once for every row (100,000 in one transaction)
  for (const PlannedRun& r : g.plan.runs) {
    Result<std::optional<int64_t>> inserted = rows.InsertIfNew(r, bed_ids.at(r.bed), now);
    if (!inserted.ok()) return inserted.status();
    int64_t run_id = 0;
    if (*inserted) {
      run_id = **inserted;
      ++out.runs_new;
    } else {
      Result<submissions::RunRows::Existing> existing = rows.Find(r.key);
      if (!existing.ok()) return existing.status();
      run_id = existing->id;
      SANDSWIM_RETURN_IF_ERROR(ReuseRun(t, run_id, existing->state, force, now, out));
    }
    ++out.runs;
    for (const std::string& name : r.sweeps) {
      auto it = id_by_name.find(name);
      if (it == id_by_name.end()) return Status::Internal("plan names unknown sweep " + name);
      SANDSWIM_RETURN_IF_ERROR(rows.AddToSweep(it->second, run_id, next_position[it->second]++));
    }
  }
  return Status::Ok();
}

// Each new sweep's counts by state (sweep_counts, schema/003_perf.sql), from its membership rows,
// in this transaction (one aggregate per sweep instead of a trigger per row), and its event.
Status FinishSweeps(Transaction& t, const std::vector<SweepSpec>& sweeps, const std::vector<int64_t>& sweep_ids,
                    std::map<int64_t, int64_t>& runs_of, double now) {
  SANDSWIM_RETURN_IF_ERROR(submissions::RecountSweeps(t, sweep_ids));
  for (size_t i = 0; i < sweeps.size(); ++i) {
    SANDSWIM_RETURN_IF_ERROR(
        t.Event(now, "sweep.submitted", "sweep/" + std::to_string(sweep_ids[i]),
                {{"name", sweeps[i].name}, {"scale", sweeps[i].scale}, {"runs", runs_of[sweep_ids[i]]}}));
  }
  return Status::Ok();
}

// The queue cap, counted after this submission's rows are written (in its transaction, so the
// count is exact and a refusal rolls everything back). A submission that queues nothing new
// (every run reused or shared) passes whatever the count.
Status CheckQueueCap(Transaction& t, int64_t cap, const SubmitResult& out) {
  const int64_t added = out.runs_new + out.runs_requeued - out.runs_failed_bed;
  if (added <= 0) return Status::Ok();
  Result<int64_t> counted = submissions::CountQueuedOrRunning(t);
  if (!counted.ok()) return counted.status();
  const int64_t queued = *counted;
  if (queued <= cap) return Status::Ok();
  return Status(StatusCode::kUnavailable,
                std::to_string(queued - added) + " runs are queued or running and this submission would add " +
                    std::to_string(added) + ", past the daemon's cap of " + std::to_string(cap) +
                    " (sandswimd --max-queued-runs): nothing was stored; submit again once runs finish, or cancel a sweep",
                "queue");
}


// One scale's plan into the store: its beds (upserted), its runs (WriteRuns), and the runs on a
// bed that failed for good failed now, saying why, rather than waiting for it for ever. A
// submission and a round of an adaptive campaign run (AddPlannedRuns) write their plans alike.
Status WritePlan(Transaction& t, const ScalePlan& g, const std::string& engine_version, bool force, double now,
                 const std::map<std::string, int64_t>& sweep_ids, std::map<int64_t, int64_t>& next_position,
                 SubmitResult& out) {
  std::vector<int64_t> bed_ids;
  std::vector<SubmittedBed> failed_beds;
  for (const PlannedBed& bed : g.plan.beds) {
    Result<SubmittedBed> b = UpsertBed(t, g.scale, bed, engine_version, now);
    if (!b.ok()) return b.status();
    bed_ids.push_back(b->id);
    if (b->failed_for_good) failed_beds.push_back(*b);
  }
  SANDSWIM_RETURN_IF_ERROR(WriteRuns(t, g, bed_ids, sweep_ids, force, now, next_position, out));
  for (const SubmittedBed& b : failed_beds) {
    Result<int64_t> n = jobs::FailRunsOfBed(t, b.id, *b.failed_for_good, now);
    if (!n.ok()) return n.status();
    out.runs_failed_bed += *n;
  }
  return Status::Ok();
}

}  // namespace

Result<SubmitResult> Submit(Store& store, const SubmitRequest& req, const std::string& engine_version, double now) {
  // ---- Everything that can be refused is decided before the transaction opens. ----
  SANDSWIM_RETURN_IF_ERROR(CheckRequest(req));
  std::vector<SweepSpec> sweeps = req.sweeps;
  std::optional<CatalogueEntry> campaign;
  std::string campaign_scale;
  if (req.campaign) {
    Result<CatalogueEntry> found = FindCampaign(store, *req.campaign);
    if (!found.ok()) return found.status();
    campaign = std::move(found).value();
    campaign_scale = req.scale.value_or(campaign->campaign.scale);
    sweeps = campaign->campaign.sweeps;
    for (SweepSpec& s : sweeps) s.scale = campaign_scale;
    // An adaptive campaign (its rounds: server/jobs/rounds.h) must afford its first round here and now.
    if (campaign->campaign.adaptive) {
      Result<AdaptiveCost> cost = rounds::AdaptiveCostNow(store, campaign_scale, now);
      if (!cost.ok()) return cost.status();
      SANDSWIM_RETURN_IF_ERROR(CheckAdaptiveBudget(campaign->campaign, campaign_scale, *cost));
    }
  }
  // Decks are hashed into keys but not kept: a run's deck is rendered again from its stored
  // point and its bed's scale when it is leased or read (RenderDriveDeck is a pure function).
  PlanOptions options;
  options.max_runs = req.max_runs;
  options.keep_decks = false;
  options.threads = 2;
  Result<std::vector<ScalePlan>> planned = PlanSubmission(sweeps, engine_version, options, req.campaign.has_value());
  if (!planned.ok()) return planned.status();
  const std::string fingerprint = Fingerprint(req, sweeps, campaign_scale);

  // ---- One transaction: all rows or none. ----
  Result<Transaction> begun = store.db().Begin();
  if (!begun.ok()) return begun.status();
  Transaction& t = *begun;
  Result<std::optional<SubmitResult>> replayed = Replayed(t, req, fingerprint);
  if (!replayed.ok()) return replayed.status();
  if (*replayed) return std::move(**replayed);

  SubmitResult out;
  Result<int64_t> submission_id = submissions::Insert(t, req.idempotency_key, fingerprint, now);
  if (!submission_id.ok()) return submission_id.status();
  if (campaign) {
    Result<int64_t> id = InsertCampaignRun(t, req, *campaign, campaign_scale, now);
    if (!id.ok()) return id.status();
    out.campaign_run_id = *id;
  }
  Result<std::vector<int64_t>> sweep_ids = InsertSweeps(t, sweeps, out.campaign_run_id, *submission_id, req.force, now);
  if (!sweep_ids.ok()) return sweep_ids.status();
  out.sweep_ids = *sweep_ids;
  std::map<std::string, int64_t> id_by_name;
  for (size_t i = 0; i < sweeps.size(); ++i) id_by_name[sweeps[i].name] = out.sweep_ids[i];

  std::map<int64_t, int64_t> next_position;
  for (const ScalePlan& g : *planned)
    SANDSWIM_RETURN_IF_ERROR(WritePlan(t, g, engine_version, req.force, now, id_by_name, next_position, out));
  SANDSWIM_RETURN_IF_ERROR(CheckQueueCap(t, req.max_queued_runs, out));
  SANDSWIM_RETURN_IF_ERROR(FinishSweeps(t, sweeps, out.sweep_ids, next_position, now));
  nlohmann::json response = out;
  SANDSWIM_RETURN_IF_ERROR(submissions::SetResponse(t, *submission_id, response.dump()));
  SANDSWIM_RETURN_IF_ERROR(t.Commit());
  return out;
}

Status AddPlannedRuns(Transaction& t, const ScalePlan& g, const std::string& engine_version, double now,
                      const std::map<std::string, int64_t>& sweep_ids, std::map<int64_t, int64_t>& next_position,
                      SubmitResult& out) {
  return WritePlan(t, g, engine_version, /*force=*/false, now, sweep_ids, next_position, out);
}

Status FinishAddedRuns(Transaction& t, const std::vector<int64_t>& sweep_ids, int64_t max_queued_runs,
                       const SubmitResult& out) {
  SANDSWIM_RETURN_IF_ERROR(CheckQueueCap(t, max_queued_runs, out));
  return submissions::RecountSweeps(t, sweep_ids);
}

}  // namespace sandswim
