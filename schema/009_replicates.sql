-- sandswim schema, migration 9: replicate beds (core/deck.h BedSeedsFor, core/aggregate.h).
--   beds.replicate    which replicate of its scale's bed this is (0 .. K-1); beds made before
--                     replicates existed are replicate 0
--   beds.seed_pour1   the insertion seeds its deck pours with (below and above the SO); NULL for
--   beds.seed_pour2   beds made before this migration (their decks state them)
ALTER TABLE beds ADD COLUMN replicate INTEGER NOT NULL DEFAULT 0;
ALTER TABLE beds ADD COLUMN seed_pour1 INTEGER;
ALTER TABLE beds ADD COLUMN seed_pour2 INTEGER;
