#include "server/jobs/lease_queue.h"

#include <fcntl.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server/store/cost_model.h"

#include "core/keys.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "core/trajectory.h"
#include "platform/clock.h"
#include "platform/data_dir.h"
#include "platform/files.h"
#include "server/store/cost_model.h"
#include "server/store/store.h"
#include "server/store/temp_store_test_util.h"
#include "server/jobs/submission.h"
#include "tests/fixture_file.h"

namespace sandswim {
namespace {

namespace fs = std::filesystem;

nlohmann::json OmegaSignSweep(const std::string& name = "omega-sign") {
  nlohmann::json j = nlohmann::json::parse(R"({"scale": "smoke",
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
    "axes": [{"param": "Omega", "values": [-80, 80]}], "combine": "product"})");
  j["name"] = name;
  return j;
}

api::Completion OkRun(double uz = -0.01) {
  api::Completion c;
  c.ok = true;
  c.result = api::RunResult{};
  c.result->uz = uz;
  c.result->stop_reason = "duration";
  c.trajectory = api::Trajectory{{0, 0.1}, {0, 0}, {0, 0}, {0, -0.001}};
  c.execution.host = "test-host";
  c.execution.engine_version = kTestEngine;
  c.log_tail = "Total wall time: 0:00:01";
  return c;
}

api::Completion Failed(const std::string& kind, const std::string& message = "it broke") {
  api::Completion c;
  c.ok = false;
  c.failure = api::Failure{kind, message};
  return c;
}

class LeaseQueueTest : public ::testing::Test {
 protected:
  void SetUp() override { OpenStore(); }
  void TearDown() override { queue_.reset(); }
  // A new, empty store (and directory) and a new queue with options_.
  void Renew() {
    queue_.reset();
    ASSERT_TRUE(store_.Renew());
    OpenStore();
  }
  // A daemon (re)start: the store's file opened again, a new queue with options_.
  void OpenStore() {
    queue_.reset();
    ASSERT_TRUE(store_.Reopen());
    queue_ = std::make_unique<LeaseQueue>(store_.get(), &clock_, options_);
  }
  int64_t SubmitJson(const nlohmann::json& body, bool force = false) {
    auto req = ParseSubmitRequest(body);
    EXPECT_TRUE(req.ok()) << req.status().ToString();
    req->force = force;
    auto r = Submit(*store_, *req, kTestEngine, clock_.Now());
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return r.ok() ? r->sweep_ids.at(0) : 0;
  }
  api::LeaseGrant MustLease(const std::string& worker = "w1") {
    auto g = queue_->Lease({worker, "host", 1});
    EXPECT_TRUE(g.ok()) << g.status().ToString();
    EXPECT_TRUE(g.ok() && g->has_value());
    return g.ok() && g->has_value() ? **g : api::LeaseGrant{};
  }
  // Leases the bed, uploads its restart and completes it.
  void PrepareBed() {
    api::LeaseGrant g = MustLease("bed-worker");
    ASSERT_EQ(g.kind, api::JobKind::kBed);
    const std::string bytes = "restart bytes";
    ASSERT_TRUE(queue_->PutBedRestart(g.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
    api::Completion c;
    c.ok = true;
    c.bed_result = api::BedResult{};
    c.bed_result->grains = 3700;
    c.bed_result->sha256 = Sha256Hex(bytes);
    auto r = queue_->Complete(g.token, c);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_EQ(r->state, "done");
  }
  std::string RunState(int64_t id) {
    auto r = store_->GetRun(id);
    return r.ok() ? ToString(r->summary.state) : r.status().ToString();
  }
  int64_t Rows(const std::string& table) { return store_->db().CountRows(table).value(); }

  FakeClock clock_;
  LeaseQueueOptions options_{/*ttl_s=*/60, /*max_attempts=*/3, /*wall_budget_s=*/0};
  testing::TempStore store_{"lq", "db/sandswim.db"};
  std::unique_ptr<LeaseQueue> queue_;
};

TEST_F(LeaseQueueTest, NothingToLeaseOnAnEmptyQueue) {
  auto g = queue_->Lease({"w", "h", 1});
  ASSERT_TRUE(g.ok());
  EXPECT_FALSE(g->has_value());
}

TEST_F(LeaseQueueTest, BedIsLeasedBeforeRunsAndRunsOnlyOnceTheBedIsDone) {
  SubmitJson(OmegaSignSweep());
  api::LeaseGrant bed = MustLease();
  EXPECT_EQ(bed.kind, api::JobKind::kBed);
  EXPECT_EQ(bed.token.size(), 32u);
  EXPECT_FALSE(bed.deck.empty());
  // The bed is running: the runs wait for it, so nothing else is leasable.
  auto none = queue_->Lease({"w2", "h", 1});
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  // Completing without an upload is refused and changes nothing.
  api::Completion c;
  c.ok = true;
  c.bed_result = api::BedResult{};
  EXPECT_EQ(queue_->Complete(bed.token, c).status().code(), StatusCode::kFailedPrecondition);
  const std::string bytes = "restart";
  EXPECT_EQ(queue_->PutBedRestart(bed.token, bytes, Sha256Hex("other"), store_.dir().string()).code(),
            StatusCode::kInvalidArgument);
  ASSERT_TRUE(queue_->PutBedRestart(bed.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
  ASSERT_EQ(queue_->Complete(bed.token, c)->state, "done");
  auto file = queue_->GetBedRestart(bed.id);
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  std::ifstream in(file->path, std::ios::binary);
  std::string read((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(read, bytes);
  EXPECT_EQ(file->sha256, Sha256Hex(bytes));

  api::LeaseGrant r1 = MustLease();
  api::LeaseGrant r2 = MustLease();
  EXPECT_EQ(r1.kind, api::JobKind::kRun);
  EXPECT_EQ(r2.kind, api::JobKind::kRun);
  EXPECT_LT(r1.id, r2.id);  // oldest first
  ASSERT_TRUE(r1.bed.has_value());
  EXPECT_EQ(r1.bed->id, bed.id);
  EXPECT_EQ(r1.bed->sha256, Sha256Hex(bytes));
  EXPECT_GT(r1.steps, 0);
  EXPECT_GT(r1.duration_s, 0);
  auto none2 = queue_->Lease({"w3", "h", 1});
  EXPECT_FALSE(none2->has_value());
}

// A grant says whether anything else is leasable once it runs (queue_dry), so that a worker may
// give it the cores of slots that would otherwise idle: a bed its runs wait for with no other bed
// queued, the last run of the queue; not a bed while another bed or a run is leasable.
TEST_F(LeaseQueueTest, GrantsSayWhenNothingElseIsLeasable) {
  nlohmann::json two_beds = OmegaSignSweep();
  two_beds["replicates"] = 2;
  SubmitJson(two_beds);
  api::LeaseGrant bed1 = MustLease();
  ASSERT_EQ(bed1.kind, api::JobKind::kBed);
  EXPECT_FALSE(bed1.queue_dry);  // the other bed is leasable
  api::LeaseGrant bed2 = MustLease();
  ASSERT_EQ(bed2.kind, api::JobKind::kBed);
  EXPECT_TRUE(bed2.queue_dry);  // every run waits for one of the two
  EXPECT_TRUE(nlohmann::json(bed2).at("queue_dry").get<bool>());
  EXPECT_FALSE(nlohmann::json(bed1).contains("queue_dry"));  // absent means false
  EXPECT_TRUE(nlohmann::json(bed2).get<api::LeaseGrant>().queue_dry);
  for (const api::LeaseGrant& bed : {bed1, bed2}) {
    const std::string bytes = "restart " + std::to_string(bed.id);
    ASSERT_TRUE(queue_->PutBedRestart(bed.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
    api::Completion c;
    c.ok = true;
    c.bed_result = api::BedResult{};
    c.bed_result->grains = 3700;
    c.bed_result->sha256 = Sha256Hex(bytes);
    c.execution.ranks = bed.queue_dry ? 2 : 1;  // as a worker with an idle slot ran it
    ASSERT_EQ(queue_->Complete(bed.token, c)->state, "done");
  }
  {
    // The event log says on how many ranks each bed was prepared.
    auto t = store_->db().Begin();
    ASSERT_TRUE(t.ok());
    Statement st = t->Prepare("SELECT detail FROM events WHERE kind = 'bed.done' AND subject = ?1");
    const std::string subject = "bed/" + std::to_string(bed2.id);
    st.Bind(1, subject);
    ASSERT_TRUE(*st.Step());
    EXPECT_EQ(nlohmann::json::parse(st.Text(0)).at("ranks"), 2);
  }
  // So do the beds' rows (the cost model's bed rates are per rank count) and the API's view.
  EXPECT_EQ(store_->GetBed(bed1.id)->ranks, std::optional<int>(1));
  EXPECT_EQ(store_->GetBed(bed2.id)->ranks, std::optional<int>(2));
  EXPECT_EQ(nlohmann::json(*store_->GetBed(bed2.id)).at("ranks"), 2);
  // Four runs (two Omega on two beds): only the last one is granted with the queue dry.
  std::vector<bool> dry;
  for (int i = 0; i < 4; ++i) dry.push_back(MustLease().queue_dry);
  EXPECT_EQ(dry, (std::vector<bool>{false, false, false, true}));
}

// With no budget from the operator every grant carries the cost model's: kWallBudgetMultiple times
// its prediction plus the margin, at the default rates until jobs are measured; an operator's
// budget is passed as it is.
TEST_F(LeaseQueueTest, GrantsCarryAWallBudgetFromTheCostModel) {
  SubmitJson(OmegaSignSweep());
  api::LeaseGrant bed = MustLease();
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  const double smoke_grains = EstimatedGrains(*FindScale("smoke"));
  EXPECT_DOUBLE_EQ(bed.wall_budget_s,
                   std::ceil(kWallBudgetMultiple * smoke_grains * kDefaultBedSecondsPerGrain + kWallBudgetMarginS));
  const std::string bytes = "restart";
  ASSERT_TRUE(queue_->PutBedRestart(bed.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
  api::Completion c;
  c.ok = true;
  c.bed_result = api::BedResult{};
  c.bed_result->grains = 3700;
  c.bed_result->sha256 = Sha256Hex(bytes);
  ASSERT_EQ(queue_->Complete(bed.token, c)->state, "done");
  api::LeaseGrant run = MustLease();
  ASSERT_EQ(run.kind, api::JobKind::kRun);
  EXPECT_DOUBLE_EQ(run.wall_budget_s, std::ceil(kWallBudgetMultiple * static_cast<double>(run.steps) * 3701 *
                                                        kDefaultSecondsPerParticleStep +
                                                    kWallBudgetMarginS));
  LeaseQueue fixed(store_.get(), &clock_, LeaseQueueOptions{60, 3, /*wall_budget_s=*/1234});
  auto other = fixed.Lease({"w2", "h", 1});
  ASSERT_TRUE(other.ok() && other->has_value());
  EXPECT_DOUBLE_EQ((*other)->wall_budget_s, 1234);
}

// A grant carries, typed, the numbers its deck states (core/deck.h DriveFacts): the worker reads
// its dump with them and never parses the deck.
TEST_F(LeaseQueueTest, GrantsCarryTheDrivesFactsTheirDeckStates) {
  SubmitJson(OmegaSignSweep());
  api::LeaseGrant bed = MustLease();
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  EXPECT_GT(bed.dt_s, 0.0);
  EXPECT_NE(bed.deck.find("timestep        " + FormatNumber(bed.dt_s) + "\n"), std::string::npos) << bed.deck;
  const std::string bytes = "restart bytes";
  ASSERT_TRUE(queue_->PutBedRestart(bed.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
  api::Completion done;
  done.ok = true;
  done.bed_result = api::BedResult{};
  done.bed_result->sha256 = Sha256Hex(bytes);
  ASSERT_TRUE(queue_->Complete(bed.token, done).ok());
  for (int i = 0; i < 2; ++i) {
    api::LeaseGrant run = MustLease();
    ASSERT_EQ(run.kind, api::JobKind::kRun);
    Result<DriveInfo> stated = ReadDriveInfo(run.deck);
    ASSERT_TRUE(stated.ok()) << stated.status().ToString();
    EXPECT_EQ(run.dt_s, stated->dt);
    EXPECT_EQ(run.f_hz, stated->f);
    EXPECT_EQ(run.A_m, stated->A);
    ASSERT_TRUE(run.z_floor_m.has_value());
    EXPECT_EQ(run.z_floor_m, stated->z_floor);
    EXPECT_GT(run.f_hz, 0.0);
    // The same on the wire.
    api::LeaseGrant back = nlohmann::json(run).get<api::LeaseGrant>();
    EXPECT_EQ(back.dt_s, run.dt_s);
    EXPECT_EQ(back.f_hz, run.f_hz);
    EXPECT_EQ(back.z_floor_m, run.z_floor_m);
  }
}

// A bed of stiffer grains is poured with its own, shorter step (core/materials.h TimeStep: 3.1e-6 s
// for E = 1e8 Pa), and its lease says so: the worker reads the bed's dump and paces its progress
// with it (it was Table 1's 1e-5 s for every bed, 3.2 times the real step here).
TEST_F(LeaseQueueTest, ABedIsLeasedWithItsOwnTimeStep) {
  nlohmann::json j = OmegaSignSweep();
  j["base"]["grain_youngs"] = 1e8;
  SubmitJson(j);
  api::LeaseGrant bed = MustLease();
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  EXPECT_EQ(bed.dt_s, 3.1e-6);
  EXPECT_NE(bed.deck.find("timestep        3.1e-06\n"), std::string::npos) << bed.deck;
  EXPECT_EQ(nlohmann::json(bed).get<api::LeaseGrant>().dt_s, 3.1e-6);
}

TEST_F(LeaseQueueTest, RunsOfOtherMaterialsAreLeasedWithTheirOwnDecks) {
  // The runs table keeps each run's materials (migration 12): the deck rendered at lease time is
  // the one its key was made from, with the SO's density set after read_restart and the stiffer
  // grains' shorter step.
  nlohmann::json j = OmegaSignSweep();
  j["base"]["grain_youngs"] = 1e8;
  j["axes"] = nlohmann::json::array({{{"param", "so_density"}, {"values", {2500, 5000}}}});
  const int64_t sweep = SubmitJson(j);
  ASSERT_GT(sweep, 0);
  EXPECT_EQ(Rows("beds"), 1);  // the SO's density keeps the bed
  PrepareBed();
  std::vector<std::string> decks;
  for (int i = 0; i < 2; ++i) {
    api::LeaseGrant run = MustLease();
    ASSERT_EQ(run.kind, api::JobKind::kRun);
    EXPECT_EQ(run.dt_s, 3.1e-6);
    EXPECT_NE(run.deck.find("timestep        3.1e-06\n"), std::string::npos);
    auto stored = store_->GetRun(run.id);
    ASSERT_TRUE(stored.ok()) << stored.status().ToString();
    EXPECT_EQ(stored->summary.point.materials.youngs, 1e8);
    EXPECT_EQ(stored->deck, run.deck);
    decks.push_back(run.deck);
  }
  EXPECT_EQ(decks[0].find("set group so density"), std::string::npos);
  EXPECT_NE(decks[1].find("set group so density 5000\n"), std::string::npos);
  auto results = store_->SweepResults(sweep);
  ASSERT_TRUE(results.ok()) << results.status().ToString();
  ASSERT_EQ(results->size(), 2u);
  EXPECT_EQ((*results)[1].point.materials.rho_so, 5000);
}

TEST_F(LeaseQueueTest, ExpiredLeaseIsRequeuedWithItsAttemptCountedThenFails) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  EXPECT_EQ(g.attempt, 1);
  clock_.Advance(30);
  ASSERT_TRUE(queue_->Heartbeat(g.token, {0.1, -0.01, 10000}).ok());
  clock_.Advance(59);  // the heartbeat extended the lease: still held
  EXPECT_EQ(*queue_->ExpireLeases(), 0);
  clock_.Advance(2);
  EXPECT_EQ(*queue_->ExpireLeases(), 1);
  EXPECT_EQ(RunState(g.id), "queued");
  EXPECT_EQ(queue_->Heartbeat(g.token, {}).status().code(), StatusCode::kConflict);

  api::LeaseGrant g2 = MustLease();
  EXPECT_EQ(g2.id, g.id);
  EXPECT_EQ(g2.attempt, 2);
  clock_.Advance(61);
  api::LeaseGrant g3 = MustLease();  // Lease() reclaims the expired one itself
  EXPECT_EQ(g3.id, g.id);
  EXPECT_EQ(g3.attempt, 3);
  clock_.Advance(61);
  EXPECT_EQ(*queue_->ExpireLeases(), 1);
  auto run = store_->GetRun(g.id);
  EXPECT_EQ(run->summary.state, JobState::kFailed);
  EXPECT_EQ(run->summary.attempts, 3);
  ASSERT_TRUE(run->summary.last_error.has_value());
  EXPECT_EQ(run->summary.last_error->kind, "lease_expired");
  EXPECT_EQ(store_->GetMetrics()->expirations, 3);
}

TEST_F(LeaseQueueTest, FailuresRetryUntilMaxAttemptsAndKeepTheLastReason) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  int64_t id = 0;
  for (int i = 1; i <= 3; ++i) {
    api::LeaseGrant g = MustLease();
    if (id == 0) id = g.id;
    ASSERT_EQ(g.id, id);
    auto r = queue_->Complete(g.token, Failed("signal", "attempt " + std::to_string(i)));
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->state, i < 3 ? "queued" : "failed");
  }
  auto run = store_->GetRun(id);
  EXPECT_EQ(run->summary.state, JobState::kFailed);
  EXPECT_EQ(run->summary.last_error->kind, "signal");
  EXPECT_EQ(run->summary.last_error->message, "attempt 3");
}

// The same deck on the same bed fails the same way again: these are not retried.
TEST_F(LeaseQueueTest, FailuresThatRepeatByNatureAreNotRetried) {
  for (const char* kind : {"deck_error", "lost_atoms", "bad_output", "not_equilibrated", "bad_lease"}) {
    SCOPED_TRACE(kind);
    Renew();  // a fresh store and queue for each kind
    SubmitJson(OmegaSignSweep());
    PrepareBed();
    api::LeaseGrant g = MustLease();
    EXPECT_EQ(queue_->Complete(g.token, Failed(kind, "x"))->state, "failed");
  }
}

// A hung engine may be the host's: it gets one more attempt, not all of them.
TEST_F(LeaseQueueTest, AStalledRunIsRetriedOnce) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant first = MustLease();
  EXPECT_EQ(queue_->Complete(first.token, Failed("stalled", "no step past 0 for 600 s"))->state, "queued");
  api::LeaseGrant second = MustLease();
  ASSERT_EQ(second.id, first.id);
  EXPECT_EQ(queue_->Complete(second.token, Failed("stalled", "no step past 0 for 600 s"))->state, "failed");
}

TEST_F(LeaseQueueTest, CompletionIsIdempotentPerToken) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  EXPECT_EQ(queue_->Complete(g.token, OkRun())->state, "done");
  int64_t events = Rows("events");
  EXPECT_EQ(queue_->Complete(g.token, OkRun(0.5))->state, "duplicate");
  EXPECT_EQ(queue_->Complete(g.token, Failed("signal"))->state, "duplicate");
  EXPECT_EQ(Rows("results"), 1);
  EXPECT_EQ(Rows("events"), events);
  auto run = store_->GetRun(g.id);
  EXPECT_EQ(run->summary.state, JobState::kDone);
  EXPECT_EQ(run->result->result.uz, -0.01);
  ASSERT_TRUE(run->trajectory.has_value());
  EXPECT_EQ(run->trajectory->z.size(), 2u);
  EXPECT_EQ(run->log_tail, "Total wall time: 0:00:01");
  EXPECT_EQ(queue_->Heartbeat(g.token, {}).status().code(), StatusCode::kConflict);
}

TEST_F(LeaseQueueTest, LateCompletionFromAnExpiredLeaseAfterReleaseConflicts) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant old = MustLease("slow");
  clock_.Advance(61);
  api::LeaseGrant fresh = MustLease("fast");
  ASSERT_EQ(fresh.id, old.id);
  auto late = queue_->Complete(old.token, OkRun(0.9));
  EXPECT_EQ(late.status().code(), StatusCode::kConflict);
  EXPECT_EQ(Rows("results"), 0);
  EXPECT_EQ(RunState(old.id), "running");
  EXPECT_EQ(queue_->Complete(fresh.token, OkRun(-0.02))->state, "done");
  EXPECT_EQ(queue_->Complete(old.token, OkRun(0.9)).status().code(), StatusCode::kConflict);
  EXPECT_EQ(Rows("results"), 1);
  EXPECT_EQ(store_->GetRun(old.id)->result->result.uz, -0.02);
}

// The worker's lease -> engine start time is kept with the result and read back with the run.
TEST_F(LeaseQueueTest, ResultKeepsLeaseToStartTime) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  api::Completion c = OkRun();
  c.execution.lease_to_start_s = 0.125;
  ASSERT_EQ(queue_->Complete(g.token, c)->state, "done");
  auto run = store_->GetRun(g.id);
  ASSERT_TRUE(run.ok() && run->result.has_value());
  EXPECT_DOUBLE_EQ(run->result->execution.lease_to_start_s, 0.125);
  EXPECT_DOUBLE_EQ(nlohmann::json(*run->result).at("lease_to_start_s").get<double>(), 0.125);
}

// A completion that asks for the next job gets it in the same transaction: the bed's completion
// makes its runs leasable at once, a run's completion leases the following run, and at the end
// the reply simply has no next job.
TEST_F(LeaseQueueTest, CompletionCanLeaseTheNextJob) {
  SubmitJson(OmegaSignSweep());
  api::LeaseGrant bed = MustLease("w");
  const std::string bytes = "restart bytes";
  ASSERT_TRUE(queue_->PutBedRestart(bed.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
  api::Completion bed_done;
  bed_done.ok = true;
  bed_done.bed_result = api::BedResult{};
  bed_done.bed_result->sha256 = Sha256Hex(bytes);
  bed_done.next = api::LeaseRequest{"w", "host", 1};
  auto r = queue_->Complete(bed.token, bed_done);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->state, "done");
  ASSERT_TRUE(r->next.has_value());
  const api::LeaseGrant first = *r->next;
  EXPECT_EQ(first.kind, api::JobKind::kRun);
  EXPECT_EQ(RunState(first.id), "running");

  api::Completion c = OkRun();
  c.next = api::LeaseRequest{"w", "host", 1};
  r = queue_->Complete(first.token, c);
  ASSERT_TRUE(r.ok() && r->next.has_value());
  const api::LeaseGrant second = *r->next;
  EXPECT_NE(second.id, first.id);
  EXPECT_EQ(RunState(first.id), "done");
  EXPECT_EQ(RunState(second.id), "running");

  r = queue_->Complete(second.token, c);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->state, "done");
  EXPECT_FALSE(r->next.has_value());  // nothing left
  EXPECT_EQ(Rows("results"), 2);
  // Serialised, an absent next job is an absent field.
  EXPECT_FALSE(nlohmann::json(*r).contains("next"));
}

// The reply to a completion with `next` is lost and the worker sends it again: the job the first
// one leased (never received) is taken back unstarted, attempt uncounted, and a job is leased
// afresh -- no job waits out a lease nobody holds.
TEST_F(LeaseQueueTest, RepeatedCompletionTakesBackTheGrantItsLostReplyCarried) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant first = MustLease();
  api::Completion c = OkRun();
  c.next = api::LeaseRequest{"w1", "host", 1};
  auto lost = queue_->Complete(first.token, c);
  ASSERT_TRUE(lost.ok() && lost->next.has_value());
  const api::LeaseGrant unreceived = *lost->next;
  auto again = queue_->Complete(first.token, c);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(again->state, "duplicate");
  ASSERT_TRUE(again->next.has_value());
  EXPECT_EQ(again->next->id, unreceived.id);  // the only queued run: the same one, a new grant
  EXPECT_NE(again->next->token, unreceived.token);
  EXPECT_EQ(again->next->attempt, 1);  // the unreceived grant did not count
  EXPECT_EQ(queue_->Heartbeat(unreceived.token, {}).status().code(), StatusCode::kConflict);
  EXPECT_EQ(Rows("results"), 1);
  auto run = store_->GetRun(unreceived.id);
  EXPECT_EQ(run->summary.state, JobState::kRunning);
  EXPECT_EQ(run->summary.attempts, 1);
  ASSERT_EQ(queue_->Complete(again->next->token, OkRun())->state, "done");
  // A plain repeated completion (no next) still changes nothing.
  EXPECT_EQ(queue_->Complete(first.token, OkRun())->state, "duplicate");
  EXPECT_EQ(RunState(unreceived.id), "done");
}

// A completion that is refused leases nothing: the next job stays queued for someone else.
TEST_F(LeaseQueueTest, RefusedCompletionLeasesNoNextJob) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  api::Completion c = OkRun();
  c.next = api::LeaseRequest{"w", "host", 1};
  EXPECT_EQ(queue_->Complete("not-a-token", c).status().code(), StatusCode::kConflict);
  api::Completion bad = c;
  bad.result.reset();  // an ok run without its result
  EXPECT_EQ(queue_->Complete(g.token, bad).status().code(), StatusCode::kInvalidArgument);
  api::Completion bad_next = c;
  bad_next.next->slurm_job = "12,13";
  auto refused = queue_->Complete(g.token, bad_next);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(refused.status().field(), "next.slurm_job");
  EXPECT_EQ(Rows("results"), 0);
  EXPECT_EQ(Rows("leases"), 2);  // the bed's and g's: no other lease was granted
  EXPECT_EQ(RunState(g.id), "running");
  api::LeaseGrant other = MustLease("other");
  EXPECT_NE(other.id, g.id);
}

// The leases of a Slurm job that is gone are reclaimed before they expire, like an expiry (the
// attempt counts) -- but only once the worker has been silent for half the TTL, and only leases
// granted before Slurm was asked. Other jobs' leases and leases outside Slurm stay; the old token
// can no longer complete.
TEST_F(LeaseQueueTest, LeasesOfAGoneSlurmJobAreReclaimedBeforeTheyExpire) {
  nlohmann::json sweep = OmegaSignSweep();
  sweep["axes"][0]["values"] = {-80, -40, 40, 80};
  SubmitJson(sweep);
  PrepareBed();
  auto a = queue_->Lease({"pilot-a", "node1", 1, "4242"});
  auto b = queue_->Lease({"pilot-b", "node2", 1, "4243"});
  auto c = queue_->Lease({"laptop", "here", 1});
  ASSERT_TRUE(a.ok() && a->has_value() && b.ok() && b->has_value() && c.ok() && c->has_value());
  EXPECT_EQ(queue_->RunningSlurmJobs().value(), (std::vector<std::string>{"4242", "4243"}));

  EXPECT_EQ(queue_->ReclaimSlurmJob("4242", clock_.Now()).value(), 0);  // silent for 0 s only
  clock_.Advance(31);                                                   // half the 60 s TTL
  // A lease granted after Slurm was asked is not judged by that answer.
  const double asked_at = clock_.Now() - 1;
  auto d = queue_->Lease({"pilot-a2", "node1", 1, "4242"});
  ASSERT_TRUE(d.ok() && d->has_value());
  clock_.Advance(31);
  ASSERT_TRUE(queue_->Heartbeat((*b)->token, {}).ok());  // b's worker is alive, whatever Slurm says
  auto n = queue_->ReclaimSlurmJob("4242", asked_at);
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  EXPECT_EQ(*n, 1);
  auto run = store_->GetRun((*a)->id);
  EXPECT_EQ(run->summary.state, JobState::kQueued);
  ASSERT_TRUE(run->summary.last_error.has_value());
  EXPECT_EQ(run->summary.last_error->kind, "pilot_gone");
  EXPECT_THAT(run->summary.last_error->message, ::testing::HasSubstr("4242"));
  EXPECT_EQ(run->summary.attempts, 1);
  EXPECT_EQ(RunState((*d)->id), "running");
  EXPECT_EQ(queue_->ReclaimSlurmJob("4243", clock_.Now()).value(), 0);  // it just heartbeated
  EXPECT_EQ(RunState((*b)->id), "running");
  EXPECT_EQ(RunState((*c)->id), "running");
  EXPECT_EQ(queue_->Complete((*a)->token, OkRun()).status().code(), StatusCode::kConflict);
  // A completed run of a job that is gone later is not touched.
  ASSERT_EQ(queue_->Complete((*b)->token, OkRun())->state, "done");
  clock_.Advance(31);
  EXPECT_EQ(queue_->ReclaimSlurmJob("4243", clock_.Now()).value(), 0);
  EXPECT_EQ(RunState((*b)->id), "done");
}

// A job id is only digits: anything else never reaches squeue.
TEST_F(LeaseQueueTest, SlurmJobMustBeAJobId) {
  SubmitJson(OmegaSignSweep());
  for (const char* bad : {"12,13", "-j", "12 13", "abc", "123456789012345678901"}) {
    auto g = queue_->Lease({"w", "h", 1, bad});
    ASSERT_FALSE(g.ok()) << bad;
    EXPECT_EQ(g.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(g.status().field(), "slurm_job");
  }
  EXPECT_EQ(Rows("leases"), 0);
}

TEST_F(LeaseQueueTest, UnknownTokenConflicts) {
  EXPECT_EQ(queue_->Complete("nope", OkRun()).status().code(), StatusCode::kConflict);
  EXPECT_EQ(queue_->Heartbeat("nope", {}).status().code(), StatusCode::kConflict);
}

// A worker that stops (Slurm's end-of-allocation signal) hands its run back: queued at once, the
// attempt not counted, and the released token can neither heartbeat nor complete.
TEST_F(LeaseQueueTest, ReleasedRunIsQueuedAgainWithoutCountingTheAttempt) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease("pilot-1");
  EXPECT_EQ(g.attempt, 1);
  auto r = queue_->Release(g.token, "slurm allocation ends");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->state, "queued");
  EXPECT_EQ(RunState(g.id), "queued");
  EXPECT_EQ(store_->GetRun(g.id)->summary.attempts, 0);
  EXPECT_EQ(queue_->Release(g.token, "again")->state, "duplicate");
  EXPECT_EQ(queue_->Heartbeat(g.token, {}).status().code(), StatusCode::kConflict);
  EXPECT_EQ(queue_->Complete(g.token, OkRun())->state, "duplicate");
  EXPECT_EQ(Rows("results"), 0);
  api::LeaseGrant again = MustLease("pilot-2");
  EXPECT_EQ(again.id, g.id);
  EXPECT_EQ(again.attempt, 1);
  EXPECT_EQ(queue_->Complete(again.token, OkRun())->state, "done");
  EXPECT_EQ(Rows("results"), 1);
  EXPECT_EQ(queue_->Release("nope", "x").status().code(), StatusCode::kConflict);
}

// A run handed back more than max_attempts times (say it is longer than any allocation it is
// leased in) stops going round: from then on a hand-back counts, and it ends failed.
TEST_F(LeaseQueueTest, RunHandedBackTooOftenEndsFailed) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  int64_t id = 0;
  std::vector<std::string> states;
  for (int i = 0; i < 10 && (states.empty() || states.back() == "queued"); ++i) {
    api::LeaseGrant g = MustLease("pilot");
    if (id == 0) id = g.id;
    ASSERT_EQ(g.id, id);
    states.push_back(queue_->Release(g.token, "allocation ends")->state);
  }
  // 3 free hand-backs (max_attempts = 3), then 3 counted ones: queued, queued, failed.
  ASSERT_EQ(states.size(), 6u);
  EXPECT_EQ(states.back(), "failed");
  EXPECT_EQ(RunState(id), "failed");
  auto run = store_->GetRun(id);
  EXPECT_EQ(run->summary.attempts, 3);
  EXPECT_EQ(Rows("results"), 0);
}

// A run whose sweep was cancelled while it ran, handed back, is cancelled, not queued again.
TEST_F(LeaseQueueTest, ReleasedRunOfACancelledSweepIsCancelled) {
  int64_t sweep = SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  ASSERT_TRUE(queue_->Cancel(sweep).ok());
  EXPECT_EQ(queue_->Release(g.token, "worker stopping")->state, "cancelled");
  EXPECT_EQ(RunState(g.id), "cancelled");
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());
}

// A run whose sweep was cancelled while it ran, and whose worker then vanished (the stop it was
// told never arrived; the lease expired), is cancelled, not run again; a run a live sweep still
// wants is queued again with none of the lost attempt's progress (it looked 91 % done while queued,
// and its ETA said minutes where the whole run was left).
TEST_F(LeaseQueueTest, AnExpiredRunOfACancelledSweepIsCancelledAndARequeuedOneStartsAgain) {
  int64_t sweep = SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  ASSERT_TRUE(queue_->Heartbeat(g.token, {0.9, 0.05, 90000}).ok());
  ASSERT_TRUE(queue_->Cancel(sweep).ok());
  clock_.Advance(61);
  EXPECT_EQ(*queue_->ExpireLeases(), 1);
  EXPECT_EQ(RunState(g.id), "cancelled");
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());

