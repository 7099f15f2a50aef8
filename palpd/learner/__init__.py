"""The online learner: hypotheses about the lumps weighed by their evidence, the chosen one's lumps and next probe."""
from palpd.learner.model import Learner
from palpd.learner.planner import ActivePlanner, palpation_time_s

__all__ = ["ActivePlanner", "Learner", "palpation_time_s"]
