#include "daemon/api/quota.h"

#include <grpcpp/server_context.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rheo::daemon {
namespace {

std::string Who(const std::string& token) {
  return token.empty() ? std::string("this client") : "token '" + token + "'";
}

std::string Number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

}  // namespace

grpc::Status Quotas::Charge(const std::string& token, std::string_view method,
                            Clock::time_point now) {
  if (limits_.calls_per_s <= 0.0) return grpc::Status::OK;
  const double burst = std::max(1.0, limits_.burst);
  std::lock_guard<std::mutex> lock(mutex_);
  auto [it, fresh] = buckets_.try_emplace(token + '\n' + std::string(method));
  Bucket& b = it->second;
  if (fresh) {
    b.tokens = burst;
  } else {
    const double dt = std::chrono::duration<double>(now - b.at).count();
    b.tokens = std::min(burst, b.tokens + std::max(0.0, dt) * limits_.calls_per_s);
  }
  b.at = now;
  if (b.tokens >= 1.0) {
    b.tokens -= 1.0;
    return grpc::Status::OK;
  }
  ++stats_.refused_rate;
  const double wait_s = (1.0 - b.tokens) / limits_.calls_per_s;
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      std::string(method) + ": " + Who(token) + " is past its limit of " +
                          Number(limits_.calls_per_s) + " calls per second to this method (" +
                          Number(burst) + " in a burst; rheod --limit-calls); retry in " +
                          Number(std::ceil(wait_s * 1e3)) + " ms");
}

grpc::Status Quotas::OpenStream(grpc::ServerContextBase* context, const std::string& token,
                                std::string_view method, Stream* out) {
  std::lock_guard<std::mutex> lock(mutex_);
  int& open = streams_by_token_[token];
  if (limits_.streams > 0 && open >= limits_.streams) {
    ++stats_.refused_streams;
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        std::string(method) + ": " + Who(token) + " has " + std::to_string(open) +
                            " streams open, the most one token may hold (rheod --limit-streams); "
                            "close some (viewers, tool streams) first");
  }
  ++open;
  ++stats_.open_streams;
  const uint64_t id = next_stream_++;
  streams_.emplace(id, OpenedStream{context, token, std::string(method), Clock::now()});
  out->owner_ = this;
  out->id_ = id;
  return grpc::Status::OK;
}

Quotas::Stream::~Stream() {
  if (owner_) owner_->Close(id_);
}

void Quotas::Stream::Touch() {
  if (!owner_) return;
  std::lock_guard<std::mutex> lock(owner_->mutex_);
  auto it = owner_->streams_.find(id_);
  if (it != owner_->streams_.end()) it->second.last = Clock::now();
}

void Quotas::Close(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = streams_.find(id);
  if (it == streams_.end()) return;
  auto t = streams_by_token_.find(it->second.token);
  if (t != streams_by_token_.end() && --t->second <= 0) streams_by_token_.erase(t);
  --stats_.open_streams;
  streams_.erase(it);
}

grpc::Status Quotas::StartJob(const std::string& token, Job* out) {
  std::lock_guard<std::mutex> lock(mutex_);
  int& running = jobs_by_token_[token];
  if (limits_.jobs > 0 && running >= limits_.jobs) {
    ++stats_.refused_jobs;
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "CreateObject: " + Who(token) + " has " + std::to_string(running) +
                            " mesh jobs running, the most one token may run at once (rheod "
                            "--limit-jobs); wait for one to finish or cancel it");
  }
  ++running;
  ++stats_.running_jobs;
  out->owner_ = this;
  out->token_ = token;
  return grpc::Status::OK;
}

Quotas::Job::~Job() {
  if (owner_) owner_->EndJob(token_);
}

void Quotas::EndJob(const std::string& token) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto t = jobs_by_token_.find(token);
  if (t != jobs_by_token_.end() && --t->second <= 0) jobs_by_token_.erase(t);
  --stats_.running_jobs;
}

int Quotas::CancelIdle(Clock::time_point now) {
  if (limits_.stream_idle.count() <= 0) return 0;
  std::lock_guard<std::mutex> lock(mutex_);
  int n = 0;
  for (auto& [id, s] : streams_) {
    if (s.cancelled || now - s.last < limits_.stream_idle) continue;
    s.cancelled = true;
    s.context->TryCancel();  // thread-safe; the handler's blocked read or write returns false
    ++n;
  }
  stats_.idle_cancelled += static_cast<uint64_t>(n);
  return n;
}

QuotaStats Quotas::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace rheo::daemon
