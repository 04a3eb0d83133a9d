#include "workers/worker.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include "core/bed_figures.h"
#include "core/deck.h"
#include "core/dump_reader.h"
#include "core/engine_log.h"
#include "core/keys.h"
#include "core/snapshot.h"
#include "core/trajectory.h"
#include "platform/slurm.h"
#include "workers/job_outcome.h"

namespace sandswim::worker {
namespace {

constexpr int kLogTailLines = 40;
constexpr char kEngineOutputFile[] = "engine.out";

}  // namespace

// Follows a file that another process appends to, handing new bytes to a callback. (Not in the
// anonymous namespace: JobProgress, declared in worker.h, holds one.)
class FileTail {
 public:
  explicit FileTail(std::string path) : path_(std::move(path)) {}
  // Reads what was appended since the last call.
  std::string ReadNew() {
    std::ifstream in(path_, std::ios::binary);
    if (!in) return "";
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size <= offset_) return "";
    in.seekg(offset_);
    std::string buf(static_cast<size_t>(size - offset_), '\0');
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    buf.resize(static_cast<size_t>(in.gcount()));
    offset_ += static_cast<std::streamoff>(buf.size());
    return buf;
  }

 private:
  std::string path_;
  std::streamoff offset_ = 0;
};

namespace {

// The last `bytes` of a file (the growing log, for a bed's progress).
std::string ReadTail(const std::string& path, size_t bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  const std::streamoff from = std::max<std::streamoff>(0, size - static_cast<std::streamoff>(bytes));
  in.seekg(from);
  std::string buf(static_cast<size_t>(size - from), '\0');
  in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
  buf.resize(static_cast<size_t>(in.gcount()));
  if (from > 0) {
    // Drop the partial first line; a dummy first line stands in for the version line.
    size_t nl = buf.find('\n');
    buf = "(tail)\n" + (nl == std::string::npos ? std::string() : buf.substr(nl + 1));
  }
  return buf;
}

}  // namespace

// The first `bytes` of a file (the drive start marker is near the top of the log).
std::string ReadHead(const std::string& path, size_t bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  std::string buf(bytes, '\0');
  in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
  buf.resize(static_cast<size_t>(in.gcount()));
  // Only whole lines: the last one may still be being written.
  const size_t nl = buf.rfind('\n');
  buf.resize(nl == std::string::npos ? 0 : nl + 1);
  return buf;
}

// Progress of a running job, for its heartbeats. A run's dump is read once, as it grows: each new
// frame updates the heartbeat and becomes one of the SO's samples, so the end of the run only
// reads what was appended last (Finish).
class JobProgress {
 public:
  JobProgress(const RunDir& dir, api::JobKind kind, double dt)
      : kind_(kind), dt_(dt), dump_(dir.File(kTrajectoryDumpFile)), log_path_(dir.File(kLogFile)), samples_(dt) {}

  api::Heartbeat Read() {
    if (kind_ == api::JobKind::kRun) {
      FeedNew();
    } else {
      EngineLog log = ParseEngineLog(ReadTail(log_path_, 64 * 1024));
      if (log.last_thermo_step >= 0) beat_.step = log.last_thermo_step;
    }
    beat_.sim_time_s = static_cast<double>(beat_.step) * dt_;
    return beat_;
  }

  // For a run with a precision target: whether it should end now (workers/job_outcome.h
  // FollowRun), on the samples read so far.
  StopVerdict Follow(const DriveInfo& drive, const PrecisionTarget& target) {
    if (!dump_status_.ok()) return StopVerdict::kContinue;
    if (!start_) start_ = ParseEngineLog(ReadHead(log_path_, 64 * 1024)).drive_start;
    return FollowRun(samples_.samples(), drive, start_, target);
  }

  // The SO's samples of the whole dump (a torn last frame dropped), or why it cannot be read.
  Result<std::vector<SoSample>> Finish() {
    FeedNew();
    if (!dump_status_.ok()) return dump_status_;
    if (Status s = reader_.Finish(); !s.ok()) return s;
    return samples_.Take();
  }

