-- sandswim schema, migration 14: the MPI ranks a bed was prepared on (core/api.h Execution::ranks
-- of its completion), so that the cost model keeps bed rates per rank count as it does runs'
-- (server/store/cost_model.h): a bed on 2 ranks takes about 0.7x the time of one on 1 rank, and
-- pooled with them it made the next 1-rank bed look up to 30 % shorter than it is.
--   beds.ranks  NULL: not recorded (every bed prepared before this migration, and beds not done
--               yet); the cost model counts such a done bed as prepared on 1 rank, and says so.
ALTER TABLE beds ADD COLUMN ranks INTEGER;
