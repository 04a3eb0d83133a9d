#include "server/jobs/scheduler.h"

#include <time.h>

#include <cstdlib>
#include <filesystem>
#include <regex>
#include <set>
#include <utility>

#include "core/scale.h"
#include "core/sweep.h"
#include "server/store/campaigns.h"
#include "server/store/schedule_table.h"
#include "server/jobs/submission.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

// What a registration needs from a campaign: its default scale and its schedule.
struct CampaignSchedule {
  std::string default_scale;
  std::optional<std::string> schedule;
};

// A registered campaign's default scale and schedule (server/store/campaigns.h).
Result<CampaignSchedule> LookUpCampaign(Store& store, const std::string& name, const std::string& field) {
  Result<CatalogueEntry> found = FindCampaign(store, name, field);
  if (!found.ok()) return found.status();
  return CampaignSchedule{found->campaign.scale, found->schedule};
}

Result<std::optional<double>> LastScheduledDue(Store& store, const std::string& campaign) {
  auto t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return schedules::LastScheduledDue(*t, campaign);
}

int CountDueIn(const CronSchedule& cron, double after, double until, CronZone zone, int cap) {
  int n = 0;
  double t = after;
  while (n < cap) {
    auto next = NextDue(cron, t, zone);
    if (!next.ok() || *next > until) break;
    ++n;
    t = *next;
  }
  return n;
}

}  // namespace

Result<ScheduleRequest> ParseScheduleFlag(const std::string& text, const std::string& field) {
  static const std::regex kName(R"([A-Za-z0-9._-]+)");
  ScheduleRequest r;
  size_t colon = text.find(':');
  r.campaign = text.substr(0, colon);
  if (r.campaign.empty() || r.campaign.size() > kMaxNameLength || !std::regex_match(r.campaign, kName)) {
    return Status::InvalidArgument(field, "\"" + text +
                                              "\" is not NAME or NAME:SCALE (a campaign name of "
                                              "[A-Za-z0-9._-], e.g. paper-58 or paper-58:smoke)");
  }
  if (colon != std::string::npos) {
    std::string scale = text.substr(colon + 1);
    if (FindScale(scale) == nullptr) {
      return Status::InvalidArgument(field, "unknown scale \"" + scale + "\" in \"" + text + "\" (paper, mini, smoke)");
    }
    r.scale = scale;
  }
  return r;
}

void to_json(json& j, const ScheduledCampaign& s) {
  j = {{"campaign", s.campaign},
       {"scale", s.scale},
       {"cron", s.cron},
       {"enabled", s.enabled},
       {"first_seen_at", s.first_seen_at},
       {"last_due", s.last_due ? json(*s.last_due) : json(nullptr)},
       {"next_due", s.next_due ? json(*s.next_due) : json(nullptr)},
       {"source", s.source}};
}

Scheduler::Scheduler(Store* store, Clock* clock, std::string engine_version, CronZone zone)
    : store_(store), clock_(clock), engine_version_(std::move(engine_version)), zone_(zone) {}

Status Scheduler::Register(const std::vector<ScheduleRequest>& requests, bool exclusive, const std::string& field) {
  struct Row {
    std::string campaign, scale, cron;
  };
  std::vector<Row> rows;
  std::set<std::string> names;
  for (const ScheduleRequest& r : requests) {
    if (!names.insert(r.campaign).second) {
      return Status::InvalidArgument(field, "campaign '" + r.campaign +
                                                "' is scheduled twice; a campaign has one "
                                                "schedule (at one scale)");
    }
    auto campaign = LookUpCampaign(*store_, r.campaign, field);
    if (!campaign.ok()) return campaign.status();
    if (!campaign->schedule) {
      // A campaign whose definition has no schedule runs by the one the API gave it.
      auto registered = Find(r.campaign);
      if (!registered.ok()) return registered.status();
      if (registered->has_value()) campaign->schedule = (*registered)->cron;
    }
    if (!campaign->schedule) {
      return Status::InvalidArgument(field, "campaign '" + r.campaign +
                                                "' has no \"schedule\"; give it one, "
                                                "e.g. \"schedule\": \"0 2 * * *\"");
    }
    auto cron = ParseCron(*campaign->schedule, field);
    if (!cron.ok()) {
      return Status::InvalidArgument(field, "campaign '" + r.campaign + "': " + cron.status().reason());
    }
    rows.push_back({r.campaign, r.scale.value_or(campaign->default_scale), cron->text});
  }

  const double now = clock_->Now();
  auto t = store_->db().Begin();
  if (!t.ok()) return t.status();
  if (exclusive) {
    Result<std::vector<std::string>> enabled = schedules::EnabledFlagCampaigns(*t);
    if (!enabled.ok()) return enabled.status();
    for (const std::string& name : *enabled) {
      if (names.count(name)) continue;
      SANDSWIM_RETURN_IF_ERROR(schedules::DisableSchedule(*t, name, now));
      SANDSWIM_RETURN_IF_ERROR(t->Event(now, "schedule.disabled", "campaign/" + name));
    }
  }
  for (const Row& r : rows) {
    // A new or re-enabled registration starts now; an enabled one keeps its first_seen_at.
    SANDSWIM_RETURN_IF_ERROR(schedules::RegisterSchedule(*t, r.campaign, r.scale, r.cron, now));
    SANDSWIM_RETURN_IF_ERROR(
        t->Event(now, "schedule.registered", "campaign/" + r.campaign, {{"scale", r.scale}, {"cron", r.cron}}));
  }
  return t->Commit();
}

