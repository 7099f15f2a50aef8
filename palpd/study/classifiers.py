"""The paper's three learning algorithms (§3.2) and the thresholds read from them.

GDA here is scikit-learn's LinearDiscriminantAnalysis: Gaussian classes with a
shared covariance, whose boundary is linear like the other two. Features are
standardised first, so C means the same whatever the units.
"""
from __future__ import annotations

import numpy as np
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

ALGORITHMS = ("lr", "gda", "svm")
GRID_STEP_MM = 0.05


def make_classifier(algorithm: str, c: float = 1.0):
    if algorithm == "lr":
        model = LogisticRegression(C=c)
    elif algorithm == "gda":
        model = LinearDiscriminantAnalysis()
    elif algorithm == "svm":
        model = SVC(kernel="linear", C=c)
    else:
        raise ValueError(f"unknown algorithm {algorithm!r}; choose from {', '.join(ALGORITHMS)}")
    return make_pipeline(StandardScaler(), model)


def fit_classifier(algorithm: str, c: float, features: np.ndarray, labels: np.ndarray):
    """A classifier, or a constant answer when the labels hold one class only."""
    labels = np.asarray(labels, dtype=int)
    if np.unique(labels).size < 2:
        return _Constant(int(labels[0]) if labels.size else 0)
    return make_classifier(algorithm, c).fit(np.asarray(features, dtype=float).reshape(len(labels), -1), labels)


def radius_threshold(classifier, max_distance_mm: float) -> float:
    """The distance where a classifier on distance alone turns from lump to tissue."""
    grid = np.arange(0.0, max(max_distance_mm, GRID_STEP_MM) + GRID_STEP_MM, GRID_STEP_MM)
    inside = classifier.predict(grid[:, None]).astype(bool)
    if not inside[0]:
        return 0.0
    outside = np.flatnonzero(~inside)
    return float(grid[outside[0]] - GRID_STEP_MM / 2) if outside.size else float(grid[-1])


class _Constant:
    def __init__(self, label: int) -> None:
        self.label = label

    def predict(self, features) -> np.ndarray:
        return np.full(len(features), self.label, dtype=int)