  SubmitJson(OmegaSignSweep("again"));  // its runs are wanted again (requeued by the submission)
  api::LeaseGrant w = MustLease();
  ASSERT_TRUE(queue_->Heartbeat(w.token, {0.9, 0.05, 90000}).ok());
  EXPECT_EQ(store_->GetRun(w.id)->summary.progress.sim_time_s, 0.9);
  clock_.Advance(61);
  EXPECT_EQ(*queue_->ExpireLeases(), 1);
  EXPECT_EQ(RunState(w.id), "queued");
  auto run = store_->GetRun(w.id);
  EXPECT_EQ(run->summary.progress.sim_time_s, 0);
  EXPECT_EQ(run->summary.progress.step, 0);
  EXPECT_FALSE(run->summary.progress.heartbeat_at.has_value());
}

// The same on the run's last attempt: its retries used up, a cancelled sweep's run whose lease
// expires ends cancelled (its sweeps no longer want it), not failed (a run still wanted fails:
// ExpiredLeaseIsRequeuedWithItsAttemptCountedThenFails).
TEST_F(LeaseQueueTest, AnExpiredLastAttemptOfACancelledSweepIsCancelledNotFailed) {
  int64_t sweep = SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  for (int attempt = 2; attempt <= 3; ++attempt) {
    clock_.Advance(61);
    ASSERT_EQ(*queue_->ExpireLeases(), 1);
    g = MustLease();
    ASSERT_EQ(g.attempt, attempt);
  }
  api::LeaseGrant other = MustLease("w2");  // the sweep's other run, on its first attempt
  ASSERT_NE(other.id, g.id);
  ASSERT_TRUE(queue_->Cancel(sweep).ok());
  clock_.Advance(61);
  EXPECT_EQ(*queue_->ExpireLeases(), 2);
  auto run = store_->GetRun(g.id);
  EXPECT_EQ(run->summary.state, JobState::kCancelled);
  ASSERT_TRUE(run->summary.last_error.has_value());
  EXPECT_EQ(run->summary.last_error->kind, "cancelled");
  EXPECT_EQ(RunState(other.id), "cancelled");
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());
}

