-- sandswim schema, migration 13: RESERVED for the campaign-versions migration of another branch
-- (schema/013_*). This file only keeps the numbering without gaps (server/store/database.cc) so
-- that migration 14 applies on this branch; delete it when the real 013 is merged. A database
-- migrated with it must not be opened by a build that has the real 013 (it would be skipped).
SELECT 1;
