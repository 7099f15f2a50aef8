"""What a study's datasets must hold, checked before scikit-learn is loaded (a second of start-up), so a bad
file is a one-line error at once."""
from __future__ import annotations

import numpy as np

from palpd.errors import PalpdError

MIN_POINTS = 4  # two per class at least, for a classifier, and k-means needs more points than clusters


def check_study(train, tests) -> None:
    check_training(train)
    for test in tests:
        check_test(test)


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
