-- sandswim schema, migration 12: a run's materials (core/materials.h), for a point that sets
-- material parameters other than Table 1's.
--   materials  JSON object of the parameters that are not Table 1's, by their sweep names
--              ({"so_density": 5000}); NULL: all Table 1's (every run before this migration).
--              The run's deck is rendered again from its point at lease time, so its materials
--              must be stored with it: without them the deck would not match the run's key.
ALTER TABLE runs ADD COLUMN materials TEXT;
