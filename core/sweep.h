// Sweeps and campaigns: parsing and validating the user's JSON, expanding axes into points, and
// planning the distinct runs (deck + content key) a set of sweeps needs at a scale.
//
// The accepted JSON is described by schema/sweep.schema.json; ParseSweep() applies the same
// rules and names the offending field with a path ("base.A", "axes[1].range.step"). Unknown
// fields are errors. Numbers must be JSON numbers (a string where a number belongs is refused).
//
// Expansion order is byte-stable: axes vary in the order given, the last axis fastest
// ("product"), or all together ("zip", equal lengths required). Values from `range` and
// `geometric` are computed as from + i*step and start*ratio^i and rounded to 12 significant
// digits, so 0.01..0.10 step 0.01 gives exactly 0.01, 0.02, ..., 0.1.
//
// Planning merges points across sweeps that drive the SO the same way (SameDrive): such a point
// runs once, at the longest duration any sweep asks for and to the tightest precision target
// (none, if one of them asks for none), and belongs to every sweep that named it.
//
// Thread safety: pure functions; Builtin campaigns are immutable.
#ifndef SANDSWIM_CORE_SWEEP_H_
#define SANDSWIM_CORE_SWEEP_H_

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/claims.h"
#include "core/deck.h"
#include "core/numerics.h"
#include "core/point.h"
#include "core/scale.h"
#include "core/status.h"

