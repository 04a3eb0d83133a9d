-- sandswim schema, migration 4: how long a worker took from its lease to the engine's start
-- (bed download, run directory, spawn), stored with each result so the orchestration overhead of
-- every run can be read back. NULL for results stored before this migration.
ALTER TABLE results ADD COLUMN lease_to_start_s REAL;
