-- sandswim schema, migration 1. Applied once at start-up in one transaction (server/store.cc
-- records it in schema_migrations and PRAGMA user_version). Times are seconds since the Unix
-- epoch (REAL). Never edit a shipped migration: add 002_*.sql.

-- Named, reproducible sets of sweeps (SPEC.md "campaign"); the nightly scheduler reads these.
CREATE TABLE campaigns (
  name                TEXT PRIMARY KEY,
  definition          TEXT NOT NULL,            -- JSON, as ParseCampaign() accepts it
  schedule            TEXT,                     -- cron expression, NULL: manual only
  drift_tolerance_mps REAL NOT NULL DEFAULT 0,
  updated_at          REAL NOT NULL
);

-- One submission of a campaign.
CREATE TABLE campaign_runs (
  id         INTEGER PRIMARY KEY,
  campaign   TEXT NOT NULL,
  scale      TEXT NOT NULL,
  trigger    TEXT NOT NULL CHECK (trigger IN ('manual', 'schedule')),
  due_time   REAL,                              -- the schedule slot it fills (NULL: manual)
  created_at REAL NOT NULL,
  UNIQUE (campaign, due_time)                   -- NULLs are distinct: manual runs never clash
);
CREATE INDEX campaign_runs_by_campaign ON campaign_runs (campaign, id);

-- One POST of sweeps/a campaign; holds the Idempotency-Key and what was answered.
CREATE TABLE submissions (
  id              INTEGER PRIMARY KEY,
  idempotency_key TEXT UNIQUE,
  fingerprint     TEXT NOT NULL,                -- SHA-256 of the normalised request
  response        TEXT NOT NULL,                -- JSON SubmitResult
  created_at      REAL NOT NULL
);

CREATE TABLE sweeps (
  id              INTEGER PRIMARY KEY,
  name            TEXT NOT NULL,
  scale           TEXT NOT NULL,
  spec            TEXT NOT NULL,                -- JSON, normalised
  campaign_run_id INTEGER REFERENCES campaign_runs (id),
  submission_id   INTEGER REFERENCES submissions (id),
  force           INTEGER NOT NULL DEFAULT 0,
  created_at      REAL NOT NULL,
  cancelled_at    REAL
);
CREATE INDEX sweeps_by_campaign_run ON sweeps (campaign_run_id);
CREATE INDEX sweeps_by_submission ON sweeps (submission_id);

-- Prepared granular beds (LIGGGHTS restart files): jobs too, prepared once per key.
CREATE TABLE beds (
  id               INTEGER PRIMARY KEY,
  key              TEXT NOT NULL UNIQUE,
  scale            TEXT NOT NULL,
  state            TEXT NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed')),
  attempts         INTEGER NOT NULL DEFAULT 0,
  max_attempts     INTEGER,                     -- NULL: the queue's default
  lease_token      TEXT,
  lease_expires_at REAL,
  worker           TEXT,
  sha256           TEXT,                        -- of the uploaded restart file
  path             TEXT,                        -- <data>/beds/<key>.restart
  grains           INTEGER,
  result           TEXT,                        -- JSON BedResult
  created_at       REAL NOT NULL,
  started_at       REAL,
  finished_at      REAL,
  last_error_kind  TEXT,
  last_error       TEXT,
  deck             TEXT NOT NULL                -- last: large
);
CREATE INDEX beds_by_state ON beds (state, lease_expires_at);

-- One row per content key: a run is done once and shared by every sweep that names its point.
CREATE TABLE runs (
  id               INTEGER PRIMARY KEY,
  key              TEXT NOT NULL UNIQUE,
  bed_id           INTEGER NOT NULL REFERENCES beds (id),
  mode             TEXT NOT NULL,
  A                REAL NOT NULL,
  f                REAL NOT NULL,
  osc_omega        REAL NOT NULL,               -- Omega: oscillatory amplitude (eq. 6), rad/s
  rot_omega        REAL NOT NULL,               -- omega: constant rotation, rad/s (SQL names are case-blind)
  axis             TEXT NOT NULL,
  duration_s       REAL NOT NULL,               -- asked for (longest of its sweeps)
  run_duration_s   REAL NOT NULL,               -- at the scale
  steps            INTEGER NOT NULL,
  state            TEXT NOT NULL
                   CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled')),
  attempts         INTEGER NOT NULL DEFAULT 0,
  max_attempts     INTEGER,                     -- NULL: the queue's default
  lease_token      TEXT,
  lease_expires_at REAL,
  worker           TEXT,
  sim_time_s       REAL,
  so_z             REAL,
  step             INTEGER,
  heartbeat_at     REAL,
  cancel_requested INTEGER NOT NULL DEFAULT 0,
  created_at       REAL NOT NULL,
  queued_at        REAL NOT NULL,               -- oldest first: order of (re)queueing
  started_at       REAL,
  finished_at      REAL,
  last_error_kind  TEXT,
  last_error       TEXT
);
CREATE INDEX runs_by_state ON runs (state, lease_expires_at);
CREATE INDEX runs_by_state_id ON runs (state, id);          -- oldest queued run first
CREATE INDEX runs_by_bed ON runs (bed_id, state);

