-- sandswim schema, migration 11: analysis 4's new figures of a run (core/trajectory.h).
--   x_osc_amplitude  m, the amplitude of x's oscillation at the drive frequency f, measured as
--                    z_osc_amplitude is; NULL: not measured (no whole period in the window, no
--                    drive period, or a result of an older analysis).
--   trend_slope      m/s^2, the least-squares slope of the window's period rates on time;
--   trend_slope_se   m/s^2, its standard error; trend_p the two-sided p value of its t test
--                    (periods - 2 degrees of freedom). NULL: too few periods for the test (the
--                    reason in trend_note) or an older analysis.
--   trending         1 when trend_p is below the analysis's trend_alpha (0.01).
ALTER TABLE results ADD COLUMN x_osc_amplitude REAL;
ALTER TABLE results ADD COLUMN trend_slope REAL;
ALTER TABLE results ADD COLUMN trend_slope_se REAL;
ALTER TABLE results ADD COLUMN trend_p REAL;
ALTER TABLE results ADD COLUMN trending INTEGER NOT NULL DEFAULT 0;
ALTER TABLE results ADD COLUMN trend_note TEXT NOT NULL DEFAULT '';
