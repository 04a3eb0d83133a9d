-- sandswim schema, migration 7: U_z from whole-period block rates with honest errors (analysis
-- version 2, core/trajectory.h). uz and uz_stderr become optional (a window with no whole period
-- has no U_z; one with fewer than 3 has no error), and a result says what its window held:
--   uz_ci95              half-width of the 95 % interval (Student t, uz_blocks - 1 dof)
--   uz_stderr_note       why uz_stderr is absent
--   uz_blocks, block_s,  the whole blocks the rate rests on, their length, and what they are:
--   block_kind           "period" (driven modes) or "block" (a fixed length: constant rotation)
--   window_end           why the window ends: run_end | surface | floor
--   conclusive           enough whole blocks; inconclusive results are shown but not fitted
--   inconclusive_reason  why not
--   dz_rate              dz over the whole run's duration
--   analysis             the analysis that made the row: 1 (line + sinusoid at f, the old
--                        estimator) or 2. Rows kept from before this migration are analysis 1,
--                        inconclusive, until the daemon re-analyses them from their stored
--                        trajectories at start-up (Store::ReanalyzeOldResults).
--   analysed_from        what the numbers were computed from: "dump" (the worker, from the
--                        engine's full dump), "trajectory" (re-analysed at start-up from the
--                        stored trajectory, at most 2000 points, with the bed's grain_top as the
--                        surface), "unreadable" (no stored trajectory that can be re-analysed:
--                        the old numbers are kept, inconclusive, and never tried again)
-- SQLite cannot drop NOT NULL in place: the table is rebuilt, rows and run ids kept.
CREATE TABLE results_v7 (
  run_id              INTEGER PRIMARY KEY REFERENCES runs (id),
  uz                  REAL,                     -- m/s; NULL: no whole block in the window
  uz_stderr           REAL,                     -- m/s; NULL: fewer than 3 blocks
  uz_ci95             REAL,
  uz_stderr_note      TEXT NOT NULL DEFAULT '',
  uz_blocks           INTEGER NOT NULL DEFAULT 0,
  block_s             REAL NOT NULL DEFAULT 0,
  block_kind          TEXT NOT NULL DEFAULT '',  -- period | block (a mode with no period)
  window_t0           REAL NOT NULL,
  window_t1           REAL NOT NULL,
  window_end          TEXT NOT NULL DEFAULT '',
  conclusive          INTEGER NOT NULL DEFAULT 0,
  inconclusive_reason TEXT NOT NULL DEFAULT '',
  dz                  REAL NOT NULL,
  dz_rate             REAL NOT NULL DEFAULT 0,
  z_osc_amplitude     REAL NOT NULL,
  x_drift             REAL NOT NULL,
  broke_surface       INTEGER NOT NULL,
  near_floor          INTEGER NOT NULL,
  stop_reason         TEXT NOT NULL,
  sim_time_s          REAL NOT NULL,
  steps               INTEGER NOT NULL,
  grains              INTEGER NOT NULL,
  z0                  REAL NOT NULL,
  analysis            INTEGER NOT NULL DEFAULT 1,
  analysed_from       TEXT NOT NULL DEFAULT 'dump'
                      CHECK (analysed_from IN ('dump', 'trajectory', 'unreadable')),
  engine_version      TEXT NOT NULL,
  host                TEXT NOT NULL,
  ranks               INTEGER NOT NULL,
  launcher            TEXT NOT NULL,
  wall_s              REAL NOT NULL,
  cpu_s               REAL NOT NULL,
  key                 TEXT NOT NULL,
  created_at          REAL NOT NULL,
  lease_to_start_s    REAL
);
INSERT INTO results_v7 (run_id, uz, uz_stderr, window_t0, window_t1, conclusive, inconclusive_reason, dz,
                        dz_rate, z_osc_amplitude, x_drift, broke_surface, near_floor, stop_reason,
                        sim_time_s, steps, grains, z0, analysis, engine_version, host, ranks, launcher,
                        wall_s, cpu_s, key, created_at, lease_to_start_s)
  SELECT run_id, uz, uz_stderr, window_t0, window_t1, 0,
         'made by the old estimator (analysis 1: a line and a sinusoid fitted over one period, with a ' ||
         'standard error ~10x too small); not yet re-analysed from its stored trajectory',
         dz, CASE WHEN sim_time_s > 0 THEN dz / sim_time_s ELSE 0 END, z_osc_amplitude, x_drift,
         broke_surface, near_floor, stop_reason, sim_time_s, steps, grains, z0, 1, engine_version,
         host, ranks, launcher, wall_s, cpu_s, key, created_at, lease_to_start_s
  FROM results;
DROP TABLE results;
ALTER TABLE results_v7 RENAME TO results;
