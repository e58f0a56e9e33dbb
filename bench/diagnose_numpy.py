#!/usr/bin/env python3
"""diagnose's library search on one run, in plain numpy, for the speed comparison of
docs/performance.md ("diagnose on long runs"). Plain means what a careful scientist would write
with numpy alone: every lag scan's cross-products at all lags by one FFT correlation per pair
of columns (as model/ scans), every lag's normal equations solved in one batched
np.linalg.solve, nothing cached between candidates but the run's columns and their spectra.

What it computes (the same steps as `fogctl diagnose --search library` on the fit run alone):
  1. The paper model `d(T1)@auto + grad@auto` by the paper method: mu0 and AR(2) from the opening
     hold (first 600 s, 3-sigma outliers out), the 61 s moving average of the output less mu0
     regressed on the two terms with one shared lag scanned over 0..600 s, d(T1) held at its
     causal least (30 s, the derivative's half window) below it; BIC of the whole run's
     AR-prewhitened innovations, n ln(RSS/n) + (1 + terms + 2 + 1) ln n.
  2. Each candidate: the effects library's terms the model lacks (T1, T1^2, T2, d(T2), d(grad),
     dd(T1), T1*d(T1), up(d(T1)), down(d(T1)), lp(T1,300), Ta, d(Ta)) and the model's two terms again at a
     second lag (kept 30 s or more from the model's lag). Its lag scanned 0..600 s beside the
     model's columns at their lags (the one-column gain at every lag); the paper model refitted
     with it at that lag (the shared lag scanned again); while the refit moves the shared lag,
     the candidate's lag rescanned beside the refitted columns and refitted (at most 3 times,
     kept while BIC falls); lag 0 refitted and kept when BIC + ln n says so; the kept refit's
     standard errors from the prewhitened design; delta BIC (a scanned lag costs ln n) and the
     fall of the compensated std (residual std, 3-sigma outliers out) on the run.
  3. The candidates ranked by delta BIC; the best printed, then the time.

How it differs from fogctl diagnose: no held-out runs, weights all 1 (no flagged or missing
samples: a `fogctl simulate` run has none), no outlier weights in the smoothing, no
collinearity checks; none of diagnose's other stages (data quality, residual whiteness and
cross-correlations, the unit's noise floor, jumps, drift in time, periodic search, look-alikes,
the pruning of small candidates); the ends of d(x) by polyfit on the one-sided window as
bench/fit_numpy.py does. Its numbers are therefore close to diagnose's, not equal; the point
is the cost of the same search.

Usage: diagnose_numpy.py RUN.csv [--reps R] [--whole]
  Prints the candidates (lag, delta BIC, fall) and the median and minimum CPU time of R searches
  (default 3) after the CSV is read; with --whole instead, the CPU time of reading the CSV and one
  search (the peer of `fogctl diagnose RUN.csv --search library` timed whole).
"""
import sys
import time

import numpy as np

MAX_LAG = 600
HALF = 30  # derivative window half-width, s (61 s slope), as model/
HOLD_S = 600
SMOOTH_S = 61
TREF_C = 20.0
AR_ORDER = 2
LAG_ITERATIONS = 3


def load(path):
    with open(path) as f:
        for skip, line in enumerate(f):
            if line.strip() and not line.startswith("#"):
                break
    names = [h.strip() for h in line.split(",")]
    want = [w for w in ("gyro_dph", "t1_c", "t2_c", "chamber_c") if w in names]
    data = np.loadtxt(path, delimiter=",", skiprows=skip + 1, usecols=[names.index(w) for w in want], ndmin=2)
    return {w: data[:, i].copy() for i, w in enumerate(want)}


def derivative_per_min(x):
    k = np.arange(-HALF, HALF + 1, dtype=float)
    d = np.convolve(x, (k / np.sum(k * k))[::-1], mode="same")
    for i in list(range(HALF)) + list(range(len(x) - HALF, len(x))):
        lo, hi = max(0, i - HALF), min(len(x), i + HALF + 1)
        d[i] = np.polyfit(np.arange(lo, hi, dtype=float), x[lo:hi], 1)[0]
    return d * 60.0


