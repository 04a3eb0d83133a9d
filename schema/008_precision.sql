-- sandswim schema, migration 8: runs that last as long as their precision needs (core/precision.h).
--   runs.precision         the run's precision target as JSON {"uz_rel", "uz_abs", "min_periods",
--                          "max_duration_s"}, NULL: none (the run lasts its whole duration).
--                          Its deck states it, so it is part of the run's key.
--   results.stop_note      why the run ended, as a sentence with its figures (stop_reason is the
--                          word: duration | surface | floor | target | window)
--   results.precision_met  1/0: the run's precision target was met; NULL: the run had none
ALTER TABLE runs ADD COLUMN precision TEXT;
ALTER TABLE results ADD COLUMN stop_note TEXT NOT NULL DEFAULT '';
ALTER TABLE results ADD COLUMN precision_met INTEGER;