 private:
  void FeedNew() {
    std::string bytes = dump_.ReadNew();
    if (bytes.empty() || !dump_status_.ok()) return;
    // Frames are lent one by one (no copies); an error stops the reader for good.
    DumpFrameFn sink([this](const DumpFrameView& f) {
      int cz = f.Column("z");
      if (cz >= 0 && f.atoms > 0) {
        beat_.step = f.step;
        beat_.so_z = f.At(0, cz);
      }
      samples_.OnFrame(f);
    });
    dump_status_ = reader_.Feed(bytes, sink);
  }

  api::JobKind kind_;
  double dt_;
  FileTail dump_;
  DumpReader reader_;
  std::string log_path_;
  SoSampleSink samples_;
  Status dump_status_;
  api::Heartbeat beat_;
  std::optional<DriveStartMarker> start_;  // from the log, once it has printed it
};

namespace {

std::string ReadFileOr(const std::string& path, const std::string& fallback) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fallback;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string JobName(const api::LeaseGrant& g) {
  return std::string(g.kind == api::JobKind::kBed ? "bed " : "run ") + std::to_string(g.id) + " attempt " +
         std::to_string(g.attempt);
}

}  // namespace

Worker::Worker(WorkerOptions options, ServerClient& client, Launcher& launcher)
    : options_(std::move(options)),
      clock_(options_.clock != nullptr ? options_.clock : &system_clock_),
      client_(client),
      launcher_(launcher),
      beds_(options_.workdir + "/beds",
            [this](const api::BedRef& bed, const std::string& dest) { return client_.DownloadBed(bed, dest); }) {}

WorkerStats Worker::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

void Worker::RequestStop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
}

bool Worker::Idle(double seconds) {
  std::unique_lock<std::mutex> lock(mu_);
  clock_->WaitFor(cv_, lock, seconds, [this] { return stopping_.load(); });
  return !stopping_;
}

bool Worker::RunFitsAllocation() {
  if (!options_.allocation_seconds_left) return true;
  std::optional<double> expected;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stats_.allocation_ending) return false;
    expected = longest_run_s_;
  }
  auto left = options_.allocation_seconds_left();
  if (!left.ok()) {
    // Slurm not answering is no reason to idle an allocation; its own signal still stops us.
    spdlog::warn("cannot read the allocation's end time ({}); leasing anyway", left.status().ToString());
    return true;
  }
  if (slurm::ShouldLease(*left, expected, options_.end_margin_s)) return true;
  std::lock_guard<std::mutex> lock(mu_);
  if (!stats_.allocation_ending) {
    stats_.allocation_ending = true;
    spdlog::info("the allocation ends in {:.0f} s and a run is expected to take {:.0f} s{}: no more leases", **left,
                 expected.value_or(options_.end_margin_s), expected ? "" : " (--end-margin, no run done yet)");
  }
  return false;
}

void Worker::Run() {
  const int slots = options_.once ? 1 : std::max(1, options_.slots);
  std::vector<std::thread> threads;
  for (int i = 0; i < slots; ++i) threads.emplace_back([this] { SlotLoop(); });
  for (auto& t : threads) t.join();
}

int Worker::Slots() const { return options_.once ? 1 : std::max(1, options_.slots); }

bool Worker::TakeFreeSlot() {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [this] { return stopping_.load() || slots_in_use_ < Slots(); });
  if (stopping_) return false;
  ++slots_in_use_;
  ++leasing_;
  return true;
}

void Worker::LeaseArrived(bool got_job) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    --leasing_;
    if (!got_job) --slots_in_use_;
  }
  cv_.notify_all();
}

