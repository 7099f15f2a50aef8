"""The five methods of the seed paper, §3.4–§3.8. Each returns labels, a centre and a radius per test set.

Equation 1's weighted centroid is used normalised, Σ a·kᵖ·x / Σ a·kᵖ: the
printed (1/n)·Σ 10·k³·x depends on the unit of stiffness, and normalised the
constant a cancels, so only the power p changes the answer.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.cluster import KMeans

from palpd.study.classifiers import fit_classifier, radius_threshold

METHODS = ("threshold-radius", "centroid-radius", "centroid-radius-stiffness", "kmeans", "kmeans-semisupervised")
SUPERVISED = METHODS[:3]


@dataclass(frozen=True)
class Options:
    c: float = 1.0  # the SVM's and LR's regularisation weight
    centroid_weights: tuple[float, float] = (10.0, 3.0)  # Equation 1's {10, 3}
    seed: int = 0


@dataclass(frozen=True)
class Labelled:
    labels: np.ndarray
    center_mm: tuple[float, float] | None
    radius_mm: float


def weighted_centroid(xy: np.ndarray, k: np.ndarray, weights: tuple[float, float]) -> np.ndarray:
    scale, power = weights
    w = scale * np.asarray(k, dtype=float) ** power
    return (w[:, None] * xy).sum(axis=0) / w.sum()


def _distance(xy, centre) -> np.ndarray:
    return np.linalg.norm(xy - np.asarray(centre), axis=1)


def _labelled(labels, centre, distance, algorithm, options) -> Labelled:
    """Labels with the radius a distance threshold learned on them gives (as §3.4's second step)."""
    radius_fit = fit_classifier(algorithm or "svm", options.c, distance[:, None], labels)
    radius = radius_threshold(radius_fit, float(distance.max())) if labels.any() else 0.0
    return Labelled(np.asarray(labels, dtype=int), None if centre is None else tuple(map(float, centre)), radius)


def threshold_radius(train, test, algorithm, options) -> Labelled:
    stiffness_fit = fit_classifier(algorithm, options.c, train.stiffness_n_per_mm[:, None], train.tumor)
    first = stiffness_fit.predict(test.stiffness_n_per_mm[:, None]).astype(bool)
    if not first.any():
        return Labelled(np.zeros(len(first), dtype=int), None, 0.0)
    centre = test.xy_mm[first].mean(axis=0)
    distance = _distance(test.xy_mm, centre)
    radius_fit = fit_classifier(algorithm, options.c, distance[:, None], first.astype(int))
    radius = radius_threshold(radius_fit, float(distance.max()))
    return Labelled((distance <= radius).astype(int), tuple(map(float, centre)), radius)


def centroid_radius(train, test, algorithm, options) -> Labelled:
    train_distance = _distance(train.xy_mm, weighted_centroid(train.xy_mm, train.stiffness_n_per_mm, options.centroid_weights))
    fitted = fit_classifier(algorithm, options.c, train_distance[:, None], train.tumor)
    centre = weighted_centroid(test.xy_mm, test.stiffness_n_per_mm, options.centroid_weights)
    distance = _distance(test.xy_mm, centre)
    radius = radius_threshold(fitted, float(max(distance.max(), train_distance.max())))
    return Labelled((distance <= radius).astype(int), tuple(map(float, centre)), radius)


def _features(data, options) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    centre = weighted_centroid(data.xy_mm, data.stiffness_n_per_mm, options.centroid_weights)
    distance = _distance(data.xy_mm, centre)
    return np.column_stack([distance, data.stiffness_n_per_mm]), centre, distance


def centroid_radius_stiffness(train, test, algorithm, options, train_labels=None) -> Labelled:
    train_features, _, _ = _features(train, options)
    labels = train.tumor if train_labels is None else train_labels
    fitted = fit_classifier(algorithm, options.c, train_features, labels)
    features, centre, distance = _features(test, options)
    return _labelled(fitted.predict(features), centre, distance, algorithm, options)


def kmeans_labels(data, options) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two k-means clusters on (distance, stiffness), standardised; the stiffer cluster is the lump."""
    features, centre, distance = _features(data, options)
    scaled = (features - features.mean(axis=0)) / np.where(features.std(axis=0) > 0, features.std(axis=0), 1.0)
    clusters = KMeans(n_clusters=2, n_init=10, random_state=options.seed).fit_predict(scaled)
    stiffer = int(np.argmax([data.stiffness_n_per_mm[clusters == c].mean() for c in (0, 1)]))
    return (clusters == stiffer).astype(int), centre, distance


def kmeans(train, test, algorithm, options) -> Labelled:
    labels, centre, distance = kmeans_labels(test, options)
    return _labelled(labels, centre, distance, None, options)


def kmeans_semisupervised(train, test, algorithm, options) -> Labelled:
    train_labels, _, _ = kmeans_labels(train, options)
    return centroid_radius_stiffness(train, test, algorithm, options, train_labels)


RUNNERS = {
    "threshold-radius": threshold_radius,
    "centroid-radius": centroid_radius,
    "centroid-radius-stiffness": centroid_radius_stiffness,
    "kmeans": kmeans,
    "kmeans-semisupervised": kmeans_semisupervised,
}
