#!/usr/bin/env python3
"""The same two fits as fogbench's model/, in plain numpy, for the speed comparison of
docs/performance.md. Plain means: the obvious vectorised implementation a scientist would
write, with one least-squares solve (normal equations by np.dot) per candidate lag.

Usage: fit_numpy.py RUN.csv [--reps R] [--whole]   (--whole: time CSV parsing + paper fit once,
the whole-process comparison with `fogctl fit RUN.csv`).
"""
import sys
import time

import numpy as np

MAX_LAG = 600
HALF = 30  # derivative window half-width, s (61 s Savitzky-Golay slope), as model/


def load(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    return data[:, 0], data[:, 1], data[:, 2], data[:, 3]


def derivative_per_min(x):
    k = np.arange(-HALF, HALF + 1, dtype=float)
    coef = k / np.sum(k * k)
    d = np.convolve(x, coef[::-1], mode="same")
    # ends: one-sided windows, as model/ does
    for i in list(range(HALF)) + list(range(len(x) - HALF, len(x))):
        lo, hi = max(0, i - HALF), min(len(x), i + HALF + 1)
        t = np.arange(lo, hi, dtype=float)
        d[i] = np.polyfit(t, x[lo:hi], 1)[0]
    return d * 60.0


def lagged(x, lag):
    out = np.empty_like(x)
    out[:lag] = x[0]
    out[lag:] = x[: len(x) - lag]
    return out


def ar_fit(y, p=2):
    X = np.column_stack([y[p - 1 - j : len(y) - 1 - j] for j in range(p)])
    Y = y[p:]
    theta = np.linalg.solve(X.T @ X, X.T @ Y)
    return theta, (Y @ Y - Y @ X @ theta) / len(y)


def paper_fit(g, t1, t2):
    hold = g[:600]
    keep = np.abs(hold - hold.mean()) <= 3 * hold.std(ddof=1)
    mu0 = hold[keep].mean()
    k, s2 = ar_fit(hold[keep] - mu0)
    smooth = np.convolve(g, np.ones(61) / 61, mode="same")
    z = smooth - mu0
    x1 = derivative_per_min(t1 - 20.0)
    x2 = (t1 - t2)
    best = (np.inf, 0, None)
    for lag in range(MAX_LAG + 1):
        X = np.column_stack([lagged(x1, lag), lagged(x2, lag)])
        G = X.T @ X
        b = X.T @ z
        th = np.linalg.solve(G, b)
        sse = z @ z - b @ th
        if sse < best[0]:
            best = (sse, lag, th)
    return mu0, k, s2, best


def joint_fit(g, t1, t2, iters=4):
    """Mirrors model/'s joint fit: OLS with one shared lag, then Cochrane-Orcutt iterations;
    the first whitened iteration searches each term's lag by coordinate descent, the later
    ones re-estimate the coefficients and the AR(2) noise at fixed lags."""
    x = [derivative_per_min(t1 - 20.0), t1 - t2]
    k = np.zeros(2)

    def whiten(v):
        return v - k[0] * np.r_[v[0], v[:-1]] - k[1] * np.r_[v[0], v[0], v[:-2]]

    def solve(yf, xf, c, lags):
        cols = [np.full_like(yf, c)] + [lagged(xf[j], lags[j]) for j in range(2)]
        X = np.column_stack(cols)
        b = X.T @ yf
        th = np.linalg.solve(X.T @ X, b)
        return th, yf @ yf - b @ th

    # OLS, one lag shared by both terms
    best = (np.inf, 0)
    for lag in range(MAX_LAG + 1):
        _, sse = solve(g, x, 1.0, [lag, lag])
        if sse < best[0]:
            best = (sse, lag)
    lags = [best[1], best[1]]
    th, _ = solve(g, x, 1.0, lags)
    for it in range(iters):
        e = g - th[0] - sum(th[j + 1] * lagged(x[j], lags[j]) for j in range(2))
        k, _ = ar_fit(e)
        yf, xf, c = whiten(g), [whiten(v) for v in x], 1 - k.sum()
        if it == 0:
            moved = True
            while moved:
                moved = False
                for j in range(2):
                    best = (np.inf, 0)
                    for lag in range(MAX_LAG + 1):
                        trial = list(lags)
                        trial[j] = lag
                        _, sse = solve(yf, xf, c, trial)
                        if sse < best[0]:
                            best = (sse, lag)
                    moved = moved or best[1] != lags[j]
                    lags[j] = best[1]
        th, _ = solve(yf, xf, c, lags)
    return th, lags, k


def main():
    path = sys.argv[1]
    reps = int(sys.argv[sys.argv.index("--reps") + 1]) if "--reps" in sys.argv else 3
    if "--whole" in sys.argv:
        t0 = time.perf_counter()
        _, g, t1, t2 = load(path)
        paper_fit(g, t1, t2)
        print(f"whole {time.perf_counter() - t0:.3f} s")
        return
    _, g, t1, t2 = load(path)
    for name, fn in (("paper", paper_fit), ("joint", joint_fit)):
        best = np.inf
        for _ in range(reps):
            t0 = time.perf_counter()
            fn(g, t1, t2)
            best = min(best, time.perf_counter() - t0)
        print(f"{name} {len(g)} {best * 1000:.1f} ms")


if __name__ == "__main__":
    main()