int Worker::TakeIdleSlots(const api::LeaseGrant& grant) {
  const int ranks = std::max(1, options_.ranks);
  if (!grant.queue_dry || options_.launcher == LauncherKind::kDirect || options_.max_ranks <= ranks) return 0;
  std::unique_lock<std::mutex> lock(mu_);
  if (widen_refused_) return 0;
  // A slot whose lease is on its way holds its core: wait for that lease (one round trip) to
  // say whether it brought a job, or the core would idle through this one for nothing.
  clock_->WaitFor(cv_, lock, kLeaseInFlightWaitS, [this] { return stopping_.load() || leasing_ == 0; });
  const int extra = std::min(Slots() - slots_in_use_, options_.max_ranks / ranks - 1);
  if (extra <= 0) return 0;
  slots_in_use_ += extra;
  ++stats_.widened;
  return extra;
}

void Worker::ReturnSlots(int n) {
  if (n <= 0) return;
  {
    std::lock_guard<std::mutex> lock(mu_);
    slots_in_use_ -= n;
  }
  cv_.notify_all();
}

void Worker::RunOnSlot(const api::LeaseGrant& grant, std::optional<api::LeaseGrant>* next) {
  const int extra = TakeIdleSlots(grant);
  const int ranks = options_.ranks * (1 + extra);
  if (extra > 0) {
    spdlog::info("{}: nothing else is leasable and {} slot(s) of this worker idle: it runs on {} ranks",
                 JobName(grant), extra, ranks);
  }
  int lent = extra;  // RunJob gives them back early when the engine will not start on them
  RunJob(grant, next, ranks, &lent);
  ReturnSlots(lent + (next != nullptr && next->has_value() ? 0 : 1));
}

void Worker::SlotLoop() {
  double backoff = 0.5;
  auto idle_since = clock_->Monotonic();
  // A job leased together with the previous completion (one round trip per job); its slot is
  // still held.
  std::optional<api::LeaseGrant> next;
  while (!stopping_) {
    if (next) {
      api::LeaseGrant grant = std::move(*next);
      next.reset();
      {
        std::lock_guard<std::mutex> lock(mu_);
        ++stats_.leased;
      }
      RunOnSlot(grant, &next);
      idle_since = clock_->Monotonic();
      continue;
    }
    // A slot whose core is lent to a wider job leases nothing until that job ends. The core is
    // taken before the lease is asked for, so no other slot's job can take it while the lease is
    // on its way; it is given back when no job comes.
    if (!TakeFreeSlot()) break;
    if (!RunFitsAllocation()) {
      LeaseArrived(false);
      break;
    }
    api::LeaseRequest request{options_.name, options_.host, options_.ranks, options_.slurm_job};
    auto lease = client_.Lease(request);
    LeaseArrived(lease.ok() && lease->has_value());
    if (!lease.ok()) {
      if (lease.status().code() == StatusCode::kUnauthenticated ||
          lease.status().code() == StatusCode::kPermissionDenied) {
        spdlog::error("lease refused: {}", lease.status().ToString());
      } else {
        spdlog::warn("cannot lease ({}); retrying in {:.1f} s. Is the daemon running at the --server URL?",
                     lease.status().ToString(), backoff);
      }
      if (options_.exit_when_idle_s > 0 && Since(idle_since) >= options_.exit_when_idle_s) {
        spdlog::warn("no daemon answer for {:.0f} s (--exit-when-idle): this slot is done", Since(idle_since));
        break;
      }
      if (!Idle(backoff)) break;
      backoff = std::min(backoff * 2, options_.max_backoff_s);
      continue;
    }
    backoff = 0.5;
    if (!lease->has_value()) {
      if (options_.exit_when_idle_s > 0 && Since(idle_since) >= options_.exit_when_idle_s) {
        spdlog::info("no work for {:.0f} s (--exit-when-idle): this slot is done", Since(idle_since));
        break;
      }
      if (!Idle(options_.exit_when_idle_s > 0 ? std::min(options_.idle_poll_s, options_.exit_when_idle_s)
                                              : options_.idle_poll_s)) {
        break;
      }
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      ++stats_.leased;
    }
    RunOnSlot(**lease, &next);
    if (options_.once) break;
    idle_since = clock_->Monotonic();
  }
  if (next) {
    // Leased with the last completion just as the worker stopped: give it straight back.
    auto reply = client_.Release(next->token, "the worker stopped before starting it");
    spdlog::info("{}: handed back unstarted ({})", JobName(*next),
                 reply.ok() ? reply->state : reply.status().ToString() + "; its lease will expire");
    ReturnSlots(1);
  }
}

