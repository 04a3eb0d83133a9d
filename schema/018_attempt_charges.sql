-- sandswim schema, migration 18: an adaptive campaign run's budget is a hard limit on what its
-- attempts spent (issue 31; server/jobs/rounds.h, server/store/rounds.h).
--
-- leases.closed_at, leases.sim_time_s: when a lease closed (completed, failed, expired, handed
-- back, taken back unreceived) and the simulated time its attempt had reached then (a run: its
-- result's on completion, else its last heartbeat's; NULL: a bed, no heartbeat, or closed before
-- this migration). Recorded by the lease queue in the transaction that closes the lease, before a
-- retry clears the run's progress, so every attempt of a retried run keeps what it spent.
ALTER TABLE leases ADD COLUMN closed_at REAL;
ALTER TABLE leases ADD COLUMN sim_time_s REAL;

-- The ledger charges each closed lease (attempt) of a campaign run's runs and beds once, by its
-- token. Rows from before this migration were charged per ending (lease_token NULL) and stay as
-- they were: a lease granted before such a look (campaign_run_charges.charged_at) is counted as
-- charged by it (a look waits for every run and bed of the campaign run, so each lease granted
-- before it had closed; the earlier attempts of a retried run that the old rule left out stay out).
CREATE TABLE campaign_run_charges_018 (
  campaign_run_id INTEGER NOT NULL REFERENCES campaign_runs (id),
  kind            TEXT NOT NULL CHECK (kind IN ('run', 'bed')),
  job_id          INTEGER NOT NULL,        -- runs.id or beds.id
  lease_token     TEXT,                    -- the attempt charged (leases.token); NULL: charged per ending (before 18)
  ended_at        REAL NOT NULL,           -- the lease's closed_at (per ending: the job's finished_at)
  state           TEXT NOT NULL,           -- the lease's outcome: done | failed | queued | cancelled | expired |
                                           -- released | unreceived (per ending: the job's state)
  sim_time_s      REAL,                    -- runs: the simulated time charged; beds: NULL
  priced_by       TEXT NOT NULL,           -- how: 'result', 'heartbeat', 'planned length', 'never ran', 'bed',
                                           -- 'leased before' (granted before the campaign run: 0),
                                           -- 'stored before' (per ending, before 18)
  core_h          REAL NOT NULL,           -- at the rates of the round it ran in (campaign_rounds.*_s_per_unit)
  round           INTEGER NOT NULL,        -- the round whose look charged it
  charged_at      REAL NOT NULL
);
INSERT INTO campaign_run_charges_018 (campaign_run_id, kind, job_id, lease_token, ended_at, state, sim_time_s,
                                      priced_by, core_h, round, charged_at)
  SELECT campaign_run_id, kind, job_id, NULL, ended_at, state, sim_time_s, priced_by, core_h, round, charged_at
  FROM campaign_run_charges;
DROP TABLE campaign_run_charges;
ALTER TABLE campaign_run_charges_018 RENAME TO campaign_run_charges;
CREATE UNIQUE INDEX campaign_run_charges_by_lease ON campaign_run_charges (campaign_run_id, lease_token)
  WHERE lease_token IS NOT NULL;
CREATE UNIQUE INDEX campaign_run_charges_by_ending ON campaign_run_charges (campaign_run_id, kind, job_id, ended_at)
  WHERE lease_token IS NULL;

-- The cost model's rates a round was planned at (core/cost.h EngineRate::s_per_unit: drive runs
-- per particle-step, beds per grain); its attempts are charged at the same rates, so that planned
-- and charged compare like with like. NULL (rounds planned before 18): charged at the rates of
-- the look.
ALTER TABLE campaign_rounds ADD COLUMN run_s_per_unit REAL;
ALTER TABLE campaign_rounds ADD COLUMN bed_s_per_unit REAL;

-- The deciding look's verdict, as GET .../claims showed it then (core/claims.h ClaimVerdictToJson):
-- what decided the claim, whatever a later rules version or a re-read says. NULL: frozen before 18.
ALTER TABLE campaign_run_verdicts ADD COLUMN decided_by TEXT;

-- A job's leases, for the ledger's look (every closed lease of a campaign run's runs and beds).
CREATE INDEX leases_by_job ON leases (kind, job_id);