// A grant whose reply was lost is taken back when its worker asks again; when every sweep of its
// run was cancelled meanwhile, the run is cancelled, not queued again, and nothing else is leased.
TEST_F(LeaseQueueTest, AnUnreceivedGrantOfACancelledSweepIsCancelledNotQueuedAgain) {
  int64_t sweep = SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant first = MustLease();
  api::Completion c = OkRun();
  c.next = api::LeaseRequest{"w1", "host", 1};
  auto lost = queue_->Complete(first.token, c);
  ASSERT_TRUE(lost.ok() && lost->next.has_value());
  const api::LeaseGrant unreceived = *lost->next;
  ASSERT_TRUE(queue_->Cancel(sweep).ok());
  EXPECT_EQ(RunState(unreceived.id), "running");  // asked to stop at a heartbeat that never comes
  auto again = queue_->Complete(first.token, c);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(again->state, "duplicate");
  EXPECT_FALSE(again->next.has_value());
  auto run = store_->GetRun(unreceived.id);
  EXPECT_EQ(run->summary.state, JobState::kCancelled);
  EXPECT_EQ(run->summary.attempts, 0);  // the unreceived grant did not count
  EXPECT_EQ(queue_->Heartbeat(unreceived.token, {}).status().code(), StatusCode::kConflict);
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());
}

