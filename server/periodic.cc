#include "server/periodic.h"

#include <utility>

namespace sandswim {

PeriodicJobs::~PeriodicJobs() { Stop(); }

void PeriodicJobs::Add(std::string name, double period_s, std::function<void()> job, bool run_at_start) {
  if (period_s <= 0) return;
  jobs_.push_back(Job{std::move(name), period_s, std::move(job), run_at_start});
}

void PeriodicJobs::Start() {
  for (const Job& job : jobs_) threads_.emplace_back([this, &job] { Loop(job); });
}

void PeriodicJobs::Stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
}

std::vector<std::string> PeriodicJobs::names() const {
  std::vector<std::string> out;
  for (const Job& job : jobs_) out.push_back(job.name);
  return out;
}

void PeriodicJobs::Loop(const Job& job) {
  const std::function<bool()> stopping = [this] { return stopping_; };
  std::unique_lock<std::mutex> lock(mu_);
  if (!job.run_at_start && clock_->WaitFor(cv_, lock, job.period_s, stopping)) return;
  while (!stopping_) {
    lock.unlock();
    job.fn();
    lock.lock();
    if (clock_->WaitFor(cv_, lock, job.period_s, stopping)) return;
  }
}

}  // namespace sandswim
