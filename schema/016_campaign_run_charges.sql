-- sandswim schema, migration 16: what an adaptive campaign run has spent is a ledger that only
-- grows (issue 31; server/jobs/rounds.h, server/store/rounds.h). At each look the daemon charges
-- every run and bed of the campaign run that ended since the last look and was not charged yet;
-- the budget left is the campaign's budget less the sum of its charges. A run that a longer one
-- replaces, or that failed, stays charged: its row is never deleted.

-- One row per ended attempt charged: a run is charged when it ends done (its simulated time),
-- failed or cancelled (the simulated time it reached); a bed when it is prepared. A run queued
-- again and ended again has a new finished_at, so it is charged again; the same ending never twice.
-- A run or bed that had ended before the campaign run was submitted (reused by its key, as a
-- nightly rerun reuses unchanged runs) is recorded at 0 core-h: it cost this campaign run nothing.
CREATE TABLE campaign_run_charges (
  campaign_run_id INTEGER NOT NULL REFERENCES campaign_runs (id),
  kind            TEXT NOT NULL CHECK (kind IN ('run', 'bed')),
  job_id          INTEGER NOT NULL,        -- runs.id or beds.id
  ended_at        REAL NOT NULL,           -- the job's finished_at when it was charged
  state           TEXT NOT NULL,           -- done | failed | cancelled
  sim_time_s      REAL,                    -- runs: the simulated time charged; beds: NULL
  priced_by       TEXT NOT NULL,           -- how: 'result', 'heartbeat', 'planned length', 'never ran', 'bed',
                                           -- 'stored before' (ended before the campaign run: 0)
  core_h          REAL NOT NULL,           -- at the cost model's rates at the look
  round           INTEGER NOT NULL,        -- the round whose look charged it
  charged_at      REAL NOT NULL,
  PRIMARY KEY (campaign_run_id, kind, job_id, ended_at)
);

-- A longer run that took a point's place on a bed in the campaign run's sweeps (a round's
-- "longer" action): the run it replaced, and where. At the look after its round the replacement
-- is settled: done, it stands ('replaced'); failed or cancelled, the point's earlier run goes back
-- to its place and the failed one leaves the sweep ('restored'), so a failed longer run never
-- costs the point its measurement. Both runs stay in the campaign run's ledger.
CREATE TABLE campaign_run_replacements (
  campaign_run_id INTEGER NOT NULL REFERENCES campaign_runs (id),
  round           INTEGER NOT NULL,        -- the round that ordered the longer run
  sweep_id        INTEGER NOT NULL REFERENCES sweeps (id),
  position        INTEGER NOT NULL,        -- the replaced run's position in that sweep
  old_run_id      INTEGER NOT NULL REFERENCES runs (id),
  new_run_id      INTEGER NOT NULL REFERENCES runs (id),
  outcome         TEXT CHECK (outcome IN ('replaced', 'restored')),  -- NULL: not settled yet
  settled_at      REAL,
  PRIMARY KEY (campaign_run_id, round, sweep_id, old_run_id)
);