// One job as it is run: its lease, what will be reported, and where the reply's next grant goes.
struct Worker::Job {
  const api::LeaseGrant& grant;
  std::optional<api::LeaseGrant>* next;
  std::string name;
  double leased_at;  // the clock's monotonic time
  int ranks = 1;  // MPI ranks the engine runs on
  api::Completion completion;
};

void Worker::Abandon(Job& job, const std::string& why) {
  spdlog::warn("{}: not completed: {}", job.name, why);
  std::lock_guard<std::mutex> lock(mu_);
  ++stats_.abandoned;
}

// The worker is stopping: give the job back so it is queued again at once, attempt uncounted.
void Worker::HandBack(Job& job, const std::string& why) {
  auto reply = client_.Release(job.grant.token, why);
  if (!reply.ok()) {
    return Abandon(job, why + "; handing it back failed (" + reply.status().ToString() +
                            "), so the lease will expire and the job be leased again");
  }
  spdlog::info("{}: handed back to the daemon ({}): {}", job.name, reply->state, why);
  std::lock_guard<std::mutex> lock(mu_);
  ++stats_.released;
}

void Worker::Complete(Job& job, const RunDir* dir) {
  api::Completion& completion = job.completion;
  // How long a run takes, known before deciding whether the next one fits the allocation.
  if (completion.ok && job.grant.kind == api::JobKind::kRun) {
    std::lock_guard<std::mutex> lock(mu_);
    longest_run_s_ = std::max(longest_run_s_.value_or(0.0), Since(job.leased_at));
  }
  // Ask for the next job in the same call unless this slot is about to end.
  if (job.next != nullptr && !options_.once && !stopping_ && RunFitsAllocation()) {
    completion.next = api::LeaseRequest{options_.name, options_.host, options_.ranks, options_.slurm_job};
  }
  auto reply = client_.Complete(job.grant.token, completion);
  if (!reply.ok()) {
    if (reply.status().code() == StatusCode::kConflict) {
      Abandon(job, "the lease was lost before completion (another worker has the run)");
    } else {
      Abandon(job,
              "completion failed: " + reply.status().ToString() + "; the lease will expire and the run be retried");
    }
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++stats_.completed;
  }
  if (job.next != nullptr) *job.next = std::move(reply->next);
  if (completion.ok) {
    spdlog::info("{}: completed ({})", job.name, reply->state);
  } else {
    spdlog::warn("{}: failed {}: {} ({})", job.name, completion.failure->kind, completion.failure->message,
                 reply->state);
  }
  if (dir != nullptr && completion.ok && !options_.keep_run_dirs) {
    if (Status removed = dir->Remove(); !removed.ok())
      spdlog::warn("{}: its run directory {} stays ({}): the result is stored; remove it by hand", job.name,
                   dir->path(), removed.ToString());
  }
}

void Worker::Fail(Job& job, const RunDir* dir, const std::string& kind, const std::string& message) {
  job.completion.ok = false;
  job.completion.failure = api::Failure{kind, message};
  Complete(job, dir);
}

// An engine that exited at once without writing its log: its launcher refused to start it (or it
// was not there at all). Not an engine stopped by the worker or the daemon.
bool Worker::EngineNeverRan(const ExitFacts& facts, const RunDir& dir) const {
  if (facts.cancelled || facts.timed_out || facts.stalled || stopping_) return false;
  if (facts.started && facts.exit_code == 0 && facts.signal == 0) return false;
  return ReadFileOr(dir.File(kLogFile), "").empty();
}

