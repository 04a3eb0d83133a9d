// The JSON types the daemon and its workers exchange (the worker protocol of /api/v1), with
// their nlohmann::json conversions. Both executables link this; schema/openapi.json describes
// the same shapes for other clients.
//
// The worker protocol, in order:
//   POST /api/v1/leases                      LeaseRequest -> 200 {"lease": LeaseGrant} | 204
//   GET  /api/v1/beds/{id}/restart           bed restart bytes (a run lease names its bed)
//   POST /api/v1/leases/{token}/heartbeat    Heartbeat -> 200 HeartbeatReply | 409 (lease lost)
//   PUT  /api/v1/beds/{id}/restart?token=T   bed restart bytes, header X-Sha256 (bed leases)
//   PUT  /api/v1/leases/{token}/snapshots/{n} a full-bed snapshot's dump (runs that ask for
//                                            snapshots, core/deck.h), header X-Sha256; before
//                                            the completion that lists it (Completion::snapshots)
//   POST /api/v1/leases/{token}/complete     Completion -> 200 CompletionReply | 409 (lease lost);
//                                            a Completion with `next` also leases the worker's
//                                            next job in the same transaction (one round trip
//                                            per job instead of two); the reply carries it
//   POST /api/v1/leases/{token}/release      ReleaseRequest -> 200 CompletionReply | 409: hands a
//                                            job back unfinished (worker stopping, e.g. its Slurm
//                                            allocation ends); the attempt does not count
// A lease token is the only proof of ownership; a completion is recorded once per token (a
// repeat answers "duplicate"; with `next` it also swaps the job its lost reply carried for a
// fresh grant), and a completion or heartbeat under a token that is no longer current never
// changes anything.
//
// Thread safety: values.
#ifndef SANDSWIM_CORE_API_H_
#define SANDSWIM_CORE_API_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/precision.h"
#include "core/status.h"

