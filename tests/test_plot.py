"""The scan picture's words: what it says of the model chosen (palpd/plot.py)."""
from palpd.plot import _title

MODEL = {"chosen": "ellipse:1", "weight": 0.994}


def test_a_finished_scan_says_its_verdict_and_a_live_estimate_its_model():
    finished = _title({"scene": "paper", "strategy": "active", "palpations": 21, "verdict": "lumps", "model": MODEL})
    assert finished == "paper — active, 21 palpations, lumps: ellipse:1 (weight 0.99)"
    live = _title({"session": "20261126-204938", "palpations": 19, "model": MODEL})  # palpctl plot: no verdict yet
    assert live == "session 20261126-204938 — scan, 19 palpations, model ellipse:1 (weight 0.99)"
    assert _title({"session": "s", "palpations": 2, "model": None}) == "session s — scan, 2 palpations"