// The ETA follows the machine's share now: two runs heartbeat every 10 s for 15 minutes at one
// pace; then either the same pace (a steady machine) or a third of it (builds took the cores).
// After a window (10 minutes) at the new pace, the ETA is the time the runs' steps left take at
// that pace -- three times as long for the slowed engines -- where the cost model's rate alone (their
// attempts so far, mostly at the old pace) said less than half of that.
TEST_F(LeaseQueueTest, TheEtaFollowsTheEnginesCurrentShare) {
  for (const int slow_by : {1, 3}) {
    SCOPED_TRACE("slowed by " + std::to_string(slow_by));
    Renew();
    const int64_t sweep = SubmitJson(OmegaSignSweep());
    PrepareBed();
    std::vector<api::LeaseGrant> runs = {MustLease("w1"), MustLease("w2")};
    ASSERT_EQ(runs[0].kind, api::JobKind::kRun);
    const int64_t steps = runs[0].steps;
    ASSERT_EQ(runs[1].steps, steps);
    int64_t step = 0;
    auto drive = [&](double seconds, int64_t per_beat) {
      for (double t = 0; t < seconds; t += 10) {
        clock_.Advance(10);
        step += per_beat;
        for (const api::LeaseGrant& g : runs) ASSERT_TRUE(queue_->Heartbeat(g.token, {0, 0, step}).ok());
      }
    };
    auto eta = [&] {
      auto e = ReadEta(*store_, EtaScope::kSweep, sweep, clock_.Now(), 2);
      EXPECT_TRUE(e.ok() && e->has_value());
      return e.ok() && e->has_value() ? **e : Eta{};
    };
    const int64_t fast = steps / 400;  // steps a beat: the whole run in 4,000 s
    drive(900, fast);
    const Eta before = eta();
    EXPECT_NEAR(before.seconds / ((steps - step) * 10.0 / fast), 1, 0.03);
    const double finish_before = clock_.Now() + before.seconds;
    drive(660, fast / slow_by);
    const Eta after = eta();
    const double truth = (steps - step) * 10.0 / (fast / slow_by);
    if (slow_by == 1) {
      EXPECT_NEAR(after.seconds / truth, 1, 0.05) << after.basis;
      EXPECT_NEAR(clock_.Now() + after.seconds, finish_before, 0.03 * before.seconds);  // the finish stays
      EXPECT_LT(after.rel_error, 0.2);
      EXPECT_NE(after.basis.find("at 1.00 of that rate over the last 10 min"), std::string::npos) << after.basis;
    } else {
      auto model = ReadCostModel(*store_, clock_.Now());
      ASSERT_TRUE(model.ok());
      // The cost model's rate alone (the done runs and the attempts so far) is faster than the
      // engines are now: its ETA falls short of the truth by the factor.
      EXPECT_GT(model->share.factor, 2);
      const double model_alone = truth / model->share.factor;
      // The rule promises: the estimate moves from the model's toward the truth, and its stated
      // 1 sigma widens to cover the truth.
      EXPECT_GT(after.seconds, model_alone * 1.2) << after.basis;
      EXPECT_LT(after.seconds, truth) << after.basis;
      EXPECT_LE(std::abs(truth - after.seconds), after.rel_error * after.seconds) << after.basis;
      EXPECT_NE(after.basis.find("now 2 engines at 0.4"), std::string::npos) << after.basis;  // of the pooled rate
      EXPECT_NE(after.basis.find("taken halfway"), std::string::npos) << after.basis;
      const nlohmann::json j = *model;  // GET /api/v1/cost-model
      EXPECT_EQ(j["share"]["engines"], 2);
      EXPECT_NEAR(j["share"]["factor"].get<double>(), model->share.factor, 1e-12);
      EXPECT_NEAR(j["share"]["scale"].get<double>(), std::sqrt(model->share.factor), 1e-12);
      EXPECT_EQ(j["engines_in_flight"], 2);
      EXPECT_EQ(j["engines_silent"], 0);
    }
  }
}

