"""The script a user would write instead of furfit: a numpy far field of the fur model's
unscattered lobes (R, TT, TRT; kappa = 0, as MODEL.md pins them) with Gauss-Legendre over
the fiber offset h, fitted by scipy.optimize.least_squares (trf) in log space from a manual
start, the six hair parameters and the exposure.

Usage: python scipy_fit.py PROFILE.csv [--nodes N]  -> one JSON line on stdout.
Independent of furfit's code: only MODEL.md's formulas.
"""

import argparse
import json
import sys
import time

import numpy as np
from scipy.optimize import least_squares

NAMES = ["eta", "alpha", "beta_m", "beta_n", "sigma_c_a", "l"]
# MODEL.md's hard bounds (open ends nudged inside).
LOWER = [1.0 + 1e-6, -20.0, 1e-3, 1e-3, 0.0, 1e-3]
UPPER = [3.0, 20.0, 60.0, 90.0, 50.0, 10.0]
# The manual start (seed 000 Sec. 5.1: "initial values are manually set"): typical hair.
START = [1.55, 2.0, 5.0, 5.0, 0.5, 1.5]


def read_csv(path):
    rows = []
    header = None
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            cells = [c.strip() for c in line.split(",")]
            if header is None:
                header = cells
                continue
            rows.append(cells)
    col = {n: i for i, n in enumerate(header)}
    a = np.array([[float(r[col[k]]) for k in ("theta_i", "theta_r", "phi", "value")] for r in rows])
    a = a[np.isfinite(a[:, 3]) & (a[:, 3] > 0)]
    # furfit fit's default --floor: samples more than eight decades below the peak are
    # left out, so both fit the same samples.
    a = a[a[:, 3] >= 1e-8 * a[:, 3].max()]
    return a[:, 0], a[:, 1], a[:, 2], a[:, 3]


def fresnel(cos_i, eta):
    """Unpolarised dielectric Fresnel reflectance."""
    sin2_t = (1.0 - cos_i**2) / eta**2
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, None))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin2_t >= 1.0, 1.0, 0.5 * (rs**2 + rp**2))


def wrapped_normal(x, sd):
    """Normal density of x on the circle, three 2 pi shifts (enough for sd <= 2)."""
    out = 0.0
    for k in (-1, 0, 1):
        y = x + 2 * np.pi * k
        out = out + np.exp(-0.5 * (y / sd) ** 2)
    return out / (sd * np.sqrt(2 * np.pi))


def gauss(x, mu, sd):
    return np.exp(-0.5 * ((x - mu) / sd) ** 2) / (sd * np.sqrt(2 * np.pi))


class Model:
    def __init__(self, ti, tr, phi, nodes):
        self.ti, self.tr = np.radians(ti), np.radians(tr)
        self.phi = np.radians(phi)[:, None]
        self.td = 0.5 * (self.tr - self.ti)
        x, w = np.polynomial.legendre.leggauss(nodes)
        self.h, self.w = x[None, :], w[None, :]

    def __call__(self, p):
        eta, alpha, beta_m, beta_n, sca, l = p
        alpha, beta_m, beta_n = np.radians([alpha, beta_m, beta_n])
        ctd = np.cos(self.td)[:, None]
        etap = np.sqrt(eta**2 - np.sin(self.td)[:, None] ** 2) / ctd
        h = self.h
        gi = np.arcsin(h)
        gt = np.arcsin(h / etap)
        f = fresnel(np.cos(gi), etap)
        F = l * f / (1.0 + (l - 1.0) * f)
        total = 0.0
        shifts = [alpha, -alpha / 2, -3 * alpha / 2]
        widths = [beta_m, beta_m / 2, 3 * beta_m / 2]
        for p_ in range(3):
            if p_ == 0:
                a = F
            else:
                tc = np.exp(-2 * p_ * np.cos(gt) * sca / ctd)
                a = (1 - F) ** 2 * F ** (p_ - 1) * tc
            big_phi = 2 * p_ * gt - 2 * gi + p_ * np.pi
            d = wrapped_normal(np.angle(np.exp(1j * (self.phi - big_phi))),
                               np.sqrt(p_ + 1) * beta_n)
            n = 0.5 * np.sum(self.w * a * d, axis=1)
            m = gauss(self.tr, -self.ti + shifts[p_], widths[p_])
            total = total + m * n
        return total


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("profile")
    ap.add_argument("--nodes", type=int, default=96)
    args = ap.parse_args()
    t0 = time.perf_counter()
    ti, tr, phi, value = read_csv(args.profile)
    model = Model(ti, tr, phi, args.nodes)
    logv = np.log(value)

    def residuals(q):
        return np.log(np.maximum(model(q[:-1]), 1e-300)) + q[-1] - logv

    x0 = np.array(START + [0.0])
    x0[-1] = np.mean(logv - np.log(np.maximum(model(x0[:-1]), 1e-300)))
    res = least_squares(residuals, x0, method="trf",
                        bounds=(LOWER + [-np.inf], UPPER + [np.inf]))
    r = res.fun
    # Optimal exposure in closed form, as furfit reports its NRMSE.
    r = r - r.mean()
    nrmse = float(np.sqrt(np.mean(r**2)) / (logv.max() - logv.min()))
    out = {
        "nrmse": nrmse,
        "params": dict(zip(NAMES, map(float, res.x[:-1]))),
        "exposure": float(np.exp(res.x[-1])),
        # nfev counts residual calls outside the 2-point Jacobian; each Jacobian costs one
        # call per unknown.
        "evaluations": int(res.nfev + res.njev * len(res.x)),
        "samples": int(len(value)),
        "nodes": args.nodes,
        "seconds": time.perf_counter() - t0,
    }
    json.dump(out, sys.stdout)
    print()


if __name__ == "__main__":
    main()
