// The record of an HHT run under a memory budget (HhtTrajectory, hht_sensitivity.h) and
// the recomputation of its segments (HhtStateWindow, hht_checkpoint.h).
#include "sensitivities/hht_checkpoint.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "dae/format.h"
#include "sensitivities/hht_sensitivity.h"

namespace mbdae::sens {

namespace {

// Blocks of at most 64 KiB; under a budget at most 1/64 of it (at least one record).
constexpr size_t kBlockBytes = 64 * 1024;
constexpr size_t kMinCheckpoints = 16;

std::string Num(double x) { return FormatG(x, 6); }

}  // namespace

// ---- RecordStore

RecordStore::RecordStore(int width, size_t block_bytes) : width_(std::max(width, 1)) {
  per_block_ = std::max<size_t>(1, block_bytes / (sizeof(double) * width_));
}

RecordStore::RecordStore(const RecordStore& other)
    : width_(other.width_), per_block_(other.per_block_), size_(other.size_) {
  const size_t n = per_block_ * width_;
  for (const auto& b : other.blocks_) {
    blocks_.emplace_back(new double[n]);
    std::memcpy(blocks_.back().get(), b.get(), n * sizeof(double));
  }
}

RecordStore& RecordStore::operator=(const RecordStore& other) {
  if (this != &other) *this = RecordStore(other);
  return *this;
}

double* RecordStore::Append() {
  if (size_ == blocks_.size() * per_block_) {
    if (blocks_.size() == blocks_.capacity()) blocks_.reserve(NextCapacity());
    blocks_.emplace_back(new double[per_block_ * width_]);
  }
  return (*this)[size_++];
}

size_t RecordStore::GrowthBytes() const {
  if (size_ % per_block_ != 0 || size_ < blocks_.size() * per_block_) return 0;
  size_t bytes = block_bytes();
  if (blocks_.size() == blocks_.capacity())
    bytes += (NextCapacity() - blocks_.capacity()) * sizeof(blocks_[0]);
  return bytes;
}

void RecordStore::KeepEvery(size_t stride) {
  if (stride <= 1 || size_ == 0) return;
  const size_t kept = (size_ - 1) / stride + 1;
  for (size_t i = 1; i < kept; ++i)
    std::memcpy((*this)[i], (*this)[i * stride], width_ * sizeof(double));
  size_ = kept;
  blocks_.resize((size_ + per_block_ - 1) / per_block_);
}

void RecordStore::Clear() {
  size_ = 0;
  blocks_.clear();
  blocks_.shrink_to_fit();
}

size_t RecordStore::bytes() const {
  return blocks_.size() * block_bytes() + blocks_.capacity() * sizeof(blocks_[0]);
}

// ---- HhtTrajectory

HhtTrajectory::HhtTrajectory(int nq, int nc) : nq_(nq), nc_(nc) { Reset(); }

size_t HhtTrajectory::minimum_budget() const {
  // The largest HHT history a system of nq coordinates can have (nq / 4 groups), so that
  // a budget accepted here holds 16 checkpoints of any integrator Attach meets.
  return kMinCheckpoints * (state_bytes() + sizeof(double) * dae::HhtHistory::Size(nq_, nc_, nq_ / 4));
}

void HhtTrajectory::set_memory_budget(size_t bytes) {
  if (size() > 0)
    throw std::logic_error("HhtTrajectory::set_memory_budget: the run is being recorded already");
  if (bytes != 0 && bytes < minimum_budget())
    throw std::invalid_argument("HhtTrajectory: a memory budget of " + std::to_string(bytes) +
                                " bytes holds fewer than " + std::to_string(kMinCheckpoints) +
                                " checkpoints; the least is " + std::to_string(minimum_budget()) +
                                " bytes (or 0: store every state)");
  budget_ = bytes;
  Reset();
}

void HhtTrajectory::Attach(dae::Integrator& integrator) {
  integrator.SaveSnapshot(&scratch_);  // the history's size; throws if unsupported
  if (budget_ != 0 && state_bytes() + sizeof(double) * scratch_.history.size() >
                          minimum_budget() / kMinCheckpoints)
    throw std::invalid_argument("HhtTrajectory::Attach: " + integrator.name() +
                                " keeps a longer history than minimum_budget() allows for");
  if (scratch_.state.q.size() != size_t(nq_) || scratch_.state.lambda.size() != size_t(nc_))
    throw std::invalid_argument("HhtTrajectory::Attach: the integrator's system has nq = " +
                                std::to_string(scratch_.state.q.size()) + ", nc = " +
                                std::to_string(scratch_.state.lambda.size()) +
                                ", the trajectory " + std::to_string(nq_) + ", " +
                                std::to_string(nc_));
  history_ = static_cast<int>(scratch_.history.size());
  integrator_ = &integrator;
  Reset();
  integrator.SetStepObserver([this](const dae::State& x, double h) { Record(x, h); });
}

dae::StepObserver HhtTrajectory::Recorder() {
  if (budget_ != 0)
    throw std::logic_error("HhtTrajectory::Recorder: a memory budget needs Attach(integrator): "
                           "checkpoints hold the integrator's history");
  return [this](const dae::State& x, double h) { Record(x, h); };
}

void HhtTrajectory::Clear() { Reset(); }

void HhtTrajectory::Reset() {
  const size_t block = budget_ > 0 ? std::min(kBlockBytes, budget_ / 64) : kBlockBytes;
  times_ = RecordStore(2, block);
  states_ = RecordStore(3 * nq_ + nc_, block);
  hist_ = RecordStore(std::max(history_, 1), block);
  dense_ = true;
  // The first checkpoint interval: the smallest power of two s1 with
  // checkpoint bytes / s1 <= state bytes / 2 (the checkpoints kept when the states no
  // longer fit take at most half of what the states took).
  interval_ = 1;
  if (budget_ > 0 && history_ > 0)
    while (checkpoint_bytes() > interval_ * state_bytes() / 2) interval_ *= 2;
  thinning_rounds_ = 0;
  exceeded_ = false;
  peak_ = memory();
}

size_t HhtTrajectory::memory() const { return times_.bytes() + states_.bytes() + hist_.bytes(); }

const double* HhtTrajectory::q(int n) const {
  if (dense_) return states_[n];
  if (n % interval_ != 0 || size_t(n / interval_) >= states_.size()) return nullptr;
  return states_[n / interval_];
}
const double* HhtTrajectory::v(int n) const {
  const double* x = q(n);
  return x ? x + nq_ : nullptr;
}
const double* HhtTrajectory::a(int n) const {
  const double* x = q(n);
  return x ? x + 2 * nq_ : nullptr;
}
const double* HhtTrajectory::lambda(int n) const {
  const double* x = q(n);
  return x ? x + 3 * nq_ : nullptr;
}

void HhtTrajectory::GetCheckpoint(int i, dae::IntegratorSnapshot* out) const {
  if (dense_ || i < 0 || i >= num_checkpoints())
    throw std::out_of_range("HhtTrajectory::GetCheckpoint: no checkpoint " + std::to_string(i));
  dae::State& x = out->state;
  const double* r = states_[i];
  x.t = t(i * interval_);
  x.q.assign(r, r + nq_);
  x.v.assign(r + nq_, r + 2 * nq_);
  x.a.assign(r + 2 * nq_, r + 3 * nq_);
  x.lambda.assign(r + 3 * nq_, r + 3 * nq_ + nc_);
  out->history.assign(hist_[i], hist_[i] + history_);
}

// Drops what the next record makes room for: first the states between the
// checkpoints (the switch from every state to checkpoints), then every other checkpoint.
bool HhtTrajectory::Shrink() {
  if (dense_) {
    states_.KeepEvery(interval_);
    dense_ = false;
    return true;
  }
  if (states_.size() <= 1) return false;
  states_.KeepEvery(2);
  hist_.KeepEvery(2);
  interval_ *= 2;
  ++thinning_rounds_;
  return true;
}

void HhtTrajectory::Record(const dae::State& x, double h) {
  if (budget_ != 0 && !integrator_)
    throw std::logic_error("HhtTrajectory: a memory budget needs Attach(integrator)");
  if (x.q.size() != size_t(nq_) || x.lambda.size() != size_t(nc_))
    throw std::invalid_argument("HhtTrajectory: a state of another system recorded");
  const size_t n = times_.size();
  bool want_state = true, want_hist = false;
  for (;;) {
    want_state = dense_ || n % interval_ == 0;
    want_hist = budget_ != 0 && n % interval_ == 0;
    if (budget_ == 0) break;
    const size_t growth = times_.GrowthBytes() + (want_state ? states_.GrowthBytes() : 0) +
                          (want_hist ? hist_.GrowthBytes() : 0);
    if (memory() + growth <= budget_) break;
    if (!Shrink()) {
      exceeded_ = true;
      break;
    }
  }
  double* th = times_.Append();
  th[0] = x.t;
  th[1] = h;
  if (want_state) {
    double* r = states_.Append();
    std::copy(x.q.begin(), x.q.end(), r);
    std::copy(x.v.begin(), x.v.end(), r + nq_);
    std::copy(x.a.begin(), x.a.end(), r + 2 * nq_);
    std::copy(x.lambda.begin(), x.lambda.end(), r + 3 * nq_);
  }
  if (want_hist) {
    integrator_->SaveSnapshot(&scratch_);
    std::copy(scratch_.history.begin(), scratch_.history.end(), hist_.Append());
  }
  peak_ = std::max(peak_, memory());
}

// ---- HhtStateWindow

HhtStateWindow::HhtStateWindow(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                               const HhtTrajectory& trajectory)
    : system_(system), options_(options), traj_(trajectory) {
  nq_ = trajectory.nq();
  nc_ = trajectory.nc();
  width_ = 3 * nq_ + nc_;
  dense_ = trajectory.stores_every_step();
  const int N = trajectory.size() - 1;
  const int s = trajectory.checkpoint_interval();
  segments_ = dense_ ? 1 : std::max(1, (N + s - 1) / s);
}

HhtStateWindow::~HhtStateWindow() = default;

int HhtStateWindow::first(int i) const { return dense_ ? 0 : i * traj_.checkpoint_interval(); }

int HhtStateWindow::last(int i) const {
  const int N = traj_.size() - 1;
  return dense_ ? N : std::min((i + 1) * traj_.checkpoint_interval(), N);
}

double HhtStateWindow::t(int n) const { return traj_.t(n); }

const double* HhtStateWindow::Record(int n) const {
  return dense_ ? traj_.q(n) : buffer_.data() + size_t(n - first_) * width_;
}

bool HhtStateWindow::Load(int i, std::string* error) {
  first_wbar_ = nullptr;
  if (dense_) {
    first_ = 0;
    return true;
  }
  try {
    return Recompute(i, error);
  } catch (const std::exception& e) {
    *error = std::string("recomputing a segment from its checkpoint: ") + e.what();
    return false;
  }
}

bool HhtStateWindow::Recompute(int i, std::string* error) {
  const int N = traj_.size() - 1;
  const int s = traj_.checkpoint_interval();
  if (!integrator_) {
    // One integrator for every segment: it replays the whole step list from the entry
    // the restored checkpoint names (dae::HhtHistory::kStep).
    options_.replay_steps.resize(N);
    for (int n = 1; n <= N; ++n) options_.replay_steps[n - 1] = traj_.h(n);
    integrator_ = dae::MakeHhtIntegrator(system_, options_);
    buffer_.assign(size_t(s + 1) * width_, 0.0);
    peak_bytes_ = sizeof(double) * (buffer_.capacity() + options_.replay_steps.capacity());
  }
  first_ = first(i);
  const int end = last(i);
  traj_.GetCheckpoint(i, &snapshot_);
  integrator_->RestoreSnapshot(snapshot_);
  const dae::State& x0 = snapshot_.state;
  auto store = [&](const dae::State& x, double* r) {
    std::copy(x.q.begin(), x.q.end(), r);
    std::copy(x.v.begin(), x.v.end(), r + nq_);
    std::copy(x.a.begin(), x.a.end(), r + 2 * nq_);
    std::copy(x.lambda.begin(), x.lambda.end(), r + 3 * nq_);
  };
  store(x0, buffer_.data());
  const int ng = static_cast<int>(system_.quaternion_offsets().size());
  if (first_ > 0 && ng > 0) {
    const double* w = snapshot_.history.data() + dae::HhtHistory::kVectors + nq_;
    wbar_.assign(w, w + 3 * ng);
    first_wbar_ = wbar_.data();
  }
  for (int n = first_ + 1; n <= end; ++n) {
    if (!integrator_->AdvanceTo(traj_.t(n))) {
      *error = "recomputing step " + std::to_string(n) + " (t = " + Num(traj_.t(n)) +
               ") from the checkpoint at t = " + Num(x0.t) + " failed: " +
               integrator_->summary().message + " (were the options those of the run?)";
      return false;
    }
    store(integrator_->state(), buffer_.data() + size_t(n - first_) * width_);
  }
  recomputed_ += end - first_;
  // A segment that ends on a checkpoint: the stored state is the run's own; measure
  // the recomputed one against it and keep the stored one.
  if (end % s == 0 && end > first_) {
    const double* stored = traj_.q(end);
    double* rec = buffer_.data() + size_t(end - first_) * width_;
    double dev = 0;
    // Positions and velocities: what the Newton iteration's stopping test bounds (it
    // weighs the correction of a by beta h^2 and gamma h; a and lambda agree to the
    // Newton tolerance divided by those factors).
    for (int j = 0; j < 2 * nq_; ++j)
      dev = std::max(dev, std::abs(rec[j] - stored[j]) / (1 + std::abs(stored[j])));
    max_deviation_ = std::max(max_deviation_, dev);
    if (!(dev <= 1e-6)) {
      *error = "the state recomputed at t = " + Num(traj_.t(end)) +
               " differs from its checkpoint by " + Num(dev) +
               " (relative, q and v): were the options those of the run?";
      return false;
    }
    std::copy(stored, stored + width_, rec);
  }
  return true;
}

}  // namespace mbdae::sens
