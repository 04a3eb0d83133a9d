-- sandswim schema, migration 16: what an adaptive campaign run has spent is a ledger that only
-- grows (issue 31; server/jobs/rounds.h, server/store/rounds.h). At each look the daemon charges
-- every run and bed of the campaign run that ended since the last look and was not charged yet;
-- the budget left is the campaign's budget less the sum of its charges. A run that a longer one
-- replaces, or that failed, stays charged: its row is never deleted.

-- One row per ended attempt charged: a run is charged when it ends done (its simulated time),
-- failed or cancelled (the simulated time it reached); a bed when it is prepared. A run queued
-- again and ended again has a new finished_at, so it is charged again; the same ending never twice.
CREATE TABLE campaign_run_charges (
  campaign_run_id INTEGER NOT NULL REFERENCES campaign_runs (id),
  kind            TEXT NOT NULL CHECK (kind IN ('run', 'bed')),
  job_id          INTEGER NOT NULL,        -- runs.id or beds.id
  ended_at        REAL NOT NULL,           -- the job's finished_at when it was charged
  state           TEXT NOT NULL,           -- done | failed | cancelled
  sim_time_s      REAL,                    -- runs: the simulated time charged; beds: NULL
  priced_by       TEXT NOT NULL,           -- how: 'result', 'heartbeat', 'planned length', 'never ran', 'bed'
  core_h          REAL NOT NULL,           -- at the cost model's rates at the look
  round           INTEGER NOT NULL,        -- the round whose look charged it
  charged_at      REAL NOT NULL,
  PRIMARY KEY (campaign_run_id, kind, job_id, ended_at)
);