namespace sandswim {

// Caps stated in the API description and in every refusal.
inline constexpr size_t kMaxRunsPerSubmission = 100000;
inline constexpr size_t kMaxNameLength = 100;           // names: [A-Za-z0-9._-]+
inline constexpr size_t kMaxDescriptionLength = 10000;  // "description" of a sweep or campaign

enum class Combine { kProduct, kZip };

struct SweepAxis {
  std::string param;           // "A", "f", "Omega", "omega", "duration_s", or a material (core/materials.h)
  std::vector<double> values;  // materialized from values | range | geometric
  // Which of "values", "range", "geometric" the user wrote: error paths name it
  // ("axes[0].values[3]", or "axes[0].range" with the value's index in the reason).
  std::string source = "values";
};

struct SweepSpec {
  std::string name;
  std::string scale;  // a FindScale() name
  Point base;
  std::vector<SweepAxis> axes;
  Combine combine = Combine::kProduct;
  // How precise its runs must be (core/precision.h); absent: the campaign's, else the scale's
  // default (Scale::default_precision), else none (runs last their whole duration).
  std::optional<PrecisionTarget> precision;
  // On how many beds each point runs (core/aggregate.h): replicate beds 0..K-1 of the scale
  // (core/deck.h BedSeedsFor). Absent: the campaign's, else 1.
  std::optional<int> replicates;
  int Replicates() const { return replicates.value_or(1); }
  // Full-bed snapshots its runs take (core/deck.h SnapshotFractions): fractions of each run's
  // actual length. Absent: the campaign's, else none.
  std::optional<SnapshotFractions> snapshots;
  // Its drive's time step (core/numerics.h). Absent: the campaign's, else the scale's default.
  std::optional<Numerics> numerics;
};

Result<SweepSpec> ParseSweep(const nlohmann::json& j);

// Every point of the sweep, in expansion order; each passes Validate() and FitsScale() at the
// sweep's scale, or the whole expansion fails naming the first bad point's field
// ("axes[0].values[3]: A = 0.2 m needs ..."). Fails with ResourceExhausted past `max_points`.
Result<std::vector<Point>> ExpandSweep(const SweepSpec& s, size_t max_points = kMaxRunsPerSubmission);

// A campaign run in rounds (core/adaptive.h): round 1 is the campaign's points on one bed,
// each later round is planned by the daemon from the claims still undecided, until every claim is
// decided, `max_rounds` rounds have run (the fixed look schedule the error rates are measured at)
// or `budget_core_h` core-hours of engine time (the cost model's) are spent. Absent: the fixed
// design, every point on every replicate bed in one go.
struct AdaptiveSettings {
  double budget_core_h = 0;  // > 0, finite; at least the first round's (checked against the cost model)
  int max_rounds = 4;        // 1 .. kMaxAdaptiveRounds, the first included
};
inline constexpr int kMaxAdaptiveRounds = 10;

struct Campaign {
  std::string name;
  std::string description;
  std::string scale;                         // default scale; a submission may override it
  std::vector<SweepSpec> sweeps;             // scale = the campaign's (its JSON sweeps have no "scale")
  std::optional<std::string> schedule;       // cron expression, daemon's local time zone
  double drift_tolerance_mps = 0.0;          // |U_z now - U_z before| above this is flagged
  std::optional<PrecisionTarget> precision;  // for its sweeps that set none
  std::optional<int> replicates;             // for its sweeps that set none
  std::optional<SnapshotFractions> snapshots;  // for its sweeps that set none
  std::optional<Numerics> numerics;            // for its sweeps that set none
  // The paper's findings it tests (core/claims.h); each rule names sweeps of this campaign.
  std::vector<Claim> claims;
  // Run in rounds (above); requires claims and one replicate bed (more beds are what rounds add).
  std::optional<AdaptiveSettings> adaptive;
};

Result<Campaign> ParseCampaign(const nlohmann::json& j);
// Campaigns shipped with sandswim (templates/campaigns/*.json, compiled in): "paper-58", "density-ratio", "dt-convergence".
std::vector<std::string> BuiltinCampaignNames();
Result<Campaign> BuiltinCampaign(const std::string& name);
// Its definition, the JSON file as shipped. NotFound for a name that is not built in.
Result<nlohmann::json> BuiltinCampaignDefinition(const std::string& name);

// One distinct run of a plan: a point on one replicate bed.
struct PlannedRun {
  Point point;                      // duration_s is the longest any sweep asked for
  int replicate = 0;                // which replicate of its bed
  int bed = 0;                      // the bed it runs on: Plan::beds[bed] (its bed materials, its replicate)
  std::vector<std::string> sweeps;  // names of the sweeps it belongs to, in plan order
  double run_duration_s = 0;        // RunDuration() at the plan's scale
  long long steps = 0;              // DriveSteps()
  // The target it runs to: its sweeps' (the tightest, none if one of them has none), else the
  // scale's default.
  std::optional<PrecisionTarget> precision;
  // The full-bed snapshots it takes: every fraction any of its sweeps asks for (core/deck.h).
  SnapshotFractions snapshots;
  std::string deck;  // RenderDriveDeck()
  std::string key;   // RunKey()
};

struct PlannedBed {
  int replicate = 0;
  BedSeeds seeds;
  Materials materials;  // its points' BedMaterials (Table 1's drive-only values)
  std::string deck;     // RenderBedDeck(scale, replicate, materials)
  std::string key;   // BedKey()
};

struct Plan {
  std::string scale;
  // One per bed materials and replicate, in first-appearance order: with Table 1's materials only,
  // replicates 0..K-1, K the most any sweep asks for.
  std::vector<PlannedBed> beds;
  std::vector<PlannedRun> runs;  // distinct, in first-appearance order
};

// Expands every sweep at `scale`, each point once on each of its sweep's replicate beds, and
// merges shared points (per bed). `engine_version` enters every key.
Result<Plan> PlanSweeps(const std::vector<SweepSpec>& sweeps, const Scale& scale, const std::string& engine_version,
                        size_t max_runs = kMaxRunsPerSubmission);

// The same plan, with knobs for big submissions: a 100,000-run plan holds about 370 MB of decks
// and takes about 1.5 s of CPU to render and hash. With keep_decks = false every deck is
// rendered and hashed but not kept (PlannedRun::deck stays empty; RenderDriveDeck(run.point,
// scale) gives the same bytes again when the run is leased). `threads` > 1 renders on that many
// threads; the plan is identical to the single-threaded one.
struct PlanOptions {
  size_t max_runs = kMaxRunsPerSubmission;  // what is left of the submission's cap for these sweeps
  size_t runs_before = 0;                   // runs of the submission planned before these (other scales)
  bool keep_decks = true;
  int threads = 1;
};
Result<Plan> PlanSweeps(const std::vector<SweepSpec>& sweeps, const Scale& scale, const std::string& engine_version,
                        const PlanOptions& options);

// A submission's plan: its sweeps grouped by scale (in first-appearance order), each group
// planned together by PlanSweeps (a point shared by sweeps of one scale runs once), the run limit
// (options.max_runs) shared by the groups. The daemon's submission (server/jobs/submission.h) and
// `sandswim expand` both plan with this, so expand shows exactly the runs the daemon would make.
// InvalidArgument when two sweeps share a name or a scale is unknown. Field paths name the
// campaign ("campaign", "scale") when `campaign`, else "sweeps[i]" when there are several sweeps.
struct ScalePlan {
  std::string scale;
  std::vector<size_t> sweep_indexes;  // into `sweeps`
  Plan plan;
};
Result<std::vector<ScalePlan>> PlanSubmission(const std::vector<SweepSpec>& sweeps, const std::string& engine_version,
                                              const PlanOptions& options, bool campaign);

// The JSON object `sandswim expand --json` prints for a run: key, mode, A, f, Omega or omega +
// axis, duration_s (asked), the materials that are not Table 1's, run_duration_s (at the scale),
// steps, dt_s and dt_criteria (core/numerics.h; only when not Table 1's 1e-5 s), sweeps.
nlohmann::json PlannedRunToJson(const PlannedRun& r);
// The point alone, as in a sweep's "base" (only the fields its mode uses, and the materials that
// are not Table 1's).
nlohmann::json PointToJson(const Point& p);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_SWEEP_H_
