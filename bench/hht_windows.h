// Fixed HHT steps timed in windows, shared by bench/bench_chain.cc and
// bench/peers/bench_step_flops.cc: every window times the same steps of the run.
#pragma once

#include <benchmark/benchmark.h>

#include "dae/integrator.h"

namespace mbdae::bench {

// Times steps of size h of `integ` as the benchmark's iterations, `window` steps per
// window: each window starts (untimed) from x0 after `warmup` untimed steps, then calls
// on_start(); on_close() is called (untimed) after every window and after the last
// steps. A failed step skips the benchmark with the integrator's message and ends the
// loop (on_close() still follows). Returns false, with nothing timed or closed, when the
// first start fails.
template <class OnStart, class OnClose>
bool TimeHhtWindows(benchmark::State& state, dae::Integrator& integ, const dae::State& x0,
                    double h, int warmup, int window, OnStart on_start, OnClose on_close) {
  auto start = [&]() -> bool {
    integ.Initialize(x0);
    if (!integ.AdvanceTo(x0.t + warmup * h)) return false;
    on_start();
    return true;
  };
  if (!start()) {
    state.SkipWithError(integ.summary().message.c_str());
    return false;
  }
  int in_window = 0;
  for (auto _ : state) {
    if (in_window == window) {
      state.PauseTiming();
      on_close();
      const bool ok = start();
      in_window = 0;
      state.ResumeTiming();
      if (!ok) {
        state.SkipWithError(integ.summary().message.c_str());
        break;
      }
    }
    if (!integ.AdvanceTo(integ.state().t + h)) {
      state.SkipWithError(integ.summary().message.c_str());
      break;
    }
    ++in_window;
  }
  on_close();
  return true;
}

}  // namespace mbdae::bench
