"""Helpers of the tests and the benchmarks (not part of viewcomp).

- ``synthetic``: synthetic, plausible runtime models and test frames (no GL).
- ``calibrations``: small real calibrations, simulated (a second or so).
- ``fuzzing``: fuzzed live input for a running player: valid and malformed OSC and stdin.
- ``materials``: the names of the measured materials the tests run on.
- ``scripts``: a repository script (scripts/, bench/) loaded as a module.
"""
