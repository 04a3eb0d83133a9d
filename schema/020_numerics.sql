-- sandswim schema, migration 20: a run's time step (core/numerics.h), for a point whose drive
-- steps otherwise than its materials' rule (core/materials.h TimeStep).
--   dt_s  the drive deck's step in s; NULL: the materials' TimeStep (every run before this
--         migration). The run's deck is rendered again from its point at lease time, so its step
--         must be stored with it: without it the deck would not match the run's key.
ALTER TABLE runs ADD COLUMN dt_s REAL;
