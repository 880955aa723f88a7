"""Fixtures of the Python package tests: the example models and models written inline.

Run by CTest (tests/python/CMakeLists.txt) with PYTHONPATH=<build>/python; by hand:
    PYTHONPATH=build/python /usr/bin/python3 -m pytest tests/python
"""

import os

import pytest

import mbdae

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PENDULUM = os.path.join(ROOT, "examples", "pendulum.yaml")
OSCILLATOR = os.path.join(ROOT, "examples", "virtual_iteration", "oscillator.yaml")

# A free body under gravity (no joints): the motion is exactly quadratic in t.
FREE_FALL = """
format: 1
name: free fall
gravity: [0, 0, -9.81]
parameters: {h: 10}
bodies:
  - {name: ball, mass: 2, inertia: [0.1, 0.1, 0.1], position: [0, 0, h], velocity: [1, 0, 0]}
measures:
  - {name: height, type: translational, i: ball.cm, component: z, frame: world}
simulation: {t_end: 1.0, output_step: 0.1, integrator: hht, hht: {alpha: -0.1, step: 1.0e-2}}
"""


@pytest.fixture
def pendulum():
    with mbdae.Model(PENDULUM) as m:
        yield m


@pytest.fixture
def oscillator():
    with mbdae.Model(OSCILLATOR) as m:
        yield m


@pytest.fixture
def free_fall():
    with mbdae.Model.from_string(FREE_FALL, "free_fall.yaml") as m:
        yield m
