#!/usr/bin/env python3
"""The overlapping Allan deviation of model/src/allan.cpp in plain numpy, for the speed
comparison of docs/performance.md ("Allan deviation"). Plain means the obvious vectorised
implementation: the angle by one float64 cumsum of the demeaned rate, then for each octave
cluster size m the second difference of the angle as three slices, squared and summed.

Usage: allan_numpy.py RUN.f64 [--reps R]   (RUN.f64: raw float64 rates in deg/h at 1 s, as
`bench_allan --write-dir DIR` writes them). Prints the median time of R repetitions
(default 21), wall and CPU, and the deviation at the shortest and longest tau, to compare with bench_allan's.
       allan_numpy.py --csv RUN.csv   the whole-process peer of `fogctl allan RUN.csv --whole-run`:
reads fogctl's CSV (np.loadtxt, the gyro column) and prints the curve once.
"""
import sys
import time

import numpy as np


def overlapping_adev(rate_dph, tau0_s=1.0):
    n = len(rate_dph)
    theta = np.concatenate(([0.0], np.cumsum(rate_dph - rate_dph.mean())))
    out = []
    m = 1
    while m <= (n - 1) // 2:
        d = theta[2 * m:] - 2.0 * theta[m:-m] + theta[:-2 * m]
        out.append((m * tau0_s, np.sqrt(np.dot(d, d) / (2.0 * m * m * len(d)))))
        m *= 2
    return out


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    if sys.argv[1] == "--csv":
        data = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1, usecols=(0, 1))
        for tau_s, adev in overlapping_adev(data[:, 1], data[1, 0] - data[0, 0]):
            print("%g %.6g" % (tau_s, adev))
        return 0
    reps = int(sys.argv[sys.argv.index("--reps") + 1]) if "--reps" in sys.argv else 21
    rate = np.fromfile(sys.argv[1], dtype="<f8")
    times, walls = [], []
    for _ in range(reps):
        t0, w0 = time.process_time(), time.perf_counter()
        curve = overlapping_adev(rate)
        times.append((time.process_time() - t0) * 1e3)
        walls.append((time.perf_counter() - w0) * 1e3)
    times.sort()
    walls.sort()
    print("numpy overlapping ADEV of %d samples at %d octave taus: median %.2f ms wall (min %.2f, max %.2f), %.2f ms CPU"
          % (len(rate), len(curve), walls[len(walls) // 2], walls[0], walls[-1], times[len(times) // 2]))
    print("  adev(1 s) %.12g deg/h, adev(%.0f s) %.12g deg/h" % (curve[0][1], curve[-1][0], curve[-1][1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
