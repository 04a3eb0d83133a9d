#!/usr/bin/env bash
# Remakes the claims' calibration tables the verdicts quote (templates/calibration/, core/claim_rates.h)
# on the truth engine: one bench_claims_calibration run per committed design. Run it from the
# repository root after any change to the rules (core/claims.h kClaimRulesVersion), the run analysis
# (core/api.h kAnalysisVersion), paper-58's definition or the truth engine's noise; then rebuild
# (the tables are compiled in) and commit them. truth_tests' CommittedCalibrationIsCurrent fails
# until then.
#   tests/truth/regenerate_calibration.sh [CAMPAIGNS_PER_LAW] [THREADS]   (default 300, 2)
set -euo pipefail
campaigns=${1:-300}
threads=${2:-2}
build=${BUILD:-build}
nice cmake --build "$build" --target bench_claims_calibration -j "$threads" >/dev/null
for beds in 1 3; do
  out=templates/calibration/paper-58.smoke.K$beds.json
  echo "== paper-58 at smoke, K = $beds: $out" >&2
  nice "$build"/bin/bench_claims_calibration --campaign paper-58 --scale smoke --beds $beds \
    --campaigns "$campaigns" --threads "$threads" --drift-campaigns 0 --json "$out" \
    > "$build/calibration-paper-58.smoke.K$beds.md"
  echo "   table: $build/calibration-paper-58.smoke.K$beds.md" >&2
done