namespace sandswim::api {

enum class JobKind { kBed, kRun };
NLOHMANN_JSON_SERIALIZE_ENUM(JobKind, {{JobKind::kBed, "bed"}, {JobKind::kRun, "run"}})

struct LeaseRequest {
  LeaseRequest() = default;
  LeaseRequest(std::string w, std::string h, int r, std::string job = "")
      : worker(std::move(w)), host(std::move(h)), ranks(r), slurm_job(std::move(job)) {}
  std::string worker;  // a stable name, "host:pid" by default
  std::string host;
  int ranks = 1;          // MPI ranks this worker gives one job
  std::string slurm_job;  // the Slurm job the worker runs in (SLURM_JOB_ID), "" outside Slurm
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(LeaseRequest, worker, host, ranks, slurm_job)

struct BedRef {
  int64_t id = 0;
  std::string sha256;  // of the restart file; a run never starts from a bed that differs
  std::string url;     // "/api/v1/beds/{id}/restart"
  std::string key;     // the bed's content key (a run's key hashes it)
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(BedRef, id, sha256, url, key)

struct LeaseGrant {
  std::string token;
  JobKind kind = JobKind::kRun;
  int64_t id = 0;             // bed id or run id
  std::string key;            // content key of the bed or run
  std::string deck;           // LIGGGHTS input, rendered by the daemon
  // The engine version `key` hashes (core/keys.h): the worker recomputes the key from `deck` (and
  // for a run its bed's key) and refuses a deck that does not match. "": not checkable (an older
  // daemon, a deck stored before migration 3).
  std::string key_engine;
  int attempt = 1;            // 1 for the first lease of this job
  double ttl_s = 60;          // heartbeat before this runs out
  double duration_s = 0;      // physical time the run simulates (0 for beds)
  int64_t steps = 0;          // steps a complete run makes (0 for beds: decided by the deck)
  double wall_budget_s = 0;   // stop the job after this much wall time (0: no budget)
  std::optional<BedRef> bed;  // runs only
  // What the deck states, typed (core/deck.h DriveFacts), for reading the job's dump: every job
  // has its timestep; runs also their drive frequency, amplitude and floor.
  double dt_s = 0;  // 0: a daemon that predates these fields
  double f_hz = 0;  // 0 when the mode does not vibrate
  double A_m = 0;
  std::optional<double> z_floor_m;
  // The SO's radius the deck states (its point's so_diameter / 2), runs only; absent from a daemon
  // older than materials: Table 1's.
  std::optional<double> so_radius_m;
  // The run's precision target (core/precision.h): the worker follows U_z on the growing dump and
  // ends the run, through the deck's control file, once DecideStop says so. Absent: the run lasts
  // `steps`.
  std::optional<PrecisionTarget> precision;
  // Full-bed snapshots the run's deck takes (core/deck.h SnapshotFractions): the worker hands in
  // the frames nearest these fractions of the run's actual length. Empty: none.
  std::vector<double> snapshots;
  // No other job was leasable when this one was granted (a bed's runs wait for it; the last runs
  // of the queue): a worker's slots that are idle now would stay idle while it runs, so the
  // worker may give this job their cores as extra MPI ranks (workers/worker.h). Ranks enter
  // neither the deck nor any key: a job on more ranks is statistically equivalent, not identical
  // (fix insert/pack places grains by the domain decomposition, and sums over ranks run in another
  // order): two runs of one key on different ranks follow different trajectories, and their
  // results agree within their errors.
  bool queue_dry = false;
};
void to_json(nlohmann::json& j, const LeaseGrant& g);
void from_json(const nlohmann::json& j, LeaseGrant& g);

struct Heartbeat {
  double sim_time_s = 0;  // simulated time reached
  double so_z = 0;        // the SO's current z, m
  int64_t step = 0;
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(Heartbeat, sim_time_s, so_z, step)

struct HeartbeatReply {
  double ttl_s = 60;
  bool cancel = false;  // the sweep was cancelled: stop the job, then complete with kind "cancelled"
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(HeartbeatReply, ttl_s, cancel)

// What a drive run measured (SPEC.md "Results a run produces"; how U_z and its window are found:
// core/trajectory.h).
// The version of that analysis: 1 was a least-squares line + sinusoid at f over [1/f, end] with
// the fit's own standard error (too small, biased by the harmonics); results made by it are
// re-analysed from their stored trajectories when the daemon upgrades its database. 2 took U_z
// from whole-period block rates; 3 takes a run ended by its precision target (its rate, error and
// interval) from the blocks after its two-stage rule's pilot (core/precision.h), instead of from
// every block with the interval its stop was chosen on, which was too narrow. 4 starts the steady
// window after a transient stated in physical time (at least one period, core/trajectory.h
// WindowRule), tests the window's period rates for a trend (trend_*) and measures x's amplitude at
// f (x_osc_amplitude).
inline constexpr int kAnalysisVersion = 4;
struct RunResult {
  std::optional<double> uz;         // m/s, mean rate over the window's whole blocks; absent: none
  std::optional<double> uz_stderr;  // m/s, from the scatter of the block rates; absent: too few
  std::optional<double> uz_ci95;    // m/s, half-width of the 95 % interval (Student t, blocks - 1)
  std::string uz_stderr_note;       // why uz_stderr is absent ("" when present)
  int uz_blocks = 0;                // whole blocks (independent rates) U_z rests on
  double block_s = 0;               // s, a block: the drive period 1/f, or the undriven block
  std::string block_kind;           // "period" (driven modes) | "block" (no period: rotation only)
  double window_t0 = 0;             // s, start of the steady window (after the transient)
  double window_t1 = 0;             // s, its end: window_t0 + uz_blocks * block_s
  std::string window_end;           // why it ends: "run_end" | "surface" | "floor"
  bool conclusive = false;          // enough whole blocks for U_z; else shown, left out of fits
  std::string inconclusive_reason;  // "" when conclusive
  double dz = 0;                    // m, z(end) - z(0)
  double dz_rate = 0;               // m/s, dz over the whole run's duration
  double z_osc_amplitude = 0;       // m, amplitude of z's oscillation at the drive frequency f
  std::optional<double> x_osc_amplitude;  // m, the same for x; absent: not measured (no whole period)
  double x_drift = 0;               // m, x(end) - x(0)
  // Whether the window's period rates drift with time (core/trajectory.h "Trend"): the slope of
  // the period rate on time, its standard error and the two-sided p value of its t test; absent
  // (trend_note says why) with too few periods. trending: p < kTrendAlpha. U_z stays as measured.
  std::optional<double> trend_slope;     // m/s^2
  std::optional<double> trend_slope_se;  // m/s^2
  std::optional<double> trend_p;
  bool trending = false;
  std::string trend_note;  // why there is no trend test ("" when there is one)
  bool broke_surface = false;       // the engine stopped because the SO broke the top surface
  bool near_floor = false;          // the engine stopped because the SO reached the floor
  // Why the run ended: "duration" (all its steps: the duration asked, or a precision target's
  // maximum) | "surface" | "floor" (the SO reached that boundary) | "target" (the precision target
  // was met) | "window" (the steady window had closed at a boundary's clearance: running on could
  // not tighten U_z). core/precision.h.
  std::string stop_reason;
  std::string stop_note;              // the same, as a sentence with its figures
  std::optional<bool> precision_met;  // the run's precision target was met (absent: no target)
  double sim_time_s = 0;              // physical time simulated
  int64_t steps = 0;
  int64_t grains = 0;
  double z0 = 0;                    // m, the SO's z at t = 0
  int analysis = kAnalysisVersion;  // the analysis that made this result
  // What it was computed from: "dump" (the worker, the engine's full dump) | "trajectory" (the
  // daemon re-analysed an old result from its stored, downsampled trajectory) | "unreadable" (an
  // old result that could not be re-analysed: old numbers, inconclusive). Set by the store only.
  std::string analysed_from = "dump";
};
void to_json(nlohmann::json& j, const RunResult& r);
void from_json(const nlohmann::json& j, RunResult& r);

// What a bed preparation produced.
struct BedResult {
  int64_t grains = 0;
  double so_z = 0;       // m, where the SO settled
  double grain_top = 0;  // m, highest grain centre
  bool equilibrated = false;
  double ke_ratio = 0;  // final kinetic energy / its initial (peak) value
  std::string sha256;   // of the uploaded restart file
  int64_t bytes = 0;
  // From the bed's dump of all atoms (core/bed_figures.h); absent for beds made before it.
  std::optional<double> bed_height;        // m, highest grain centre above the floor
  std::optional<double> so_depth;          // m, highest grain centre above the SO's top
  std::optional<double> packing_fraction;  // solid fraction in the shell one grain diameter around the SO
  std::optional<int64_t> shell_grains;     // grains whose centre is in that shell
};
void to_json(nlohmann::json& j, const BedResult& b);
void from_json(const nlohmann::json& j, BedResult& b);

// The SO's trajectory, downsampled for storage and plots (t ascending).
struct Trajectory {
  std::vector<double> t, x, y, z;
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(Trajectory, t, x, y, z)

// A full-bed snapshot a run handed in (its dump uploaded first, under the lease's token).
struct Snapshot {
  int idx = 0;          // 0 .. n-1, in the order of the fractions asked
  double fraction = 0;  // asked: 0 the run's start, 1 its end
  double t_s = 0;       // the frame's physical time
  int64_t step = 0;
  int64_t grains = 0;  // type-1 atoms in it (the SO besides)
  int64_t bytes = 0;   // of the dump
  std::string sha256;  // of the dump
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(Snapshot, idx, fraction, t_s, step, grains, bytes, sha256)

// Why a job failed; `kind` is one of:
//   "deck_error"     LIGGGHTS printed ERROR: (line in `message`)
//   "not_equilibrated" a bed missed the kinetic-energy criterion (its figures in `message`)
//   "lost_atoms"     LIGGGHTS lost atoms
//   "signal"         the engine died on a signal
//   "timeout"        the job outlived its wall-time budget
//   "stalled"        the engine's simulated time stood still (a hung engine); stopped by the worker
//   "engine_missing" mpirun/srun/liggghts could not be started
//   "incomplete"     the engine exited without doing all its steps
//   "bad_output"     the dump or log could not be read
//   "bed_mismatch"   the bed restart's checksum did not match
//   "bad_lease"      the lease lacks what the worker needs (a daemon older than the worker)
//   "key_mismatch"   the lease's deck does not hash to its content key (changed on its way): not run
//   "cancelled"      stopped because the sweep was cancelled
struct Failure {
  std::string kind;
  std::string message;
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(Failure, kind, message)

// How many attempts a job gets when its attempts fail this way, at most `max_attempts` (the
// daemon's): a failure that repeats by nature -- the same deck, bed and engine give the same error,
// lost atoms, unreadable output, missed equilibrium, or a lease the worker cannot use -- gets no
// second attempt (1); a hung engine ("stalled") one more (2: a stall may be the host's); the rest
// (signals, a missing engine, an incomplete run, a bed checksum, an expired lease, a time-out) are
// the infrastructure's and get them all.
int AttemptsFor(const std::string& failure_kind, int max_attempts);

// Facts about the execution, for every completion.
struct Execution {
  std::string engine_version;  // first line of the LIGGGHTS log
  std::string host;
  int ranks = 1;
  std::string launcher;  // "mpirun" | "srun" | "direct"
  double wall_s = 0;
  double cpu_s = 0;
  double lease_to_start_s = 0;  // orchestration overhead before the engine ran
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(Execution, engine_version, host, ranks, launcher, wall_s, cpu_s,
                                                lease_to_start_s)

struct Completion {
  bool ok = false;
  std::optional<RunResult> result;       // ok run
  std::optional<BedResult> bed_result;   // ok bed
  std::optional<Trajectory> trajectory;  // ok run
  std::vector<Snapshot> snapshots;       // ok run that asked for them: each uploaded before
  std::optional<Failure> failure;        // !ok
  Execution execution;
  std::string log_tail;  // last lines of the engine's log
  // Set by a worker that wants more work: lease its next job in the same call. The completion is
  // applied first; when it is refused (409, 4xx) nothing is leased either.
  std::optional<LeaseRequest> next;
};
void to_json(nlohmann::json& j, const Completion& c);
void from_json(const nlohmann::json& j, Completion& c);

struct CompletionReply {
  CompletionReply() = default;
  CompletionReply(std::string s) : state(std::move(s)) {}  // NOLINT: implicit, as {"done"} reads
  // "done", "failed", "queued" (a retry will follow), "cancelled", or "duplicate" (this token
  // had already completed: nothing changed).
  std::string state;
  // The next job when the completion asked for one (`Completion::next`) and one was leasable;
  // absent otherwise (nothing to do now: poll POST /api/v1/leases later).
  std::optional<LeaseGrant> next;
};
void to_json(nlohmann::json& j, const CompletionReply& r);
void from_json(const nlohmann::json& j, CompletionReply& r);

// JSON text of `j` for the wire or the store. Strings that are not valid UTF-8 -- engine output
// is not always: LIGGGHTS has been seen to print stray bytes after an ERROR line -- have the bad
// bytes replaced by U+FFFD instead of throwing.
std::string ToJsonText(const nlohmann::json& j);

// A job handed back unfinished by a worker that is stopping (not the job's fault).
struct ReleaseRequest {
  std::string reason;  // for the event log, e.g. "slurm allocation 123 ends"
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(ReleaseRequest, reason)

// Lengths the daemon takes in worker messages: every string a worker sends is stored and shown on
// the live feed, and a 1 MB worker name once made every live snapshot 19 MB. Names (worker, host,
// slurm_job, engine_version, launcher) past kMaxWorkerNameLength are refused (InvalidArgument
// naming the field); free text (a failure's message, the log tail, a release reason) is cut to
// kMaxWorkerTextLength bytes, at a UTF-8 boundary, with a note -- a completion is never refused
// for a long log. Real values are far inside: "host:pid" names, a 40-line log tail.
inline constexpr size_t kMaxWorkerNameLength = 256;
inline constexpr size_t kMaxWorkerTextLength = 16 * 1024;
Status LimitLengths(LeaseRequest& r);
Status LimitLengths(Completion& c);
Status LimitLengths(ReleaseRequest& r);

}  // namespace sandswim::api

#endif  // SANDSWIM_CORE_API_H_