void Worker::RunJob(const api::LeaseGrant& grant, std::optional<api::LeaseGrant>* next, int ranks) {
  RunJob(grant, next, ranks, nullptr);
}

void Worker::RunJob(const api::LeaseGrant& grant, std::optional<api::LeaseGrant>* next, int ranks, int* lent) {
  Job job{grant, next, JobName(grant), clock_->Monotonic(), ranks > 0 ? ranks : options_.ranks, {}};
  spdlog::info("{}: leased ({} steps, wall budget {} s, {} rank(s))", job.name, grant.steps, grant.wall_budget_s,
               job.ranks);
  job.completion.execution.host = options_.host;
  job.completion.execution.ranks = job.ranks;
  job.completion.execution.launcher = LauncherName(options_.launcher);

  auto dir = Prepare(job);
  if (!dir) return;
  // What the deck states, typed in the lease (core/deck.h DriveFacts): never read back from it.
  if (!(grant.dt_s > 0) || !std::isfinite(grant.dt_s)) {
    return Fail(job, &*dir, "bad_lease",
                "the lease carries no timestep (dt_s): the daemon is older than this worker; upgrade sandswimd");
  }
  const DriveInfo drive{grant.dt_s, grant.f_hz, grant.A_m, grant.z_floor_m,
                        grant.so_radius_m.value_or(kMaterials.d_so / 2)};
  auto progress = std::make_unique<JobProgress>(*dir, grant.kind, drive.dt);
  std::optional<ExitFacts> facts = Supervise(job, *dir, drive, *progress);
  if (!facts) return;  // abandoned or handed back
  if (job.ranks > options_.ranks && EngineNeverRan(*facts, *dir)) {
    // The launcher refused the extra ranks (an MPI without --oversubscribe, a host that will not
    // have them): no fault of the job's, so it is not failed (that would count an attempt, and
    // every retry would be widened again) but run at once on the worker's own ranks, and this
    // worker widens no job again.
    spdlog::warn("{}: the engine did not start on {} ranks ({}); it runs on {} rank(s), and this worker gives no "
                 "job idle slots' cores from now on (check the MPI launcher's output to widen again)",
                 job.name, job.ranks, LastLines(ReadFileOr(dir->File(kEngineOutputFile), facts->start_error), 3),
                 options_.ranks);
    {
      std::lock_guard<std::mutex> lock(mu_);
      widen_refused_ = true;
    }
    if (lent != nullptr) {
      ReturnSlots(*lent);
      *lent = 0;
    }
    job.ranks = options_.ranks;
    job.completion.execution.ranks = job.ranks;
    progress = std::make_unique<JobProgress>(*dir, grant.kind, drive.dt);
    facts = Supervise(job, *dir, drive, *progress);
    if (!facts) return;
  }

  const std::string log_text = ReadFileOr(dir->File(kLogFile), "");
  const EngineLog log = ParseEngineLog(log_text);
  job.completion.execution.engine_version = log.version_line;
  job.completion.log_tail =
      LastLines(log_text.empty() ? ReadFileOr(dir->File(kEngineOutputFile), "") : log_text, kLogTailLines);
  const bool is_run = grant.kind == api::JobKind::kRun;
  Result<std::vector<SoSample>> samples =
      is_run && facts->started ? progress->Finish() : Result<std::vector<SoSample>>(std::vector<SoSample>());
  std::optional<std::string> bed_dump;
  if (!is_run && std::filesystem::exists(dir->File(kBedDumpFile))) bed_dump = ReadFileOr(dir->File(kBedDumpFile), "");
  JobOutcome outcome = JudgeJob(grant.kind, grant.steps, *facts, log, drive, samples, grant.precision, bed_dump);
  if (outcome.failure) {
    if (outcome.engine_exit && facts->started && !facts->cancelled && !facts->timed_out && StoppedWithTheWorker()) {
      return HandBack(job, "the worker is stopping and its engine was stopped with it");
    }
    return Fail(job, &*dir, outcome.failure->kind, outcome.failure->message);
  }
  if (outcome.bed) return ReportBed(job, *dir, *outcome.bed);
  job.completion.ok = true;
  job.completion.result = std::move(outcome.result);
  job.completion.trajectory = std::move(outcome.trajectory);
  if (!grant.snapshots.empty() && !HandInSnapshots(job, *dir, job.completion.result->sim_time_s)) return;
  Complete(job, &*dir);
}

