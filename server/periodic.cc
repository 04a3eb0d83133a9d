#include "server/periodic.h"

#include <chrono>
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
  const auto period = std::chrono::duration<double>(job.period_s);
  std::unique_lock<std::mutex> lock(mu_);
  if (!job.run_at_start && cv_.wait_for(lock, period, [this] { return stopping_; })) return;
  while (!stopping_) {
    lock.unlock();
    job.fn();
    lock.lock();
    if (cv_.wait_for(lock, period, [this] { return stopping_; })) return;
  }
}

}  // namespace sandswim
