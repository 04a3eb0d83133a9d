-- sandswim schema, migration 2: nightly campaign reruns (server/scheduler.h) and their drift
-- reports (server/drift_report.h). Times are seconds since the Unix epoch (REAL).

-- Campaigns the daemon reruns on their schedule. One row per campaign: campaign_runs is unique
-- per (campaign, due_time), so a campaign is scheduled at one scale. A row survives restarts:
-- first_seen_at is when scheduling began, so a due time missed while the daemon was down is
-- still found (and run once) at the next start.
CREATE TABLE campaign_schedules (
  campaign      TEXT PRIMARY KEY,
  scale         TEXT NOT NULL,
  cron          TEXT NOT NULL,                  -- the campaign's schedule when registered
  enabled       INTEGER NOT NULL DEFAULT 1,
  first_seen_at REAL NOT NULL,                  -- no due time at or before this is run
  updated_at    REAL NOT NULL
);

-- One drift report per finished campaign run: per point, U_z now vs the previous report of the
-- same campaign and scale. The report keeps the U_z values it saw, because a forced rerun
-- replaces the result row of a run it shares with earlier campaign runs.
CREATE TABLE drift_reports (
  campaign_run_id          INTEGER PRIMARY KEY REFERENCES campaign_runs (id),
  campaign                 TEXT NOT NULL,
  scale                    TEXT NOT NULL,
  previous_campaign_run_id INTEGER REFERENCES campaign_runs (id),
  tolerance_mps            REAL NOT NULL,
  points                   INTEGER NOT NULL,
  reused                   INTEGER NOT NULL,
  ran                      INTEGER NOT NULL,
  missing                  INTEGER NOT NULL,  -- failed or cancelled: no U_z this time
  drifted                  INTEGER NOT NULL,
  report                   TEXT NOT NULL,     -- JSON DriftReport
  created_at               REAL NOT NULL
);
CREATE INDEX drift_reports_by_campaign ON drift_reports (campaign, scale, campaign_run_id);