Result<std::vector<ScheduledCampaign>> Scheduler::List() {
  std::vector<ScheduledCampaign> out;
  {
    auto t = store_->db().BeginRead();
    if (!t.ok()) return t.status();
    Result<std::vector<schedules::ScheduleRow>> rows = schedules::ListSchedules(*t);
    if (!rows.ok()) return rows.status();
    for (schedules::ScheduleRow& row : *rows) {
      ScheduledCampaign s;
      s.campaign = std::move(row.campaign);
      s.scale = std::move(row.scale);
      s.cron = std::move(row.cron);
      s.enabled = row.enabled;
      s.first_seen_at = row.first_seen_at;
      s.last_due = row.last_due;
      s.source = std::move(row.source);
      out.push_back(std::move(s));
    }
  }
  const double now = clock_->Now();
  for (ScheduledCampaign& s : out) {
    auto cron = ParseCron(s.cron);
    if (!cron.ok() || !s.enabled) continue;
    double from = std::max({s.first_seen_at, s.last_due.value_or(0.0), now});
    auto next = NextDue(*cron, from, zone_);
    if (next.ok()) s.next_due = *next;
  }
  return out;
}

Result<std::optional<ScheduledCampaign>> Scheduler::Find(const std::string& campaign) {
  auto all = List();
  if (!all.ok()) return all.status();
  for (ScheduledCampaign& s : *all) {
    if (s.campaign == campaign && s.enabled) return std::optional<ScheduledCampaign>(std::move(s));
  }
  return std::optional<ScheduledCampaign>();
}

Result<ScheduledCampaign> Scheduler::Put(const std::string& campaign, const std::string& cron,
                                         const std::optional<std::string>& scale) {
  auto found = LookUpCampaign(*store_, campaign, "name");
  if (!found.ok()) return found.status();
  auto parsed = ParseCron(cron, "cron");
  if (!parsed.ok()) return Status(StatusCode::kFailedPrecondition, parsed.status().reason(), "cron");
  if (scale && FindScale(*scale) == nullptr) {
    return Status(StatusCode::kFailedPrecondition, "unknown scale \"" + *scale + "\" (paper, mini, smoke)", "scale");
  }
  const std::string at = scale.value_or(found->default_scale);
  const double now = clock_->Now();
  auto t = store_->db().Begin();
  if (!t.ok()) return t.status();
  SANDSWIM_RETURN_IF_ERROR(schedules::RegisterSchedule(*t, campaign, at, parsed->text, now, "api"));
  SANDSWIM_RETURN_IF_ERROR(t->Event(now, "schedule.registered", "campaign/" + campaign,
                                    {{"scale", at}, {"cron", parsed->text}, {"source", "api"}}));
  SANDSWIM_RETURN_IF_ERROR(t->Commit());
  auto put = Find(campaign);
  if (!put.ok()) return put.status();
  if (!put->has_value()) return Status::Internal("the schedule of '" + campaign + "' was stored but is not there");
  return std::move(**put);
}

