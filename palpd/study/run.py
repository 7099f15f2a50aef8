"""A study: every method and algorithm on every test set, counted as false positives and negatives."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from palpd.study.classifiers import ALGORITHMS
from palpd.study.inputs import check_study
from palpd.study.methods import METHODS, RUNNERS, Options

def run_study(train, tests, options: Options = Options(), methods=METHODS) -> list[dict]:
    check_study(train, tests)
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
