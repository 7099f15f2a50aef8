"""The learner's posterior as plain lists (reply.estimate.get's `map`): what the live view and the plots draw."""
from __future__ import annotations

MAP_CELLS_PER_SIDE = 61  # a 61 x 61 map keeps an estimate.get reply near 100 kB


def posterior_grid(learner, max_cells_per_side: int = MAP_CELLS_PER_SIDE) -> dict | None:
    """P(lump), mean and sd of the stiffness on an evenly thinned grid, learner frame (PosteriorMap's fields);
    None before the learner's first stiffness point."""
    grid = learner.posterior_grid()  # the chosen hypothesis's map (learner/maps.py)
    if grid is None:
        return None
    step = max(1, -(-len(learner.xs) // max_cells_per_side))
    cells = (slice(None, None, step), slice(None, None, step))
    p_lump, mean, sd = grid.p_lump, grid.mean, grid.sd
    return {"xs_mm": [round(float(x), 3) for x in learner.xs[cells[1]]],
            "ys_mm": [round(float(y), 3) for y in learner.ys[cells[0]]],
            "p_lump": p_lump[cells].round(4).tolist(), "stiffness_n_per_mm": mean[cells].round(5).tolist(),
            "stiffness_sd_n_per_mm": sd[cells].round(5).tolist(), "confidence": learner.settings.confidence}


def learned_from_probes(probes: list[dict], size_mm, settings, seed: int = 0):
    """A learner fed a scan's probes in order: the posterior of a raster or random scan, for its picture."""
    from palpd.learner.planner import make_learner

    learner = make_learner(settings, tuple(size_mm), seed)
    for probe in probes:  # a failed palpation where it was aimed
        xy = probe["xy_mm"] if probe["stiffness_n_per_mm"] is not None else probe.get("target_xy_mm") or probe["xy_mm"]
        learner.observe(xy, probe["stiffness_n_per_mm"], probe.get("stiffness_se_n_per_mm") or 0.0)
    return learner