Status Scheduler::Remove(const std::string& campaign) {
  const double now = clock_->Now();
  auto t = store_->db().Begin();
  if (!t.ok()) return t.status();
  Result<bool> removed = schedules::RemoveSchedule(*t, campaign);
  if (!removed.ok()) return removed.status();
  if (!*removed) return Status(StatusCode::kNotFound, "campaign '" + campaign + "' has no schedule", "schedule");
  SANDSWIM_RETURN_IF_ERROR(t->Event(now, "schedule.removed", "campaign/" + campaign));
  return t->Commit();
}

Result<TickResult> Scheduler::Tick() {
  auto schedules = List();
  if (!schedules.ok()) return schedules.status();
  const double now = clock_->Now();
  TickResult result;
  for (const ScheduledCampaign& s : *schedules) {
    if (!s.enabled) continue;
    auto cron = ParseCron(s.cron);
    if (!cron.ok()) {
      result.errors.emplace_back(s.campaign, cron.status());
      continue;
    }
    // List() read last_due a moment ago; read it again so a Tick racing another sees its work.
    auto last_due = LastScheduledDue(*store_, s.campaign);
    if (!last_due.ok()) return last_due.status();
    const double anchor = std::max(s.first_seen_at, last_due->value_or(s.first_seen_at));
    auto due = LatestDueIn(*cron, anchor, now, zone_);
    if (!due.ok()) {
      result.errors.emplace_back(s.campaign, due.status());
      continue;
    }
    if (!due->has_value()) continue;

    SubmitRequest request;
    request.campaign = s.campaign;
    request.scale = s.scale;
    request.trigger = "schedule";
    request.due_time = **due;
    auto submitted = Submit(*store_, request, engine_version_, now);
    if (!submitted.ok()) {
      result.errors.emplace_back(s.campaign, submitted.status());
      continue;
    }
    ScheduledRerun r;
    r.campaign = s.campaign;
    r.scale = s.scale;
    r.due_time = **due;
    r.skipped = CountDueIn(*cron, anchor, **due, zone_, 100000) - 1;
    r.campaign_run_id = submitted->campaign_run_id.value_or(0);
    r.replayed = submitted->replayed;
    r.runs = submitted->runs;
    r.runs_reused = submitted->runs_reused;
    r.runs_new = submitted->runs_new;
    r.runs_requeued = submitted->runs_requeued;
    r.runs_shared = submitted->runs_shared;
    result.submitted.push_back(std::move(r));
  }
  return result;
}

std::string DescribeRerun(const ScheduledRerun& r, CronZone zone) {
  std::string line = r.campaign + "@" + r.scale + " night " + FormatWallMinute(r.due_time, zone) + ": ";
  if (r.replayed) {
    line += "already submitted as campaign run " + std::to_string(r.campaign_run_id);
  } else {
    line += "submitted campaign run " + std::to_string(r.campaign_run_id) + " (" + std::to_string(r.runs) +
            " runs: " + std::to_string(r.runs_reused) + " reused, " + std::to_string(r.runs_new + r.runs_requeued) +
            " to run, " + std::to_string(r.runs_shared) + " already in flight)";
  }
  if (r.skipped > 0) {
    line += "; " + std::to_string(r.skipped) + " earlier due time(s) missed while the daemon was down were skipped";
  }
  return line;
}

std::string LocalTimeZoneDescription(double now) {
  std::string name;
  if (const char* tz = std::getenv("TZ"); tz != nullptr && *tz != '\0') {
    name = tz[0] == ':' ? tz + 1 : tz;
  } else {
    std::error_code ec;
    std::filesystem::path target = std::filesystem::read_symlink("/etc/localtime", ec);
    std::string s = target.string();
    size_t at = s.find("zoneinfo/");
    if (!ec && at != std::string::npos) name = s.substr(at + 9);
  }
  time_t t = static_cast<time_t>(now);
  struct tm tm {};
  localtime_r(&t, &tm);
  long offset = tm.tm_gmtoff;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s, UTC%c%02ld:%02ld", tm.tm_zone ? tm.tm_zone : "?", offset < 0 ? '-' : '+',
                std::labs(offset) / 3600, (std::labs(offset) % 3600) / 60);
  return name.empty() ? std::string(buf) : name + " (" + buf + ")";
}

}  // namespace sandswim
