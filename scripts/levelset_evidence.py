"""What evidence a level-set free-form model would earn beside the learner's hypotheses (docs/learner-history.md,
"A level-set free-form model, prototyped"). A measurement, not part of palpd: the learner does not use it.

    .venv/bin/python scripts/levelset_evidence.py [--budget 40] [--max-contrast C] SCENE | FILE.toml ...

Each scene is scanned as `palpd scan --scene SCENE --strategy active` would (default settings, seed 0), and on
the readings it ended with, the level set

    log k(x) = background(x) + log(1 + C·Φ(f(x))),   f ~ GP(m·σ_f, σ_f² exp(−d²/2ℓ²))

is fitted: the parametric fits' background (level and two slopes, their Gaussian priors; shapes.background),
the contrast C log-uniform over the lump prior's range (or up to --max-contrast), f whitened at the readings
(f = m·σ_f + L u, u ~ N(0, I)), so that the fit is one more least-squares problem for the learner's solver
(residuals: the readings', u and the background's prior) and its Laplace evidence
log L + log p + ½·4·log 2π − ½·log det(JᵀJ + P) is comparable with the parametric fits' (evidence.py). The
hyperparameters (ℓ, σ_f, m) range over a grid with a uniform prior: the row's "level set" is the log of the
mean evidence over it. P(lump) at a spot is P(f > 0) under the Laplace posterior of u, and its ½ region is
scored against the scene's truth (IoU over the grid, every true lump's area together).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from palpd.threads import pin_blas_to_one_thread

pin_blas_to_one_thread()

import numpy as np  # noqa: E402
from scipy.special import logsumexp, ndtr, ndtri  # noqa: E402

from palpd.learner.evidence import _gaussian_prior_norm  # noqa: E402
from palpd.learner.likelihood import log_likelihood, noise_sd_ml, residuals  # noqa: E402
from palpd.learner.observations import EXACT, Observations  # noqa: E402
from palpd.learner.priors import LEVEL_SD, MAX_CONTRAST, SLOPE_SD, Priors  # noqa: E402
from palpd.learner.solver import levenberg_marquardt  # noqa: E402
from palpd.learner.threshold import tissue_level  # noqa: E402

LOG_2PI = math.log(2.0 * math.pi)
# the background's three Gaussian priors' normalising constants, as the parametric fits' evidence counts them
BACKGROUND_NORM = 0.5 * _gaussian_prior_norm(None)
LENGTHS_MM = (4.0, 7.0, 10.0, 14.0)
SIGNAL_SDS = (4.0, 8.0, 16.0)
FAR_MEANS = (-0.5, -1.0, -2.0)  # m: far from every reading P(lump) ≈ Φ(m)
JITTER = 1e-6
NOISE_ROUNDS = 3


def fit(obs: Observations, priors: Priors, noise_floor: float, length_mm: float, signal_sd: float, far_mean: float,
        max_contrast: float = MAX_CONTRAST) -> dict:
    """The level set's MAP fit at one hyperparameter point, its Laplace log evidence and posterior."""
    n, scale = obs.n, priors.scale_mm
    d2 = ((obs.xy[:, None, :] - obs.xy[None, :, :]) ** 2).sum(-1)
    chol = np.linalg.cholesky(signal_sd**2 * (np.exp(-0.5 * d2 / length_mm**2) + JITTER * np.eye(n)))
    mean_f = far_mean * signal_sd
    lo_c, hi_c = math.log(priors.min_contrast), math.log(max_contrast)
    x, y = obs.xy[:, 0] / scale, obs.xy[:, 1] / scale

    def problem(theta: np.ndarray, noise: float):
        level, gx, gy, log_c = theta[:4]
        u = theta[4:]
        f = mean_f + chol @ u
        g, phi, c = ndtr(f), np.exp(-0.5 * f * f) / math.sqrt(2.0 * math.pi), math.exp(log_c)
        predicted = level + gx * x + gy * y + np.log1p(c * g)
        jac = np.zeros((n, 4 + n))
        jac[:, 0], jac[:, 1], jac[:, 2], jac[:, 3] = 1.0, x, y, c * g / (1.0 + c * g)
        jac[:, 4:] = (c * phi / (1.0 + c * g))[:, None] * chol
        r, jr = residuals(predicted, jac, obs.y, obs.sd, obs.kind, noise)
        prior = np.concatenate([[(level - priors.level) / LEVEL_SD, gx / SLOPE_SD, gy / SLOPE_SD], u])
        jp = np.zeros((3 + n, 4 + n))
        jp[0, 0], jp[1, 1], jp[2, 2] = 1.0 / LEVEL_SD, 1.0 / SLOPE_SD, 1.0 / SLOPE_SD
        jp[3:, 4:] = np.eye(n)
        return np.concatenate([r, prior]), np.vstack([jr, jp]), predicted

    exact = obs.kind == EXACT
    tissue = tissue_level(np.exp(obs.y[exact]))
    contrast = float(np.clip(np.exp(obs.y[exact]).max() / tissue - 1.0, priors.min_contrast * 1.01, max_contrast * 0.99))
    share = np.clip((np.exp(obs.y - math.log(tissue)) - 1.0) / contrast, 0.02, 0.98)  # of the contrast, each reading
    theta = np.concatenate([[math.log(tissue), 0.0, 0.0, math.log(contrast)],
                            np.linalg.solve(chol, ndtri(share) - mean_f)])
    lo, hi = np.full(4 + n, -np.inf), np.full(4 + n, np.inf)
    lo[3], hi[3] = lo_c, hi_c
    noise = noise_floor
    # the contrast held at the readings' own first: freed at once, the fit slides to a graded field in Φ's lower
    # tail (C at its bound, f near its prior mean everywhere), a poor mode 50-150 nats below the step it is
    held_lo, held_hi = lo.copy(), hi.copy()
    held_lo[3] = held_hi[3] = theta[3]
    theta, _, _ = levenberg_marquardt(lambda t: problem(t, noise)[:2], theta, held_lo, held_hi, 1e-4, 200)
    for _ in range(NOISE_ROUNDS):  # σ_w from the residuals, then the fit again at it, as evidence.fit does
        theta, _, _ = levenberg_marquardt(lambda t: problem(t, noise)[:2], theta, lo, hi, 1e-4, 200)
        predicted = problem(theta, noise)[2]
        new = noise_sd_ml(obs.y[exact] - predicted[exact], obs.sd[exact], noise_floor)
        if abs(math.log(new / noise)) < 0.05:
            break
        noise = new
    r, jac, _ = problem(theta, noise)
    curvature = jac.T @ jac
    curvature[3, 3] += 12.0 / (hi_c - lo_c) ** 2  # the uniform prior's stand-in curvature (priors.precision)
    _, log_det = np.linalg.slogdet(curvature)
    prior = r[n:]
    log_z = (log_likelihood(r[:n], obs.sd, obs.kind, noise) - 0.5 * float(prior @ prior) - BACKGROUND_NORM
             - math.log(hi_c - lo_c) + 2.0 * LOG_2PI - 0.5 * log_det)
    return {"log_z": log_z, "theta": theta, "cov": np.linalg.inv(curvature), "chol": chol, "length_mm": length_mm,
            "signal_sd": signal_sd, "mean_f": mean_f, "far_mean": far_mean, "noise": noise}


