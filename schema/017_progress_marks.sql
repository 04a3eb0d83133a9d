-- sandswim schema, migration 17: what the ETA
-- needs to follow the machine's current share (server/store/cost_model.h).
--   run_progress    a running run's progress marks: its step at a heartbeat, at most one a
--                   kProgressMarkS (job_table.h RecordProgress), marks older than
--                   kProgressHorizonS removed as new ones come. The ETA compares the running runs'
--                   rate over the last kShareWindowS with the cost model's (core/cost.h
--                   CurrentShare). Marks from before a run's current attempt (at < runs.started_at)
--                   are not its attempt's and are not read.
--   beds.heartbeat_at  a bed's last heartbeat (runs have theirs): a running job counts as an
--                   engine only while it heartbeats (cost_model.h kLiveEngineS).
ALTER TABLE beds ADD COLUMN heartbeat_at REAL;
CREATE TABLE run_progress (
  run_id INTEGER NOT NULL REFERENCES runs (id),
  at     REAL NOT NULL,
  step   INTEGER NOT NULL,
  PRIMARY KEY (run_id, at)
) WITHOUT ROWID;