def low_pass(x, tau_s, block=512):
    """lp(x, tau): y[i] = y[i-1] + a (x[i] - y[i-1]), a = 1 - exp(-1 s / tau), y[-1] = x[0], as
    model/ (no scipy here): within blocks of 512 samples in closed form, the carry block by block."""
    a = 1.0 - np.exp(-1.0 / tau_s)
    r = 1.0 - a
    n = len(x)
    nb = -(-n // block)
    xp = np.concatenate((x, np.zeros(nb * block - n))).reshape(nb, block)
    k = np.arange(block)
    inner = a * r ** k * np.cumsum(xp * r ** (-k), axis=1)  # the block's own inputs
    carry = r ** (k + 1)
    y = np.empty_like(xp)
    prev = x[0]
    for b in range(nb):
        y[b] = carry * prev + inner[b]
        prev = y[b, -1]
    return y.reshape(-1)[:n]


def lagged(x, lag):
    if lag == 0:
        return x
    out = np.empty_like(x)
    out[:lag] = x[0]
    out[lag:] = x[: len(x) - lag]
    return out


def ar_fit(y, p=AR_ORDER):
    X = np.column_stack([y[p - 1 - j: len(y) - 1 - j] for j in range(p)])
    return np.linalg.solve(X.T @ X, X.T @ y[p:])


def moving_average(x, m):
    c = np.convolve(x, np.ones(m), mode="same")
    cnt = np.convolve(np.ones_like(x), np.ones(m), mode="same")
    return c / cnt


class Run:
    """One run's signals, target and the spectra of the columns scanned (made once each)."""

    def __init__(self, d):
        g = d["gyro_dph"]
        self.y = g
        self.n = len(g)
        self.nfft = 1 << int(np.ceil(np.log2(self.n + MAX_LAG + 1)))
        hold = g[:HOLD_S]
        keep = np.abs(hold - hold.mean()) <= 3 * hold.std(ddof=1)
        self.mu0 = hold[keep].mean()
        self.ar = ar_fit(hold[keep] - self.mu0)
        self.z = moving_average(g, SMOOTH_S) - self.mu0
        self.zz = self.z @ self.z
        self.zcum = np.concatenate(([0.0], np.cumsum(self.z)))
        sig = {"T1": d["t1_c"] - TREF_C, "T2": d["t2_c"] - TREF_C, "grad": d["t1_c"] - d["t2_c"]}
        if "chamber_c" in d:
            sig["Ta"] = d["chamber_c"] - TREF_C
        self.sig = sig
        self._cols = {}
        self._spec = {}

    def column(self, name):
        if name not in self._cols:
            s = self.sig
            dT1 = lambda: self.column("d(T1)")  # noqa: E731
            make = {
                "T1": lambda: s["T1"], "T2": lambda: s["T2"], "grad": lambda: s["grad"], "Ta": lambda: s["Ta"],
                "d(T1)": lambda: derivative_per_min(s["T1"]), "d(T2)": lambda: derivative_per_min(s["T2"]),
                "d(grad)": lambda: derivative_per_min(s["grad"]), "d(Ta)": lambda: derivative_per_min(s["Ta"]),
                "dd(T1)": lambda: derivative_per_min(dT1()), "T1^2": lambda: s["T1"] ** 2,
                "T1*d(T1)": lambda: s["T1"] * dT1(), "up(d(T1))": lambda: np.maximum(dT1(), 0.0),
                "down(d(T1))": lambda: np.minimum(dT1(), 0.0), "lp(T1,300)": lambda: low_pass(s["T1"], 300.0),
            }[name]
            self._cols[name] = make()
        return self._cols[name]

    def spectrum(self, key, x):
        if "@" in key:  # a column at one lag: used by one scan or two, not kept
            return np.fft.rfft(x, self.nfft)
        if key not in self._spec:
            self._spec[key] = np.fft.rfft(x, self.nfft)
        return self._spec[key]

    def corr(self, a_key, a, v_key, v):
        """sum_t a[t] v[t - l] for l = 0..MAX_LAG, v before the start held at v[0]."""
        c = np.fft.irfft(self.spectrum(a_key, a) * np.conj(self.spectrum(v_key, v)), self.nfft)[: MAX_LAG + 1]
        head = np.concatenate(([0.0], np.cumsum(a[:MAX_LAG])))  # sum_{t<l} a[t]
        return c + v[0] * head


def scan(run, fixed, varying, lags):
    """Least squares of z on the fixed columns and the varying ones at a shared lag, at every lag
    in `lags` (a range within 0..MAX_LAG). fixed: [(key, column)], varying: [(key, column)].
    Returns (sse, theta) per lag. Varying columns at lag l: x[t - l], held at x[0] before."""
    n, L = run.n, np.asarray(lags)
    kf, kv = len(fixed), len(varying)
    k = kf + kv
    G = np.empty((len(L), k, k))
    b = np.empty((len(L), k))
    F = np.column_stack([c for _, c in fixed]) if kf else np.zeros((n, 0))
    if kf:
        G[:, :kf, :kf] = F.T @ F
        b[:, :kf] = F.T @ run.z
    for i, (vk, v) in enumerate(varying):
        b[:, kf + i] = run.corr("z", run.z, vk, v)[L]
        for j, (fk, f) in enumerate(fixed):
            g = run.corr(fk, f, vk, v)[L]
            G[:, j, kf + i] = G[:, kf + i, j] = g
        for j in range(i + 1):
            wk, w = varying[j]
            p = np.concatenate(([0.0], np.cumsum(v * w)))
            g = p[n - L] + L * v[0] * w[0]
            G[:, kf + i, kf + j] = G[:, kf + j, kf + i] = g
    theta = np.linalg.solve(G, b[..., None])[..., 0]
    sse = run.zz - np.einsum("lk,lk->l", b, theta)
    return sse, theta


def fit_paper(run, extra=None):
    """The paper model, optionally with one more term at a fixed lag (key, column, lag_s).
    Returns dict(lag, coefs [(key, lag, coef)], bic, se)."""
    base = [("d(T1)", run.column("d(T1)")), ("grad", run.column("grad"))]
    fixed = []
    if extra:
        fixed = [(f"{extra[0]}@{extra[2]}", lagged(extra[1], extra[2]))]
    # Shared lag >= 30 s: both move; below: d(T1) held at 30 s (its causal least), grad moves.
    sse_hi, th_hi = scan(run, fixed, base, range(HALF, MAX_LAG + 1))
    lo_fixed = fixed + [("d(T1)@30", lagged(base[0][1], HALF))]
    sse_lo, th_lo = scan(run, lo_fixed, base[1:], range(0, HALF))
    i_hi, i_lo = int(np.argmin(sse_hi)), int(np.argmin(sse_lo))
    if sse_lo[i_lo] < sse_hi[i_hi]:
        lag, th = i_lo, th_lo[i_lo]
        terms = ([(extra[0], extra[2])] if extra else []) + [("d(T1)", HALF), ("grad", lag)]
        cols = [c for _, c in lo_fixed] + [lagged(base[1][1], lag)]
    else:
        lag, th = HALF + i_hi, th_hi[i_hi]
        terms = ([(extra[0], extra[2])] if extra else []) + [("d(T1)", lag), ("grad", lag)]
        cols = [c for _, c in fixed] + [lagged(base[0][1], lag), lagged(base[1][1], lag)]
    X = np.column_stack(cols)
    e = run.y - run.mu0 - X @ th
    k1, k2 = run.ar
    a = e[2:] - k1 * e[1:-1] - k2 * e[:-2]
    nw = len(a)
    rss = a @ a
    nparams = 1 + len(cols) + AR_ORDER + 1
    bic = nw * np.log(rss / nw) + nparams * np.log(nw)
    return {"lag": lag, "terms": terms, "theta": th, "X": X, "e": e, "rss": rss, "nw": nw, "nparams": nparams, "bic": bic}


def standard_errors(run, m):
    k1, k2 = run.ar
    X = np.column_stack([np.ones(run.n)] + [m["X"][:, j] for j in range(m["X"].shape[1])])
    Xw = X[2:] - k1 * X[1:-1] - k2 * X[:-2]
    s2 = m["rss"] / (m["nw"] - m["nparams"])
    return np.sqrt(np.diag(s2 * np.linalg.inv(Xw.T @ Xw)))


def comp_std(run, m):
    r = m["e"]
    keep = np.abs(r - r.mean()) <= 3 * r.std(ddof=1)
    return r[keep].std(ddof=1)


def best_lag_beside(run, m, key, x, avoid=None):
    """The candidate's best lag beside the model m's columns at their lags (the one-column gain)."""
    fixed = [(f"{t}@{lag}", m["X"][:, j]) for j, (t, lag) in enumerate(m["terms"])]
    sse, _ = scan(run, fixed, [(key, x)], range(0, MAX_LAG + 1))
    if avoid is not None:
        sse[max(0, avoid - HALF): avoid + HALF + 1] = np.inf
    return int(np.argmin(sse))


def search(run):
    base = fit_paper(run)
    rms0 = comp_std(run, base)
    ln_n = np.log(base["nw"])
    cands = ["T1", "T1^2", "T2", "d(T2)", "d(grad)", "dd(T1)", "T1*d(T1)", "up(d(T1))", "down(d(T1))", "lp(T1,300)"]
    if "Ta" in run.sig:
        cands += ["Ta", "d(Ta)"]
    cands = [(c, None) for c in cands] + [(t, lag) for t, lag in base["terms"]]  # second lags
    out = []
    for key, own in cands:
        x = run.column(key)
        lag = best_lag_beside(run, base, key, x, own)
        m = fit_paper(run, (key, x, lag))
        for _ in range(LAG_ITERATIONS):
            if m["lag"] == base["lag"] or own is not None:
                break
            beside = dict(m, terms=m["terms"][1:], X=m["X"][:, 1:])
            lag2 = best_lag_beside(run, beside, key, x)
            if lag2 == lag:
                break
            m2 = fit_paper(run, (key, x, lag2))
            if m2["bic"] >= m["bic"]:
                break
            lag, m = lag2, m2
        extra = 1
        if lag != 0 and own is None:
            m0 = fit_paper(run, (key, x, 0))
            if m0["bic"] <= m["bic"] + ln_n:
                lag, m, extra = 0, m0, 0
        se = standard_errors(run, m)
        coef = m["theta"][0]
        dbic = m["bic"] + extra * ln_n - base["bic"]
        fall = 1.0 - comp_std(run, m) / rms0
        out.append((dbic, key + ("" if own is None else " (second lag)"), lag, coef, se[1], fall))
    out.sort()
    return base, out


def main():
    path = sys.argv[1]
    reps = int(sys.argv[sys.argv.index("--reps") + 1]) if "--reps" in sys.argv else 3
    if "--whole" in sys.argv:
        c0 = time.process_time()
        search(Run(load(path)))
        print(f"whole (read + search) cpu {time.process_time() - c0:.3f} s")
        return
    d = load(path)
    times = []
    for _ in range(reps):
        c0 = time.process_time()
        base, out = search(Run(d))
        times.append(time.process_time() - c0)
    print(f"paper model: shared lag {base['lag']} s, BIC {base['bic']:.1f}")
    for dbic, key, lag, coef, se, fall in out:
        print(f"  {key:24s} lag {lag:4d} s  delta BIC {dbic:12.1f}  coef {coef: .4g} (se {se:.2g})  fall {100 * fall:6.2f} %")
    times.sort()
    print(f"library search on {len(d['gyro_dph'])} samples: cpu median {times[len(times) // 2]:.3f} s, min {times[0]:.3f} s ({reps} reps)")


if __name__ == "__main__":
    main()