bool Worker::HandInSnapshots(Job& job, const RunDir& dir, double t_end) {
  const std::vector<SnapshotFrame> frames = ListSnapshotFrames(dir, job.grant.dt_s);
  if (frames.empty()) {
    spdlog::warn("{}: the run asked for snapshots but its engine wrote no frames; it completes without them", job.name);
    return true;
  }
  std::vector<double> frame_t;
  for (const SnapshotFrame& f : frames) frame_t.push_back(f.t);
  const std::vector<size_t> picked = PickSnapshotFrames(frame_t, job.grant.snapshots, t_end);
  for (size_t i = 0; i < picked.size(); ++i) {
    const SnapshotFrame& frame = frames[picked[i]];
    const std::string text = ReadFileOr(frame.path, "");
    Result<BedSnapshot> snapshot = ParseBedSnapshot(text);
    if (!snapshot.ok()) {
      spdlog::warn("{}: snapshot {} ({}) is unreadable and is left out: {}", job.name, i, frame.path,
                   snapshot.status().ToString());
      continue;
    }
    api::Snapshot meta;
    meta.idx = static_cast<int>(i);
    meta.fraction = job.grant.snapshots[i];
    meta.step = snapshot->step;
    meta.t_s = static_cast<double>(snapshot->step) * job.grant.dt_s;
    meta.grains = snapshot->grains();
    meta.bytes = static_cast<int64_t>(text.size());
    meta.sha256 = Sha256Hex(text);
    if (Status s = client_.UploadSnapshot(job.grant.token, meta.idx, text, meta.sha256); !s.ok()) {
      if (s.code() == StatusCode::kConflict) {
        Abandon(job, "the lease was lost during the snapshot upload");
        return false;
      }
      if (stopping_) {
        HandBack(job, "the worker stopped during the snapshot upload");
        return false;
      }
      spdlog::warn("{}: snapshot {} was not handed in ({}); the run completes without it", job.name, i, s.ToString());
      continue;
    }
    job.completion.snapshots.push_back(meta);
  }
  spdlog::info("{}: handed in {} of {} snapshot(s)", job.name, job.completion.snapshots.size(), picked.size());
  return true;
}

std::optional<RunDir> Worker::Prepare(Job& job) {
  const api::LeaseGrant& grant = job.grant;
  auto dir = RunDir::Create(options_.workdir, grant.kind, grant.id, grant.attempt);
  if (!dir.ok()) {
    spdlog::error("{}: {} (check --workdir: it must be writable)", job.name, dir.status().ToString());
    Abandon(job, dir.status().ToString());
    return std::nullopt;
  }
  if (std::optional<api::Failure> wrong = CheckDeckKey(grant); wrong) {
    spdlog::error("{}: {}", job.name, wrong->message);
    Fail(job, &*dir, wrong->kind, wrong->message);
    return std::nullopt;
  }
  const std::string deck_file = grant.kind == api::JobKind::kBed ? "bed.in" : "drive.in";
  if (Status s = dir->Write(deck_file, grant.deck); !s.ok()) {
    Abandon(job, s.ToString());
    return std::nullopt;
  }
  if (grant.kind == api::JobKind::kRun) {
    if (!grant.bed) {
      Fail(job, &*dir, "bed_mismatch", "the run's lease names no bed");
      return std::nullopt;
    }
    if (Status s = beds_.Provide(*grant.bed, *dir); !s.ok()) {
      if (stopping_) {
        HandBack(job, "the worker stopped while fetching the bed");
      } else {
        Fail(job, &*dir, "bed_mismatch", s.reason());
      }
      return std::nullopt;
    }
  }
  return std::move(dir).value();
}

