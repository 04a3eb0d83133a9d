-- sandswim schema, migration 6: the Slurm job a lease was granted to (the worker's SLURM_JOB_ID;
-- NULL outside Slurm). The daemon asks Slurm whether those jobs still run, and reclaims the leases
-- of a job that is gone at once instead of when they expire (a pilot killed with its node, or by
-- SIGKILL, never hands its runs back).
ALTER TABLE leases ADD COLUMN slurm_job TEXT;
CREATE INDEX leases_slurm_job ON leases (slurm_job) WHERE slurm_job IS NOT NULL AND completed_at IS NULL;