TEST_F(LeaseQueueTest, ReleaseOfALeaseNoLongerHeldConflicts) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant old = MustLease("slow");
  clock_.Advance(61);
  api::LeaseGrant fresh = MustLease("fast");
  ASSERT_EQ(fresh.id, old.id);
  EXPECT_EQ(queue_->Release(old.token, "late").status().code(), StatusCode::kConflict);
  EXPECT_EQ(RunState(fresh.id), "running");
  EXPECT_EQ(store_->GetRun(fresh.id)->summary.attempts, 2);
}

TEST_F(LeaseQueueTest, MalformedCompletionChangesNothing) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  api::Completion c;
  c.ok = true;  // no result
  EXPECT_EQ(queue_->Complete(g.token, c).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(RunState(g.id), "running");
  EXPECT_EQ(queue_->Complete(g.token, OkRun())->state, "done");
}

TEST_F(LeaseQueueTest, CancelDropsQueuedRunsAndStopsRunningOnesAtHeartbeat) {
  int64_t sweep = SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant running = MustLease();
  auto hb = queue_->Heartbeat(running.token, {});
  EXPECT_FALSE(hb->cancel);
  auto summary = queue_->Cancel(sweep);
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary->cancelled, 1);
  EXPECT_EQ(summary->stopping, 1);
  EXPECT_TRUE(queue_->Heartbeat(running.token, {})->cancel);
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());
  EXPECT_EQ(queue_->Complete(running.token, Failed("cancelled", "stopped"))->state, "cancelled");
  auto info = store_->GetSweep(sweep);
  EXPECT_EQ(info->counts.cancelled, 2);
  EXPECT_TRUE(info->cancelled_at.has_value());
  EXPECT_EQ(queue_->Cancel(9999).status().code(), StatusCode::kNotFound);
}

