#!/usr/bin/env python3
"""Picasso's fitting rate on the frames of `smartagg bench frames --dir DIR`.

Every frame of DIR/spots.tif is one spot (the whole frame is the box), so
this times Picasso's fitting alone — no detection, no file output — on the
same spots that `smartagg localize` processes end to end:

* picasso.fitting.gaussfit.fit_spots, SPHERICAL model, mle=True (the
  Levenberg–Marquardt Poisson MLE of Picasso >= 0.11), one thread, and
  fit_spots_async on Picasso's default thread count;
* picasso.gaussmle.gaussmle(eps=0.001, max_it=100, method="sigma") (the
  older Newton MLE), one thread, and gaussmle_async likewise.

Numba compiles each kernel on a small warm-up set first (not timed). The
RMSE of x and y against DIR/truth.csv is printed beside each rate (Picasso
puts pixel centres at integer coordinates: x_picasso + 0.5 = x).

Usage: python3 tools/picasso_rate.py DIR  (needs picassosr and tifffile)
"""
import sys
import time

import numpy as np
import tifffile


def rmse(x, y, tx, ty):
    d2 = ((x - tx) ** 2 + (y - ty) ** 2) / 2.0
    ok = np.isfinite(d2) & (d2 < 4.0)
    return float(np.sqrt(d2[ok].mean())), int(ok.sum())


def main():
    d = sys.argv[1]
    spots = tifffile.imread(f"{d}/spots.tif").astype(np.float32)
    if spots.ndim == 2:
        spots = spots[None]
    truth = np.loadtxt(f"{d}/truth.csv", delimiter=",", skiprows=1)
    tx, ty = truth[:, 1] - 0.5, truth[:, 2] - 0.5
    n, box = len(spots), spots.shape[1]
    from picasso.fitting import gaussfit, seeds
    from picasso import gaussmle, lib

    threads = gaussfit.n_workers()
    print(f"picasso: {n} spots of {box}x{box}; default threads {threads} "
          f"(75% of {lib.os.cpu_count() if hasattr(lib, 'os') else '?'} CPUs)")

    init = seeds.initial_parameters_gauss(spots, box, spherical=True)
    # Warm-up: numba compilation.
    gaussfit.fit_spots(gaussfit.SPHERICAL, spots[:50], init[:50], mle=True)
    af = gaussfit.fit_spots_async(gaussfit.SPHERICAL, spots[:50], init[:50],
                                  mle=True)
    while not af.finished():
        time.sleep(0.001)
    gaussmle.gaussmle(spots[:50], eps=0.001, max_it=100, method="sigma")
    cur, *_ = gaussmle.gaussmle_async(spots[:50], 0.001, 100, "sigma")
    while cur[0] < 50:
        time.sleep(0.001)
    time.sleep(0.1)

    def report(label, seconds, x, y):
        r, k = rmse(x, y, tx, ty)
        print(f"  {label:<44} {n / seconds:>10.0f} fits/s   RMSE {r:.4f} px "
              f"({k} within 2 px)")

    t0, c0 = time.perf_counter(), time.thread_time()
    th, *_ = gaussfit.fit_spots(gaussfit.SPHERICAL, spots, init, mle=True)
    t1, c1 = time.perf_counter(), time.thread_time()
    # SPHERICAL: photons, x, y, s, bg.
    report("fit_spots(SPHERICAL, mle=True), 1 thread", t1 - t0, th[:, 1], th[:, 2])
    # Thread CPU time: robust to a shared machine's load.
    print(f"  {'  the same, per CPU second':<44} {n / (c1 - c0):>10.0f} fits/s")

    t0 = time.perf_counter()
    af = gaussfit.fit_spots_async(gaussfit.SPHERICAL, spots, init, mle=True)
    while not af.finished():
        time.sleep(0.0005)
    t1 = time.perf_counter()
    th, *_ = af.results()
    report(f"fit_spots_async(mle=True), {threads} threads", t1 - t0,
           th[:, 1], th[:, 2])

    t0 = time.perf_counter()
    th, *_ = gaussmle.gaussmle(spots, eps=0.001, max_it=100, method="sigma")
    t1 = time.perf_counter()
    # gaussmle: x, y, photons, bg, sx, sy (x is the column).
    report("gaussmle(method='sigma'), 1 thread", t1 - t0, th[:, 0], th[:, 1])

    t0 = time.perf_counter()
    cur, th, *_ = gaussmle.gaussmle_async(spots, 0.001, 100, "sigma")
    while cur[0] < n:
        time.sleep(0.0005)
    t1 = time.perf_counter()
    # The counter reaches n when the last spot is taken, not fitted: wait
    # for the pool to drain (a few fits) before reading the results.
    time.sleep(0.05)
    report(f"gaussmle_async('sigma'), {lib.n_workers()} threads", t1 - t0,
           th[:, 0], th[:, 1])


if __name__ == "__main__":
    main()
