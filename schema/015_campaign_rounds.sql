-- sandswim schema, migration 15: campaigns run in rounds (issue 31; core/adaptive.h,
-- server/jobs/rounds.h, server/store/rounds.h). An adaptive campaign run (its recorded definition
-- has "adaptive") runs round 1 as submitted; after each round the daemon looks at the claims,
-- freezes those decided and plans the next round, or stops and says why. Each round is one row;
-- the runs a round adds are ordinary runs (by content key) in the campaign run's sweeps.

-- One row per round of a campaign run, written when the round is planned; finished_at,
-- core_h_spent and verdicts_after when the look after it is taken (in the same transaction that
-- plans the next round or stops). A campaign run has stopped when one of its rounds has a
-- stop_reason (the last one).
CREATE TABLE campaign_rounds (
  campaign_run_id INTEGER NOT NULL REFERENCES campaign_runs (id),
  round           INTEGER NOT NULL CHECK (round >= 1),
  planned_at      REAL NOT NULL,
  finished_at     REAL,                    -- the look after it; NULL: its runs are not all finished
  core_h_planned  REAL NOT NULL,           -- at most: its runs at their longest, its new beds
  core_h_spent    REAL,                    -- as its runs ran (the cost model's rates at the look)
  actions         TEXT NOT NULL,           -- JSON: [{"kind","claim","reason","core_h","gain","draws","runs":[...]}]
  verdicts_after  TEXT,                    -- JSON: [{"claim","verdict","frozen_at"?}] at the look after it
  stop_reason     TEXT,                    -- why no round follows it; NULL: one does (or its look is to come)
  PRIMARY KEY (campaign_run_id, round)
);

-- A claim's verdict frozen at the first look that decided it (core/adaptive.h FreezeDecisions):
-- never looked at again, whatever later rounds add.
CREATE TABLE campaign_run_verdicts (
  campaign_run_id INTEGER NOT NULL REFERENCES campaign_runs (id),
  claim           TEXT NOT NULL,
  verdict         TEXT NOT NULL CHECK (verdict IN ('holds', 'differs')),
  round           INTEGER NOT NULL,        -- the round whose look decided it
  frozen_at       REAL NOT NULL,
  PRIMARY KEY (campaign_run_id, claim)
);