TEST_F(LeaseQueueTest, CancelKeepsRunsAnotherLiveSweepShares) {
  int64_t a = SubmitJson(OmegaSignSweep("a"));
  int64_t b = SubmitJson(OmegaSignSweep("b"));  // same points: shared runs
  EXPECT_EQ(Rows("runs"), 2);
  auto s = queue_->Cancel(a);
  EXPECT_EQ(s->cancelled, 0);
  EXPECT_EQ(store_->GetSweep(b)->counts.queued, 2);
  EXPECT_EQ(queue_->Cancel(b)->cancelled, 2);
}

TEST_F(LeaseQueueTest, BedFailingForGoodFailsItsRuns) {
  int64_t sweep = SubmitJson(OmegaSignSweep());
  for (int i = 0; i < 3; ++i) {
    api::LeaseGrant g = MustLease();
    ASSERT_EQ(g.kind, api::JobKind::kBed);
    ASSERT_TRUE(queue_->Complete(g.token, Failed("signal", "killed")).ok());
  }
  auto info = store_->GetSweep(sweep);
  EXPECT_EQ(info->counts.failed, 2);
  auto runs = store_->ListRuns({sweep, std::nullopt, 0, 10});
  EXPECT_EQ(runs->runs[0].last_error->kind, "bed_failed");
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());
}

// A bed that missed the kinetic-energy criterion comes out the same from the same deck: a later
// submission does not prepare it again; the runs it brings fail at once, saying why, rather than
// wait for ever. A bed that failed otherwise (killed) is prepared again.
TEST_F(LeaseQueueTest, BedNotEquilibratedFailsForGoodAcrossSubmissions) {
  SubmitJson(OmegaSignSweep());
  api::LeaseGrant g = MustLease();
  ASSERT_EQ(g.kind, api::JobKind::kBed);
  ASSERT_EQ(queue_->Complete(g.token, Failed("not_equilibrated", "the bed missed the criterion."))->state, "failed");

  nlohmann::json body = OmegaSignSweep("again");
  body["axes"][0]["values"] = {-40, 80};
  auto req = ParseSubmitRequest(body);
  ASSERT_TRUE(req.ok());
  auto again = Submit(*store_, *req, kTestEngine, clock_.Now());
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(again->runs_new, 1);         // -40
  EXPECT_EQ(again->runs_requeued, 1);    // +80 had failed with the bed
  EXPECT_EQ(again->runs_failed_bed, 2);  // both fail at once
  auto info = store_->GetSweep(again->sweep_ids.at(0));
  EXPECT_EQ(info->counts.failed, 2);
  EXPECT_EQ(info->counts.queued, 0);
  auto runs = store_->ListRuns({again->sweep_ids.at(0), std::nullopt, 0, 10});
  for (const auto& r : runs->runs) {
    ASSERT_TRUE(r.last_error.has_value());
    EXPECT_EQ(r.last_error->kind, "bed_failed");
    EXPECT_NE(r.last_error->message.find("failed for good"), std::string::npos) << r.last_error->message;
    EXPECT_NE(r.last_error->message.find("the bed missed the criterion."), std::string::npos);
  }
  EXPECT_FALSE(queue_->Lease({"w", "h", 1})->has_value());  // nothing to prepare, nothing to run
}

TEST_F(LeaseQueueTest, BedFailedOtherwiseIsPreparedAgainByALaterSubmission) {
  SubmitJson(OmegaSignSweep());
  for (int i = 0; i < 3; ++i) {
    api::LeaseGrant g = MustLease();
    ASSERT_EQ(g.kind, api::JobKind::kBed);
    ASSERT_TRUE(queue_->Complete(g.token, Failed("signal", "killed")).ok());
  }
  int64_t sweep = SubmitJson(OmegaSignSweep());
  EXPECT_EQ(store_->GetSweep(sweep)->counts.queued, 2);
  EXPECT_EQ(MustLease().kind, api::JobKind::kBed);
}

TEST_F(LeaseQueueTest, ReopeningTheFileKeepsLeasesAndRuns) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  OpenStore();  // a daemon restart
  ASSERT_TRUE(queue_->Heartbeat(g.token, {0.2, 0, 1}).ok());
  EXPECT_EQ(RunState(g.id), "running");
  EXPECT_EQ(queue_->Complete(g.token, OkRun())->state, "done");
  EXPECT_EQ(queue_->Complete(g.token, OkRun())->state, "duplicate");
  auto m = store_->GetMetrics();
  EXPECT_EQ(m->runs.done, 1);
  EXPECT_EQ(m->runs.queued, 1);
  EXPECT_EQ(m->leases_granted, 2);
}

// Decks are not stored at submission (schema/003_perf.sql): the deck a run is leased with, and
// the one GET /api/v1/runs/{id} shows, are rendered again and must be byte for byte the deck its
// key was computed from.
TEST_F(LeaseQueueTest, LeasedDeckIsTheDeckTheKeyWasComputedFrom) {
  const nlohmann::json body = OmegaSignSweep();
  auto req = ParseSubmitRequest(body);
  ASSERT_TRUE(req.ok());
  auto plan = PlanSweeps(req->sweeps, *FindScale(req->sweeps[0].scale), kTestEngine);  // keeps decks
  ASSERT_TRUE(plan.ok());
  SubmitJson(body);
  EXPECT_EQ(Rows("run_decks"), 0);
  PrepareBed();
  for (size_t i = 0; i < plan->runs.size(); ++i) {
    api::LeaseGrant g = MustLease();
    ASSERT_EQ(g.kind, api::JobKind::kRun);
    const PlannedRun* planned = nullptr;
    for (const PlannedRun& r : plan->runs) {
      if (r.key == g.key) planned = &r;
    }
    ASSERT_NE(planned, nullptr) << g.key;
    EXPECT_EQ(g.deck, planned->deck);
    EXPECT_EQ(RunKey(g.deck, plan->beds.at(0).key, kTestEngine), g.key);
    auto detail = store_->GetRun(g.id);
    ASSERT_TRUE(detail.ok());
    EXPECT_EQ(detail->deck, planned->deck);
  }
}

// A run whose deck no longer renders to its key (templates changed after it was submitted) is
// never handed out with a deck that differs from its key: it fails as a deck_error.
TEST_F(LeaseQueueTest, RunWhoseDeckNoLongerMatchesItsKeyFails) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  {
    auto t = store_->db().Begin();
    ASSERT_TRUE(t.ok());
    ASSERT_TRUE(t->Exec("UPDATE runs SET key = 'stale-' || id WHERE id = 1").ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  api::LeaseGrant g = MustLease();
  EXPECT_NE(g.id, 1);
  auto r1 = store_->GetRun(1);
  ASSERT_TRUE(r1.ok());
  EXPECT_EQ(r1->summary.state, JobState::kFailed);
  ASSERT_TRUE(r1->summary.last_error.has_value());
  EXPECT_EQ(r1->summary.last_error->kind, "deck_error");
}

// sweep_counts follow every state change in the transaction that makes it.
TEST_F(LeaseQueueTest, SweepCountsFollowStateChanges) {
  const int64_t sweep = SubmitJson(OmegaSignSweep());
  auto counts = [&] { return store_->GetSweep(sweep).value().counts; };
  const int64_t total = counts().total();
  EXPECT_GT(total, 1);
  EXPECT_EQ(counts().queued, total);
  PrepareBed();
  api::LeaseGrant g = MustLease();
  EXPECT_EQ(counts().running, 1);
  EXPECT_EQ(counts().queued, total - 1);
  ASSERT_TRUE(queue_->Complete(g.token, OkRun()).ok());
  EXPECT_EQ(counts().done, 1);
  EXPECT_EQ(counts().running, 0);
  ASSERT_TRUE(queue_->Cancel(sweep).ok());
  EXPECT_EQ(counts().cancelled, total - 1);
  EXPECT_EQ(counts().total(), total);
}

}  // namespace

