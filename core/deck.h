// Deck rendering: pure functions from a validated Point and a Scale to LIGGGHTS input text.
//
// The templates live in templates/*.in and are compiled into the library (templates/README.md
// lists every placeholder). Every placeholder is replaced by a number this renderer formatted
// itself (shortest round-trip form) or by one of the fixed file names below; no user string ever
// reaches a deck (LIGGGHTS has a `shell` command). Output is byte-stable: the same inputs give
// the same bytes on every machine, which the content keys (core/keys.h) rely on.
//
// Decks use file names relative to the run directory, so a deck does not depend on where it runs.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_DECK_H_
#define SANDSWIM_CORE_DECK_H_

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/point.h"
#include "core/scale.h"
#include "core/status.h"

namespace sandswim {

// Bumped whenever a template changes in a way that changes results; part of every content key.
inline constexpr int kTemplateVersion = 2;

// Files a deck reads or writes, relative to its run directory.
inline constexpr char kBedRestartFile[] = "bed.restart";    // bed deck writes, drive deck reads
inline constexpr char kBedDumpFile[] = "bed.dump";          // bed deck: all atoms at the end (bed_figures.h)
inline constexpr char kTrajectoryDumpFile[] = "so.dump";    // drive deck: the SO, every 1 ms
inline constexpr char kInitialDumpFile[] = "initial.dump";  // drive deck: all atoms at t = 0
inline constexpr char kLogFile[] = "log.liggghts";
// The worker's requests to a running drive deck: the deck writes it ("variable sandswim_stop
// equal 0") before its first chunk and `include`s it after every chunk; the worker replaces it
// (write, then rename) with ControlFileText() to end the run cleanly.
inline constexpr char kControlFile[] = "control.in";

// Full-bed snapshots (the paper's Fig. 5), for a run that asks for them: fractions of the run's
// actual length (0 its start, 0.5 its middle, 1 its end; a run may stop early, so the length is
// known only at its end). The deck dumps every atom (kSnapshotColumns, core/snapshot.h) every
// SnapshotEverySteps() steps into kSnapshotFramePattern ('*' = the step) and once more when it
// ends into kSnapshotLastFile; the worker keeps the frames nearest the fractions asked
// (core/snapshot.h PickSnapshotFrames) and hands those in. A run that asks for none renders the
// deck it always did, so its content key is unchanged; asking for snapshots changes the deck,
// hence the key: such a run is a run of its own.
inline constexpr size_t kMaxSnapshots = 10;
inline constexpr int kSnapshotFramesPerRun = 20;  // frames over the run's longest duration
inline constexpr char kSnapshotFramePattern[] = "frame.*.dump";
inline constexpr char kSnapshotLastFile[] = "frame.last.dump";
using SnapshotFractions = std::vector<double>;  // ascending, distinct, each in [0, 1]
// InvalidArgument ("snapshots") unless the fractions are at most kMaxSnapshots distinct numbers in
// [0, 1]; the ascending set on success.
Result<SnapshotFractions> CheckSnapshotFractions(std::vector<double> fractions);
// The database's form (runs.snapshots): a JSON array, NULL (nullopt) for none; and back, with
// Corruption naming the column when the text is not such an array.
std::optional<std::string> SnapshotFractionsText(const SnapshotFractions& fractions);
Result<SnapshotFractions> StoredSnapshotFractions(const std::optional<std::string>& text);

// Time between updates of the SO's prescribed angular velocity (a chunk): the SO is left out of
// the integrator, so its omega holds between updates. 1 ms (100 steps of Table 1's 1e-5 s), in
// steps of the point's own step (core/numerics.h), fewer when f is high: OmegaUpdateSteps() keeps
// at least kMinOmegaUpdatesPerPeriod updates in every drive period.
inline constexpr double kOmegaUpdateS = 1e-3;
inline constexpr int kOmegaUpdateSteps = 100;  // at Table 1's step
inline constexpr int kMinOmegaUpdatesPerPeriod = 20;
// Steps between trajectory frames at Table 1's step: 1 ms of physical time (DumpEverySteps: at
// the point's own step, still 1 ms).
inline constexpr int kDumpEverySteps = 100;

// Lines the decks print for the worker to read (all start with "SANDSWIM ").
//   SANDSWIM bed grains N so_z Z grain_top Z step S
//   SANDSWIM bed equilibrated|not_equilibrated ke E ke_peak E
//   SANDSWIM drive stop duration|surface|floor|target|window step S t T z Z
inline constexpr char kMarkerPrefix[] = "SANDSWIM ";

// Replicate beds (core/aggregate.h): replicate r of a scale's bed is poured with insertion seeds
// of its own, so its grains lie elsewhere; the seeds are in the deck, hence in the bed's key, and
// each replicate is prepared once. Replicate 0 is the bed a sweep without replicates uses.
inline constexpr int kMaxReplicates = 20;
struct BedSeeds {
  long long pour1 = 0;  // fix insert/pack of the layer below the SO
  long long pour2 = 0;  // and of the layer above it
};
// REQUIRES: 0 <= replicate < kMaxReplicates (else std::logic_error).
BedSeeds BedSeedsFor(int replicate);

// The bed of `materials` (their BedMaterials: drive-only values do not enter it) at the scale's box
// for them (BoxFor), at their time step (TimeStep). Table 1's materials render the deck they
// always did; others add a header of the values that are not Table 1's and the step's rule.
std::string RenderBedDeck(const Scale& scale, int replicate = 0, const Materials& materials = kTable1);

// REQUIRES: Validate(p).ok() and FitsScale(p, scale).ok(); `snapshots` passed
// CheckSnapshotFractions. `target` is the run's precision target (absent: the run lasts its whole
// duration); its numbers are stated in the deck, so they are part of the run's content key, as
// are the snapshots asked for (none: the deck has no snapshot lines at all).
std::string RenderDriveDeck(const Point& p, const Scale& scale, const std::optional<PrecisionTarget>& target,
                            const SnapshotFractions& snapshots = {});

// Steps between two full-bed frames of a run with snapshots: its longest duration over
// kSnapshotFramesPerRun, in whole chunks (OmegaUpdateSteps), at least one chunk.
long long SnapshotEverySteps(const Point& p, const std::optional<PrecisionTarget>& target);

// Steps between omega updates for this point: 1 ms of its step (kOmegaUpdateSteps at Table 1's),
// or fewer so that a drive period holds at least kMinOmegaUpdatesPerPeriod updates (f = 50 Hz and
// below: 1 ms).
int OmegaUpdateSteps(const Point& p);
// Steps between trajectory frames for this point: 1 ms of its step, at least one.
int DumpEverySteps(const Point& p);

// Number of steps a drive run of this point makes when it is not stopped early: RunDuration
// (core/precision.h) rounded up to whole chunks.
long long DriveSteps(const Point& p, const std::optional<PrecisionTarget>& target);

// What the worker writes to kControlFile: 0 = go on, 1 = the precision target is met, 2 = the
// steady window has closed (core/precision.h StopVerdict).
std::string ControlFileText(StopVerdict verdict);

// Drive facts a drive deck states (its `timestep`, `variable f/A equal`, floor wall `zplane` and
// `variable top_gap equal v_so_z+<r>-...` lines): what reading the run's dump needs besides the dump.
struct DriveInfo {
  double dt = 0;                  // s
  double f = 0;                   // Hz; 0 when the mode does not vibrate
  double A = 0;                   // m
  std::optional<double> z_floor;  // m, the floor wall's height, when the deck has one
  // m, the SO's radius (its point's so_diameter / 2): the analysis keeps the SO's clearance from
  // the surface and the floor with it (core/trajectory.h BedBounds). Table 1's when not stated.
  double so_radius = kMaterials.d_so / 2;
};

// The drive facts of `p` at `scale`, exactly as RenderDriveDeck states them (the same numbers:
// the lease grant carries these, so a worker never reads them back out of the deck text).
DriveInfo DriveFacts(const Point& p, const Scale& scale);

// The shortest decimal text that reads back as `v` ("0.03", "1e-05", "-80").
std::string FormatNumber(double v);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_DECK_H_
