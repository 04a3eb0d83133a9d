#include "platform/slurm.h"
#include "core/text.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>

namespace sandswim::slurm {
namespace {

bool AllDigits(std::string_view s) {
  return !s.empty() && s.size() <= 9 &&
         std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
}

std::vector<std::string_view> Split(std::string_view s, char sep) {
  std::vector<std::string_view> parts;
  size_t start = 0;
  while (true) {
    size_t end = s.find(sep, start);
    parts.push_back(s.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start));
    if (end == std::string_view::npos) return parts;
    start = end + 1;
  }
}

}  // namespace

Result<CommandOutput> ProcessSlurmCommands::Run(const std::vector<std::string>& argv,
                                                const std::vector<std::pair<std::string, std::string>>& env) {
  Result<CommandOutput> run = processes_->Run(argv, env, timeout_s_);
  if (!run.ok()) {
    if (run.status().code() != StatusCode::kUnavailable) return run.status();
    return Status::Unavailable(run.status().reason() + ": are Slurm's client commands installed and on PATH?");
  }
  if (run->timed_out) {
    return Status::Unavailable("'" + argv[0] + "' did not finish within " +
                               std::to_string(static_cast<int>(timeout_s_)) +
                               " s and was killed: is the Slurm controller answering?");
  }
  return run;
}

Result<std::optional<double>> ParseSlurmDuration(std::string_view text, const std::string& field) {
  using Out = std::optional<double>;
  const std::string_view t = Trim(text);
  if (t == "UNLIMITED" || t == "INFINITE" || t == "NOT_SET" || t == "Partition_Limit") return Out();
  auto bad = [&] {
    return Status::InvalidArgument(
        field, "'" + std::string(t) + "' is not a Slurm time (minutes, M:S, H:M:S, D-H, D-H:M or D-H:M:S)");
  };
  double days = 0;
  std::string_view clock = t;
  const size_t dash = t.find('-');
  if (dash != std::string_view::npos) {
    if (!AllDigits(t.substr(0, dash))) return bad();
    days = std::stod(std::string(t.substr(0, dash)));
    clock = t.substr(dash + 1);
  }
  std::vector<std::string_view> parts = Split(clock, ':');
  if (parts.size() > 3) return bad();
  std::vector<double> v;
  for (std::string_view p : parts) {
    if (!AllDigits(p)) return bad();
    v.push_back(std::stod(std::string(p)));
  }
  double seconds = 0;
  if (dash != std::string_view::npos) {
    // After "D-": hours, hours:minutes or hours:minutes:seconds.
    seconds = v[0] * 3600 + (v.size() > 1 ? v[1] * 60 : 0) + (v.size() > 2 ? v[2] : 0);
  } else if (v.size() == 1) {
    seconds = v[0] * 60;  // a bare number is minutes
  } else if (v.size() == 2) {
    seconds = v[0] * 60 + v[1];
  } else {
    seconds = v[0] * 3600 + v[1] * 60 + v[2];
  }
  return Out(days * 86400 + seconds);
}