-- A run's rendered deck (a few KB each), apart from runs so that state queries over 10^5 runs
-- read small rows.
CREATE TABLE run_decks (
  run_id INTEGER PRIMARY KEY REFERENCES runs (id),
  deck   TEXT NOT NULL
);

CREATE TABLE sweep_runs (
  sweep_id INTEGER NOT NULL REFERENCES sweeps (id),
  run_id   INTEGER NOT NULL REFERENCES runs (id),
  position INTEGER NOT NULL,                    -- first appearance in the sweep's expansion
  PRIMARY KEY (sweep_id, run_id)
);
CREATE INDEX sweep_runs_by_run ON sweep_runs (run_id);
CREATE INDEX sweep_runs_by_position ON sweep_runs (sweep_id, position);

-- Every lease ever granted: how a repeated completion is told from a foreign one.
CREATE TABLE leases (
  token        TEXT PRIMARY KEY,
  kind         TEXT NOT NULL CHECK (kind IN ('bed', 'run')),
  job_id       INTEGER NOT NULL,
  attempt      INTEGER NOT NULL,
  worker       TEXT NOT NULL,
  host         TEXT NOT NULL,
  ranks        INTEGER NOT NULL,
  granted_at   REAL NOT NULL,
  completed_at REAL,
  outcome      TEXT                             -- the CompletionReply state, or 'expired'
) WITHOUT ROWID;

CREATE TABLE results (
  run_id          INTEGER PRIMARY KEY REFERENCES runs (id),
  uz              REAL NOT NULL,                -- m/s
  uz_stderr       REAL NOT NULL,
  window_t0       REAL NOT NULL,
  window_t1       REAL NOT NULL,
  dz              REAL NOT NULL,
  z_osc_amplitude REAL NOT NULL,
  x_drift         REAL NOT NULL,
  broke_surface   INTEGER NOT NULL,
  near_floor      INTEGER NOT NULL,
  stop_reason     TEXT NOT NULL,
  sim_time_s      REAL NOT NULL,
  steps           INTEGER NOT NULL,
  grains          INTEGER NOT NULL,
  z0              REAL NOT NULL,
  engine_version  TEXT NOT NULL,
  host            TEXT NOT NULL,
  ranks           INTEGER NOT NULL,
  launcher        TEXT NOT NULL,
  wall_s          REAL NOT NULL,
  cpu_s           REAL NOT NULL,
  key             TEXT NOT NULL,                -- the run key it was computed under
  created_at      REAL NOT NULL
);

CREATE TABLE trajectories (
  run_id INTEGER PRIMARY KEY REFERENCES runs (id),
  data   TEXT NOT NULL                          -- JSON {"t":[..],"x":[..],"y":[..],"z":[..]}
);

CREATE TABLE run_logs (
  run_id   INTEGER PRIMARY KEY REFERENCES runs (id),
  log_tail TEXT NOT NULL
);

-- Append-only audit of every state change.
CREATE TABLE events (
  id      INTEGER PRIMARY KEY,
  time    REAL NOT NULL,
  kind    TEXT NOT NULL,                        -- "run.leased", "bed.done", "sweep.cancelled", ...
  subject TEXT NOT NULL,                        -- "run/12", "bed/3", "sweep/7"
  detail  TEXT NOT NULL                         -- JSON
);
CREATE INDEX events_by_subject ON events (subject, id);

-- Monotonic counters for /metrics (leases granted, completions, expirations, ...).
CREATE TABLE counters (
  name  TEXT PRIMARY KEY,
  value INTEGER NOT NULL
) WITHOUT ROWID;
