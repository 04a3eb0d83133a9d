-- sandswim schema, migration 6.
-- slurm_job: the Slurm job a lease was granted to (the worker's SLURM_JOB_ID; NULL outside Slurm).
-- The daemon asks Slurm whether those jobs still run, and reclaims the leases of a job that is
-- gone (and silent) before they expire: a pilot killed with its node, or by SIGKILL, never hands
-- its runs back.
-- next_token: the lease granted together with this lease's completion (Completion.next). A
-- completion retried because its reply was lost finds it there and takes it back unstarted
-- before leasing again, so no job waits out a lease its worker never received.
ALTER TABLE leases ADD COLUMN slurm_job TEXT;
ALTER TABLE leases ADD COLUMN next_token TEXT;
CREATE INDEX leases_open_by_slurm_job ON leases (slurm_job)
  WHERE slurm_job IS NOT NULL AND completed_at IS NULL AND outcome IS NULL;
