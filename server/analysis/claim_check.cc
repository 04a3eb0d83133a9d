#include "server/analysis/claim_check.h"

#include <algorithm>
#include <map>
#include <set>
#include <utility>

#include "core/job_state.h"
#include "server/store/campaigns.h"

namespace sandswim {
namespace {

// The claims of the campaign a run belongs to, and where they come from: the definition the run
// recorded (schema/013: what it ran, whatever the campaign became since) when it states claims;
// else, for a campaign run made before definitions were recorded or of a built-in campaign recorded
// before its file stated claims, the campaign's catalogue entry by name.
Status FindClaims(Store& store, const CampaignRunInfo& run, CampaignRunClaims& out, std::vector<Claim>& claims,
                  nlohmann::json& definition) {
  const std::string& campaign = run.campaign;
  if (run.definition.is_object() &&
      (run.definition.contains("claims") || !BuiltinCampaign(campaign).ok())) {
    Result<Campaign> recorded = ParseCampaign(run.definition);
    if (recorded.ok()) {
      claims = recorded->claims;
      definition = run.definition;
      out.claims_source = run.campaign_version.value_or(0) > 0 ? "stored" : "builtin";
      if (claims.empty()) {
        out.claims_source = "none";
        out.note = "the definition this run recorded states no claims";
      }
      return Status::Ok();
    }
    out.note = "the definition this run recorded no longer parses (" + recorded.status().ToString() +
               "): the claims are the campaign's current ones";
  }
  Result<CatalogueEntry> entry = FindCampaign(store, campaign);
  if (!entry.ok()) {
    if (entry.status().code() != StatusCode::kNotFound) return entry.status();
    out.claims_source = "none";
    out.note = "the campaign '" + campaign + "' is no longer known: it states no claims";
    return Status::Ok();
  }
  claims = entry->campaign.claims;
  definition = entry->definition;
  out.claims_source = entry->stored ? "stored" : "builtin";
  if (entry->stored && !entry->definition.contains("claims")) {
    // A built-in campaign recorded when first submitted, before its file stated claims.
    Result<Campaign> builtin = BuiltinCampaign(campaign);
    if (builtin.ok() && !builtin->claims.empty()) {
      claims = builtin->claims;
      out.claims_source = "builtin";
      out.note = "the stored definition of '" + campaign +
                 "' predates claims: they are the built-in campaign file's, whose sweeps bear the same names";
    }
  }
  if (claims.empty()) {
    out.claims_source = "none";
    if (out.note.empty()) out.note = "the campaign '" + campaign + "' states no claims";
  }
  return Status::Ok();
}

// The last error of each failed run of a sweep, "kind: message".
Result<std::map<int64_t, std::string>> FailuresOf(Store& store, int64_t sweep_id) {
  std::map<int64_t, std::string> out;
  RunFilter filter;
  filter.sweep_id = sweep_id;
  filter.state = JobState::kFailed;
  filter.limit = 1000;
  while (true) {
    Result<RunPage> page = store.ListRuns(filter);
    if (!page.ok()) return page.status();
    for (const RunSummary& r : page->runs)
      out[r.id] = r.last_error ? r.last_error->kind + ": " + r.last_error->message : std::string();
    if (!page->next_cursor) break;
    filter.after_id = *page->next_cursor;
  }
  return out;
}

}  // namespace

ClaimSweep ClaimSweepOf(const SweepAnalysis& analysis, const std::vector<ResultRow>& rows,
                        const std::map<int64_t, std::string>& failures) {
  ClaimSweep sweep;
  sweep.name = analysis.info.name;
  sweep.samples = analysis.samples;
  sweep.fits = analysis.fits;
  for (const ResultRow& row : rows) {
    ClaimRun run;
    run.run_id = row.run_id;
    run.point = row.point;
    run.replicate = row.replicate;
    run.state = row.state;
    // A requeued run's old result is not its result.
    if (row.state == JobState::kDone && row.result) run.result = row.result->result;
    if (auto f = failures.find(row.run_id); f != failures.end()) run.failure = f->second;
    sweep.runs.push_back(std::move(run));
  }
  return sweep;
}

Result<CampaignRunClaims> CheckClaims(Store& store, int64_t campaign_run_id) {
  Result<CampaignRunInfo> info = store.GetCampaignRun(campaign_run_id);
  if (!info.ok()) return info.status();
  Result<std::vector<SweepAnalysis>> analyses = AnalyzeCampaignRun(store, *info);
  if (!analyses.ok()) return analyses.status();
  return CheckClaims(store, *info, *analyses);
}

namespace {

// The runs and beds of a campaign run's analysed sweeps as the claims read them.
Result<ClaimInput> InputOf(Store& store, const CampaignRunInfo& campaign_run,
                           const std::vector<SweepAnalysis>& analyses) {
  ClaimInput input;
  input.scale = campaign_run.scale;
  std::set<int64_t> bed_ids;
  for (const SweepAnalysis& a : analyses) {
    Result<std::vector<ResultRow>> rows = store.SweepResults(a.info.id);
    if (!rows.ok()) return rows.status();
    Result<std::map<int64_t, std::string>> failures = FailuresOf(store, a.info.id);
    if (!failures.ok()) return failures.status();
    for (const ResultRow& row : *rows) bed_ids.insert(row.bed_id);
    input.sweeps.push_back(ClaimSweepOf(a, *rows, *failures));
  }
  for (int64_t id : bed_ids) {
    Result<BedView> bed = store.GetBed(id);
    if (!bed.ok()) return bed.status();
    ClaimBed b;
    b.id = bed->id;
    b.replicate = bed->replicate;
    b.state = bed->state;
    if (bed->state == JobState::kDone && bed->result) {
      b.grains = bed->result->grains;
      b.bed_height = bed->result->bed_height;
    }
    input.beds.push_back(b);
  }
  return input;
}

}  // namespace

Result<ClaimLook> LookAtClaims(Store& store, const CampaignRunInfo& campaign_run) {
  ClaimLook look;
  CampaignRunClaims out;
  nlohmann::json definition;
  SANDSWIM_RETURN_IF_ERROR(FindClaims(store, campaign_run, out, look.claims, definition));
  if (look.claims.empty()) return look;
  Result<std::vector<SweepAnalysis>> analyses = AnalyzeCampaignRun(store, campaign_run);
  if (!analyses.ok()) return analyses.status();
  Result<ClaimInput> input = InputOf(store, campaign_run, *analyses);
  if (!input.ok()) return input.status();
  look.input = std::move(input).value();
  return look;
}

Result<CampaignRunClaims> CheckClaims(Store& store, const CampaignRunInfo& campaign_run,
                                      const std::vector<SweepAnalysis>& analyses) {
  CampaignRunClaims out;
  out.campaign_run = campaign_run;
  std::vector<Claim> claims;
  nlohmann::json definition;
  SANDSWIM_RETURN_IF_ERROR(FindClaims(store, campaign_run, out, claims, definition));
  out.adaptive = rounds::RunsInRounds(campaign_run);
  if (claims.empty()) return out;
  Result<ClaimInput> found = InputOf(store, campaign_run, analyses);
  if (!found.ok()) return found.status();
  const ClaimInput& input = *found;
  out.verdicts = EvaluateClaims(claims, input);
  out.design = DesignOf(campaign_run.campaign, definition, claims, input);
  if (!out.adaptive) {
    AttachClaimRates(out.verdicts, out.design);
    out.design_text = DescribeDesign(out.design);
    return out;
  }
  // An adaptive run's verdicts come from a sequence of looks, at beds that vary by point: the
  // single-look tables (keyed by the same definition and K) are not its rates.
  Result<std::vector<rounds::RoundRow>> rows = rounds::ListRounds(store, campaign_run.id);
  if (!rows.ok()) return rows.status();
  out.rounds_so_far = RoundsSoFarOf(*rows);
  out.design_text = DescribeAdaptiveDesign(out.design, input, out.rounds_so_far);
  AttachAdaptiveRates(out.verdicts, out.design_text);
  Result<std::map<std::string, rounds::FrozenVerdict>> frozen = rounds::FrozenVerdicts(store, campaign_run.id);
  if (!frozen.ok()) return frozen.status();
  out.frozen = std::move(frozen).value();
  out.current = ShowFrozenVerdicts(out.verdicts, out.frozen, out.rounds_so_far);
  return out;
}

RoundsSoFar RoundsSoFarOf(const std::vector<rounds::RoundRow>& rows) {
  RoundsSoFar so_far;
  // Round 1 is what was submitted: before its row is written (at the first look), it is running.
  if (rows.empty()) {
    so_far.rounds = 1;
    so_far.next_look = 1;
    return so_far;
  }
  so_far.rounds = rows.back().round;
  if (rows.back().stop_reason) {
    so_far.stopped_after = rows.back().round;
  } else {
    so_far.next_look = rows.back().finished_at ? rows.back().round + 1 : rows.back().round;
  }
  return so_far;
}

std::string DescribeAdaptiveDesign(const DesignKey& key, const ClaimInput& input, const RoundsSoFar& so_far) {
  // Beds a point ran on, by sweep and point as the claims name it.
  std::map<std::pair<std::string, std::string>, std::set<int>> beds;
  for (const ClaimSweep& s : input.sweeps)
    for (const ClaimRun& r : s.runs) beds[{s.name, DescribeClaimPoint(r.point)}].insert(r.replicate);
  size_t fewest = 0, most = 0;
  for (const auto& [point, b] : beds) {
    fewest = fewest == 0 ? b.size() : std::min(fewest, b.size());
    most = std::max(most, b.size());
  }
  std::string text = key.campaign + " at " + key.scale + ", adaptive: in rounds (" + std::to_string(so_far.rounds) +
                     (so_far.rounds == 1 ? " round" : " rounds") + " so far), beds vary by point (";
  text += fewest == most ? std::to_string(most) + (most == 1 ? " bed a point so far" : " beds a point so far")
                         : std::to_string(fewest) + " to " + std::to_string(most) + " beds a point";
  return text + "), rules " + std::to_string(key.rules_version) + ", analysis " + std::to_string(key.analysis_version);
}

ClaimRates AdaptiveClaimRates(const std::string& design_text) {
  ClaimRates r;
  r.calibrated = false;
  r.design = design_text;
  r.text = kAdaptiveRatesText;
  return r;
}

void AttachAdaptiveRates(std::vector<ClaimVerdict>& verdicts, const std::string& design_text) {
  const ClaimRates rates = AdaptiveClaimRates(design_text);
  for (ClaimVerdict& v : verdicts) {
    v.rates = rates;
    for (ClaimPart& p : v.parts) p.rates = rates;
  }
}

namespace {

// "with all 3 rounds' runs" ("with round 1's runs" for one).
std::string WithRoundsRuns(int rounds) {
  return rounds <= 1 ? "with round 1's runs" : "with all " + std::to_string(rounds) + " rounds' runs";
}

}  // namespace

std::map<std::string, Verdict> ShowFrozenVerdicts(std::vector<ClaimVerdict>& verdicts,
                                                  const std::map<std::string, rounds::FrozenVerdict>& frozen,
                                                  const RoundsSoFar& so_far) {
  std::map<std::string, Verdict> current;
  for (ClaimVerdict& v : verdicts) {
    current[v.claim.id] = v.verdict;
    const std::string reads = VerdictName(v.verdict);
    auto it = frozen.find(v.claim.id);
    if (it == frozen.end()) {
      // Open: only a look decides, so a decision read between looks is not one yet.
      if (v.verdict == Verdict::kInconclusive) continue;
      v.verdict = Verdict::kInconclusive;
      const std::string when =
          so_far.next_look ? "only the look after a round decides (the next look: after round " +
                                 std::to_string(*so_far.next_look) + ")"
                           : "only the look after a round decides, and none is to come (the rounds stopped after "
                             "round " + std::to_string(so_far.stopped_after) + ")";
      v.reason = "reads " + reads + " with the runs so far; " + when + ": " + v.reason;
      continue;
    }
    const rounds::FrozenVerdict& f = it->second;
    const std::string look = "the look after round " + std::to_string(f.round);
    if (v.verdict == f.verdict) {
      v.reason = std::string(VerdictName(f.verdict)) + " since " + look +
                 " (frozen there); what follows is the current evaluation " + WithRoundsRuns(so_far.rounds) +
                 ", not the numbers of that look: " + v.reason;
      continue;
    }
    // A later evaluation reads it otherwise: its numbers are not the decision's, so none are shown.
    v.verdict = f.verdict;
    v.reason = std::string("decided (") + VerdictName(f.verdict) + ") at " + look + " and frozen there; " +
               WithRoundsRuns(so_far.rounds) + " it now reads " + reads +
               ", which does not count (frozen): a decided claim is not judged again with later rounds' runs, so "
               "that the procedure's error rates hold for the whole sequence of looks." +
               (f.decided_by.is_null() ? std::string(" The numbers of that look were not kept (frozen before they were)")
                                       : std::string(" What that look read is in decided_by"));
    v.parts.clear();
    v.missing.clear();
  }
  return current;
}

std::string FrozenVerdictText(const ClaimVerdict& v, const std::map<std::string, rounds::FrozenVerdict>& frozen) {
  auto it = frozen.find(v.claim.id);
  if (it == frozen.end()) return VerdictAtScale(v);
  return VerdictAtScale(v) + " (frozen at round " + std::to_string(it->second.round) + ")";
}

DesignKey DesignOf(const std::string& campaign, const nlohmann::json& definition, const std::vector<Claim>& claims,
                   const ClaimInput& input) {
  DesignKey key;
  key.campaign = campaign;
  key.definition_hash = CampaignDefinitionHash(definition, claims);
  key.scale = input.scale;
  // K: the beds the campaign run's points ran on (a point runs on every replicate bed).
  int beds = 1;
  for (const ClaimSweep& s : input.sweeps)
    for (const ClaimRun& r : s.runs) beds = std::max(beds, r.replicate + 1);
  key.beds = beds;
  key.bed_sd_rel = BedPriorOf(key.scale);
  return key;
}

nlohmann::json CampaignRunClaimsToJson(const CampaignRunClaims& c) {
  nlohmann::json claims = nlohmann::json::array();
  for (const ClaimVerdict& v : c.verdicts) {
    nlohmann::json j = ClaimVerdictToJson(v);
    if (c.adaptive) {
      auto it = c.frozen.find(v.claim.id);
      j["frozen_at_round"] = it == c.frozen.end() ? nlohmann::json(nullptr) : nlohmann::json(it->second.round);
      j["frozen_at"] = it == c.frozen.end() ? nlohmann::json(nullptr) : nlohmann::json(it->second.frozen_at);
      // The deciding look's own verdict (its parts and numbers), as stored when it froze the claim.
      j["decided_by"] = it == c.frozen.end() ? nlohmann::json(nullptr) : it->second.decided_by;
      j["verdict_text"] = FrozenVerdictText(v, c.frozen);
      auto now = c.current.find(v.claim.id);
      j["current_verdict"] = now == c.current.end() ? nlohmann::json(nullptr) : nlohmann::json(VerdictName(now->second));
    }
    claims.push_back(std::move(j));
  }
  const VerdictCounts n = CountVerdicts(c.verdicts);
  nlohmann::json design = DesignKeyToJson(c.design);
  if (c.adaptive) design["adaptive"] = true;
  const nlohmann::json counts = {{"holds", n.holds}, {"differs", n.differs}, {"inconclusive", n.inconclusive}};
  return {{"campaign_run_id", c.campaign_run.id},
          {"campaign", c.campaign_run.campaign},
          {"scale", c.campaign_run.scale},
          {"claims_source", c.claims_source},
          {"note", c.note},
          {"adaptive", c.adaptive},
          {"counts", counts},
          {"design", design},
          {"design_text", c.design_text.empty() ? DescribeDesign(c.design) : c.design_text},
          {"claims", claims}};
}

}  // namespace sandswim
