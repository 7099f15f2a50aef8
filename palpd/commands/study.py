"""palpd study: the seed paper's five methods on dataset CSVs, with FP/FN per method and algorithm."""
from __future__ import annotations

import json
import math
import sys


def add_parser(subparsers):
    study = subparsers.add_parser("study", help="the seed paper's five lump-labelling methods on dataset CSVs")
    study.add_argument("--train", required=True, metavar="FILE.csv", help="labelled training set (tumor column)")
    study.add_argument("--test", required=True, action="append", metavar="FILE.csv", help="test set (repeatable)")
    study.add_argument("--report", metavar="FILE.json")
    study.add_argument("--plot", metavar="FILE.png", help="FP+FN bars (Figure 10) and maps (Figure 9)")
    study.add_argument("--svm-c", type=float, default=1.0, metavar="C", help="SVM and LR regularisation weight")
    study.add_argument("--centroid-weights", default="10,3", metavar="A,P", help="Equation 1's {10, 3}")
    return study


def run(args) -> int:
    from palpd.datafile import read_dataset
    from palpd.errors import UsageError
    from palpd.files import check_writable, write_json
    from palpd.study.inputs import check_study

    if not (math.isfinite(args.svm_c) and args.svm_c > 0):
        raise UsageError("--svm-c must be a positive number")
    weights = _weights(args.centroid_weights)
    train = read_dataset(args.train)
    tests = [read_dataset(path) for path in args.test]
    check_study(train, tests)
    check_writable(args.report, args.plot)
    # Only now scikit-learn (the methods): a bad argument or file above is a one-line error at once.
    from palpd.study.methods import Options
    from palpd.study.run import run_study

    options = Options(c=args.svm_c, centroid_weights=weights)
    results = run_study(train, tests, options)
    report = {"train": args.train, "tests": args.test, "svm_c": args.svm_c,
              "centroid_weights": list(options.centroid_weights), "gda": "LinearDiscriminantAnalysis",
              "results": results}
    if args.report:
        write_json(args.report, report)
    if args.plot:
        from palpd.study.plot import plot_study

        plot_study(results, tests, args.plot)
    _print_table(results)
    return 0


def _weights(text: str) -> tuple[float, float]:
    from palpd.errors import UsageError

    try:
        scale, power = (float(v) for v in text.split(","))
    except ValueError:
        raise UsageError(f"--centroid-weights {text!r}: expected two numbers A,P such as 10,3") from None
    if not (scale > 0 and math.isfinite(scale) and math.isfinite(power)):
        raise UsageError(f"--centroid-weights {text!r}: A must be positive and both finite")
    return scale, power


def _print_table(results: list[dict]) -> None:
    for r in results:
        centre = "none" if r["center_mm"] is None else f"({r['center_mm'][0]:.1f}, {r['center_mm'][1]:.1f})"
        print(f"{r['method']:26s} {r['algorithm'] or '-':4s} {r['test']:20s} n={r['n']:3d} fp={r['fp']:2d} "
              f"fn={r['fn']:2d} ({100 * (r['fp'] + r['fn']) / r['n']:4.1f} %) centre {centre} r {r['radius_mm']:.1f} mm")
    sys.stdout.flush()
