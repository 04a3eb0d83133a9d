-- sandswim schema, migration 5: how often a job was handed back by a stopping worker (Slurm's
-- end-of-allocation signal, scancel, a worker shut down). A hand-back does not count as an attempt
-- until a job has been handed back max_attempts times, so a run that never fits the allocations
-- it is leased in ends failed instead of going round for ever.
ALTER TABLE runs ADD COLUMN releases INTEGER NOT NULL DEFAULT 0;
ALTER TABLE beds ADD COLUMN releases INTEGER NOT NULL DEFAULT 0;
