// The ball chain of issue 12's benchmarks as a model file (the same scene as
// bench/scenes/ball_chain.py): n rods of 0.1 m and 1 kg, box inertia 0.1 x 0.01 x 0.01 m,
// spherical joints, the first to the ground, at rest along +x, gravity -9.81 y. Shared by
// tests/dae/test_tree_kkt.cc and bench/bench_kkt.cc.
#pragma once

#include <sstream>
#include <string>

namespace mbdae::testing {

inline std::string BallChainYaml(int n, double output_step) {
  std::ostringstream s;
  s.precision(17);
  const double m = 1.0, len = 0.1, w = 0.01;
  const double ixx = m * (2 * w * w) / 12, iyy = m * (len * len + w * w) / 12;
  s << "format: 1\nname: chain\ngravity: [0, -9.81, 0]\nbodies:\n";
  for (int k = 1; k <= n; ++k)
    s << "  - {name: rod" << k << ", mass: " << m << ", inertia: [" << ixx << ", " << iyy
      << ", " << iyy << "], position: [" << (k - 0.5) * len
      << ", 0, 0], orientation: [1, 0, 0, 0], markers: {A: {position: [" << -len / 2
      << ", 0, 0]}, B: {position: [" << len / 2 << ", 0, 0]}}}\n";
  s << "joints:\n  - {name: ball1, type: spherical, i: rod1.A, j: ground.O}\n";
  for (int k = 2; k <= n; ++k)
    s << "  - {name: ball" << k << ", type: spherical, i: rod" << k << ".A, j: rod" << k - 1
      << ".B}\n";
  s << "simulation: {t_end: 1, output_step: " << output_step << "}\n";
  return s.str();
}

}  // namespace mbdae::testing