// A snapshot dump as the engine writes it: two grains and the SO.
std::string SnapshotDump(int64_t step) {
  return "ITEM: TIMESTEP\n" + std::to_string(step) +
         "\nITEM: NUMBER OF ATOMS\n3\nITEM: BOX BOUNDS pp pp ff\n-0.09 0.09\n-0.09 0.09\n-0.35 0.4\n"
         "ITEM: ATOMS id type x y z vx vy vz radius\n"
         "1 1 0.001 0.02 0.1 0 0 0.1 0.01\n2 1 0.05 -0.03 -0.2 0.2 0 0 0.01\n3 2 0 0 0 0 0.1 0 0.06\n";
}

// Snapshots: uploaded under the run's lease, checked, stored, recorded by the completion that
// lists them; a completion listing one not uploaded (or with other bytes) is refused; what no
// completion recorded is removed.
TEST_F(LeaseQueueTest, SnapshotsAreUploadedThenRecordedByTheCompletion) {
  options_.data_dir = (store_.dir() / "data").string();
  OpenStore();
  nlohmann::json sweep = OmegaSignSweep();
  sweep["axes"][0]["values"] = {-80};
  sweep["snapshots"] = {0, 1};
  SubmitJson(sweep);
  PrepareBed();
  api::LeaseGrant g = MustLease();
  ASSERT_EQ(g.kind, api::JobKind::kRun);
  EXPECT_EQ(g.snapshots, (std::vector<double>{0, 1}));
  EXPECT_THAT(g.deck, ::testing::HasSubstr("frame.last.dump"));
  const std::string first = SnapshotDump(0), last = SnapshotDump(30000);
  // Refused: other bytes than the checksum says, not a snapshot, an index the run did not ask for,
  // a token that is not the run's lease.
  EXPECT_EQ(queue_->PutRunSnapshot(g.token, 0, first, Sha256Hex(last)).field(), "X-Sha256");
  EXPECT_EQ(queue_->PutRunSnapshot(g.token, 0, "not a dump", Sha256Hex("not a dump")).field(), "body");
  EXPECT_EQ(queue_->PutRunSnapshot(g.token, 2, first, Sha256Hex(first)).field(), "n");
  EXPECT_FALSE(queue_->PutRunSnapshot("nope", 0, first, Sha256Hex(first)).ok());
  ASSERT_TRUE(queue_->PutRunSnapshot(g.token, 0, first, Sha256Hex(first)).ok());
  // The daemon starting again meanwhile leaves a running run's uploads for its completion.
  EXPECT_EQ(*queue_->RemoveUnrecordedSnapshots(), 0);
  EXPECT_TRUE(fs::exists(DataDir(options_.data_dir).Snapshot(g.id, 0)));
  api::Completion c = OkRun();
  c.snapshots = {api::Snapshot{0, 0, 0, 0, 2, static_cast<int64_t>(first.size()), Sha256Hex(first)},
                 api::Snapshot{1, 1, 0.3, 30000, 2, static_cast<int64_t>(last.size()), Sha256Hex(last)}};
  // Snapshot 1 was never uploaded: refused, nothing recorded.
  auto refused = queue_->Complete(g.token, c);
  ASSERT_FALSE(refused.ok()) << refused->state;
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(refused.status().field(), "snapshots[1]");
  EXPECT_TRUE(store_->GetRun(g.id)->snapshots.empty());
  // Uploaded with other bytes than the completion says: refused.
  ASSERT_TRUE(queue_->PutRunSnapshot(g.token, 1, first, Sha256Hex(first)).ok());
  auto mismatched = queue_->Complete(g.token, c);
  ASSERT_FALSE(mismatched.ok()) << mismatched->state;
  EXPECT_EQ(mismatched.status().field(), "snapshots[1].sha256");
  ASSERT_TRUE(queue_->PutRunSnapshot(g.token, 1, last, Sha256Hex(last)).ok());
  auto done = queue_->Complete(g.token, c);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->state, "done");
  auto run = store_->GetRun(g.id);
  ASSERT_TRUE(run.ok());
  ASSERT_EQ(run->snapshots.size(), 2u);
  EXPECT_EQ(run->snapshots[1].t_s, 0.3);
  EXPECT_EQ(run->snapshots[1].sha256, Sha256Hex(last));
  auto read = ReadStoredSnapshot(options_.data_dir, g.id, 1);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ(read->step, 30000);
  // A stray upload (a run whose attempt never completed) goes at the daemon's next start; the
  // recorded ones stay, and so do a running run's (its worker may still complete it).
  const std::string stray = DataDir(options_.data_dir).Snapshot(g.id + 100, 0);
  fs::create_directories(fs::path(stray).parent_path());
  std::ofstream(stray) << first;
  auto removed = queue_->RemoveUnrecordedSnapshots();
  ASSERT_TRUE(removed.ok());
  EXPECT_EQ(*removed, 1);
  EXPECT_FALSE(fs::exists(stray));
  EXPECT_TRUE(fs::exists(DataDir(options_.data_dir).Snapshot(g.id, 0)));
  EXPECT_TRUE(fs::exists(DataDir(options_.data_dir).Snapshot(g.id, 1)));
}


// An upload received into a file under DATA/uploads is renamed into place: the stored restart and
// snapshot are that very file (same inode), and no second copy is left behind.
TEST_F(LeaseQueueTest, UploadsAreRenamedIntoPlaceNotCopied) {
  options_.data_dir = (store_.dir() / "data").string();
  OpenStore();
  const DataDir data(options_.data_dir);
  nlohmann::json sweep = OmegaSignSweep();
  sweep["axes"][0]["values"] = {-80};
  sweep["snapshots"] = {0};
  SubmitJson(sweep);
  auto received = [&](const std::string& name, const std::string& bytes) {
    const std::string path = data.Uploads() + "/" + name;
    fs::create_directories(data.Uploads());
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  };
  api::LeaseGrant bed = MustLease("bed-worker");
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  const std::string restart = "restart bytes";
  const std::string restart_upload = received("bed.part", restart);
  const uint64_t restart_inode = IdentifyFile(restart_upload)->inode;
  ASSERT_TRUE(queue_->PutBedRestart(bed.token, restart, Sha256Hex(restart), data.root(), restart_upload).ok());
  api::Completion c;
  c.ok = true;
  c.bed_result = api::BedResult{};
  c.bed_result->sha256 = Sha256Hex(restart);
  ASSERT_EQ(queue_->Complete(bed.token, c)->state, "done");
  auto file = queue_->GetBedRestart(bed.id);
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  EXPECT_EQ(file->path, data.BedRestart(file->key));
  EXPECT_EQ(IdentifyFile(file->path)->inode, restart_inode);
  EXPECT_FALSE(fs::exists(restart_upload));

  api::LeaseGrant g = MustLease();
  ASSERT_EQ(g.kind, api::JobKind::kRun);
  const std::string dump = SnapshotDump(0);
  const std::string dump_upload = received("snapshot.part", dump);
  const uint64_t dump_inode = IdentifyFile(dump_upload)->inode;
  ASSERT_TRUE(queue_->PutRunSnapshot(g.token, 0, dump, Sha256Hex(dump), dump_upload).ok());
  EXPECT_EQ(IdentifyFile(data.Snapshot(g.id, 0))->inode, dump_inode);
  EXPECT_FALSE(fs::exists(dump_upload));
  EXPECT_TRUE(fs::is_empty(data.Uploads()));
}