std::optional<ExitFacts> Worker::Supervise(Job& job, const RunDir& dir, const DriveInfo& drive, JobProgress& progress) {
  const api::LeaseGrant& grant = job.grant;
  const std::string deck_file = grant.kind == api::JobKind::kBed ? "bed.in" : "drive.in";
  LaunchSpec spec = EngineCommand(options_.launcher, job.ranks, options_.engine, deck_file, kLogFile, dir.path(),
                                  options_.as_root, /*widened=*/job.ranks > options_.ranks);
  spec.output_file = kEngineOutputFile;
  ExitFacts facts;
  auto started = launcher_.Start(spec);
  job.completion.execution.lease_to_start_s = Since(job.leased_at);
  if (!started.ok()) {
    facts.started = false;
    facts.start_error = started.status().reason();
    return facts;
  }
  std::unique_ptr<EngineProcess> proc = std::move(*started);
  const double start = clock_->Monotonic();
  const double hb_every = std::max(0.001, std::min(options_.heartbeat_every_s, grant.ttl_s / 3));
  double next_beat = start + hb_every;
  bool stop_asked = false;  // the control file asks the deck to end the run
  int64_t last_step = -1;   // the furthest step seen, and when it was first seen
  auto moved_at = start;
  // The engine's CPU when the step last moved, and whether it was seen runnable since: a stand
  // with the engine runnable but given little CPU is starvation, not a hang.
  auto engine_cpu = [&]() -> std::optional<TreeCpu> {
    return options_.engine_cpu ? options_.engine_cpu(proc->pid()) : std::nullopt;
  };
  std::optional<TreeCpu> cpu_at_move = engine_cpu();
  bool runnable_since_move = false;
  while (true) {
    // Wake for the next heartbeat, and at least every 0.25 s to notice a stop request.
    const double until_beat = next_beat - clock_->Monotonic();
    if (proc->WaitFor(std::clamp(until_beat, 0.0, 0.25))) break;
    if (stopping_) {
      proc->Stop(options_.stop_grace_s);
      HandBack(job, "the worker is stopping");
      return std::nullopt;
    }
    if (grant.wall_budget_s > 0 && Since(start) > grant.wall_budget_s) {
      spdlog::warn("{}: wall-time budget of {} s used up; stopping the engine", job.name, grant.wall_budget_s);
      facts.timed_out = true;
      proc->Stop(options_.stop_grace_s);
      break;
    }
    if (clock_->Monotonic() >= next_beat) {
      const api::Heartbeat beat = progress.Read();
      std::optional<TreeCpu> cpu_now;
      const bool moved = beat.step > last_step;
      if (moved) {
        last_step = beat.step;
        moved_at = clock_->Monotonic();
        cpu_at_move = engine_cpu();
        runnable_since_move = false;
      } else if (options_.stall_after_s > 0 && (cpu_now = engine_cpu()) && cpu_now->runnable) {
        runnable_since_move = true;
      }
      const double stood_s = Since(moved_at);
      const bool starved = cpu_now && cpu_at_move && runnable_since_move &&
                           cpu_now->cpu_s - cpu_at_move->cpu_s < 0.25 * stood_s;
      if (!moved && options_.stall_after_s > 0 && stood_s > options_.stall_after_s && starved) {
        spdlog::warn("{}: the engine's simulated time stood still for {:.0f} s while it had {:.1f} CPU-s: the machine "
                     "is busy with other work, so it is not counted as hung (waiting another {:.0f} s)",
                     job.name, stood_s, cpu_now->cpu_s - cpu_at_move->cpu_s, options_.stall_after_s);
        moved_at = clock_->Monotonic();
        cpu_at_move = cpu_now;
        runnable_since_move = false;
      } else if (!moved && options_.stall_after_s > 0 && stood_s > options_.stall_after_s) {
        facts.stalled = true;
        facts.stall_note = "its simulated time stood at t = " + FormatNumber(beat.sim_time_s) + " s (step " +
                           std::to_string(std::max<int64_t>(last_step, 0)) + ") for " +
                           std::to_string(static_cast<int64_t>(Since(moved_at))) + " s of wall time";
        spdlog::warn("{}: the engine is hung ({}); stopping it", job.name, facts.stall_note);
        proc->Stop(options_.stop_grace_s);
        break;
      }
      if (!grant.snapshots.empty()) DropUnneededSnapshotFrames(dir, grant.dt_s, grant.snapshots, beat.sim_time_s);
      if (grant.precision && !stop_asked) {
        const StopVerdict verdict = progress.Follow(drive, *grant.precision);
        if (verdict != StopVerdict::kContinue) {
          // The deck reads the control file after its next chunk and ends the run cleanly.
          if (Status s = dir.Write(kControlFile, ControlFileText(verdict)); s.ok()) {
            stop_asked = true;
            spdlog::info("{}: {} at t = {} s; asking the engine to stop", job.name,
                         verdict == StopVerdict::kTargetMet ? "precision target met" : "steady window closed",
                         beat.sim_time_s);
          } else {
            spdlog::warn("{}: cannot ask the engine to stop ({}); it runs to its maximum", job.name, s.ToString());
          }
        }
      }
      auto reply = client_.Heartbeat(grant.token, beat);
      if (reply.ok()) {
        if (reply->cancel) {
          spdlog::info("{}: cancelled by the daemon; stopping the engine", job.name);
          facts.cancelled = true;
          proc->Stop(options_.stop_grace_s);
          break;
        }
      } else if (reply.status().code() == StatusCode::kConflict) {
        proc->Stop(options_.stop_grace_s);
        Abandon(job, "the lease was lost (409 on heartbeat); the engine was stopped");
        return std::nullopt;
      } else {
        spdlog::warn("{}: heartbeat failed ({}); the job keeps running", job.name, reply.status().ToString());
      }
      next_beat = clock_->Monotonic() + hb_every;
    }
  }
  const ExitStatus exit_status = proc->exit_status();
  facts.exit_code = exit_status.exit_code;
  facts.signal = exit_status.signal;
  job.completion.execution.wall_s = exit_status.wall_s;
  job.completion.execution.cpu_s = exit_status.cpu_s;
  return facts;
}

