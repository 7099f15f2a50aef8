"""The supervised threshold: τ learned from a labelled training set, as the seed paper's §3.4 did.

The training set is a dataset CSV with a `tumor` column (what `palpd dataset`
writes). A one-feature classifier on stiffness (logistic regression, the
paper's first algorithm) separates tumour from tissue; τ is the stiffness where
its decision turns. Its classes are weighted as equally likely: how many
training points fell on a lump says how that set was palpated, not how likely
a lump is where the learner probes next (unweighted, 5 lump points in 81 push
τ well above the half-height). With the dataset labelled by each lump's radius, τ lands on
the training lump's boundary stiffness, close to its half-height.
"""
from __future__ import annotations

import numpy as np

from palpd.datafile import read_training_set
from palpd.errors import ConfigError


def supervised_tau(path: str) -> float:
    """τ (N/mm) from the labelled training set at `path`; a file that cannot teach one is a ConfigError."""
    data = read_training_set(path)
    k, tumor = data.stiffness_n_per_mm, data.tumor.astype(bool)
    from sklearn.linear_model import LogisticRegression  # after the checks: a bad file fails at once
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    classifier = make_pipeline(StandardScaler(), LogisticRegression(class_weight="balanced"))
    return tau_between(classifier.fit(k[:, None], tumor.astype(int)), k)


def tau_between(classifier, k: np.ndarray) -> float:
    """The stiffness where a fitted one-feature classifier's decision function crosses zero."""
    def decision(value: float) -> float:
        return float(classifier.decision_function(np.array([[value]]))[0])

    low, high = float(k.min()), float(k.max())
    if decision(low) >= 0.0 or decision(high) <= 0.0:  # the classes overlap so much it never turns inside
        raise ConfigError("learner.training_set: stiffness does not separate tumor from tissue")
    from scipy.optimize import brentq  # here: only a supervised τ needs it, and it is slow to import

    return float(brentq(decision, low, high, xtol=1e-9))