Result<std::vector<std::string>> PilotSbatchArgs(const PilotRequest& r) {
  if (r.nodes < 1) return Status::InvalidArgument("nodes", "must be at least 1");
  if (r.ranks_per_run < 1) return Status::InvalidArgument("ranks-per-run", "must be at least 1");
  if (r.tasks_per_node < 0) return Status::InvalidArgument("tasks-per-node", "must be at least 1 (0: ranks-per-run)");
  if (r.time.empty()) return Status::InvalidArgument("time", "a time limit is required (e.g. 2:00:00)");
  auto limit = ParseSlurmDuration(r.time, "time");
  if (!limit.ok()) return limit.status();
  if (r.array < 0) return Status::InvalidArgument("array", "must be at least 1");
  if (r.throttle < 0) return Status::InvalidArgument("throttle", "must be at least 1");
  if (r.throttle > 0 && r.array == 0) return Status::InvalidArgument("throttle", "only an --array has a throttle");
  if (r.array > 0 && r.throttle > r.array) {
    return Status::InvalidArgument("throttle", "is larger than the array (" + std::to_string(r.array) + ")");
  }
  if (r.script.empty()) return Status::InvalidArgument("script", "the batch script is required");
  const int per_node = r.tasks_per_node > 0 ? r.tasks_per_node : r.ranks_per_run;
  if (r.array == 0 && per_node * r.nodes < r.ranks_per_run) {
    return Status::InvalidArgument("tasks-per-node", "the pilot's " + std::to_string(per_node * r.nodes) +
                                                         " tasks cannot hold one run of " +
                                                         std::to_string(r.ranks_per_run) + " ranks");
  }
  if (r.array == 0 && *limit && *limit <= r.signal_lead_s) {
    return Status::InvalidArgument("time", "must be longer than the " + std::to_string(r.signal_lead_s) +
                                               " s warning the pilot gets before its end");
  }
  if (*limit && **limit <= r.end_margin_s) {
    return Status::InvalidArgument(
        "time", "must be longer than the " + std::to_string(static_cast<int>(r.end_margin_s)) +
                    " s a worker expects its first run to take (--end-margin): it would lease nothing");
  }
  std::vector<std::string> argv = {"sbatch", "--parsable", "--job-name", r.job_name,
                                   "--time", r.time,       "--nodes",    std::to_string(r.nodes)};
  if (r.array > 0) {
    // One run per element: exactly the ranks of one run.
    argv.insert(argv.end(), {"--ntasks", std::to_string(r.ranks_per_run)});
    std::string spec = "0-" + std::to_string(r.array - 1);
    if (r.throttle > 0) spec += "%" + std::to_string(r.throttle);
    argv.insert(argv.end(), {"--array", spec});
  } else {
    argv.insert(argv.end(), {"--ntasks-per-node", std::to_string(per_node)});
    // B: the batch shell (which execs the worker) gets USR1, not the engines' steps.
    argv.push_back("--signal=B:USR1@" + std::to_string(r.signal_lead_s));
  }
  if (!r.partition.empty()) argv.insert(argv.end(), {"--partition", r.partition});
  if (!r.account.empty()) argv.insert(argv.end(), {"--account", r.account});
  if (!r.output.empty()) argv.insert(argv.end(), {"--output", r.output});
  argv.push_back("--export=ALL");
  argv.push_back(r.script);
  return argv;
}

Result<int64_t> ParseSbatchJobId(std::string_view out) {
  std::string_view t = Trim(out);
  // A warning may precede the id: the id is the last line.
  const size_t nl = t.rfind('\n');
  if (nl != std::string_view::npos) t = Trim(t.substr(nl + 1));
  const size_t semi = t.find(';');
  if (semi != std::string_view::npos) t = t.substr(0, semi);
  if (!AllDigits(t)) return Status::Corruption("sbatch printed no job id: '" + std::string(Trim(out)) + "'");
  return static_cast<int64_t>(std::stoll(std::string(t)));
}

bool ShouldLease(std::optional<double> seconds_left, std::optional<double> expected_run_s, double margin_s) {
  if (!seconds_left) return true;
  const double need = expected_run_s ? *expected_run_s : margin_s;
  return *seconds_left >= need;
}

AllocationDeadline::AllocationDeadline(SlurmCommands& slurm, std::string job_id, std::function<double()> now,
                                       double refresh_s)
    : slurm_(slurm), job_id_(std::move(job_id)), now_(std::move(now)), refresh_s_(refresh_s) {}

Result<std::optional<double>> AllocationDeadline::SecondsLeft() {
  using Out = std::optional<double>;
  const double now = now_();
  auto counted_down = [&]() -> Out {
    if (!left_at_ask_) return Out();
    return Out(std::max(0.0, *left_at_ask_ - (now - asked_at_)));
  };
  if (known_ && now - asked_at_ < refresh_s_) return counted_down();
  auto out = slurm_.Run({"squeue", "-h", "-j", job_id_, "-o", "%L"});
  Status error = Status::Ok();
  if (!out.ok()) {
    error = out.status();
  } else if (out->exit_code != 0 || Trim(out->out).empty()) {
    error = Status::Unavailable("squeue -j " + job_id_ + " answered nothing: " + std::string(Trim(out->err)));
  } else {
    auto left = ParseSlurmDuration(Trim(out->out), "squeue %L");
    if (!left.ok()) {
      error = left.status();
    } else {
      known_ = true;
      asked_at_ = now;
      left_at_ask_ = *left;
      return *left;
    }
  }
  if (known_) return counted_down();
  return error;
}

}  // namespace sandswim::slurm