// A snapshot is hashed once, when it is uploaded: the completion compares its checksum with that
// one (the file is still the one written: a stat), not with a second read of the file. A file
// the daemon did not see written (it started again since) is hashed before the completion's
// transaction, and a replaced one is still caught.
TEST_F(LeaseQueueTest, ASnapshotIsHashedWhenUploadedAndTheCompletionComparesWithThat) {
  options_.data_dir = (store_.dir() / "data").string();
  OpenStore();
  const DataDir data(options_.data_dir);
  nlohmann::json sweep = OmegaSignSweep();
  sweep["axes"][0]["values"] = {-80, -60};
  sweep["snapshots"] = {0};
  SubmitJson(sweep);
  PrepareBed();
  const std::string dump = SnapshotDump(0);
  api::Completion c = OkRun();
  c.snapshots = {api::Snapshot{0, 0, 0, 0, 2, static_cast<int64_t>(dump.size()), Sha256Hex(dump)}};

  // Written by PutRunSnapshot: its bytes are then changed behind the daemon's back with the file's
  // size and time kept; the completion goes by the checksum taken at upload, so it never re-read it.
  api::LeaseGrant first = MustLease();
  ASSERT_TRUE(queue_->PutRunSnapshot(first.token, 0, dump, Sha256Hex(dump)).ok());
  const std::string path = data.Snapshot(first.id, 0);
  const FileIdentity before = *IdentifyFile(path);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(0);
    f.put('#');
  }
  const struct timespec times[2] = {{0, UTIME_OMIT},
                                    {static_cast<time_t>(before.mtime_ns / 1000000000), before.mtime_ns % 1000000000}};
  ASSERT_EQ(utimensat(AT_FDCWD, path.c_str(), times, 0), 0);
  ASSERT_EQ(*IdentifyFile(path), before);
  ASSERT_NE(*Sha256OfFile(path), Sha256Hex(dump));
  auto done = queue_->Complete(first.token, c);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->state, "done");

  // After a restart the daemon has seen no upload: it hashes the file, and a file replaced with
  // other bytes is refused as before.
  api::LeaseGrant second = MustLease();
  ASSERT_TRUE(queue_->PutRunSnapshot(second.token, 0, dump, Sha256Hex(dump)).ok());
  OpenStore();
  ASSERT_TRUE(WriteFileAtomically(data.Snapshot(second.id, 0), SnapshotDump(30000)).ok());
  auto refused = queue_->Complete(second.token, c);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().field(), "snapshots[0].sha256");
  ASSERT_TRUE(WriteFileAtomically(data.Snapshot(second.id, 0), dump).ok());
  auto after_restart = queue_->Complete(second.token, c);
  ASSERT_TRUE(after_restart.ok()) << after_restart.status().ToString();
  EXPECT_EQ(after_restart->state, "done");
}

// A daemon that was down longer than a lease TTL: at start-up the running jobs' leases run one TTL
// from now, so their workers' next heartbeats land instead of the runs being leased again.
TEST_F(LeaseQueueTest, LeasesRunOneTtlAfterARestart) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant g = MustLease();
  ASSERT_EQ(g.kind, api::JobKind::kRun);
  clock_.Advance(options_.ttl_s * 5);  // the outage
  OpenStore();                          // the daemon starts again on the same file
  auto extended = queue_->ExtendLeasesAfterRestart();
  ASSERT_TRUE(extended.ok());
  EXPECT_EQ(*extended, 1);
  EXPECT_EQ(*queue_->ExpireLeases(), 0);
  EXPECT_EQ(RunState(g.id), "running");
  EXPECT_TRUE(queue_->Heartbeat(g.token, api::Heartbeat{}).ok());
  // A worker that died meanwhile is reclaimed one TTL after the start.
  clock_.Advance(options_.ttl_s + 1);
  EXPECT_EQ(*queue_->ExpireLeases(), 1);
  EXPECT_EQ(RunState(g.id), "queued");
}

}  // namespace sandswim

namespace sandswim {

// The daemon stopped (or was killed) and its local worker with it: at the next start, the leases that
// worker held are handed back when they expire without a heartbeat -- queued again, attempts
// uncounted -- while a lease of any other worker that went silent expires counted, as before. A
// local worker that outlived its daemon and heartbeats keeps its lease, and from then on is
// counted like any other if it goes silent.
TEST_F(LeaseQueueTest, LeasesOfAStoppedDaemonsLocalWorkerAreHandedBackNotCounted) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant local = MustLease("host:local-100");
  api::LeaseGrant remote = MustLease("node7:4242");
  ASSERT_NE(local.id, remote.id);
  clock_.Advance(options_.ttl_s * 5);
  OpenStore();
  auto extended =
      queue_->ExtendLeasesAfterRestart([](const std::string& worker) { return worker.rfind("host:local-", 0) == 0; });
  ASSERT_TRUE(extended.ok()) << extended.status().ToString();
  EXPECT_EQ(*extended, 2);
  EXPECT_EQ(queue_->LeasesLeftByStoppedDaemon(), 1u);
  EXPECT_EQ(*queue_->ExpireLeases(), 0) << "each lease runs one TTL after the start";
  clock_.Advance(options_.ttl_s + 1);
  EXPECT_EQ(*queue_->ExpireLeases(), 2);
  auto handed = store_->GetRun(local.id);
  EXPECT_EQ(handed->summary.state, JobState::kQueued);
  EXPECT_EQ(handed->summary.attempts, 0) << "the daemon stopping was not the run's fault";
  auto expired = store_->GetRun(remote.id);
  EXPECT_EQ(expired->summary.state, JobState::kQueued);
  EXPECT_EQ(expired->summary.attempts, 1);
  ASSERT_TRUE(expired->summary.last_error.has_value());
  EXPECT_EQ(expired->summary.last_error->kind, "lease_expired");
  EXPECT_EQ(store_->GetMetrics()->expirations, 1) << "a hand-back is no expiration";
  EXPECT_EQ(queue_->Heartbeat(local.token, {}).status().code(), StatusCode::kConflict);

  // A local worker that outlived its daemon heartbeats: alive, its lease is its own again.
  api::LeaseGrant again = MustLease("host:local-100");
  const int leased_attempts = store_->GetRun(again.id)->summary.attempts;
  clock_.Advance(1);
  OpenStore();
  ASSERT_TRUE(queue_->ExtendLeasesAfterRestart([](const std::string& w) { return w.rfind("host:local-", 0) == 0; }).ok());
  ASSERT_TRUE(queue_->Heartbeat(again.token, {0.1, 0, 100}).ok());
  EXPECT_EQ(queue_->LeasesLeftByStoppedDaemon(), 0u);
  clock_.Advance(options_.ttl_s + 1);
  EXPECT_EQ(*queue_->ExpireLeases(), 1);
  EXPECT_EQ(store_->GetRun(again.id)->summary.attempts, leased_attempts) << "silent after heartbeating: counted";
}

// A daemon that stops hands back what its (now stopped) local worker still held: attempt uncounted,
// every other worker's lease untouched; and, as for any hand-back, not for ever.
TEST_F(LeaseQueueTest, TheDaemonHandsBackItsStoppedLocalWorkersJobs) {
  SubmitJson(OmegaSignSweep());
  PrepareBed();
  api::LeaseGrant local = MustLease("host:local-7");
  api::LeaseGrant other = MustLease("node7:4242");
  auto handed = queue_->HandBackLeasesOf("host:local-7", "the daemon stopped");
  ASSERT_TRUE(handed.ok()) << handed.status().ToString();
  EXPECT_EQ(*handed, 1);
  EXPECT_EQ(RunState(local.id), "queued");
  EXPECT_EQ(store_->GetRun(local.id)->summary.attempts, 0);
  EXPECT_EQ(RunState(other.id), "running");
  EXPECT_EQ(queue_->Complete(local.token, OkRun())->state, "duplicate");
  EXPECT_EQ(*queue_->HandBackLeasesOf("host:local-7", "again"), 0);
  // Handed back max_attempts times, a run's hand-backs count (Release's rule): no endless loop of a
  // run whose every attempt brings the daemon down.
  std::string state = "queued";
  for (int i = 0; i < 10 && state == "queued"; ++i) {
    api::LeaseGrant g = MustLease("host:local-7");
    ASSERT_EQ(g.id, local.id);
    ASSERT_EQ(*queue_->HandBackLeasesOf("host:local-7", "the daemon stopped"), 1);
    state = RunState(local.id);
  }
  EXPECT_EQ(state, "failed");
}

}  // namespace sandswim
