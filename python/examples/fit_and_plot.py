"""Fit a shipped species and plot its data against the fit (issue 63's example).

    python python/examples/fit_and_plot.py [SPECIES] [--out reports/python_fit_SPECIES.png]

Run from the repository root. Loads measurements/SPECIES (default red-fox), fits the fur
model (seed 1, as ``furfit fit measurements/SPECIES --seed 1``), and plots, per incident
angle, the in-plane sweeps (phi = 0, light and camera on one side; phi = 180, forward)
of the data against the fitted model, which ``furfit.synth`` evaluates on a fine theta_r
grid. matplotlib is optional: without it the fit is printed and no figure is made.
"""

import argparse
import sys

import numpy as np

import furfit


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("species", nargs="?", default="red-fox")
    ap.add_argument("--out", help="image path (default reports/python_fit_SPECIES.png)")
    a = ap.parse_args()
    prof = furfit.load_profile(f"measurements/{a.species}")
    res = furfit.fit(prof, seed=1)
    print(res)
    print("  " + " ".join(f"{k}={v:.4g}" for k, v in res.params.items()))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no figure (pip install matplotlib)")
        return 0

    thetas = np.unique(prof.theta_i)
    fine = np.linspace(-80, 80, 321)
    # The model at the fitted parameters and exposure, on the fine grid: (ti, tr, phi).
    model = furfit.synth(res, thetas, fine, [0.0, 180.0])
    fig, axes = plt.subplots(1, len(thetas), figsize=(4 * len(thetas), 3.6), sharey=True)
    for k, (ax, ti) in enumerate(zip(np.atleast_1d(axes), thetas)):
        for j, (phi, colour) in enumerate([(0.0, "tab:blue"), (180.0, "tab:red")]):
            sel = (prof.theta_i == ti) & (prof.phi == phi) & (prof.value > 0)
            ax.errorbar(prof.theta_r[sel], prof.value[sel],
                        yerr=None if prof.sigma is None else prof.sigma[sel],
                        fmt="o", ms=3, color=colour, alpha=0.6, label=f"data, phi {phi:.0f}")
            ax.plot(fine, model[k, :, j], color=colour, lw=1.5, label=f"fit, phi {phi:.0f}")
        ax.set_yscale("log")
        ax.set_title(f"theta_i = {ti:.0f} deg")
        ax.set_xlabel("theta_r (deg)")
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("value")
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle(f"{a.species}: {res.model} fit by furfit.fit (seed 1), "
                 f"NRMSE {100 * res.nrmse:.2f} %, exposure {res.exposure:.3g}")
    fig.tight_layout()
    out = a.out or f"reports/python_fit_{a.species}.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
