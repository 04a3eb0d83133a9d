-- sandswim schema, migration 3: what a 100,000-run sweep needs to stay cheap (figures
-- in tests/bench/bench_daemon.cc).

-- 1. A sweep's run counts by state, one row per sweep, so GET /api/v1/sweeps/{id} reads one row
--    instead of joining every membership row to its run. A new sweep's row comes from the trigger
--    on sweeps; every change of a run's state is counted by the trigger on runs, which runs
--    inside the statement that changes it, hence in the same transaction. Membership rows
--    (sweep_runs) are written only by a submission, which recounts each of its new sweeps from
--    those rows in its own transaction (server/submission.cc): a trigger per membership row cost
--    about 1 s for 100,000 rows. Nothing deletes membership rows. So the counts never disagree
--    with the runs.
CREATE TABLE sweep_counts (
  sweep_id  INTEGER PRIMARY KEY REFERENCES sweeps (id),
  queued    INTEGER NOT NULL DEFAULT 0,
  running   INTEGER NOT NULL DEFAULT 0,
  done      INTEGER NOT NULL DEFAULT 0,
  failed    INTEGER NOT NULL DEFAULT 0,
  cancelled INTEGER NOT NULL DEFAULT 0
);

INSERT INTO sweep_counts (sweep_id, queued, running, done, failed, cancelled)
  SELECT s.id,
         COALESCE(SUM(r.state = 'queued'), 0), COALESCE(SUM(r.state = 'running'), 0),
         COALESCE(SUM(r.state = 'done'), 0), COALESCE(SUM(r.state = 'failed'), 0),
         COALESCE(SUM(r.state = 'cancelled'), 0)
  FROM sweeps s LEFT JOIN sweep_runs sr ON sr.sweep_id = s.id LEFT JOIN runs r ON r.id = sr.run_id
  GROUP BY s.id;

CREATE TRIGGER sweep_counts_new_sweep AFTER INSERT ON sweeps BEGIN
  INSERT INTO sweep_counts (sweep_id) VALUES (NEW.id);
END;

CREATE TRIGGER sweep_counts_run_state AFTER UPDATE OF state ON runs
WHEN OLD.state IS NOT NEW.state BEGIN
  UPDATE sweep_counts SET
    queued = queued + (NEW.state = 'queued') - (OLD.state = 'queued'),
    running = running + (NEW.state = 'running') - (OLD.state = 'running'),
    done = done + (NEW.state = 'done') - (OLD.state = 'done'),
    failed = failed + (NEW.state = 'failed') - (OLD.state = 'failed'),
    cancelled = cancelled + (NEW.state = 'cancelled') - (OLD.state = 'cancelled')
  WHERE sweep_id IN (SELECT sweep_id FROM sweep_runs WHERE run_id = NEW.id);
END;

-- 2. Run decks are no longer stored at submission (100,000 decks were ~365 MB): a run's deck is
--    RenderDriveDeck(point, bed's scale), rendered again when it is leased or read, and checked
--    against the run's key (RunKey(deck, bed key, engine version)), which needs the engine
--    version the bed's key was made with. Runs submitted before this migration keep their
--    run_decks row, which is used as it is.
ALTER TABLE beds ADD COLUMN engine_version TEXT;
