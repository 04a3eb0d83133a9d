-- sandswim schema, migration 10: full-bed snapshots of a run (the paper's Fig. 5; core/deck.h,
-- core/snapshot.h).
--   runs.snapshots   the fractions of the run's length it takes snapshots at, as a JSON array
--                    ([0, 0.5, 1]); NULL: none. Its deck states them, so they are in its key.
--   snapshots        one row per snapshot a done run handed in; the file is
--                    DATA_DIR/snapshots/run-<run_id>/<idx>.dump (every atom: id type x y z vx vy
--                    vz radius), written when the worker uploaded it and recorded here, with its
--                    checksum, in the transaction that records the run's result.
ALTER TABLE runs ADD COLUMN snapshots TEXT;
CREATE TABLE snapshots (
  run_id   INTEGER NOT NULL REFERENCES runs(id),
  idx      INTEGER NOT NULL,  -- 0 .. n-1, in the order of the fractions
  fraction REAL    NOT NULL,  -- asked: 0 the run's start, 1 its end
  t_s      REAL    NOT NULL,  -- the frame's physical time
  step     INTEGER NOT NULL,
  grains   INTEGER NOT NULL,
  bytes    INTEGER NOT NULL,
  sha256   TEXT    NOT NULL,
  PRIMARY KEY (run_id, idx)
);