// A stop of the whole worker (scancel, the allocation's end, systemd) also reaches the engine,
// which then exits -- with status 0 if it was LIGGGHTS that got SIGTERM -- short of its steps, at
// about the moment the worker hears of it: give the worker's own stop a moment to land. An engine
// stopped with its worker is handed back, not failed.
bool Worker::StoppedWithTheWorker() {
  if (!stopping_ && options_.stop_settle_s > 0) {
    std::unique_lock<std::mutex> lock(mu_);
    clock_->WaitFor(cv_, lock, options_.stop_settle_s, [this] { return stopping_.load(); });
  }
  return stopping_;
}

void Worker::ReportBed(Job& job, const RunDir& dir, api::BedResult bed) {
  const std::string restart = dir.File(kBedRestartFile);
  auto sha = Sha256OfFile(restart);
  if (!sha.ok()) return Fail(job, &dir, "bad_output", "the bed deck wrote no " + std::string(kBedRestartFile));
  std::ifstream in(restart, std::ios::binary | std::ios::ate);
  bed.sha256 = *sha;
  bed.bytes = static_cast<int64_t>(in.tellg());
  if (Status s = client_.UploadBed(job.grant.id, job.grant.token, restart, *sha); !s.ok()) {
    if (s.code() == StatusCode::kConflict) return Abandon(job, "the lease was lost before the bed upload");
    if (stopping_) return HandBack(job, "the worker stopped during the bed upload");
    return Fail(job, &dir, "bad_output", "bed upload failed: " + s.ToString());
  }
  job.completion.ok = true;
  job.completion.bed_result = bed;
  Complete(job, &dir);
}

}  // namespace sandswim::worker