def p_lump(result: dict, obs: Observations, xy: np.ndarray) -> np.ndarray:
    """P(f > 0) at each point under the fit's Laplace posterior of u."""
    d2 = ((xy[:, None, :] - obs.xy[None, :, :]) ** 2).sum(-1)
    k_star = result["signal_sd"] ** 2 * np.exp(-0.5 * d2 / result["length_mm"] ** 2)
    a = np.linalg.solve(result["chol"], k_star.T).T  # k*ᵀ L⁻ᵀ: f* = m σ_f + a u
    mean = result["mean_f"] + a @ result["theta"][4:]
    var = result["signal_sd"] ** 2 - (a * a).sum(1) + np.einsum("ij,jk,ik->i", a, result["cov"][4:, 4:], a)
    return ndtr(mean / np.sqrt(np.maximum(var, 1e-12)))


def best(obs: Observations, priors: Priors, noise_floor: float, max_contrast: float = MAX_CONTRAST):
    """(the most evident fit, the log of the mean evidence over the hyperparameter grid)."""
    fits = [fit(obs, priors, noise_floor, length, sd, m, max_contrast)
            for length in LENGTHS_MM for sd in SIGNAL_SDS for m in FAR_MEANS]
    log_z = np.array([f["log_z"] for f in fits])
    return fits[int(np.argmax(log_z))], float(logsumexp(log_z) - math.log(len(fits)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--budget", type=int, default=40)
    parser.add_argument("--max-contrast", type=float, default=MAX_CONTRAST)
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from active_scenes import scene_path

    from drivers.sim.scene import load_scene
    from palpd import metrics
    from palpd.bench import open_simulated_bench
    from palpd.config import Settings
    from palpd.scan import plan, run_scan

    print("| scene (palpations) | level set | best ℓ, σ_f, m | GP map | best parametric | level set IoU | reported IoU |")
    print("|---|---|---|---|---|---|---|")
    for name in args.scenes:
        scene = load_scene(scene_path(name))
        settings = Settings().updated(scan={"strategy": "active"})
        planner = plan("active", scene.tissue.size_mm, args.budget, 0, settings)
        report = run_scan(open_simulated_bench(settings, scene, seed=0), settings, planner)
        learner = planner.learner
        truth = metrics.scene_truth(scene, settings.scan.min_contrast)
        reported = metrics.compare(truth, report["lumps"], scene.tissue.size_mm)["min_iou"]
        top, mean_log_z = best(learner.obs, learner.hypotheses.priors(learner.obs), learner.noise_floor,
                               args.max_contrast)
        inside = np.zeros(len(learner.grid_xy), dtype=bool)
        for lump in truth:
            inside |= metrics.inside_truth(learner.grid_xy, lump)
        drawn = p_lump(top, learner.obs, learner.grid_xy) > 0.5
        iou = np.count_nonzero(drawn & inside) / max(np.count_nonzero(drawn | inside), 1)
        fits = [(f.log_evidence, n) for n, f in learner.hypotheses.fits.items() if f is not None and f.supported]
        parametric = max(fits) if fits else (math.nan, "–")
        print(f"| {scene.name} ({report['palpations']}) | {mean_log_z:+.1f} | {top['length_mm']:g}, "
              f"{top['signal_sd']:g}, {top['far_mean']:g} | {learner._free_form_evidence():+.1f} | "
              f"{parametric[0]:+.1f} ({parametric[1]}) | {iou:.3f} | {reported if reported is not None else '–'} |",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
