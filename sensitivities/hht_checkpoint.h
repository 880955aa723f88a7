// Checkpoints of HHT runs for the sweeps of sensitivities/hht_sensitivity.h (docs/
// sensitivities.md, "Memory and checkpoints"): the block storage the trajectory keeps its
// records in, and the window through which the sweeps read the states of one segment of
// the run, recomputed from its checkpoint when the trajectory did not keep them.
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "dae/hht.h"
#include "dae/integrator.h"
#include "dae/mechanical_system.h"

namespace mbdae::sens {

class HhtTrajectory;

// Records of `width` doubles in blocks of a fixed number of records: appending never
// moves what is stored (no reallocation peak), and thinning frees whole blocks, so the
// bytes held are the blocks in use (plus the small table of block pointers).
class RecordStore {
 public:
  RecordStore() = default;
  // width >= 1 doubles a record; a block holds max(1, block_bytes / (8 width)) records.
  RecordStore(int width, size_t block_bytes);
  RecordStore(const RecordStore& other);
  RecordStore& operator=(const RecordStore& other);
  RecordStore(RecordStore&&) = default;
  RecordStore& operator=(RecordStore&&) = default;

  int width() const { return width_; }
  size_t size() const { return size_; }
  double* operator[](size_t i) { return blocks_[i / per_block_].get() + (i % per_block_) * width_; }
  const double* operator[](size_t i) const {
    return blocks_[i / per_block_].get() + (i % per_block_) * width_;
  }
  // Room for one more record (a new block when the last one is full).
  double* Append();
  // Bytes the next Append allocates: nothing, or one block (and a larger table of
  // block pointers when it is full).
  size_t GrowthBytes() const;
  // Keeps records 0, stride, 2 stride, ... (in place, in order) and frees the blocks
  // emptied.
  void KeepEvery(size_t stride);
  void Clear();
  size_t bytes() const;

 private:
  size_t block_bytes() const { return per_block_ * static_cast<size_t>(width_) * sizeof(double); }
  size_t NextCapacity() const { return std::max<size_t>(8, 2 * blocks_.capacity()); }
  int width_ = 1;
  size_t per_block_ = 1;
  size_t size_ = 0;
  std::vector<std::unique_ptr<double[]>> blocks_;
};

// The states of one segment of a recorded run, steps first(i)..last(i), for the sweeps:
// views into the trajectory when it stores every state (one segment, nothing
// recomputed); otherwise segment i starts at checkpoint i and its states are recomputed
// by one HHT integrator on the same system with the run's options, restored from the
// checkpoint and replaying the stored step sizes (HhtOptions::replay_steps; each step
// lands exactly on its stored time). The recomputed states equal the run's to the
// Newton tolerance; a segment that ends on the next checkpoint takes that checkpoint's
// stored state as its last one and reports how far the recomputed one was from it.
class HhtStateWindow {
 public:
  HhtStateWindow(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                 const HhtTrajectory& trajectory);
  ~HhtStateWindow();

  int segments() const { return segments_; }
  int first(int i) const;
  int last(int i) const;
  // Makes the states of segment i available. Returns false with *error when the
  // recomputation fails or strays from the stored checkpoint by more than 1e-6
  // (max_deviation(); the options are then not those of the run).
  bool Load(int i, std::string* error);

  // States of the loaded segment, n in [first, last].
  double t(int n) const;
  const double* q(int n) const { return Record(n); }
  const double* v(int n) const { return Record(n) + nq_; }
  const double* a(int n) const { return Record(n) + 2 * nq_; }
  const double* lambda(int n) const { return Record(n) + 3 * nq_; }
  // The integrator's omegabar' of the Euler-parameter groups at first(i) when the
  // segment was recomputed from a checkpoint past the start (3 per group), else nullptr:
  // the sweeps then compute it from the states n - 1 and n.
  const double* first_wbar() const { return first_wbar_; }

  long recomputed_steps() const { return recomputed_; }
  // The largest difference between a recomputed state and the checkpoint it ran into,
  // max |x_recomputed - x_stored| / (1 + |x_stored|) over q and v (what the Newton
  // iteration's stopping test bounds; a and lambda agree to that divided by gamma h and
  // beta h^2).
  double max_deviation() const { return max_deviation_; }
  // Bytes this window held at most beyond the trajectory: the segment's states and the
  // replayed step list.
  size_t peak_bytes() const { return peak_bytes_; }

 private:
  const double* Record(int n) const;
  bool Recompute(int i, std::string* error);

  dae::MechanicalSystem& system_;
  dae::HhtOptions options_;
  const HhtTrajectory& traj_;
  int nq_ = 0, nc_ = 0, width_ = 0;
  int segments_ = 1;
  int first_ = 0;
  bool dense_ = true;
  std::unique_ptr<dae::Integrator> integrator_;
  dae::IntegratorSnapshot snapshot_;
  std::vector<double> buffer_;  // records first..last of a recomputed segment
  std::vector<double> wbar_;
  const double* first_wbar_ = nullptr;
  long recomputed_ = 0;
  double max_deviation_ = 0;
  size_t peak_bytes_ = 0;
};

}  // namespace mbdae::sens
