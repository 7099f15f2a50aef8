"""A study: every method and algorithm on every test set, counted as false positives and negatives."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from palpd.errors import PalpdError
from palpd.study.classifiers import ALGORITHMS
from palpd.study.methods import METHODS, RUNNERS, Options

MIN_POINTS = 4  # two per class at least, for a classifier, and k-means needs more points than clusters


def check_training(train) -> None:
    if train.tumor is None:
        raise PalpdError(f"{train.path}: the training set has no tumor column (labels 0/1 are needed to train)")
    _check_size(train, "training")
    if min(np.count_nonzero(train.tumor == 1), np.count_nonzero(train.tumor == 0)) < 2:
        raise PalpdError(f"{train.path}: the training set needs at least 2 tumor and 2 non-tumor points")


def check_test(test) -> None:
    if test.tumor is None:
        raise PalpdError(f"{test.path}: the test set has no tumor column, so errors cannot be counted")
    _check_size(test, "test")
    if np.unique(test.tumor).size < 2:
        raise PalpdError(f"{test.path}: the test set has one class only (all tumor={int(test.tumor[0])}); "
                         "false positives and negatives need both")


def _check_size(data, role: str) -> None:
    if len(data.stiffness_n_per_mm) < MIN_POINTS:
        raise PalpdError(f"{data.path}: the {role} set has {len(data.stiffness_n_per_mm)} points; "
                         f"the methods need at least {MIN_POINTS}")


def run_study(train, tests, options: Options = Options(), methods=METHODS) -> list[dict]:
    check_training(train)
    for test in tests:
        check_test(test)
    results = []
    for method in methods:
        for algorithm in ([None] if method == "kmeans" else ALGORITHMS):
            for test in tests:
                results.append(_one(method, algorithm, train, test, options))
    return results


def _one(method: str, algorithm, train, test, options: Options) -> dict:
    found = RUNNERS[method](train, test, algorithm, options)
    truth = test.tumor.astype(bool)
    predicted = found.labels.astype(bool)
    return {
        "method": method, "algorithm": algorithm, "test": Path(test.path).name, "n": int(truth.size),
        "fp": int(np.count_nonzero(predicted & ~truth)), "fn": int(np.count_nonzero(~predicted & truth)),
        "center_mm": None if found.center_mm is None else [round(v, 3) for v in found.center_mm],
        "radius_mm": round(found.radius_mm, 3),
    }
