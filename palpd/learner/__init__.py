"""The online learner: a GP map of stiffness, P(lump) at a learned threshold, lumps and the next probe."""
from palpd.learner.model import Learner
from palpd.learner.planner import ActivePlanner, palpation_time_s

__all__ = ["ActivePlanner", "Learner", "palpation_time_s"]
